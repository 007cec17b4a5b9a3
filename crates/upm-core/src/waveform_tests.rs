//! Tests of the waveforms ([`super`]).
use super::*;

#[test]
fn two_harmonic_matches_its_definition() {
    let (b, phi, a, f) = (0.7, 0.4, 2.0, 3.0);
    let w: Waveform = Harmonics::two_harmonic(b, phi, a, f).unwrap().into();
    for &t in &[0.0, 0.01, 0.1234, 0.3] {
        let wt = TAU * f * t;
        let v = a * (wt.sin() + b * (2.0 * wt + phi).sin());
        let acc = a * TAU * f * (wt.cos() + 2.0 * b * (2.0 * wt + phi).cos());
        assert!((w.velocity(t) - v).abs() < 1e-13);
        assert!((w.acceleration(t) - acc).abs() < 1e-11);
    }
}

#[test]
fn pieces_cover_a_period_and_find_the_range() {
    // sin t + cos(2t)/2 ranges over [-1.5, 0.75] (docs/spec.md §2.2).
    let w: Waveform = Harmonics::new(vec![0.0, 0.5], vec![1.0], 1.0)
        .unwrap()
        .into();
    let p = w.pieces().unwrap();
    let total: f64 = p.pieces().iter().map(|q| q.x1 - q.x0).sum();
    assert!((total - TAU).abs() < 1e-12);
    let (lo, hi) = p.range();
    assert!(
        (lo + 1.5).abs() < 1e-14 && (hi - 0.75).abs() < 1e-14,
        "{lo} {hi}"
    );
}

#[test]
fn bang_bang_is_continuous_and_zero_mean() {
    let b = BangBang::new(0.3, 2.0, 0.5).unwrap();
    let w: Waveform = b.into();
    let n = 100_000;
    let mean: f64 = (0..n)
        .map(|i| w.velocity(0.5 * (i as f64 + 0.5) / n as f64))
        .sum::<f64>()
        / n as f64;
    assert!(mean.abs() < 1e-9, "{mean}");
    let (t1, t2) = (0.35 * 0.5, 0.65 * 0.5);
    for t in [t1, t2, 0.5] {
        assert!((w.velocity(t - 1e-12) - w.velocity(t)).abs() < 1e-9);
    }
}

#[test]
fn direct_and_piecewise_mean_signs_agree() {
    let w: Waveform = Harmonics::new(vec![0.3, -0.8, 0.05, 0.4], vec![1.0, 0.25, -0.6, 0.1], 2.0)
        .unwrap()
        .into();
    let p = w.pieces().unwrap();
    let (lo, hi) = p.range();
    for k in 0..=50 {
        let level = lo - 0.1 + (hi - lo + 0.2) * k as f64 / 50.0;
        let (a, b) = (w.mean_sign(level).unwrap(), p.mean_sign(level));
        assert!((a - b).abs() < 1e-12, "level {level}: {a} vs {b}");
    }
}

#[test]
fn extreme_scales_give_the_same_shape() {
    // Root finding runs in normalised units, so 1e-300 and 1e300 m/s behave like 1 m/s.
    for scale in [1e-300, 1e-5, 1.0, 1e300] {
        let w: Waveform = Harmonics::two_harmonic(0.5, 1.0, scale, 1.0)
            .unwrap()
            .into();
        let p = w.pieces().unwrap();
        let want = 0.5 * 1f64.sin(); // (3.16)
        assert!((p.median() / scale - want).abs() < 1e-12, "scale {scale}");
    }
    assert!(BangBang::new(0.5, 1e300, 1e300).is_err());
    let tiny: Waveform = BangBang::new(0.5, 1e-200, 1e-100).unwrap().into();
    assert!((crate::friction::feed_rate(&tiny).unwrap() / 1e-300 - 0.0625).abs() < 1e-12);
}

#[test]
fn rejects_bad_parameters() {
    assert!(
        matches!(BangBang::new(1.0, 1.0, 1.0), Err(Error::Parameter { ref name, .. }) if name == "z")
    );
    assert!(matches!(
        Harmonics::new(vec![0.0], vec![0.0], 1.0),
        Err(Error::Parameter { .. })
    ));
    assert!(
        matches!(Harmonics::new(vec![f64::NAN], vec![], 1.0), Err(Error::Parameter { ref name, .. }) if name == "cos[0]")
    );
    assert!(Harmonics::new(vec![1.0], vec![], 0.0).is_err());
}
