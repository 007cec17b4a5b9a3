//! Known answers of docs/spec.md §2–3 (each line cited), Theorem 1 against the exact root-based
//! average, and Lemmas 1–2 as property tests. References are docs/spec.md's checked numbers or an
//! independent computation written here, never the code under test.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_3, FRAC_PI_4, PI, TAU};

use proptest::prelude::*;
use upm_core::friction::{feed_rate, gcd, mean_force, mean_forces, two_sinusoid_force};
use upm_core::theory::*;
use upm_core::{BangBang, Harmonics, Waveform};

fn two_harmonic(b: f64, phi: f64) -> Waveform {
    Harmonics::two_harmonic(b, phi, 1.0, 1.0 / TAU)
        .unwrap()
        .into()
}

/// `sin t + b cos 2t`, the waveform of (3.15) and Fig. 3.6.
fn sin_plus_cos2(b: f64) -> Waveform {
    Harmonics::new(vec![0.0, b], vec![1.0], 1.0 / TAU)
        .unwrap()
        .into()
}

/// Independent reference: mean of sgn(v) by the midpoint rule on a fine grid (error ~ 1/n).
fn sampled_mean_sign(v: impl Fn(f64) -> f64, n: usize) -> f64 {
    (0..n)
        .map(|i| v(TAU * (i as f64 + 0.5) / n as f64).signum())
        .sum::<f64>()
        / n as f64
}

#[test]
fn spec_2_1_bang_bang_known_answers() {
    // docs/spec.md §2.1 (checked; a_max = T = 1): z -> v_eq; z = 0.3 -> f/(mu m g) 0.09 at rest.
    for (z, v_eq) in [
        (0.1, 0.0025),
        (0.3, 0.0225),
        (0.5, 0.0625),
        (0.7, 0.0225),
        (0.9, 0.0025),
    ] {
        let w: Waveform = BangBang::new(z, 1.0, 1.0).unwrap().into();
        assert!((feed_rate(&w).unwrap() - v_eq).abs() < 1e-12, "z = {z}");
        assert!(
            (bang_bang_feed_rate(z, 1.0, 1.0).unwrap() - v_eq).abs() < 1e-15,
            "z = {z}"
        );
    }
    assert!((bang_bang_force(0.3, 0.0, 1.0, 1.0).unwrap() - 0.09).abs() < 1e-15);
    // eta1 = 0.0625, eta2 = 1/3 at the optimum z = 1/2 (3.5).
    let (e1, e2) = bang_bang_efficiency(0.5).unwrap();
    assert!((e1 - 0.0625).abs() < 1e-15 && (e2 - 1.0 / 3.0).abs() < 1e-15);
    // Viscous gain K = 4 mu m g / (a_max T) (3.12).
    assert!((viscous_gain(2.0, 0.5, 1.0).unwrap() - 4.0).abs() < 1e-15);
    assert!((viscous_gain(2.0, 0.5, 0.3).unwrap() - 1.2).abs() < 1e-15);
}

#[test]
fn spec_2_1_bang_bang_force_line_matches_the_exact_average() {
    // (3.10) f(v_p) = z^2 - 4 v_p / (a_max T) on [v_min, v_max), checked against the root-based average.
    for z in [0.0, 0.2, 0.5, 0.8] {
        let (a_max, period) = (3.0, 0.2);
        let w: Waveform = BangBang::new(z, a_max, period).unwrap().into();
        let (lo, hi) = bang_bang_velocity_range(z, a_max, period).unwrap();
        for k in 0..=20 {
            let vp = lo - 0.1 + (hi - lo + 0.2) * k as f64 / 20.0;
            let exact = mean_force(&w, vp).unwrap();
            let closed = bang_bang_force(z, vp, a_max, period).unwrap();
            assert!(
                (exact - closed).abs() < 1e-12,
                "z={z} vp={vp}: {exact} vs {closed}"
            );
        }
    }
}

#[test]
fn spec_2_2_two_harmonic_feed_rates() {
    // docs/spec.md §2.2 (checked). Erratum E1: Fig. 3.7's caption lists (1/2, 1/3, 1/4) for
    // (1/2, pi/2), (1, pi/2), (1/2, pi/4); (3.16)/(3.17) and simulation give (0.5, 0.25, 0.354).
    let cases = [
        (0.5, FRAC_PI_2, 0.5),
        (1.0, FRAC_PI_2, 0.25),
        (0.5, FRAC_PI_4, 0.3536),
        (0.25, FRAC_PI_2, 0.25),
        (0.3, FRAC_PI_3, 0.2598),
        (2.0, FRAC_PI_2, 0.125),
    ];
    for (b, phi, want) in cases {
        let got = feed_rate(&two_harmonic(b, phi)).unwrap();
        assert!((got - want).abs() < 5e-5, "({b}, {phi}): {got} vs {want}");
        let closed = two_harmonic_feed_rate(b, phi, 1.0).unwrap();
        assert!(
            (got - closed).abs() < 1e-12,
            "({b}, {phi}): exact {got} vs (3.16)/(3.17) {closed}"
        );
    }
}

#[test]
fn spec_2_2_two_harmonic_forces_at_rest() {
    // docs/spec.md §2.2 (checked): force at rest for (b, phi) = (0.5, pi/2) 0.2386, (1, pi/2) 0.3333,
    // (0.5, pi/4) 0.2237, (0.25, pi/2) 0.1443.
    for (b, phi, want) in [
        (0.5, FRAC_PI_2, 0.2386),
        (1.0, FRAC_PI_2, 0.3333),
        (0.5, FRAC_PI_4, 0.2237),
        (0.25, FRAC_PI_2, 0.1443),
    ] {
        let got = mean_force(&two_harmonic(b, phi), 0.0).unwrap();
        assert!((got - want).abs() < 5e-5, "({b}, {phi}): {got} vs {want}");
    }
}

#[test]
fn spec_2_2_eq_3_15_closed_form() {
    // docs/spec.md §2.2: eq. (3.15) b = 0.25 -> 0.1443, b = 0.9 -> 0.3201, b = 1.5 -> 0.0813.
    // Erratum E3: "f ~ b/3 for |b| < 1" is loose: b = 0.5 gives 0.2386, not 0.167.
    for (b, want) in [(0.25, 0.1443), (0.9, 0.3201), (1.5, 0.0813), (0.5, 0.2386)] {
        let closed = two_harmonic_force_at_rest(b).unwrap();
        let exact = mean_force(&sin_plus_cos2(b), 0.0).unwrap();
        assert!(
            (exact - want).abs() < 5e-5,
            "b = {b}: exact {exact} vs docs/spec.md {want}"
        );
        assert!(
            (closed - exact).abs() < 1e-12,
            "b = {b}: (3.15) {closed} vs exact {exact}"
        );
    }
    assert!((two_harmonic_force_at_rest(0.5).unwrap() - 0.5 / 3.0).abs() > 0.07);
}

#[test]
fn eq_3_15_is_odd_in_b_and_right_on_every_branch() {
    // The b < -1 branch as printed ("1 - 2 c2/pi") is not odd in b; the odd extension agrees with
    // an independent sampled average on all three branches.
    for b in [-3.0, -1.7, -1.0, -0.6, -0.1, 0.1, 0.6, 1.0, 1.7, 3.0] {
        let closed = two_harmonic_force_at_rest(b).unwrap();
        let sampled = sampled_mean_sign(|t| t.sin() + b * (2.0 * t).cos(), 2_000_000);
        assert!(
            (closed - sampled).abs() < 2e-6,
            "b = {b}: {closed} vs sampled {sampled}"
        );
        assert_eq!(closed, -two_harmonic_force_at_rest(-b).unwrap());
    }
    // Fig. 3.6: the force at rest peaks at b = 1 and the feed rate at b = 1/2.
    let f = |b: f64| two_harmonic_force_at_rest(b).unwrap();
    assert!(f(1.0) > f(0.95) && f(1.0) > f(1.05));
    let v = |b: f64| feed_rate(&sin_plus_cos2(b)).unwrap();
    assert!(v(0.5) > v(0.45) && v(0.5) > v(0.55));
}

#[test]
fn spec_2_2_gamma_and_normalised_drive() {
    // docs/spec.md §2.2: gamma(1/2) = 1.7602, gamma(1) = 2.7358 (E2: computed, not the printed form);
    // at b = 1/2: v_min = -3 a T/(4 pi gamma), v_max = 3 a T/(8 pi gamma), v_eq = a T/(4 pi gamma),
    // eta1 = 0.0452, eta2 = 1/3.
    assert!((gamma(0.5).unwrap() - 1.7602).abs() < 5e-5);
    assert!((gamma(1.0).unwrap() - 2.7358).abs() < 5e-5);
    let (a, t) = (16.0, 0.03);
    let d = normalized_drive(0.5, a, t).unwrap();
    assert!((d.v_min + 3.0 * a * t / (4.0 * PI * d.gamma)).abs() < 1e-14);
    assert!((d.v_max - 3.0 * a * t / (8.0 * PI * d.gamma)).abs() < 1e-14);
    assert!((d.v_eq - a * t / (4.0 * PI * d.gamma)).abs() < 1e-14);
    assert!((d.eta1 - 0.0452).abs() < 5e-5 && (d.eta2 - 1.0 / 3.0).abs() < 1e-14);
    // The normalised acceleration peaks at exactly a_max and the closed forms match the waveform.
    for b in [0.1, 0.3, 0.5, 0.9, 2.0] {
        let d = normalized_drive(b, a, t).unwrap();
        let w = TAU / t;
        let scale = a / (d.gamma * w);
        let vel: Waveform = Harmonics::new(vec![0.0, scale * b], vec![scale], 1.0 / t)
            .unwrap()
            .into();
        let peak = (0..20_000)
            .map(|i| vel.acceleration(t * i as f64 / 20_000.0).abs())
            .fold(0.0, f64::max);
        assert!(
            (peak - a).abs() < 1e-3 * a,
            "b = {b}: peak acceleration {peak}"
        );
        let (lo, hi) = vel.pieces().unwrap().range();
        assert!(
            (lo - d.v_min).abs() < 1e-12 && (hi - d.v_max).abs() < 1e-12,
            "b = {b}"
        );
        assert!((feed_rate(&vel).unwrap() - d.v_eq).abs() < 1e-12, "b = {b}");
    }
}

#[test]
fn spec_3_theorem1_against_exact_average_for_every_coprime_pair_up_to_7() {
    // docs/spec.md §3: f = Tri(n1 n2 psi)/(n2^2 - n1^2) (checked to 1e-5); both odd -> 0 (Lemma 1).
    let mut pairs = 0;
    for n2 in 2..=7i64 {
        for n1 in 1..n2 {
            if gcd(n1, n2) != 1 {
                continue;
            }
            pairs += 1;
            for k in 0..97 {
                let psi = -1.0 + 7.3 * k as f64 / 96.0;
                let closed = theorem1_force(n1, n2, psi).unwrap();
                let exact = two_sinusoid_force(n1, n2, psi, 1.0).unwrap();
                assert!(
                    (closed - exact).abs() < 1e-9,
                    "({n1},{n2}) psi={psi}: {closed} vs {exact}"
                );
            }
        }
    }
    assert_eq!(pairs, 17);
}

#[test]
fn spec_3_peaks_periods_and_corollaries() {
    // Peaks 1/(n2^2 - n1^2) at psi = 0; period in psi 2 pi/(n1 n2); aligned roots -> 0 (Cor. 2).
    for (n1, n2, peak) in [
        (1, 2, 1.0 / 3.0),
        (2, 3, 0.2),
        (1, 4, 1.0 / 15.0),
        (2, 5, 1.0 / 21.0),
        (3, 4, 1.0 / 7.0),
    ] {
        assert!((two_sinusoid_force(n1, n2, 0.0, 1.0).unwrap() - peak).abs() < 1e-12);
        let period = TAU / (n1 * n2) as f64;
        for psi in [0.1, 0.7, 1.3] {
            let a = two_sinusoid_force(n1, n2, psi, 1.0).unwrap();
            let b = two_sinusoid_force(n1, n2, psi + period, 1.0).unwrap();
            assert!((a - b).abs() < 1e-12);
        }
        let quarter = period / 4.0; // Tri crosses zero a quarter period from its peak.
        assert!(two_sinusoid_force(n1, n2, quarter, 1.0).unwrap().abs() < 1e-12);
    }
    // Corollary 1: (1, 2) with psi = 0 is the maximum over all pairs and phases.
    let best = (2..=9i64)
        .flat_map(|n2| {
            (1..n2)
                .filter(move |&n1| gcd(n1, n2) == 1)
                .map(move |n1| (n1, n2))
        })
        .flat_map(|(n1, n2)| {
            (0..64).map(move |k| two_sinusoid_force(n1, n2, TAU * k as f64 / 64.0, 1.0).unwrap())
        })
        .fold(f64::NEG_INFINITY, f64::max);
    assert!((best - 1.0 / 3.0).abs() < 1e-12);
    // docs/spec.md §3: cos t - cos(2t)/2 -> 0.2386 (the "0.24 mu m g" of 5.1.2 and 6.4).
    assert!((two_sinusoid_force(1, 2, 0.0, 0.5).unwrap() - 0.2386).abs() < 5e-5);
}

#[test]
fn mean_force_decreases_with_part_velocity_and_vanishes_at_the_feed_rate() {
    for (b, phi) in [(0.5, FRAC_PI_2), (1.0, 1.0), (0.2, -0.4), (3.0, 2.0)] {
        let w = two_harmonic(b, phi);
        let (lo, hi) = w.pieces().unwrap().range();
        let vs: Vec<f64> = (0..=400)
            .map(|k| lo - 0.05 + (hi - lo + 0.1) * k as f64 / 400.0)
            .collect();
        let f = mean_forces(&w, &vs).unwrap();
        assert!(
            f.windows(2).all(|p| p[1] <= p[0] + 1e-15),
            "not monotone for ({b}, {phi})"
        );
        assert_eq!(f[0], 1.0);
        assert_eq!(f[400], -1.0);
        let v_eq = feed_rate(&w).unwrap();
        assert!(mean_force(&w, v_eq).unwrap().abs() < 1e-9, "({b}, {phi})");
    }
}

#[test]
fn exact_average_agrees_with_fine_sampling() {
    // An independent check of the root machinery on a five-harmonic waveform with close extrema.
    let cos = vec![0.3, -0.8, 0.05, 0.4, -0.2];
    let sin = vec![1.0, 0.25, -0.6, 0.1, 0.33];
    let w: Waveform = Harmonics::new(cos.clone(), sin.clone(), 1.0 / TAU)
        .unwrap()
        .into();
    let v = |t: f64| {
        (0..5)
            .map(|k| cos[k] * ((k + 1) as f64 * t).cos() + sin[k] * ((k + 1) as f64 * t).sin())
            .sum::<f64>()
    };
    for level in [-0.7, -0.1, 0.0, 0.4, 1.1] {
        let exact = mean_force(&w, level).unwrap();
        let sampled = sampled_mean_sign(|t| v(t) - level, 2_000_000);
        assert!(
            (exact - sampled).abs() < 5e-6,
            "level {level}: {exact} vs {sampled}"
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn lemma1_both_odd_never_feed(b in -3.0f64..3.0, phi in -4.0f64..4.0, pair in 0usize..5) {
        // Lemma 1: sin(n1 t) + b sin(n2 (t - phi)) with n1, n2 both odd -> f = 0.
        let (n1, n2) = [(1usize, 3usize), (1, 5), (3, 5), (3, 7), (5, 7)][pair];
        let mut cos = vec![0.0; n2];
        let mut sin = vec![0.0; n2];
        sin[n1 - 1] = 1.0;
        let (s, c) = (n2 as f64 * phi).sin_cos();
        sin[n2 - 1] = b * c;
        cos[n2 - 1] = -b * s;
        let w: Waveform = Harmonics::new(cos, sin, 1.0 / TAU).unwrap().into();
        prop_assert!(mean_force(&w, 0.0).unwrap().abs() < 1e-12);
    }

    #[test]
    fn lemma2_zero_phase_never_feeds(b in -3.0f64..3.0, pair in 0usize..6) {
        // Lemma 2: phi = 0 makes sigma odd in t -> f = 0, for any pair.
        let (n1, n2) = [(1usize, 2usize), (2, 3), (1, 4), (3, 4), (2, 5), (1, 6)][pair];
        let mut sin = vec![0.0; n2];
        sin[n1 - 1] = 1.0;
        sin[n2 - 1] = b;
        let w: Waveform = Harmonics::new(vec![], sin, 1.0 / TAU).unwrap().into();
        prop_assert!(mean_force(&w, 0.0).unwrap().abs() < 1e-12);
    }

    #[test]
    fn two_harmonic_closed_form_holds_for_small_b(b in -0.5f64..0.5, phi in -4.0f64..4.0) {
        let exact = feed_rate(&two_harmonic(b, phi)).unwrap();
        prop_assert!((exact - b * phi.sin()).abs() < 1e-11, "{} vs {}", exact, b * phi.sin());
    }
}
