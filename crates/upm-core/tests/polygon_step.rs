//! The polygon part's implicit stick–slip step against references outside it: the closed form of
//! a part spinning down in place, the optimality condition of the step written out here, the
//! limit surface's gauge, the point's closed form and the disk's step.

mod common;

use common::{extrapolate, pentagon, uniform, HISTORY, TRUSTED};
use upm_core::polygon::{Polygon, Request, Stepper};

fn regular(n: usize, r: f64) -> Polygon {
    let v: Vec<[f64; 2]> = (0..n)
        .map(|k| {
            let a = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
            [r * a.cos(), r * a.sin()]
        })
        .collect();
    Polygon::new("n-gon", &v).unwrap()
}

/// The optimality condition of the step to `w` from the free twist `free` (`c = mu g dt`) written
/// out, `(w - w*, k² (omega - omega*)) - c F(w)` with `F` the friction wrench of `w` (zero at the
/// minimiser), and its size `|r_x| + |r_y| + |r_m| / k`.
fn optimality(p: &Stepper, free: [f64; 3], c: f64, w: [f64; 3]) -> ([f64; 3], f64) {
    let k2 = p.gyration * p.gyration;
    let f = p.shape.wrench([w[0], w[1]], w[2]);
    let res = [
        w[0] - free[0] - c * f[0],
        w[1] - free[1] - c * f[1],
        k2 * (w[2] - free[2]) - c * f[2],
    ];
    (res, res[0].abs() + res[1].abs() + res[2].abs() / p.gyration)
}

#[test]
fn a_part_spinning_in_place_slows_by_the_mean_distance_over_the_gyration_squared() {
    // a square feels no force spinning about its centroid (an irregular part does, and that
    // couples a little translation into the spin)
    let p = Stepper::new(
        Polygon::new("sq", &[[0.0, 0.0], [0.02, 0.0], [0.02, 0.02], [0.0, 0.02]]).unwrap(),
    );
    let c = 0.3 * 9.81 * 1e-4;
    let k2 = p.gyration * p.gyration;
    for spin in [30.0, -4.0, 0.5] {
        let st = p.step([0.0, 0.0, spin], c, c, false, None).unwrap();
        let want = spin - spin.signum() * c * p.mean_distance / k2;
        assert!(!st.stuck);
        assert!(
            (st.w[2] - want).abs() < 1e-12 * spin.abs(),
            "{st:?} vs {want}"
        );
        assert!(st.w[0].hypot(st.w[1]) < 1e-15);
    }
    // slower than one step's loss: it stops
    let slow = 0.9 * c * p.mean_distance / k2;
    assert!(p.step([0.0, 0.0, slow], c, c, false, None).unwrap().stuck);
}

#[test]
fn a_spin_at_the_edge_of_sticking_with_a_trace_of_translation_steps_without_error() {
    // Newton stalls at the kink at 0 here; the step is then the closed-form bound by Moreau's
    // decomposition, no longer than (1 - 1/gauge) of the free twist
    let p = Stepper::new(
        Polygon::new(
            "rect",
            &[[-0.02, -0.01], [0.02, -0.01], [0.02, 0.01], [-0.02, 0.01]],
        )
        .unwrap(),
    );
    let c = 0.3 * 9.81 / 1680.0;
    let k2 = p.gyration * p.gyration;
    let edge = c * p.mean_distance / k2; // the spin one step's friction stops
                                         // the case an environment met: a spin about the rotation's centre, the plate at 35 Hz
    let met = [
        4.057074677797014e-11,
        -1.3747949125035572e-10,
        0.12470613882083903,
    ];
    let mut cases = vec![met];
    for e in [-1e-9, -1e-12, 0.0, 1e-13, 1e-12, 1e-10, 1e-8, 1e-7] {
        for trace in [0.0, 1e-12, 3e-10, 1e-9] {
            cases.push([trace, -3.3 * trace, edge * (1.0 + e)]);
        }
    }
    for free in cases {
        let st = p.step(free, c, c, false, None).unwrap();
        let size = (free[0].powi(2) + free[1].powi(2) + k2 * free[2].powi(2)).sqrt();
        let got = (st.w[0].powi(2) + st.w[1].powi(2) + k2 * st.w[2].powi(2)).sqrt();
        assert!(got <= 1e-6 * size, "{free:?} -> {st:?}");
        assert!(st.w[2] * free[2] >= 0.0, "{free:?} -> {st:?}"); // never turned back
    }
    // well past the edge, the closed form of a part spinning down in place
    let spin = edge * 1.001;
    let st = p.step([0.0, 0.0, spin], c, c, false, None).unwrap();
    assert!((st.w[2] - (spin - edge)).abs() < 1e-9 * spin, "{st:?}");
}

#[test]
fn the_step_is_the_minimiser_stuck_exactly_inside_the_limit_set() {
    let shape = pentagon();
    let p = Stepper::new(shape.clone());
    let k2 = p.gyration * p.gyration;
    let c = 0.25 * 9.81 * 2e-4;
    let r = uniform(3 * 400, 5);
    let (mut stuck, mut slid) = (0, 0);
    for i in 0..400 {
        // free twists from well inside the limit set to far outside it
        let scale = c * (0.2 + 1.5 * (r[3 * i] + 1.0));
        let free = [
            scale * r[3 * i + 1],
            scale * r[3 * i + 2],
            scale * r[3 * i + 1] * r[3 * i + 2] * p.mean_distance / k2,
        ];
        let st = p.step(free, c, c, false, None).unwrap();
        let z = [free[0] / c, free[1] / c, k2 * free[2] / c];
        let gauge = shape.gauge(z[0], z[1], z[2]).unwrap().value;
        if (gauge - 1.0).abs() < 1e-9 {
            continue;
        }
        assert_eq!(st.stuck, gauge <= 1.0, "twist {i}: gauge {gauge}, {st:?}");
        if st.stuck {
            stuck += 1;
            assert_eq!(st.w, [0.0; 3]);
            continue;
        }
        slid += 1;
        let (res, off) = optimality(&p, free, c, st.w);
        let size = free[0].hypot(free[1]) + p.gyration * free[2].abs();
        // started from a nearby guess (the last step's twist in a run) it lands on the same point
        let near = [st.w[0] * 1.01, st.w[1] * 0.99, st.w[2] * 1.02];
        let warm = p.step(free, c, c, false, Some(near)).unwrap();
        for j in 0..3 {
            let scale = if j == 2 { size / p.gyration } else { size };
            assert!(
                (warm.w[j] - st.w[j]).abs() < 1e-11 * scale,
                "twist {i}: {warm:?} vs {st:?}"
            );
        }
        assert!(
            off < 1e-12 * size,
            "twist {i}: residual {res:?} free {free:?} c {c} {st:?}"
        );
    }
    assert!(stuck > 40 && slid > 40, "{stuck} stuck, {slid} slid");
}

#[test]
fn static_friction_holds_a_stuck_part_longer_and_then_lets_it_slide() {
    let p = Stepper::new(pentagon());
    let (slide, hold) = (1e-3, 1.5e-3);
    let free = [1.2e-3, 0.0, 0.0];
    assert!(p.step(free, slide, hold, true, None).unwrap().stuck);
    let moving = p.step(free, slide, hold, false, None).unwrap();
    assert!(!moving.stuck && (moving.w[0] - 0.2e-3).abs() < 1e-18);
    // past static friction it slides under sliding friction, with spin too
    let free = [1.0e-3, 0.8e-3, 0.05];
    let st = p.step(free, slide, hold, true, None).unwrap();
    let again = p.step(free, slide, slide, false, None).unwrap();
    assert!(!st.stuck && !again.stuck);
    for k in 0..3 {
        assert!(
            (st.w[k] - again.w[k]).abs() < 1e-15 * (1.0 + again.w[k].abs()),
            "{st:?} {again:?}"
        );
    }
}

#[test]
fn without_spin_a_part_slides_as_a_point() {
    let p = Stepper::new(pentagon());
    let c = 2e-3;
    let st = p.step([3e-3, -4e-3, 0.0], c, c, false, None).unwrap();
    let f = 1.0 - c / 5e-3;
    assert_eq!(st.w, [3e-3 * f, -4e-3 * f, 0.0]);
    assert!(!st.stuck && st.iterations == 0);
}

#[test]
fn a_polygon_of_many_sides_steps_as_the_disk() {
    let radius = 0.02;
    let p = Stepper::new(regular(2048, radius));
    let c = 0.3 * 9.81 * 1e-4;
    let r = uniform(3 * 60, 11);
    for i in 0..60 {
        let scale = c * (0.5 + 4.0 * (r[3 * i] + 1.0));
        let free = [
            scale * r[3 * i + 1],
            scale * r[3 * i + 2],
            scale * r[3 * i] / radius,
        ];
        let st = p.step(free, c, c, false, None).unwrap();
        let disk = upm_core::disk::implicit_step([free[0], free[1]], radius * free[2], c, c, false);
        assert_eq!(st.stuck, disk.stuck, "twist {i}");
        let err = (st.w[0] - disk.w[0]).abs()
            + (st.w[1] - disk.w[1]).abs()
            + (radius * st.w[2] - disk.s).abs();
        assert!(err < 2e-5 * scale, "twist {i}: {st:?} vs {disk:?}");
    }
}

#[test]
fn a_start_far_from_a_small_answer_ends_at_the_minimiser_not_at_the_kink() {
    // Free twists just outside the limit set (the answer is small) solved from guesses far from
    // it, as a part sliding on hands its last twist when the motion turns: the answer is the one
    // of a cold start, and it satisfies the optimality condition.
    let shape = regular(6, 0.008);
    let p = Stepper::new(shape.clone());
    let k2 = p.gyration * p.gyration;
    let c = 0.3 * 9.81 * 7.14e-5;
    let r = uniform(6 * 300, 11);
    let mut checked = 0;
    for i in 0..300 {
        let [a, b, s, g0, g1, g2] = std::array::from_fn(|j| r[6 * i + j]);
        // just outside: the force a hair over the unit disk, a moment of either sign
        let angle = std::f64::consts::PI * a;
        let force = 1.0 + 0.01 * (b + 1.0);
        let free = [
            c * force * angle.cos(),
            c * force * angle.sin(),
            c * 3.0 * s * p.mean_distance / k2,
        ];
        let cold = p.step(free, c, c, false, None).unwrap();
        if cold.stuck {
            continue;
        }
        // guesses up to ten times the free twist, in any direction
        let guess = [
            10.0 * c * g0,
            10.0 * c * g1,
            10.0 * c * g2 * p.mean_distance / k2,
        ];
        let warm = p.step(free, c, c, false, Some(guess)).unwrap();
        let size = free[0].hypot(free[1]) + p.gyration * free[2].abs();
        let (res, off) = optimality(&p, free, c, warm.w);
        assert!(
            off < 1e-12 * size,
            "twist {i}: residual {res:?}, free {free:?}, guess {guess:?}: {warm:?} vs {cold:?}"
        );
        for j in 0..3 {
            let scale = if j == 2 { size / p.gyration } else { size };
            assert!((warm.w[j] - cold.w[j]).abs() < 1e-11 * scale, "twist {i}");
        }
        checked += 1;
    }
    assert!(checked > 100, "{checked} sliding");
}

#[test]
fn a_pure_moment_holds_only_up_to_the_largest_pure_moment_of_the_limit_set() {
    // A right triangle spinning about its centroid feels a force (0.06 mu N): the largest
    // moment, its mean distance, comes with that force, and a pure moment holds only up to
    // 1 / gauge(0, 0, 1), 0.27 % less. Just under the mean distance the part must slide.
    let shape = Polygon::new("t", &[[0.0, 0.0], [0.03, 0.0], [0.0, 0.015]]).unwrap();
    let p = Stepper::new(shape.clone());
    let k2 = p.gyration * p.gyration;
    let c = 0.3 * 9.81 * 1e-4;
    let largest = 1.0 / shape.gauge(0.0, 0.0, 1.0).unwrap().value;
    assert!(
        largest < 0.998 * p.mean_distance,
        "{largest} {}",
        p.mean_distance
    );
    for (s, holds) in [(0.999, false), (0.99, true), (1.001, false)] {
        for sign in [1.0, -1.0] {
            let m = sign * s * p.mean_distance;
            let st = p.step([0.0, 0.0, m * c / k2], c, c, false, None).unwrap();
            let gauge = shape.gauge(0.0, 0.0, m).unwrap().value;
            assert_eq!(gauge <= 1.0, holds, "gauge {gauge}");
            assert_eq!(st.stuck, holds, "moment {s} x the mean distance: {st:?}");
        }
    }
    // the same at the boundary itself, either side
    for (s, holds) in [(1.0 - 1e-9, true), (1.0 + 1e-9, false)] {
        let st = p
            .step([0.0, 0.0, s * largest * c / k2], c, c, false, None)
            .unwrap();
        assert_eq!(st.stuck, holds, "{s} x the largest pure moment: {st:?}");
    }
}

#[test]
fn near_the_largest_moment_with_little_force_the_step_is_the_minimiser() {
    // Between the largest pure moment and the mean distance (an asymmetric part's cylinder
    // bound) a wrench slides though no sampled plane says so: the solve must start from the
    // gauge's direction, not end at the kink at 0 (found by `upm demo sort-shapes`, a triangle
    // spinning at 0.0047 rad/s with 4e-7 m/s).
    let shape = Polygon::new("t", &[[0.0, 0.0], [0.04, 0.0], [0.0, 0.025]]).unwrap();
    let p = Stepper::new(shape.clone());
    let k2 = p.gyration * p.gyration;
    let c = 0.3 * 9.81 * 1.98e-5;
    let st = p
        .step(
            [
                -2.716486005220002e-8,
                -3.832646674626287e-7,
                0.004693536713432422,
            ],
            c,
            c,
            false,
            None,
        )
        .unwrap();
    assert!(!st.stuck);
    let r = uniform(3 * 200, 17);
    let (mut stuck, mut slid) = (0, 0);
    for i in 0..200 {
        let m = (0.995 + 0.02 * (r[3 * i] + 1.0) / 2.0) * p.mean_distance * r[3 * i].signum();
        let f = 0.02 * c;
        let a = std::f64::consts::PI * r[3 * i + 1];
        let free = [f * a.cos(), f * a.sin(), m * c / k2];
        let st = p.step(free, c, c, false, None).unwrap();
        let gauge = shape.gauge(free[0] / c, free[1] / c, m).unwrap().value;
        if (gauge - 1.0).abs() < 1e-9 {
            continue;
        }
        assert_eq!(st.stuck, gauge <= 1.0, "twist {i}: gauge {gauge}, {st:?}");
        if st.stuck {
            stuck += 1;
            continue;
        }
        slid += 1;
        let (res, off) = optimality(&p, free, c, st.w);
        let size = free[0].hypot(free[1]) + p.gyration * free[2].abs();
        assert!(off < 1e-11 * size, "twist {i}: residual {res:?} {st:?}");
    }
    assert!(stuck > 20 && slid > 20, "{stuck} stuck, {slid} slid");
}

#[test]
fn a_solve_trusting_the_last_solve_s_contraction_ends_where_a_cold_one_does() {
    // A part sliding on along a smooth path of free twists (400 steps a period, the spin kept
    // from zero, where the friction of a twist far from a rotation is a quadrature's), each solve
    // started as the integrator starts it: from its last twists extrapolated, trusting the
    // contraction its last solve measured, so that most end after one Newton step. Each lands
    // where the solve from nothing does, on the minimiser (the optimality condition).
    let shape = pentagon();
    let p = Stepper::new(shape.clone());
    let k2 = p.gyration * p.gyration;
    let c = 0.3 * 9.81 * 7.14e-5;
    let (mut history, mut slid) = ([[0.0; 3]; HISTORY], 0);
    let (mut contraction, mut trusted) = (None, 0);
    let (mut once, steps) = (0, 1200);
    for s in 0..steps {
        let t = 2.0 * std::f64::consts::PI * s as f64 / 400.0;
        let free = [
            c * (3.0 + 2.0 * t.cos()),
            c * (1.5 * (2.0 * t).sin() - 0.5),
            c * (2.5 + 1.5 * t.sin()) * p.mean_distance / k2,
        ];
        let warm = p
            .step_request(&Request {
                free,
                slide: c,
                hold: c,
                was_stuck: false,
                guess: (slid > 0).then(|| extrapolate(&history, slid)),
                contraction: contraction.filter(|_| trusted < TRUSTED),
            })
            .unwrap();
        let cold = p.step(free, c, c, false, None).unwrap();
        assert!(!warm.stuck && !cold.stuck, "step {s}");
        let size = free[0].hypot(free[1]) + p.gyration * free[2].abs();
        for j in 0..3 {
            let scale = if j == 2 { size / p.gyration } else { size };
            assert!(
                (warm.w[j] - cold.w[j]).abs() < 1e-13 * scale,
                "step {s}: {warm:?} vs {cold:?}"
            );
        }
        let (res, off) = optimality(&p, free, c, warm.w);
        assert!(off < 1e-13 * size, "step {s}: residual {res:?}");
        once += usize::from(warm.iterations == 1);
        history.rotate_right(1);
        history[0] = warm.w;
        slid = (slid + 1).min(HISTORY);
        (contraction, trusted) = match warm.contraction {
            Some(k) => (Some(k), 0),
            None => (contraction, trusted + 1),
        };
    }
    // (the first solves and one in 33 measure the contraction: two steps)
    assert!(
        once > steps * 3 / 4,
        "{once} of {steps} solves took one Newton step"
    );
}
