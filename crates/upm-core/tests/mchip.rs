//! The M-Chip model (rapier3d) against references independent of it: a damped oscillator's
//! decay and frequency, its linear steady response, no feeding without drive, feeding with it,
//! and results that hold when the step is halved or the solver iterates more.

use std::f64::consts::PI;

use upm_core::mchip::{simulate, Design, Drive, Output, Scheme, Settings};

fn one_resonator(quality: f64) -> Design {
    Design {
        rows: 1,
        cols: 1,
        quality,
        ..Design::default()
    }
}

/// Local maxima of a sampled signal: (time, value).
fn peaks(t: &[f64], y: &[f64]) -> Vec<(f64, f64)> {
    (1..y.len() - 1)
        .filter(|&k| y[k] > y[k - 1] && y[k] >= y[k + 1])
        .map(|k| (t[k], y[k]))
        .collect()
}

/// Quality factor and period of a free ring-down from a 0.05 rad start.
fn ring_down(q: f64, dt: f64, iterations: usize) -> (f64, f64) {
    let settings = Settings {
        duration: 2e-3,
        dt,
        iterations,
        record_every: 1,
        initial_angle: 0.05,
        part: false,
        ..Settings::default()
    };
    let drive = Drive {
        scheme: Scheme::Off,
        ..Drive::default()
    };
    let out = simulate(&one_resonator(q), &drive, &settings).unwrap();
    let p = peaks(&out.t, &out.angles);
    assert!(p.len() >= 4, "{p:?}");
    // Logarithmic decrement of a linear damped oscillator: delta = 2 pi zeta / sqrt(1 - zeta^2).
    let delta = (p[0].1 / p[3].1).ln() / 3.0;
    let zeta = delta / (4.0 * PI * PI + delta * delta).sqrt();
    (1.0 / (2.0 * zeta), (p[3].0 - p[0].0) / 3.0)
}

#[test]
fn a_free_resonator_rings_down_with_the_quality_factor_set() {
    // The logarithmic decrement gives back the Q set, at the default step and for 1, 4 and 8
    // solver substeps (the spring is read where it keeps rapier's substepping area-preserving;
    // without that, Q = 50 came out as 121 at dt = 1 us).
    for iterations in [1, 4, 8] {
        for q in [5.0, 50.0] {
            let (got, period) = ring_down(q, 1e-6, iterations);
            assert!(
                (got / q - 1.0).abs() < 0.005,
                "Q = {got} for {q} with {iterations} substeps"
            );
            let want_period = 1.0 / (5000.0 * (1.0 - 0.25 / (q * q)).sqrt());
            assert!(
                (period / want_period - 1.0).abs() < 0.005,
                "period {period} vs {want_period}"
            );
        }
    }
    // Halving the step changes Q = 5 by less than 0.1%.
    let (coarse, _) = ring_down(5.0, 1e-6, 4);
    let (fine, _) = ring_down(5.0, 0.5e-6, 4);
    assert!((coarse / fine - 1.0).abs() < 1e-3, "{coarse} vs {fine}");
}

#[test]
fn the_driven_resonator_peaks_at_the_angle_asked_and_never_goes_far_below_zero() {
    // The torque is sized from the Fourier series of the linear response; the simulated steady
    // oscillation must reach it (0.08 rad) and stay positive but for the small undershoot.
    let out = simulate(
        &one_resonator(0.8),
        &Drive::default(),
        &Settings {
            duration: 4e-3,
            record_every: 1,
            part: false,
            ..Settings::default()
        },
    )
    .unwrap();
    let late = out.t.len() / 2;
    let hi = out.angles[late..].iter().copied().fold(f64::MIN, f64::max);
    let lo = out.angles[late..].iter().copied().fold(f64::MAX, f64::min);
    assert!((hi - 0.08).abs() < 0.08 * 0.01, "peak {hi}");
    assert!(lo > -0.01, "trough {lo}");
}

fn feed(out: &Output) -> f64 {
    let n = out.t.len();
    let k = n / 3;
    (out.position[n - 1][0] - out.position[k][0]) / (out.t[n - 1] - out.t[k])
}

fn run(drive: Drive, dt: f64, iterations: usize) -> Output {
    simulate(
        &Design::default(),
        &drive,
        &Settings {
            duration: 0.03,
            dt,
            iterations,
            record_every: 50,
            ..Settings::default()
        },
    )
    .unwrap()
}

#[test]
fn the_part_feeds_forward_only_when_driven_and_the_rate_survives_halving_dt() {
    let off = run(
        Drive {
            scheme: Scheme::Off,
            ..Drive::default()
        },
        1e-6,
        4,
    );
    let still = feed(&off).abs();
    assert!(still < 1e-6, "undriven part moved at {still} m/s");
    let on = run(Drive::default(), 1e-6, 4);
    let rate = feed(&on);
    assert!(rate > 5e-4, "driven feed rate {rate} m/s");
    // Impacts are chaotic in detail; the mean feed rate must not depend on the numerics.
    for (dt, it) in [(0.5e-6, 4), (1e-6, 8)] {
        let other = feed(&run(Drive::default(), dt, it));
        assert!(
            (other / rate - 1.0).abs() < 0.25,
            "dt {dt}, {it} iterations: {other} vs {rate}"
        );
    }
    // Most of the part's energy is in the vertical hop.
    let e = on.energy;
    assert!(e.part_translation[2] > 5.0 * e.part_translation[0].max(e.part_translation[1]));
}

#[test]
fn bad_designs_and_drives_are_refused_by_name() {
    let s = Settings::default();
    let bad = |d: Design, dr: Drive, word: &str| {
        let e = simulate(&d, &dr, &s).unwrap_err().to_string();
        assert!(e.starts_with(word), "{e}");
    };
    bad(
        Design {
            ridge_distance: 1e-3,
            ..Design::default()
        },
        Drive::default(),
        "ridge_distance",
    );
    bad(
        Design::default(),
        Drive {
            duty: 0.0,
            ..Drive::default()
        },
        "duty",
    );
    bad(
        Design::default(),
        Drive {
            scheme: Scheme::Strobe { tau: 0, delta: 4 },
            ..Drive::default()
        },
        "scheme",
    );
    bad(
        Design::default(),
        Drive {
            scheme: Scheme::Phases(vec![0.0; 3]),
            ..Drive::default()
        },
        "phases",
    );
    let e = simulate(
        &Design::default(),
        &Drive::default(),
        &Settings {
            dt: 1e-5,
            ..Settings::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.starts_with("dt"), "{e}");
}
