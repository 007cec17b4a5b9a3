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
//!   1e-3n`; 3 x 3 points (the triangle's Jacobian `s` takes one degree) integrate every term
//!   up to degree 4 exactly, the first left out below 1e-15 relative; measured against 8 x 8
//!   points they agree to 5.6e-16 from 1e3 to 1e4 radii, and to 1e-15 out to 1e12 (tested).

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
        quadrature::<HESSIAN, 3>(p, v, omega)
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

/// Quadrature points over a polygon: on each triangle that fans from the centroid, `K x K`
/// Gauss–Legendre points, in lanes of [`LANES`] (padded with points of no weight).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Nodes {
    x: Box<[f64]>,
    y: Box<[f64]>,
    /// The area element `ws wt s |a x b|` of each point (the triangle `(0, a, b)` as `s (a + t
    /// (b - a))`).
    w: Box<[f64]>,
}

/// Lanes of the quadrature's sums: the sums run in this many partial sums whatever the build,
/// so that every build gives the same bits.
const LANES: usize = 4;

/// The Gauss–Legendre rules the quadrature takes, by points per direction (the order of
/// [`rules`]' nodes).
const RULES: [usize; 4] = [3, 4, 6, 8];

/// The polygon's nodes for each of [`RULES`] (`vertices` about the centroid).
pub(super) fn rules(vertices: &[[f64; 2]]) -> [Nodes; 4] {
    RULES.map(|k| nodes(vertices, k))
}

/// The `k x k`-point nodes of the polygon with `vertices` (about the centroid).
fn nodes(vertices: &[[f64; 2]], k: usize) -> Nodes {
    let (x, w) = rule(k);
    let n = vertices.len();
    let room = (n * k * k).div_ceil(LANES) * LANES;
    let (mut px, mut py, mut pw) = (
        Vec::with_capacity(room),
        Vec::with_capacity(room),
        Vec::with_capacity(room),
    );
    for k in 0..n {
        let (a, b) = (vertices[k], vertices[(k + 1) % n]);
        let jac = cross(a, b);
        for (&s, &ws) in x.iter().zip(w) {
            for (&t, &wt) in x.iter().zip(w) {
                px.push(s * (a[0] + t * (b[0] - a[0])));
                py.push(s * (a[1] + t * (b[1] - a[1])));
                pw.push(ws * wt * s * jac);
            }
        }
    }
    // (padding of no weight at the last point: inside the part, like every other)
    let padded = px.len().div_ceil(LANES) * LANES;
    let (lx, ly) = (px[px.len() - 1], py[py.len() - 1]);
    px.resize(padded, lx);
    py.resize(padded, ly);
    pw.resize(padded, 0.0);
    Nodes {
        x: px.into(),
        y: py.into(),
        w: pw.into(),
    }
}

fn rule(k: usize) -> (&'static [f64], &'static [f64]) {
    match k {
        3 => (&GAUSS3_X, &GAUSS3_W),
        4 => (&GAUSS4_X, &GAUSS4_W),
        6 => (&GAUSS6_X, &GAUSS6_W),
        8 => (&GAUSS8_X, &GAUSS8_W),
        _ => unreachable!("3, 4, 6 or 8 points"),
    }
}

/// The friction by `K x K`-point Gauss–Legendre quadrature on each triangle fanning from the
/// centroid (`K` one of [`RULES`]), the points' sums in lanes (AVX2 where the simulations take it; the
/// same bits on every build).
pub(super) fn quadrature<const HESSIAN: bool, const K: usize>(
    p: &Polygon,
    v: [f64; 2],
    omega: f64,
) -> Friction {
    // the twist scaled to slip speeds of order 1 (no overflow or underflow in the squares);
    // the wrench does not change, the rate of work scales with it and its Hessian inversely
    let scale = v[0].abs() + v[1].abs() + omega.abs() * p.radius;
    if scale == 0.0 {
        return Friction::default();
    }
    let (v, omega) = ([v[0] / scale, v[1] / scale], omega / scale);
    let slot = RULES.iter().position(|&k| k == K).expect("one of RULES");
    let nodes = &p.nodes[slot];
    #[cfg(target_arch = "x86_64")]
    let sums = if matches!(
        crate::simd::simd(),
        crate::simd::Simd::Avx2 | crate::simd::Simd::Avx512
    ) {
        // SAFETY: simd() chooses these builds only on a CPU that has AVX2.
        unsafe { sums_avx2::<HESSIAN>(nodes, v, omega, p.load) }
    } else {
        sums::<HESSIAN>(nodes, v, omega, p.load)
    };
    #[cfg(not(target_arch = "x86_64"))]
    let sums = sums::<HESSIAN>(nodes, v, omega, p.load);
    let [fx, fy, m, work, h00, h01, h02, h11, h12, h22] = sums;
    let a = p.area;
    let q = a * scale;
    let hessian = if HESSIAN {
        [
            [h00 / q, h01 / q, h02 / q],
            [h01 / q, h11 / q, h12 / q],
            [h02 / q, h12 / q, h22 / q],
        ]
    } else {
        [[0.0; 3]; 3]
    };
    Friction {
        wrench: [fx / a, fy / a, m / a],
        work: work / a * scale,
        hessian,
    }
}

/// [`sums`] in AVX2 lanes, the same operations in the same order on each lane (the same bits).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn sums_avx2<const HESSIAN: bool>(
    nodes: &Nodes,
    v: [f64; 2],
    omega: f64,
    load: [f64; 2],
) -> [f64; 10] {
    use std::arch::x86_64::*;
    let (v0, v1, om) = (
        _mm256_set1_pd(v[0]),
        _mm256_set1_pd(v[1]),
        _mm256_set1_pd(omega),
    );
    let (k0, k1, one) = (
        _mm256_set1_pd(load[0]),
        _mm256_set1_pd(load[1]),
        _mm256_set1_pd(1.0),
    );
    let floor = _mm256_set1_pd(1e-100);
    let mut acc = [_mm256_setzero_pd(); 10];
    let n = nodes.x.len();
    let mut i = 0;
    while i < n {
        // SAFETY: the three arrays have the same length, a multiple of LANES, and i < n.
        let (x, y, w) = unsafe {
            (
                _mm256_loadu_pd(nodes.x.as_ptr().add(i)),
                _mm256_loadu_pd(nodes.y.as_ptr().add(i)),
                _mm256_loadu_pd(nodes.w.as_ptr().add(i)),
            )
        };
        let ux = _mm256_sub_pd(v0, _mm256_mul_pd(om, y));
        let uy = _mm256_add_pd(v1, _mm256_mul_pd(om, x));
        let sq = _mm256_add_pd(_mm256_mul_pd(ux, ux), _mm256_mul_pd(uy, uy));
        let norm = _mm256_max_pd(_mm256_sqrt_pd(sq), floor);
        let weight = _mm256_add_pd(
            _mm256_add_pd(one, _mm256_mul_pd(k0, x)),
            _mm256_mul_pd(k1, y),
        );
        let area = _mm256_mul_pd(w, weight);
        // one division a point: 1/|u| serves the wrench and the Hessian
        let inv = _mm256_div_pd(one, norm);
        let wgt = _mm256_mul_pd(area, inv);
        acc[0] = _mm256_sub_pd(acc[0], _mm256_mul_pd(wgt, ux));
        acc[1] = _mm256_sub_pd(acc[1], _mm256_mul_pd(wgt, uy));
        let cr = _mm256_sub_pd(_mm256_mul_pd(x, uy), _mm256_mul_pd(y, ux));
        acc[2] = _mm256_sub_pd(acc[2], _mm256_mul_pd(wgt, cr));
        acc[3] = _mm256_add_pd(acc[3], _mm256_mul_pd(area, norm));
        if HESSIAN {
            let q2 = _mm256_add_pd(_mm256_mul_pd(x, ux), _mm256_mul_pd(y, uy));
            let g = _mm256_mul_pd(_mm256_mul_pd(wgt, inv), inv);
            let gy = _mm256_mul_pd(g, uy);
            let gx = _mm256_mul_pd(g, ux);
            acc[4] = _mm256_add_pd(acc[4], _mm256_mul_pd(gy, uy));
            acc[5] = _mm256_sub_pd(acc[5], _mm256_mul_pd(gy, ux));
            acc[6] = _mm256_sub_pd(acc[6], _mm256_mul_pd(gy, q2));
            acc[7] = _mm256_add_pd(acc[7], _mm256_mul_pd(gx, ux));
            acc[8] = _mm256_add_pd(acc[8], _mm256_mul_pd(gx, q2));
            acc[9] = _mm256_add_pd(acc[9], _mm256_mul_pd(_mm256_mul_pd(g, q2), q2));
        }
        i += LANES;
    }
    acc.map(|a| {
        let mut l = [0.0; LANES];
        // SAFETY: l holds LANES doubles.
        unsafe { _mm256_storeu_pd(l.as_mut_ptr(), a) };
        (l[0] + l[1]) + (l[2] + l[3])
    })
}

/// The quadrature's sums `(-∫ û, -∫ r x û, ∫ |u|` and the Hessian's six terms `∫ q q^T / |u|`,
/// `q = (z x û, r x (z x û))`), each over the lanes and then added in one order. A point the
/// twist leaves still (`u = 0`, the instantaneous centre on it) adds nothing: its speed is
/// floored at 1e-100 (the twist is scaled to speeds of order 1), which leaves `u` zero.
#[inline(always)]
fn sums<const HESSIAN: bool>(nodes: &Nodes, v: [f64; 2], omega: f64, load: [f64; 2]) -> [f64; 10] {
    let mut acc = [[0.0f64; LANES]; 10];
    for ((x, y), w) in nodes
        .x
        .chunks_exact(LANES)
        .zip(nodes.y.chunks_exact(LANES))
        .zip(nodes.w.chunks_exact(LANES))
    {
        let (x, y, w): (&[f64; LANES], &[f64; LANES], &[f64; LANES]) = (
            x.try_into().unwrap(),
            y.try_into().unwrap(),
            w.try_into().unwrap(),
        );
        let ux: [f64; LANES] = std::array::from_fn(|l| v[0] - omega * y[l]);
        let uy: [f64; LANES] = std::array::from_fn(|l| v[1] + omega * x[l]);
        let norm: [f64; LANES] =
            std::array::from_fn(|l| (ux[l] * ux[l] + uy[l] * uy[l]).sqrt().max(1e-100));
        // (the pressure's weight, 1 under uniform pressure)
        let area: [f64; LANES] =
            std::array::from_fn(|l| w[l] * (1.0 + load[0] * x[l] + load[1] * y[l]));
        // one division a point: 1/|u| serves the wrench and the Hessian
        let inv: [f64; LANES] = std::array::from_fn(|l| 1.0 / norm[l]);
        let wgt: [f64; LANES] = std::array::from_fn(|l| area[l] * inv[l]);
        for l in 0..LANES {
            acc[0][l] -= wgt[l] * ux[l];
            acc[1][l] -= wgt[l] * uy[l];
            acc[2][l] -= wgt[l] * (x[l] * uy[l] - y[l] * ux[l]);
            acc[3][l] += area[l] * norm[l];
        }
        if HESSIAN {
            // J^T (I - û û^T) J / |u| = J^T p p^T J / |u|, p = z x û: wgt q q^T / |u|² with
            // q = (-u_y, u_x, r x (z x u))
            let q2: [f64; LANES] = std::array::from_fn(|l| x[l] * ux[l] + y[l] * uy[l]);
            let g: [f64; LANES] = std::array::from_fn(|l| (wgt[l] * inv[l]) * inv[l]);
            for l in 0..LANES {
                let (gy, gx) = (g[l] * uy[l], g[l] * ux[l]);
                acc[4][l] += gy * uy[l];
                acc[5][l] -= gy * ux[l];
                acc[6][l] -= gy * q2[l];
                acc[7][l] += gx * ux[l];
                acc[8][l] += gx * q2[l];
                acc[9][l] += (g[l] * q2[l]) * q2[l];
            }
        }
    }
    acc.map(|a| (a[0] + a[1]) + (a[2] + a[3]))
}

/// Gauss–Legendre nodes on [0, 1], 3 points.
const GAUSS3_X: [f64; 3] = [0.112_701_665_379_258_31, 0.5, 0.887_298_334_620_741_7];

/// Gauss–Legendre weights on [0, 1], 3 points.
const GAUSS3_W: [f64; 3] = [
    0.277_777_777_777_777_8,
    0.444_444_444_444_444_4,
    0.277_777_777_777_777_8,
];

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

/// Gauss–Legendre nodes on [0, 1], 6 points.
const GAUSS6_X: [f64; 6] = [
    0.033_765_242_898_423_99,
    0.169_395_306_766_867_73,
    0.380_690_406_958_401_56,
    0.619_309_593_041_598_5,
    0.830_604_693_233_132_2,
    0.966_234_757_101_576,
];

/// Gauss–Legendre weights on [0, 1], 6 points.
const GAUSS6_W: [f64; 6] = [
    0.085_662_246_189_585_18,
    0.180_380_786_524_069_3,
    0.233_956_967_286_345_52,
    0.233_956_967_286_345_52,
    0.180_380_786_524_069_3,
    0.085_662_246_189_585_18,
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

    /// The quadrature point by point, summed in order (the form before the lanes): the
    /// reference the lanes' sums must match to rounding.
    fn reference<const K: usize>(p: &Polygon, v: [f64; 2], omega: f64) -> [f64; 4] {
        let (x, w) = rule(K);
        let n = p.vertices.len();
        let mut out = [0.0; 4];
        for k in 0..n {
            let (a, b) = (p.vertices[k], p.vertices[(k + 1) % n]);
            let jac = cross(a, b);
            for (&s, &ws) in x.iter().zip(w) {
                for (&t, &wt) in x.iter().zip(w) {
                    let r = [
                        s * (a[0] + t * (b[0] - a[0])),
                        s * (a[1] + t * (b[1] - a[1])),
                    ];
                    let u = [v[0] - omega * r[1], v[1] + omega * r[0]];
                    let norm = u[0].hypot(u[1]);
                    let area = ws * wt * s * jac * (1.0 + p.load[0] * r[0] + p.load[1] * r[1]);
                    out[0] -= area * u[0] / norm;
                    out[1] -= area * u[1] / norm;
                    out[2] -= area * cross(r, u) / norm;
                    out[3] += area * norm;
                }
            }
        }
        out.map(|x| x / p.area)
    }

    #[test]
    fn the_lanes_sum_the_points_as_one_by_one_does() {
        let mut p = part();
        for load in [[0.0, 0.0], [20.0, -15.0]] {
            p.set_load(load).unwrap();
            for (i, (v, omega)) in [([0.3, -0.2], 2.0), ([1.0, 0.0], 1e-3), ([0.0, 0.4], -30.0)]
                .into_iter()
                .enumerate()
            {
                let want = reference::<8>(&p, v, omega);
                let got = quadrature::<true, 8>(&p, v, omega);
                let got4 = quadrature::<false, 4>(&p, v, omega);
                let want4 = reference::<4>(&p, v, omega);
                let got6 = quadrature::<false, 6>(&p, v, omega);
                let want6 = reference::<6>(&p, v, omega);
                let got3 = quadrature::<false, 3>(&p, v, omega);
                let want3 = reference::<3>(&p, v, omega);
                let speed = v[0].hypot(v[1]) + omega.abs() * p.radius;
                for k in 0..3 {
                    let tol = if k == 2 { 1e-15 * p.radius } else { 1e-15 };
                    assert!(
                        (got.wrench[k] - want[k]).abs() <= tol,
                        "{i} {k}: {got:?} {want:?}"
                    );
                    assert!((got4.wrench[k] - want4[k]).abs() <= tol, "{i} {k} (4)");
                    assert!((got6.wrench[k] - want6[k]).abs() <= tol, "{i} {k} (6)");
                    assert!((got3.wrench[k] - want3[k]).abs() <= tol, "{i} {k} (3)");
                }
                assert!((got.work - want[3]).abs() <= 1e-15 * speed);
                // the AVX2 build and the portable one give the same bits
                #[cfg(target_arch = "x86_64")]
                if is_x86_feature_detected!("avx2") {
                    let scale = v[0].abs() + v[1].abs() + omega.abs() * p.radius;
                    let (vs, ws) = ([v[0] / scale, v[1] / scale], omega / scale);
                    let fast = unsafe { sums_avx2::<true>(&p.nodes[3], vs, ws, p.load) };
                    assert_eq!(fast, sums::<true>(&p.nodes[3], vs, ws, p.load));
                }
            }
        }
    }

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
        let (x, w) = rule(8);
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
