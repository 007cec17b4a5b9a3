//! Plate motion programs: the velocity-only paths (`velocity`, the simulator's table through
//! `velocities_into`) against the closed forms of docs/spec.md §1 and 6.4, written out here.

use std::f64::consts::{PI, TAU};

use upm_core::motion::PlateMotion;
use upm_core::{Harmonics, Waveform};

fn two_harmonic(frequency: f64) -> Waveform {
    Harmonics::new(vec![0.7, -0.35], vec![0.1, 0.05], frequency)
        .unwrap()
        .into()
}

/// A program of every timed kind: an enveloped jet, an enveloped rotation, a rest and a
/// translation, then rest for ever.
fn program() -> PlateMotion {
    let jet = PlateMotion::jet([0.03, -0.02], [0.6, 0.8], 0.05, 0.4, 35.0)
        .unwrap()
        .with_envelope(0.1, 0.15, 0.08)
        .unwrap();
    let rotation = PlateMotion::rotation([0.1, 0.05], two_harmonic(50.0))
        .unwrap()
        .with_envelope(0.06, 0.1, 0.06)
        .unwrap();
    let translation = PlateMotion::translation([1.0, 1.0], two_harmonic(25.0))
        .unwrap()
        .for_duration(0.2)
        .unwrap();
    PlateMotion::sequence(vec![
        jet,
        rotation,
        PlateMotion::rest(0.05).unwrap(),
        translation,
    ])
    .unwrap()
}

fn raised(t: f64, attack: f64, sustain: f64, decay: f64) -> f64 {
    let ramp = |s: f64, len: f64| 0.5 - 0.5 * (PI * s / len).cos();
    if t < attack {
        ramp(t, attack)
    } else if t <= attack + sustain {
        1.0
    } else {
        ramp(attack + sustain + decay - t, decay)
    }
}

/// The same program written out from its formulas, one trigonometric call per term.
fn reference(t: f64) -> [f64; 3] {
    let harm = |f: f64, t: f64| {
        let x = TAU * f * t;
        0.7 * x.cos() + 0.1 * x.sin() - 0.35 * (2.0 * x).cos() + 0.05 * (2.0 * x).sin()
    };
    let (a, b, c) = (0.33, 0.33 + 0.22, 0.33 + 0.22 + 0.05);
    if t < a {
        let w = TAU * 35.0;
        let g = (w * t).cos() - (2.0 * w * t).cos();
        let spin = 2.0 * 0.4 / 0.05 * (2.0 * w * t / 3.0).sin();
        let e = raised(t, 0.1, 0.15, 0.08);
        [
            e * (0.4 * 0.6 * g + spin * -0.02),
            e * (0.4 * 0.8 * g - spin * 0.03),
            e * spin,
        ]
    } else if t < b {
        let w = raised(t - a, 0.06, 0.1, 0.06) * harm(50.0, t - a);
        [w * 0.05, -w * 0.1, w]
    } else if t < c {
        [0.0; 3]
    } else if t < c + 0.2 {
        let v = harm(25.0, t - c) / 2f64.sqrt();
        [v, v, 0.0]
    } else {
        [0.0; 3]
    }
}

#[test]
fn velocity_matches_the_closed_forms_and_the_full_evaluation() {
    let m = program();
    for k in 0..20_000 {
        let t = k as f64 * 4.3e-5 + 1e-7;
        let (v, f, r) = (m.velocity(t), m.at(t).0, reference(t));
        for j in 0..3 {
            assert!((v[j] - r[j]).abs() <= 1e-12, "t = {t}: {v:?} vs {r:?}");
            assert!((v[j] - f[j]).abs() <= 1e-13, "t = {t}: {v:?} vs at() {f:?}");
        }
    }
}

#[test]
fn the_table_is_the_velocity_at_each_step_end() {
    let m = program();
    let dt = 1.0 / 3360.0;
    for (first, end) in [(0, 2800), (1, 2), (700, 1900), (2500, 3000)] {
        let mut out = vec![[9.0; 3]];
        m.velocities_into(first..end, dt, &mut out);
        assert_eq!(out.len(), 1 + end - first);
        for (s, u) in (first..end).zip(&out[1..]) {
            // the table carries its sines by rotation: the closed forms to the same bound as
            // the direct evaluation, and that within both's rounding of the phase (about
            // `w t` units in the last place of amplitudes up to 16 rad/s here)
            let t = ((s + 1) as f64 - 1e-6) * dt;
            let (v, r) = (m.velocity(t), reference(t));
            for j in 0..3 {
                assert!((u[j] - r[j]).abs() <= 1e-12, "step {s}: {u:?} vs {r:?}");
                assert!(
                    (u[j] - v[j]).abs() <= 5e-13,
                    "step {s}: {u:?} vs velocity() {v:?}"
                );
            }
        }
    }
}
