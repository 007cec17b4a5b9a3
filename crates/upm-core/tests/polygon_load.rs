//! The friction of a polygon under pressure that varies linearly across its footprint (a part on
//! a rocking plate) against references outside the closed forms: a brute-force sum over a fine
//! grid written here, the rate of work's derivatives, and the quadrature where both hold.

mod common;

use common::{pentagon, uniform};
use upm_core::polygon::Polygon;

/// `(wrench, work)` per `mu N` of the relative twist `(v, omega)` under the pressure `1 + k . r`
/// by the midpoint rule on an `n x n` grid over the bounding box (cells whose centre is inside).
fn brute(p: &Polygon, k: [f64; 2], v: [f64; 2], omega: f64, n: usize) -> ([f64; 3], f64) {
    let vs = &p.vertices;
    let (lo, hi) = vs
        .iter()
        .fold(([f64::MAX; 2], [f64::MIN; 2]), |(lo, hi), q| {
            (
                [lo[0].min(q[0]), lo[1].min(q[1])],
                [hi[0].max(q[0]), hi[1].max(q[1])],
            )
        });
    let (hx, hy) = ((hi[0] - lo[0]) / n as f64, (hi[1] - lo[1]) / n as f64);
    let inside = |r: [f64; 2]| {
        (0..vs.len()).all(|i| {
            let (a, b) = (vs[i], vs[(i + 1) % vs.len()]);
            (b[0] - a[0]) * (r[1] - a[1]) - (b[1] - a[1]) * (r[0] - a[0]) >= 0.0
        })
    };
    let (mut w, mut work, mut area) = ([0.0; 3], 0.0, 0.0);
    for i in 0..n {
        for j in 0..n {
            let r = [lo[0] + (i as f64 + 0.5) * hx, lo[1] + (j as f64 + 0.5) * hy];
            if !inside(r) {
                continue;
            }
            let u = [v[0] - omega * r[1], v[1] + omega * r[0]];
            let s = u[0].hypot(u[1]);
            let weight = 1.0 + k[0] * r[0] + k[1] * r[1];
            area += 1.0;
            work += weight * s;
            if s > 0.0 {
                w[0] -= weight * u[0] / s;
                w[1] -= weight * u[1] / s;
                w[2] -= weight * (r[0] * u[1] - r[1] * u[0]) / s;
            }
        }
    }
    (w.map(|x| x / area), work / area)
}

/// Loads that take the pressure from nearly zero at one vertex to nearly twice the mean.
fn loads(p: &Polygon) -> Vec<[f64; 2]> {
    let r = p.radius;
    vec![[0.9 / r, 0.0], [-0.3 / r, 0.6 / r], [0.05 / r, -0.8 / r]]
}

#[test]
fn the_loaded_wrench_is_the_sum_over_the_footprint() {
    let mut p = pentagon();
    let r = p.radius;
    // instantaneous centres inside, near an edge, outside, far; and a pure translation
    let twists = [
        ([0.0, 0.0], 3.0),
        ([-3.0 * 0.004, 3.0 * 0.003], 3.0),
        ([2.0 * 0.9 * r, -2.0 * 0.2 * r], -2.0),
        ([0.05, 0.02], 1.0),
        ([0.3, -0.4], 0.0),
    ];
    for k in loads(&p) {
        p.set_load(k).unwrap();
        for &(v, omega) in &twists {
            let (w, d) = p.friction(v, omega);
            let (bw, bd) = brute(&p, k, v, omega, 1200);
            for i in 0..3 {
                let scale = if i == 2 { r } else { 1.0 };
                assert!(
                    (w[i] - bw[i]).abs() < 2e-3 * scale,
                    "k {k:?} twist {v:?} {omega}: {w:?} vs {bw:?}"
                );
            }
            let speed = v[0].hypot(v[1]) + omega.abs() * r;
            assert!((d - bd).abs() < 2e-3 * speed, "work {d} vs {bd}");
        }
    }
    // the load matters: the same twist under uniform pressure is far from it
    let (w, _) = p.friction([0.0, 0.0], 3.0);
    let mut q = pentagon();
    q.set_load([0.0; 2]).unwrap();
    let (u, _) = q.friction([0.0, 0.0], 3.0);
    assert!(
        (w[0] - u[0]).abs() + (w[1] - u[1]).abs() > 0.05,
        "{w:?} vs {u:?}"
    );
}

#[test]
fn the_loaded_wrench_and_hessian_are_the_derivatives_of_the_rate_of_work() {
    let mut p = pentagon();
    let r = p.radius;
    let centres = [
        [0.0, 0.0],
        [0.004, -0.002],
        [0.3 * r, 0.2 * r],
        [1.7 * r, -0.4 * r],
        [-0.5 * r, 3.0 * r],
        [40.0 * r, -20.0 * r],
        [1500.0 * r, 700.0 * r],
    ];
    for k in loads(&p) {
        p.set_load(k).unwrap();
        for (i, c) in centres.iter().enumerate() {
            let omega = if i % 2 == 0 { 3.0 } else { -2.0 };
            let x = [omega * c[1], -omega * c[0], omega];
            let got = p.friction_hessian([x[0], x[1]], x[2]);
            let sigma = [1.0, 1.0, r];
            let norm = (0..3)
                .map(|k| got.hessian[k][k] / (sigma[k] * sigma[k]))
                .fold(0.0, f64::max);
            for j in 0..3 {
                let h = 1e-6 * (x[0].hypot(x[1]) + r * x[2].abs()) / if j == 2 { r } else { 1.0 };
                let (mut up, mut down) = (x, x);
                up[j] += h;
                down[j] -= h;
                let (fu, fd) = (
                    p.friction([up[0], up[1]], up[2]),
                    p.friction([down[0], down[1]], down[2]),
                );
                // minus the gradient of the rate of work is the wrench
                let want = -(fu.1 - fd.1) / (2.0 * h);
                let size = got.wrench[0].hypot(got.wrench[1]) + got.wrench[2].abs() / r;
                assert!(
                    (got.wrench[j] - want).abs() <= 1e-7 * size * sigma[j],
                    "k {k:?} centre {i}: w{j} {} vs {want}",
                    got.wrench[j]
                );
                for m in 0..3 {
                    let want = -(fu.0[m] - fd.0[m]) / (2.0 * h);
                    assert!(
                        (got.hessian[m][j] - want).abs() <= 1e-6 * norm * sigma[m] * sigma[j],
                        "k {k:?} centre {i}: d w{m} / d x{j}: {} vs {want}",
                        got.hessian[m][j]
                    );
                }
            }
        }
    }
}

#[test]
fn the_loaded_closed_form_meets_the_quadrature_where_both_hold() {
    let mut p = pentagon();
    for k in loads(&p) {
        p.set_load(k).unwrap();
        // the closed form up to LOADED_FAR (20) radii, the quadrature beyond: they meet
        // (and 4 x 4 points beyond 100 radii, which must meet the 8 x 8 rule there)
        for far in [2.0, 5.0, 10.0, 19.9, 20.1, 99.9, 100.1, 400.0] {
            let omega = 2.0;
            let v = [0.3 * omega * far * p.radius, -omega * far * p.radius];
            let (a, b) = (p.wrench(v, omega), p.wrench_quadrature(v, omega));
            for i in 0..3 {
                assert!((a[i] - b[i]).abs() < 1e-12, "far {far}: {a:?} vs {b:?}");
            }
        }
    }
}

#[test]
fn a_load_that_makes_the_pressure_negative_is_refused() {
    let mut p = pentagon();
    let r = p.radius;
    let err = p.set_load([1.5 / r, 0.0]).unwrap_err().to_string();
    assert!(err.contains("load") && err.contains(">= 0"), "{err}");
    assert!(p.set_load([f64::NAN, 0.0]).is_err());
    assert_eq!(p.load(), [0.0; 2]);
}

#[test]
fn the_loaded_step_is_the_minimiser_and_sticks_only_where_zero_is() {
    use upm_core::polygon::Stepper;
    let mut shape = pentagon();
    let r = shape.radius;
    shape.set_load([0.5 / r, -0.4 / r]).unwrap();
    let p = Stepper::new(pentagon());
    let mut loaded = p.clone();
    loaded.shape = shape.clone();
    let k2 = p.gyration * p.gyration;
    let c = 0.25 * 9.81 * 2e-4;
    let x = uniform(3 * 300, 11);
    let dirs = uniform(3 * 4000, 12);
    let (mut stuck, mut slid, mut differ) = (0, 0, 0);
    for i in 0..300 {
        let scale = c * (0.2 + 1.5 * (x[3 * i] + 1.0));
        let free = [
            scale * x[3 * i + 1],
            scale * x[3 * i + 2],
            scale * x[3 * i + 1] * x[3 * i + 2] * p.mean_distance / k2,
        ];
        let st = loaded.step(free, c, c, false, None).unwrap();
        differ += usize::from(st.stuck != p.step(free, c, c, false, None).unwrap().stuck);
        let z = [free[0] / c, free[1] / c, k2 * free[2] / c];
        if st.stuck {
            // 0 is the minimiser: no direction e lowers Phi, <z, e> <= D(e) for every e
            stuck += 1;
            for j in 0..4000 {
                let e = [dirs[3 * j], dirs[3 * j + 1], dirs[3 * j + 2] / r];
                let d = shape.friction([e[0], e[1]], e[2]).1;
                let ze = z[0] * e[0] + z[1] * e[1] + z[2] * e[2];
                assert!(
                    ze <= d * (1.0 + 1e-9),
                    "twist {i}: direction {j} lowers Phi: {ze} > {d}"
                );
            }
            continue;
        }
        slid += 1;
        let f = shape.wrench([st.w[0], st.w[1]], st.w[2]);
        let res = [
            st.w[0] - free[0] - c * f[0],
            st.w[1] - free[1] - c * f[1],
            k2 * (st.w[2] - free[2]) - c * f[2],
        ];
        let size = free[0].hypot(free[1]) + p.gyration * free[2].abs();
        assert!(
            res[0].abs() + res[1].abs() + res[2].abs() / p.gyration < 1e-12 * size,
            "twist {i}: residual {res:?} {st:?}"
        );
        let near = [st.w[0] * 1.01, st.w[1] * 0.99, st.w[2] * 1.02];
        let warm = loaded.step(free, c, c, false, Some(near)).unwrap();
        for j in 0..3 {
            let s = if j == 2 { size / p.gyration } else { size };
            assert!(
                (warm.w[j] - st.w[j]).abs() < 1e-11 * s,
                "twist {i}: {warm:?} vs {st:?}"
            );
        }
    }
    assert!(stuck > 30 && slid > 30, "{stuck} stuck, {slid} slid");
    // the load moves the limit surface: some twists stick under one pressure and slide under the other
    assert!(
        differ > 0,
        "no twist changed between uniform and loaded pressure"
    );
}

#[test]
fn between_20_and_100_radii_the_six_point_rule_is_the_eight_point_one_to_rounding() {
    // the simulation takes 6 x 6 points a triangle there; `wrench_quadrature` is 8 x 8
    let mut p = pentagon();
    for far in [20.1, 30.0, 50.0, 99.9] {
        for k in loads(&p) {
            p.set_load(k).unwrap();
            for t in 0..32 {
                let a = t as f64 * 0.2;
                let omega = 2.0;
                let v = [
                    a.cos() * omega * far * p.radius,
                    a.sin() * omega * far * p.radius,
                ];
                let (x, y) = (p.wrench(v, omega), p.wrench_quadrature(v, omega));
                for i in 0..3 {
                    let scale = if i == 2 { p.radius } else { 1.0 };
                    assert!(
                        (x[i] - y[i]).abs() <= 2e-15 * scale,
                        "far {far}, direction {t}: {x:?} vs {y:?}"
                    );
                }
            }
        }
    }
}
