//! Three-point support against references written out here: the three feet's forces summed by
//! hand, the gauge as the largest ratio over a fine sphere of twist directions (with the pivots,
//! where it may sit on a kink), and the step's optimality condition with each foot's force
//! (a still foot's within its share).

mod common;

use common::{pentagon, uniform};
use upm_core::polygon::{Polygon, Stepper};

/// A 4 cm right-angled part standing on three feet, in its vertices' frame.
fn part(feet: [[f64; 2]; 3]) -> Polygon {
    let mut p = Polygon::new("p", &[[0.0, 0.0], [0.04, 0.0], [0.04, 0.03], [0.0, 0.03]]).unwrap();
    p.set_feet("support", Some(feet)).unwrap();
    p
}

/// Feet around the centroid (0.02, 0.015), one carrying most of the load.
fn lopsided() -> Polygon {
    part([[0.021, 0.019], [0.004, 0.004], [0.036, 0.004]])
}

/// Feet `(s_i, share_i)` from the centroid.
fn feet(p: &Polygon) -> Vec<([f64; 2], f64)> {
    let t = p.tripod().unwrap();
    (0..3).map(|i| (t.feet[i], t.shares[i])).collect()
}

/// The rate of work `sum share |v + omega z x s|` and the wrench, foot by foot.
fn by_hand(p: &Polygon, v: [f64; 2], w: f64) -> (f64, [f64; 3]) {
    let (mut d, mut f) = (0.0, [0.0; 3]);
    for (s, l) in feet(p) {
        let u = [v[0] - w * s[1], v[1] + w * s[0]];
        let n = u[0].hypot(u[1]);
        if n > 0.0 {
            d += l * n;
            f[0] -= l * u[0] / n;
            f[1] -= l * u[1] / n;
            f[2] -= l * (s[0] * u[1] - s[1] * u[0]) / n;
        }
    }
    (d, f)
}

#[test]
fn the_shares_carry_the_weight_and_its_moment() {
    let p = lopsided();
    let f = feet(&p);
    let total: f64 = f.iter().map(|x| x.1).sum();
    assert!((total - 1.0).abs() < 1e-15);
    assert!(f.iter().all(|x| x.1 > 0.0) && f[0].1 > 0.6, "{f:?}");
    for k in 0..2 {
        let m: f64 = f.iter().map(|(s, l)| l * s[k]).sum();
        assert!(m.abs() < 1e-17, "moment {m}");
    }
    // on a rocking plate the centre of pressure moves to S k, as a footprint's does
    let mut q = p.clone();
    let k = [9.0, -5.0];
    q.set_load(k).unwrap();
    let s = q.second_moments();
    let want = [s[0] * k[0] + s[1] * k[1], s[1] * k[0] + s[2] * k[1]];
    for (j, w) in want.iter().enumerate() {
        let m: f64 = feet(&q).iter().map(|(s, l)| l * s[j]).sum();
        assert!((m - w).abs() < 1e-15, "{m} vs {w}");
    }
    // a load that would lift a foot is refused, and steady_load shortens it to the edge
    let big = [400.0, 0.0];
    assert!(q.set_load(big).is_err());
    let steady = q.steady_load(big);
    q.set_load(steady).unwrap();
    let least = feet(&q).iter().map(|x| x.1).fold(1.0, f64::min);
    assert!((0.0..1e-11).contains(&least), "{least}");
}

#[test]
fn the_friction_is_the_three_feet_summed_and_its_hessian_the_derivative() {
    let p = lopsided();
    let r = uniform(60, 3);
    for i in 0..20 {
        let v = [0.01 * r[3 * i], 0.01 * r[3 * i + 1]];
        let w = 2.0 * r[3 * i + 2];
        let (d, f) = by_hand(&p, v, w);
        let got = p.friction_hessian(v, w);
        assert!((got.work - d).abs() < 1e-16 + 1e-15 * d);
        for k in 0..3 {
            assert!((got.wrench[k] - f[k]).abs() < 1e-15, "{got:?} vs {f:?}");
        }
        // the Hessian of the rate of work: the derivative of minus the wrench
        let h = 1e-7;
        for j in 0..3 {
            let mut a = [v[0], v[1], w];
            let mut b = a;
            let step = if j == 2 { h / 0.02 } else { h };
            a[j] += step;
            b[j] -= step;
            let fa = by_hand(&p, [a[0], a[1]], a[2]).1;
            let fb = by_hand(&p, [b[0], b[1]], b[2]).1;
            for k in 0..3 {
                let fd = -(fa[k] - fb[k]) / (2.0 * step);
                let scale = got
                    .hessian
                    .iter()
                    .flatten()
                    .fold(1.0, |a: f64, x| a.max(x.abs()));
                assert!(
                    (got.hessian[k][j] - fd).abs() < 1e-6 * scale,
                    "({k},{j}): {} vs {fd}",
                    got.hessian[k][j]
                );
            }
        }
    }
}

/// The gauge as the largest `<z, e> / D(e)` over a fine spiral of twist directions and over the
/// three pivots (either sign): a lower bound within a few 1e-5 of it.
fn gauge_by_search(p: &Polygon, z: [f64; 3]) -> f64 {
    let l = 0.02;
    let ratio = |e: [f64; 3]| {
        let d = by_hand(p, [e[0], e[1]], e[2] / l).0;
        (z[0] * e[0] + z[1] * e[1] + z[2] * e[2] / l) / d
    };
    let mut best = f64::NEG_INFINITY;
    for (s, _) in feet(p) {
        for sign in [1.0, -1.0] {
            best = best.max(ratio([sign * s[1], -sign * s[0], sign * l]));
        }
    }
    let n = 40_000;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let mut at = [0.0; 3];
    for i in 0..n {
        let zc = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
        let r = (1.0 - zc * zc).sqrt();
        let a = golden * i as f64;
        let e = [r * a.cos(), r * a.sin(), zc];
        let x = ratio(e);
        if x > best {
            (best, at) = (x, e);
        }
    }
    // polish by a shrinking pattern search about the best direction
    let mut h = 0.01;
    while h > 1e-9 {
        let mut moved = false;
        for j in 0..3 {
            for sign in [1.0, -1.0] {
                let mut e = at;
                e[j] += sign * h;
                let x = ratio(e);
                if x > best {
                    (best, at, moved) = (x, e, true);
                }
            }
        }
        if !moved {
            h *= 0.5;
        }
    }
    best
}

#[test]
fn the_gauge_is_the_largest_ratio_over_all_twists() {
    let p = lopsided();
    let r = uniform(3 * 25, 11);
    for i in 0..25 {
        let z = [r[3 * i], r[3 * i + 1], 0.02 * r[3 * i + 2]];
        let g = p.gauge(z[0], z[1], z[2]).unwrap();
        let search = gauge_by_search(&p, z);
        assert!(
            search <= g.value * (1.0 + 1e-12) && search >= g.value * (1.0 - 1e-6),
            "z {z:?}: gauge {} search {search}",
            g.value
        );
        // the twist it names gives the wrench on the limit surface, in the wrench's direction
        let f = by_hand(&p, [g.twist[0], g.twist[1]], g.twist[2]).1;
        let scaled = [z[0] / g.value, z[1] / g.value, z[2] / g.value];
        if g.twist[2] != 0.0 && !on_pivot(&p, g.twist) {
            for k in 0..3 {
                assert!((f[k] - scaled[k]).abs() < 1e-9, "{f:?} vs {scaled:?}");
            }
        }
    }
}

/// Whether the twist turns the part about one of its feet.
fn on_pivot(p: &Polygon, w: [f64; 3]) -> bool {
    feet(p).iter().any(|(s, _)| {
        let u = [w[0] - w[2] * s[1], w[1] + w[2] * s[0]];
        u[0].hypot(u[1]) <= 1e-12 * (w[0].hypot(w[1]) + 0.02 * w[2].abs())
    })
}

/// The step's optimality condition: `(w - w*, k² (omega - omega*)) = c (F, M)` with each
/// sliding foot's force against its motion and a still foot's within its share; true if it
/// holds to `tol` (relative), with the still foot (if any).
fn optimal(p: &Polygon, k: f64, free: [f64; 3], c: f64, w: [f64; 3], tol: f64) -> (bool, usize) {
    let size = free[0].hypot(free[1]) + k * free[2].abs() + c;
    let mut res = [w[0] - free[0], w[1] - free[1], k * k * (w[2] - free[2])];
    let mut still = None;
    for (i, (s, l)) in feet(p).into_iter().enumerate() {
        let u = [w[0] - w[2] * s[1], w[1] + w[2] * s[0]];
        let n = u[0].hypot(u[1]);
        if n <= 1e-13 * size {
            still = Some((i, s, l));
            continue;
        }
        res[0] += c * l * u[0] / n;
        res[1] += c * l * u[1] / n;
        res[2] += c * l * (s[0] * u[1] - s[1] * u[0]) / n;
    }
    let mut count = 0;
    if let Some((i, s, l)) = still {
        // the still foot's force f = -res / c, its moment s x f, within its share
        let f = [-res[0] / c, -res[1] / c];
        let ok = f[0].hypot(f[1]) <= l * (1.0 + tol);
        res = [0.0, 0.0, res[2] + c * (s[0] * f[1] - s[1] * f[0])];
        count = i + 1;
        if !ok {
            return (false, count);
        }
    }
    let err = res[0].abs() + res[1].abs() + res[2].abs() / k;
    (err <= tol * size, count)
}

#[test]
fn the_step_sticks_pivots_or_slides_exactly() {
    steps_exactly(lopsided());
}

#[test]
fn on_a_rocking_plate_the_step_sticks_pivots_or_slides_exactly() {
    // the centre of pressure moved towards foot 2, off the heavy foot 0
    let mut shape = lopsided();
    shape.set_load([30.0, -40.0]).unwrap();
    let s = feet(&shape);
    assert!(s[2].1 > 0.3 && s[0].1 < 0.55 && s[1].1 > 0.1, "{s:?}");
    steps_exactly(shape);
}

fn steps_exactly(shape: Polygon) {
    let p = Stepper::new(shape.clone());
    let k = p.gyration;
    let c = 0.3 * 9.81 * 2e-4;
    let r = uniform(4 * 300, 7);
    let (mut stuck, mut pivots, mut slid) = (0, 0, 0);
    for i in 0..300 {
        let scale = c * (0.2 + 1.5 * (r[4 * i] + 1.0));
        let mut free = [
            scale * r[4 * i + 1],
            scale * r[4 * i + 2],
            scale * r[4 * i + 3] * 0.02 / (k * k),
        ];
        if i % 3 == 0 {
            // a free turn about the heavy foot: such parts pivot on it
            let s = feet(&shape)[0].0;
            let om = free[2] * 3.0;
            free = [om * s[1] + 0.05 * free[0], -om * s[0], om];
        }
        let st = p.step(free, c, c, false, None).unwrap();
        let z = [free[0] / c, free[1] / c, k * k * free[2] / c];
        let gauge = gauge_by_search(&shape, z);
        if (gauge - 1.0).abs() < 1e-4 {
            continue; // the search's own accuracy
        }
        assert_eq!(st.stuck, gauge <= 1.0, "twist {i}: gauge {gauge}, {st:?}");
        if st.stuck {
            stuck += 1;
            assert_eq!(st.w, [0.0; 3]);
            continue;
        }
        let (ok, still) = optimal(&shape, k, free, c, st.w, 1e-11);
        assert!(ok, "twist {i}: free {free:?} -> {st:?} not optimal");
        if still > 0 {
            pivots += 1;
        } else {
            slid += 1;
        }
        // started from a nearby guess it lands on the same point
        let near = [st.w[0] * 1.01, st.w[1] * 0.99, st.w[2] * 1.02];
        let warm = p.step(free, c, c, false, Some(near)).unwrap();
        let (ok, _) = optimal(&shape, k, free, c, warm.w, 1e-11);
        assert!(ok, "twist {i} warm: {warm:?}");
    }
    assert!(
        stuck > 25 && pivots > 25 && slid > 25,
        "{stuck} stuck, {pivots} pivoted, {slid} slid"
    );
}

#[test]
fn a_part_on_three_even_feet_spins_down_and_sticks_at_their_radius() {
    // feet at 1 cm around the centroid of a square: spinning in place it feels mu N times 1 cm
    let rho = 0.01;
    let f: [[f64; 2]; 3] = std::array::from_fn(|i| {
        let a = 2.0 * std::f64::consts::PI * i as f64 / 3.0 + 0.3;
        [0.02 + rho * a.cos(), 0.02 + rho * a.sin()]
    });
    let mut shape =
        Polygon::new("sq", &[[0.0, 0.0], [0.04, 0.0], [0.04, 0.04], [0.0, 0.04]]).unwrap();
    shape.set_feet("support", Some(f)).unwrap();
    let p = Stepper::new(shape.clone());
    let k2 = p.gyration * p.gyration;
    let c = 0.3 * 9.81 * 1e-4;
    assert!((p.mean_distance - rho).abs() < 1e-17);
    assert!((p.pure_moment - rho).abs() < 1e-15, "{}", p.pure_moment);
    for spin in [30.0, -4.0] {
        let st = p.step([0.0, 0.0, spin], c, c, false, None).unwrap();
        let want = spin - spin.signum() * c * rho / k2;
        assert!(
            !st.stuck && (st.w[2] - want).abs() < 1e-12 * spin.abs(),
            "{st:?}"
        );
        assert!(st.w[0].hypot(st.w[1]) < 1e-15);
    }
    // a plate spinning up about the part's centroid carries it while I alpha <= mu m g rho
    for (s, holds) in [(0.999, true), (1.001, false)] {
        let st = p
            .step([0.0, 0.0, s * c * rho / k2], c, c, false, None)
            .unwrap();
        assert_eq!(st.stuck, holds, "{s}: {st:?}");
    }
    // translating, it slides as a point does
    let st = p.step([3e-3, -4e-3, 0.0], c, c, false, None).unwrap();
    let g = 1.0 - c / 5e-3;
    assert_eq!(st.w, [3e-3 * g, -4e-3 * g, 0.0]);
}

#[test]
fn bad_feet_are_refused_with_the_reason() {
    let mut p = pentagon();
    let bad = |p: &mut Polygon, f: [[f64; 2]; 3]| {
        p.set_feet("parts[2].support", Some(f))
            .unwrap_err()
            .to_string()
    };
    let e = bad(&mut p, [[0.0, 0.0], [0.01, 0.0], [0.02, 0.0]]);
    assert!(
        e.contains("parts[2].support") && e.contains("one line"),
        "{e}"
    );
    let e = bad(&mut p, [[0.0, 0.0], [0.03, -0.004], [0.2, 0.2]]);
    assert!(e.contains("foot 2") && e.contains("outside"), "{e}");
    let e = bad(&mut p, [[0.0, 0.0], [0.03, -0.004], [0.005, 0.001]]);
    assert!(e.contains("tips"), "{e}");
    let e = bad(&mut p, [[f64::NAN, 0.0], [0.03, -0.004], [0.005, 0.001]]);
    assert!(e.contains("finite"), "{e}");
    // and a refused support leaves the footprint
    assert!(p.tripod().is_none());
}
