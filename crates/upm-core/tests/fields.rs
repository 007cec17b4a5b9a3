//! Known answers of docs/spec.md §7 (jets) and agreement of the general average with the closed forms.

use std::f64::consts::PI;

use upm_core::field::{self, TOL};
use upm_core::motion::PlateMotion;
use upm_core::{friction, Harmonics, Waveform};

#[test]
fn jet_known_answers() {
    // docs/spec.md §7: d = (0, 1), rho = 1, C = 0; force / (mu m g), four decimals.
    let cases = [
        ([0.0, 0.0], [0.0, 0.3333]),
        ([0.25, 0.0], [0.0, 0.1869]),
        ([0.5, 0.0], [0.0, 0.0813]),
        ([1.0, 0.0], [0.0, -0.0559]),
        ([2.0, 0.0], [0.0, 0.0138]),
        ([4.0, 0.0], [0.0, 0.0036]),
        ([0.0, 0.5], [0.0, 0.1442]),
        ([0.0, 1.0], [0.0, 0.0821]),
        ([0.0, 2.0], [0.0, 0.0434]),
        ([0.7, 0.7], [0.0443, 0.0425]),
    ];
    for (p, want) in cases {
        let f = field::jet_field(p, [0.0, 0.0], [0.0, 1.0], 1.0, TOL).unwrap();
        assert!(
            (f[0] - want[0]).abs() < 6e-5 && (f[1] - want[1]).abs() < 6e-5,
            "{p:?}: {f:?} vs {want:?}"
        );
    }
    // Corollary 1: exactly a third at the focus.
    let f = field::jet_field([0.0, 0.0], [0.0, 0.0], [0.0, 1.0], 1.0, TOL).unwrap();
    assert!((f[1] - 1.0 / 3.0).abs() < 1e-12 && f[0] == 0.0);
}

#[test]
fn jets_are_covariant_under_rigid_motions_and_scaling() {
    // Rotating and shifting the whole layout rotates the field; scaling rho with P - C leaves it.
    let (s, c) = (0.3f64).sin_cos();
    let rot = |v: [f64; 2]| [c * v[0] - s * v[1], s * v[0] + c * v[1]];
    let centre = [0.2, -0.1];
    for p in [[0.3, 0.4], [-0.7, 0.1], [0.05, -1.3]] {
        let f = field::jet_field(p, [0.0, 0.0], [0.0, 1.0], 1.0, TOL).unwrap();
        let q = rot(p);
        let g = field::jet_field(
            [q[0] + centre[0], q[1] + centre[1]],
            centre,
            rot([0.0, 2.0]),
            1.0,
            TOL,
        )
        .unwrap();
        let want = rot(f);
        assert!((g[0] - want[0]).abs() < 1e-9 && (g[1] - want[1]).abs() < 1e-9);
        let h =
            field::jet_field([3.0 * p[0], 3.0 * p[1]], [0.0, 0.0], [0.0, 1.0], 3.0, TOL).unwrap();
        assert!((h[0] - f[0]).abs() < 1e-9 && (h[1] - f[1]).abs() < 1e-9);
    }
}

#[test]
fn average_field_agrees_with_the_jet_and_rotation_closed_forms() {
    let jet = PlateMotion::jet([0.1, 0.0], [1.0, 1.0], 0.05, 0.3, 35.0).unwrap();
    for p in [[0.1, 0.0], [0.13, 0.02], [0.08, -0.04], [0.15, 0.0]] {
        let a = field::average_field(&jet, p, [0.0, 0.0], TOL).unwrap();
        let b = field::jet_field(p, [0.1, 0.0], [1.0, 1.0], 0.05, TOL).unwrap();
        assert!(
            (a[0] - b[0]).abs() < 1e-8 && (a[1] - b[1]).abs() < 1e-8,
            "{p:?}: {a:?} {b:?}"
        );
    }
    // Time-asymmetric rotation cos wt - cos(2wt)/2: every resting part gets mean_sign * tangent.
    let wave = Waveform::from(Harmonics::new(vec![1.0, -0.5], vec![0.0, 0.0], 35.0).unwrap());
    let f0 = friction::mean_force(&wave, 0.0).unwrap();
    assert!((f0 - 0.2386).abs() < 1e-4, "{f0}");
    let rot = PlateMotion::rotation([-0.05, 0.02], wave).unwrap();
    for p in [[0.1, 0.0], [-0.2, 0.3], [0.0, -0.01]] {
        let a = field::average_field(&rot, p, [0.0, 0.0], TOL).unwrap();
        let t = field::rotation_field(p, [-0.05, 0.02]);
        assert!(
            (a[0] - f0 * t[0]).abs() < 1e-9 && (a[1] - f0 * t[1]).abs() < 1e-9,
            "{a:?}"
        );
    }
}

#[test]
fn average_field_of_a_translation_is_the_exact_one_dimensional_force() {
    // A moving part: the 1-D root-based mean sign at the relative velocity.
    let wave = Waveform::from(Harmonics::two_harmonic(0.5, 0.5 * PI, 0.4, 20.0).unwrap());
    let (s, c) = (0.7f64).sin_cos();
    let m = PlateMotion::translation([c, s], wave.clone()).unwrap();
    for v in [0.0, 0.05, -0.12] {
        let a = field::average_field(&m, [0.3, 0.1], [v * c, v * s], TOL).unwrap();
        let f = friction::mean_force(&wave, v).unwrap();
        assert!(
            (a[0] - f * c).abs() < 1e-9 && (a[1] - f * s).abs() < 1e-9,
            "{v}: {a:?} {f}"
        );
    }
}

#[test]
fn sequences_average_their_items_by_duration() {
    let wave = Waveform::from(Harmonics::new(vec![1.0, -0.5], vec![0.0, 0.0], 10.0).unwrap());
    let a = PlateMotion::rotation([0.0, 0.0], wave.clone())
        .unwrap()
        .for_duration(0.3)
        .unwrap();
    let b = PlateMotion::rest(0.1).unwrap();
    let m = PlateMotion::sequence(vec![a, b]).unwrap();
    let f0 = friction::mean_force(&wave, 0.0).unwrap();
    let got = field::average_field(&m, [0.0, 0.2], [0.0, 0.0], TOL).unwrap();
    assert!(
        (got[0] + 0.75 * f0).abs() < 1e-9 && got[1].abs() < 1e-12,
        "{got:?}"
    );
}
