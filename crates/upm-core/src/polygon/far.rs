//! The friction of a polygon whose instantaneous centre is far away (more than [`super::FAR`]
//! part radii, or a pure translation), where the fan's closed forms cancel each other.
//!
//! With `V = |v|`, `beta = omega / V` and `a`, `b` a point's coordinates along `v` and across it,
//! the slip direction is `((1 - beta b) v/V + beta a z x v/V) / q`, `q² = 1 - 2 beta b + beta²
//! |r|²`: a series in `beta |r| <= 1/FAR`. Two regimes:
//!
//! - `beta R <= LINEAR` (1e-8, `R` the part's radius): the series' first terms are exact to
//!   rounding (the next are `(beta R)² <= 1e-16` relative): `F = -v/V`, `M = -omega <a²> / V`,
//!   `D = V + omega² <a²> / (2V)`, with `<a²>` from the part's second moments of area;
//! - otherwise Gauss–Legendre quadrature over the triangles that fan from the centroid. The
//!   integrand is analytic, its Taylor terms of degree `n` of relative size `(beta R)^n <=
//!   1e-3n`; 4 x 4 points integrate every term up to degree 6 exactly (the first left out is
//!   below 1e-21), so they are exact to rounding too.

use super::{cross, Friction, Polygon};

/// Below this `|omega| R / |v|` the part's friction is the series' first terms.
const LINEAR: f64 = 1e-8;

/// The friction of `(v, omega)` with the instantaneous centre far away (module docs); the Hessian
/// of the rate of work if `HESSIAN`.
pub(super) fn friction<const HESSIAN: bool>(p: &Polygon, v: [f64; 2], omega: f64) -> Friction {
    let speed = v[0].hypot(v[1]);
    if omega.abs() * p.radius <= LINEAR * speed {
        linear::<HESSIAN>(p, v, omega, speed)
    } else {
        quadrature::<HESSIAN, 4>(p, v, omega)
    }
}

/// The first terms of the series in `beta` (module docs).
fn linear<const HESSIAN: bool>(p: &Polygon, v: [f64; 2], omega: f64, speed: f64) -> Friction {
    let e = [v[0] / speed, v[1] / speed];
    let [sxx, sxy, syy] = p.second;
    // <a²> = e^T S e
    let se = [sxx * e[0] + sxy * e[1], sxy * e[0] + syy * e[1]];
    let a2 = e[0] * se[0] + e[1] * se[1];
    let mut hessian = [[0.0; 3]; 3];
    if HESSIAN {
        // D = V + omega² v^T S v / (2 V³)
        for i in 0..2 {
            for j in 0..2 {
                let eye = if i == j { 1.0 } else { 0.0 };
                hessian[i][j] = (eye - e[i] * e[j]) / speed;
            }
            // d²D / dv_i d omega = omega (2 (S e)_i - 3 <a²> e_i) / V²
            hessian[i][2] = omega * (2.0 * se[i] - 3.0 * a2 * e[i]) / (speed * speed);
            hessian[2][i] = hessian[i][2];
        }
        hessian[2][2] = a2 / speed;
    }
    Friction {
        wrench: [-e[0], -e[1], -omega * a2 / speed],
        work: speed + 0.5 * omega * omega * a2 / speed,
        hessian,
    }
}

/// The friction by `K x K`-point Gauss–Legendre quadrature on each triangle fanning from the
/// centroid (`K` = 4 or 8).
pub(super) fn quadrature<const HESSIAN: bool, const K: usize>(
    p: &Polygon,
    v: [f64; 2],
    omega: f64,
) -> Friction {
    let (x, w): (&[f64], &[f64]) = match K {
        4 => (&GAUSS4_X, &GAUSS4_W),
        8 => (&GAUSS8_X, &GAUSS8_W),
        _ => unreachable!("4 or 8 points"),
    };
    // the twist scaled to slip speeds of order 1 (no overflow or underflow in the squares);
    // the wrench does not change, the rate of work scales with it and its Hessian inversely
    let scale = v[0].abs() + v[1].abs() + omega.abs() * p.radius;
    if scale == 0.0 {
        return Friction::default();
    }
    let (v, omega) = ([v[0] / scale, v[1] / scale], omega / scale);
    let n = p.vertices.len();
    let (mut fx, mut fy, mut m, mut work) = (0.0, 0.0, 0.0, 0.0);
    let mut hessian = [[0.0; 3]; 3];
    for k in 0..n {
        let (a, b) = (p.vertices[k], p.vertices[(k + 1) % n]);
        let jac = cross(a, b);
        for (&s, &ws) in x.iter().zip(w) {
            for (&t, &wt) in x.iter().zip(w) {
                // the triangle (0, a, b) as s (a + t (b - a)), dA = s |a x b| ds dt
                let r = [
                    s * (a[0] + t * (b[0] - a[0])),
                    s * (a[1] + t * (b[1] - a[1])),
                ];
                let u = [v[0] - omega * r[1], v[1] + omega * r[0]];
                let norm = (u[0] * u[0] + u[1] * u[1]).sqrt();
                if norm == 0.0 {
                    continue;
                }
                // (the pressure's weight, 1 under uniform pressure)
                let area = ws * wt * s * jac * (1.0 + p.load[0] * r[0] + p.load[1] * r[1]);
                let wgt = area / norm;
                fx -= wgt * u[0];
                fy -= wgt * u[1];
                m -= wgt * cross(r, u);
                work += area * norm;
                if HESSIAN {
                    // J^T (I - û û^T) J / |u| = J^T p p^T J / |u|, p = z x û
                    let q = [-u[1] / norm, u[0] / norm];
                    let q = [q[0], q[1], cross(r, q)];
                    for (i, row) in hessian.iter_mut().enumerate() {
                        for (j, h) in row.iter_mut().enumerate() {
                            *h += wgt * q[i] * q[j];
                        }
                    }
                }
            }
        }
    }
    let a = p.area;
    for h in hessian.iter_mut().flatten() {
        *h /= a * scale;
    }
    Friction {
        wrench: [fx / a, fy / a, m / a],
        work: work / a * scale,
        hessian,
    }
}

/// Gauss–Legendre nodes on [0, 1], 4 points.
const GAUSS4_X: [f64; 4] = [
    0.069_431_844_202_973_71,
    0.330_009_478_207_571_9,
    0.669_990_521_792_428_1,
    0.930_568_155_797_026_3,
];

/// Gauss–Legendre weights on [0, 1], 4 points.
const GAUSS4_W: [f64; 4] = [
    0.173_927_422_568_726_93,
    0.326_072_577_431_273_07,
    0.326_072_577_431_273_07,
    0.173_927_422_568_726_93,
];

/// Gauss–Legendre nodes on [0, 1], 8 points.
const GAUSS8_X: [f64; 8] = [
    0.019_855_071_751_231_856,
    0.101_666_761_293_186_63,
    0.237_233_795_041_835_5,
    0.408_282_678_752_175_1,
    0.591_717_321_247_825,
    0.762_766_204_958_164_5,
    0.898_333_238_706_813_4,
    0.980_144_928_248_768_1,
];

/// Gauss–Legendre weights on [0, 1], 8 points.
const GAUSS8_W: [f64; 8] = [
    0.050_614_268_145_188_13,
    0.111_190_517_226_687_24,
    0.156_853_322_938_943_64,
    0.181_341_891_689_181,
    0.181_341_891_689_181,
    0.156_853_322_938_943_64,
    0.111_190_517_226_687_24,
    0.050_614_268_145_188_13,
];

#[cfg(test)]
mod tests {
    use super::*;

    fn part() -> Polygon {
        Polygon::new("p", &[[0.0, 0.0], [0.03, 0.0], [0.04, 0.02], [0.0, 0.01]]).unwrap()
    }

    #[test]
    fn every_far_regime_agrees_with_the_fine_quadrature() {
        let p = part();
        let r = p.radius;
        // instantaneous centres from 1e3 to 1e12 radii away, in several directions
        for (i, far) in [1.001e3, 3e3, 1e5, 9e7, 1.1e8, 1e10, 1e12]
            .into_iter()
            .enumerate()
        {
            let angle = 0.7 + 1.9 * i as f64;
            let omega = if i % 2 == 0 { 2.5 } else { -0.4 };
            let r0 = [far * r * angle.cos(), far * r * angle.sin()];
            let v = [-omega * r0[1], omega * r0[0]];
            let got = friction::<true>(&p, v, omega);
            let want = quadrature::<true, 8>(&p, v, omega);
            let speed = v[0].hypot(v[1]);
            for k in 0..3 {
                // a few ulps of the integrand's terms (the moment sums terms of size r to a
                // small total, which the fine quadrature knows to about 1e-16 r)
                let tol = if k == 2 { 1e-15 * r } else { 1e-15 };
                assert!(
                    (got.wrench[k] - want.wrench[k]).abs() <= tol,
                    "far {far:e}, wrench {k}: {:e} vs {:e}",
                    got.wrench[k],
                    want.wrench[k]
                );
            }
            let dw = (got.work - want.work).abs() / speed;
            assert!(
                dw <= 1e-15,
                "far {far:e}, work: {:e} vs {:e}",
                got.work,
                want.work
            );
            // the moment is there, and linear in the spin: -omega <a²> / V to leading order
            assert!(got.wrench[2] * omega < 0.0, "far {far:e}");
            // the Hessian (only Newton's steps use it) to a few digits
            let scale = 1.0 / speed;
            let sigma = [1.0, 1.0, r];
            for a in 0..3 {
                for b in 0..3 {
                    let (g, w) = (got.hessian[a][b], want.hessian[a][b]);
                    assert!(
                        (g - w).abs() <= 1e-9 * scale * sigma[a] * sigma[b],
                        "far {far:e}, hessian {a}{b}: {g:e} vs {w:e}"
                    );
                }
            }
        }
        // a pure translation: against the motion, no moment, exactly
        let t = friction::<false>(&p, [0.3, -0.4], 0.0);
        assert_eq!(t.wrench, [-0.6, 0.8, 0.0]);
        assert_eq!(t.work, 0.5);
    }

    #[test]
    fn the_second_moments_are_the_quadrature_s() {
        let p = part();
        let mut want = [0.0; 3];
        let (x, w) = (&GAUSS8_X, &GAUSS8_W);
        let n = p.vertices.len();
        for k in 0..n {
            let (a, b) = (p.vertices[k], p.vertices[(k + 1) % n]);
            let jac = a[0] * b[1] - a[1] * b[0];
            for (&s, &ws) in x.iter().zip(w) {
                for (&t, &wt) in x.iter().zip(w) {
                    let r = [
                        s * (a[0] + t * (b[0] - a[0])),
                        s * (a[1] + t * (b[1] - a[1])),
                    ];
                    let da = ws * wt * s * jac / p.area;
                    want[0] += da * r[0] * r[0];
                    want[1] += da * r[0] * r[1];
                    want[2] += da * r[1] * r[1];
                }
            }
        }
        for k in 0..3 {
            assert!(
                (p.second[k] - want[k]).abs() < 1e-18,
                "{:?} vs {want:?}",
                p.second
            );
        }
        let polar = (p.second[0] + p.second[2]) * p.area;
        assert!((polar - p.polar).abs() < 1e-15 * p.polar);
    }
}
