//! Polygon parts on a plate that moves out of its plane (docs/spec.md §10, §11) against
//! references outside the polygon step: the point part's step at the centroid, and the closed
//! form of a square spinning down under a varying normal force.

use std::f64::consts::PI;

use upm_core::motion::spatial::{Spatial, Term};
mod common;

use common::pentagon;
use upm_core::motion::PlateMotion;
use upm_core::polygon::Polygon;
use upm_core::sim::{simulate, Config, Parts};

const G: f64 = 9.81;

fn term(amplitude: f64, phase: f64) -> Vec<Term> {
    vec![Term {
        harmonic: 1,
        amplitude,
        phase,
    }]
}

/// 20 Hz: the PPOD's circular translation (x'', y'' of its Sink) and a heave, `z'' = 14
/// sin(wt)` (> g: it throws parts) when `lift`, else `6 sin(wt + 1)`; no rocking, so the pressure
/// stays uniform across a part.
fn heaving(lift: bool) -> PlateMotion {
    let z = if lift {
        term(14.0, 0.0)
    } else {
        term(6.0, 1.0)
    };
    let terms = [
        term(10.0, 0.0),
        term(10.0, PI / 2.0),
        z,
        Vec::new(),
        Vec::new(),
        Vec::new(),
    ];
    PlateMotion::spatial(Spatial::new(20.0, terms).unwrap())
}

fn cfg(dt: f64, steps: usize) -> Config {
    Config {
        dt,
        duration: steps as f64 * dt,
        g: G,
        plate_size: None,
        record_every: 1,
        tilt: [0.0; 2],
    }
}

fn polygon_parts(shape: &Polygon, origin: [f64; 2], spin: f64, mu: f64) -> Parts {
    Parts {
        position: vec![origin],
        velocity: vec![[0.0; 2]],
        mu: vec![mu],
        mu_s: vec![mu],
        radius: vec![0.0],
        angle: vec![0.0],
        spin: vec![spin],
        polygons: vec![(0, shape.clone())],
    }
}

#[test]
fn a_polygon_that_does_not_spin_moves_and_flies_like_a_point_at_its_centroid() {
    // Without rocking the pressure is uniform, scaled by the normal force: a part that translates
    // feels the force a point at its centroid feels, and leaves and lands with it.
    let shape = pentagon();
    let dt = 1.0 / 20.0 / 400.0;
    let c = cfg(dt, 1600);
    // (mu 1.1: static friction holds the part through part of each cycle)
    for (lift, origin, mu) in [(false, [0.05, -0.03], 1.1), (true, [0.04, 0.02], 0.35)] {
        let motion = heaving(lift);
        let poly = simulate(&motion, &polygon_parts(&shape, origin, 0.0, mu), &c).unwrap();
        let at = [origin[0] + shape.centroid[0], origin[1] + shape.centroid[1]];
        let point = simulate(
            &motion,
            &Parts::points(vec![at], vec![[0.0; 2]], vec![mu], vec![mu]),
            &c,
        )
        .unwrap();
        let (mut slid, mut stuck) = (0, 0);
        for r in 0..poly.t.len() {
            let p = poly.positions[r];
            let q = point.positions[r];
            // the recorded origin moved as the centroid (the angle stays 0)
            let d = ((p[0] + shape.centroid[0] - q[0]).abs())
                .max((p[1] + shape.centroid[1] - q[1]).abs());
            assert!(d < 1e-13, "lift {lift}, row {r}: {p:?} vs {q:?}");
            let (v, w) = (poly.velocities[r], point.velocities[r]);
            assert!(
                (v[0] - w[0]).abs().max((v[1] - w[1]).abs()) < 1e-13,
                "row {r}"
            );
            assert_eq!(poly.stuck[r], point.stuck[r], "lift {lift}, row {r}");
            assert_eq!(poly.angles[r], 0.0);
            slid += usize::from(!poly.stuck[r]);
            stuck += usize::from(poly.stuck[r]);
        }
        assert!(slid > 100, "{slid} sliding");
        assert!(lift || stuck > 100, "{stuck} stuck");
        assert_eq!(poly.flight[0], point.flight[0], "lift {lift}");
        if lift {
            // thrown every cycle (0.0134 s in all over the 4 cycles)
            assert!(poly.flight[0] > 0.005, "{}", poly.flight[0]);
        } else {
            assert_eq!(poly.flight[0], 0.0);
        }
    }
}

#[test]
fn a_square_spinning_in_place_slows_in_proportion_to_the_normal_force() {
    // Spinning about its centroid on a plate that only heaves (z'' = 6 sin(wt + 1)), a square of
    // side L feels the moment 0.382598 mu N L (SPEC §11) with N = m (g + z''), and I = m L²/6:
    // each step takes 6 * 0.382598 mu (g + z''(t)) dt / L off the spin, z'' sampled at the
    // step's end.
    let l = 0.02;
    let shape = Polygon::new("sq", &[[0.0, 0.0], [l, 0.0], [l, l], [0.0, l]]).unwrap();
    let (a, w, phase) = (6.0, 2.0 * PI * 25.0, 1.0);
    let heave = [
        Vec::new(),
        Vec::new(),
        term(a, phase),
        Vec::new(),
        Vec::new(),
        Vec::new(),
    ];
    let motion = PlateMotion::spatial(Spatial::new(25.0, heave).unwrap());
    let (mu, dt, steps, spin) = (0.3, 1e-4, 600, 40.0);
    let run = simulate(
        &motion,
        &polygon_parts(&shape, [0.01, -0.02], spin, mu),
        &cfg(dt, steps),
    )
    .unwrap();
    let per = 6.0 * (2.0_f64.sqrt() + (1.0 + 2.0_f64.sqrt()).ln()) / 6.0 * mu / l;
    let mut want = spin;
    for k in 0..steps {
        let t = (k + 1) as f64 * dt;
        want -= per * (G + a * (w * t + phase).sin()) * dt;
        let got = run.spins[k + 1];
        assert!(
            (got - want).abs() < 1e-9 * spin,
            "step {k}: {got} vs {want}"
        );
    }
    // the heave changed the slowing: a uniform load would have ended elsewhere
    let uniform = spin - per * G * dt * steps as f64;
    assert!((want - uniform).abs() > 0.05, "{want} vs {uniform}");
    assert!(run.spins[steps] > 0.0 && run.spins[steps] < spin);
}
