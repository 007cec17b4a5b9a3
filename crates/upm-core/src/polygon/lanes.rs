//! The fan integrals of [`Polygon::fan`] eight edges at a time: each edge is a lane, its
//! branches are selections, and the logarithm is this module's [`ln_1p`], written in plain
//! arithmetic so that the AVX2 build ([`super::avx2`], also on AVX-512 machines) and the
//! portable one compute the same bits (no fused multiply–adds, the lanes summed in one order).

use super::load::Linear;
use super::{Fan, Polygon};
#[cfg(target_arch = "x86_64")]
use crate::simd::{simd, Simd};

/// Edges per lane group.
pub(super) const LANES: usize = 8;

/// Eight edges in lanes: edge `k` runs from `(ax, ay)` to `(bx, by)` (vertices about the
/// centroid) along the unit `(ex, ey)` for `len`; `live` is false in the lanes that pad the last
/// group (they add nothing).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Edges {
    pub(super) ax: [f64; LANES],
    pub(super) ay: [f64; LANES],
    pub(super) bx: [f64; LANES],
    pub(super) by: [f64; LANES],
    pub(super) ex: [f64; LANES],
    pub(super) ey: [f64; LANES],
    pub(super) len: [f64; LANES],
    pub(super) live: [bool; LANES],
    /// `live` as lane masks (all ones in a live lane).
    pub(super) bits: [u64; LANES],
    /// Whether any of the upper half's lanes (`LANES / 2..`) is live: every build leaves out a
    /// half that is not (a triangle or a quadrilateral fills four lanes of eight).
    pub(super) upper: bool,
}

/// The polygon's edges (`vertices` about the centroid, counter-clockwise) in groups of
/// [`LANES`].
pub(super) fn edges(vertices: &[[f64; 2]]) -> Vec<Edges> {
    let n = vertices.len();
    (0..n.div_ceil(LANES))
        .map(|g| {
            let mut e = Edges {
                ax: [0.0; LANES],
                ay: [0.0; LANES],
                bx: [0.0; LANES],
                by: [0.0; LANES],
                ex: [0.0; LANES],
                ey: [0.0; LANES],
                len: [0.0; LANES],
                live: [false; LANES],
                bits: [0; LANES],
                upper: g * LANES + LANES / 2 < n,
            };
            for l in 0..LANES {
                // a padding lane repeats edge 0, so that its arithmetic stays finite
                let k = if g * LANES + l < n { g * LANES + l } else { 0 };
                let (a, b) = (vertices[k], vertices[(k + 1) % n]);
                let d = [b[0] - a[0], b[1] - a[1]];
                let len = (d[0] * d[0] + d[1] * d[1]).sqrt();
                (e.ax[l], e.ay[l], e.bx[l], e.by[l]) = (a[0], a[1], b[0], b[1]);
                (e.ex[l], e.ey[l], e.len[l]) = (d[0] / len, d[1] / len, len);
                e.live[l] = g * LANES + l < n;
                e.bits[l] = if e.live[l] { u64::MAX } else { 0 };
            }
            e
        })
        .collect()
}

/// The fan integrals about `r0`, the curvature only if `CURVATURE`, on the build the
/// simulations take (`crate::simd::simd`).
pub(super) fn fan<const CURVATURE: bool>(p: &Polygon, r0: [f64; 2]) -> Fan {
    fan_loaded::<CURVATURE, false>(p, r0, [0.0; 2]).0
}

/// [`fan`] and, if `LOADED`, the terms a pressure gradient `k` adds to it ([`super::load`]), from the
/// same pass over the edges (the load's terms reuse each edge's distances, differences and
/// logarithm).
pub(super) fn fan_loaded<const CURVATURE: bool, const LOADED: bool>(
    p: &Polygon,
    r0: [f64; 2],
    k: [f64; 2],
) -> (Fan, Linear) {
    #[cfg(target_arch = "x86_64")]
    if matches!(simd(), Simd::Avx2 | Simd::Avx512) {
        // SAFETY: simd() chooses these builds only on a CPU that has AVX2 (AVX-512 has it).
        return unsafe { super::avx2::fan::<CURVATURE, LOADED>(p, r0, k) };
    }
    fan_with::<CURVATURE, LOADED>(p, r0, k)
}

/// Picks `a` where `c`, else `b` (a blend in the vector builds).
#[inline(always)]
fn pick(c: bool, a: f64, b: f64) -> f64 {
    let m = (c as u64).wrapping_neg();
    f64::from_bits((a.to_bits() & m) | (b.to_bits() & !m))
}

/// The difference `asinh(tb/|h|) - asinh(ta/|h|)` along an edge of length `len` (`tb = ta +
/// len`, `ra` and `rb` the distances of its ends, `drho = rb - ra`) as `ln(1 + arg)`, `arg >= 0`
/// returned (zero where `skip`, no area): with `asinh(t/|h|) = ln((t + rho)/|h|)`, on one side of
/// the foot of `h` the difference is one `ln_1p` of a ratio `a1 = n1 / d1` of positive sums,
/// across it a sum `ln(1 + a1) + ln(1 + a2)`, one logarithm of `(1 + a1)(1 + a2)`: `arg = (n1 d2
/// + n2 (d1 + n1)) / (d1 d2)`, positive sums over one division. (There `|h|` is taken at least
/// 1e-100 of the edge's length, so that `d1 d2` stays a normal number: closer to the line the
/// logarithm, below 500 either way, enters the sums times `h²`, far below their rounding.)
#[inline(always)]
pub(super) fn log_arg(
    h: f64,
    ta: f64,
    tb: f64,
    ra: f64,
    rb: f64,
    len: f64,
    drho: f64,
    skip: bool,
) -> f64 {
    let (after, before) = (ta >= 0.0, tb <= 0.0);
    let across = !after && !before;
    let hh = pick(across, h.abs().max(1e-100 * len), h.abs());
    let n1 = pick(
        after,
        len + drho,
        pick(before, len - drho, tb * (hh + rb + tb)),
    );
    let d1 = pick(after, ta + ra, pick(before, rb - tb, hh * (hh + rb)));
    let (n2, d2) = (-ta * (hh + ra - ta), hh * (hh + ra));
    let num = pick(across, n1 * d2 + n2 * (d1 + n1), n1);
    let den = pick(across, d1 * d2, d1);
    pick(skip, 0.0, num / den)
}

/// The portable build of [`fan_loaded`]: each lane's arithmetic in plain Rust.
#[inline(always)]
pub(super) fn fan_with<const CURVATURE: bool, const LOADED: bool>(
    p: &Polygon,
    r0: [f64; 2],
    k: [f64; 2],
) -> (Fan, Linear) {
    let mut acc = [[0.0; LANES]; 12];
    for e in &p.lanes {
        // (a half with no live lane adds nothing: left out, as the vector builds do)
        let width = if e.upper { LANES } else { LANES / 2 };
        let mut arg = [0.0; LANES];
        let mut geo = [[0.0; LANES]; 6]; // h, ta, ra, rb, drho, skip
        for l in 0..width {
            let a = [e.ax[l] - r0[0], e.ay[l] - r0[1]];
            let b = [e.bx[l] - r0[0], e.by[l] - r0[1]];
            let (ex, ey, len) = (e.ex[l], e.ey[l], e.len[l]);
            // r0 is within FAR radii of the centroid: no overflow
            let ra = (a[0] * a[0] + a[1] * a[1]).sqrt();
            let rb = (b[0] * b[0] + b[1] * b[1]).sqrt();
            // the edge's line: p = h n + t e, n = (e_y, -e_x), h signed (> 0: r0 on its inner
            // side); h = 0 (r0 on the line) spans no area
            let h = a[0] * ey - a[1] * ex;
            let skip = !e.live[l] || h == 0.0;
            let ta = a[0] * ex + a[1] * ey;
            let tb = ta + len;
            // rb - ra without cancellation
            let drho = len * (ta + tb) / (ra + rb);
            arg[l] = log_arg(h, ta, tb, ra, rb, len, drho, skip);
            geo[0][l] = pick(skip, 0.0, h);
            geo[1][l] = ta;
            (geo[2][l], geo[3][l], geo[4][l]) = (ra, rb, drho);
            geo[5][l] = pick(skip, 1.0, 0.0);
        }
        let dasinh = ln_1p8(&arg);
        for l in 0..width {
            let [h, ta, ra, rb, drho, skip] = [0, 1, 2, 3, 4, 5].map(|i| geo[i][l]);
            let (ex, ey, len) = (e.ex[l], e.ey[l], e.len[l]);
            let d = dasinh[l];
            // ∫ |p| dA = (h/3) ∫ sqrt(h² + t²) dt = (h/6) [t rho + h² asinh(t/|h|)]
            acc[0][l] += h / 6.0 * (len * rb + ta * drho + h * h * d);
            // ∫ p/|p| dA = (h/2) ∫ (h n + t e)/rho dt = (h/2) [h n asinh(t/|h|) + e rho]
            let (nx, ny) = (ey, -ex);
            acc[1][l] += 0.5 * h * (h * nx * d + ex * drho);
            acc[2][l] += 0.5 * h * (h * ny * d + ey * drho);
            // a lane of no area may hold infinities (r0 at a vertex): it adds nothing
            let live = skip == 0.0;
            let (mut ia, mut ib, mut s) = (0.0, 0.0, 0.0);
            if CURVATURE {
                // ∫ p p^T/|p|³ dA = h ∫ (h n + t e)(h n + t e)^T / rho³ dt
                //   = h [s n n^T + h c (n e^T + e n^T) + (asinh(t/|h|) - s) e e^T]
                // between the ends, s = t/rho and c = -1/rho (their differences below)
                (ia, ib) = (1.0 / ra, 1.0 / rb);
                s = (len * ra - ta * drho) * ia * ib; // tb/rb - ta/ra
                let c = ia - ib;
                let (nn, ne, ee) = (h * s, h * h * c, h * (d - s));
                let (gxx, gxy, gyy) = in_plane(nn, ne, ee, [nx, ny], [ex, ey]);
                acc[3][l] += pick(live, gxx, 0.0);
                acc[4][l] += pick(live, gxy, 0.0);
                acc[5][l] += pick(live, gyy, 0.0);
            }
            if LOADED {
                // the load's terms (module `load`), the triangle's edge with n = (e_y, -e_x)
                let h2 = h * h;
                let (kn, kt) = (k[0] * nx + k[1] * ny, k[0] * ex + k[1] * ey);
                // tb rb - ta ra
                let dtr = len * rb + ta * drho;
                // ∫ d d^T / rho dA: h/3 ∫ (h² n n^T + h t (n e^T + e n^T) + t² e e^T) / rho
                let i2 = 0.5 * (dtr - h2 * d);
                let (snn, snt, stt) = (h * h2 * d * THIRD, h2 * drho * THIRD, h * i2 * THIRD);
                let (cn, ct) = (snn * kn + snt * kt, snt * kn + stt * kt);
                acc[6][l] += cn * nx + ct * ex;
                acc[7][l] += cn * ny + ct * ey;
                // ∫ d rho dA: h/4 ∫ (h n + t e) rho dt
                let j0 = 0.5 * (dtr + h2 * d);
                let j1 = drho * (ra * ra + ra * rb + rb * rb) * THIRD;
                acc[8][l] += 0.25 * h * (h * kn * j0 + kt * j1);
                if CURVATURE {
                    // ∫ (k . d) d d^T / rho³ dA: h/2 ∫ (h kn + t kt) p p^T / rho³ dt
                    let k0 = s / h2;
                    let k1 = drho * ia * ib; // 1/ra - 1/rb
                    let k2 = d - s;
                    let k3 = drho - h2 * k1;
                    let cnn = 0.5 * h * (h2 * h * kn * k0 + h2 * kt * k1);
                    let cnt = 0.5 * h * (h2 * kn * k1 + h * kt * k2);
                    let ctt = 0.5 * h * (h * kn * k2 + kt * k3);
                    let (lxx, lxy, lyy) = in_plane(cnn, cnt, ctt, [nx, ny], [ex, ey]);
                    acc[9][l] += pick(live, lxx, 0.0);
                    acc[10][l] += pick(live, lxy, 0.0);
                    acc[11][l] += pick(live, lyy, 0.0);
                }
            }
        }
    }
    let sum = |a: &[f64; LANES]| {
        // pairwise, in one order for every build
        let q = [a[0] + a[4], a[1] + a[5], a[2] + a[6], a[3] + a[7]];
        (q[0] + q[2]) + (q[1] + q[3])
    };
    from_sums(acc.map(|a| sum(&a)))
}

/// The fan's sums and the load's, in the order the lanes accumulate them.
pub(super) fn from_sums(sums: [f64; 12]) -> (Fan, Linear) {
    let [dist, ux, uy, xx, xy, yy, lx, ly, ld, lxx, lxy, lyy] = sums;
    (
        Fan {
            dist,
            unit: [ux, uy],
            curvature: [xx, xy, yy],
        },
        Linear {
            unit: [lx, ly],
            dist: ld,
            curvature: [lxx, lxy, lyy],
        },
    )
}

/// `(xx, xy, yy)` of `nn n n^T + ne (n e^T + e n^T) + ee e e^T`.
#[inline(always)]
fn in_plane(nn: f64, ne: f64, ee: f64, n: [f64; 2], e: [f64; 2]) -> (f64, f64, f64) {
    (
        nn * n[0] * n[0] + 2.0 * ne * n[0] * e[0] + ee * e[0] * e[0],
        nn * n[0] * n[1] + ne * (n[0] * e[1] + e[0] * n[1]) + ee * e[0] * e[1],
        nn * n[1] * n[1] + 2.0 * ne * n[1] * e[1] + ee * e[1] * e[1],
    )
}

/// One third (a product with it costs less than a division by 3).
pub(super) const THIRD: f64 = 1.0 / 3.0;

pub(super) const LN2_HI: f64 = 0.6931471803691238;
pub(super) const LN2_LO: f64 = 1.9082149292705877e-10;
/// `1 / u` for `u >= 1` to about 1.5 % (from its bits, one Newton step; some number past
/// `1e308`), for a correction far below an ulp, without a division.
#[inline(always)]
pub(super) fn recip(u: f64) -> f64 {
    let r = f64::from_bits(RECIP.wrapping_sub(u.to_bits()));
    r * (2.0 - u * r)
}

/// The bits whose difference with a double's approximate its reciprocal.
pub(super) const RECIP: u64 = 0x7fde_6238_22fc_16e6;

/// The minimax polynomial `R(s²)` of `ln(1 + f) = f - f²/2 + s (f²/2 + R)`, `s = f / (2 + f)`,
/// on `sqrt(2)/2 <= 1 + f < sqrt(2)` (fdlibm's coefficients, error below 2^-58).
pub(super) const LG: [f64; 7] = [
    0.6666666666666735,
    0.3999999999940942,
    0.2857142874366239,
    0.22222198432149784,
    0.1818357216161805,
    0.15313837699209373,
    0.14798198605116586,
];

/// `ln(1 + x)` for `x >= 0` finite (lanes with other values give some number, unused), within
/// about 1 ulp: `1 + x = 2^k m`, `m` in `[sqrt(2)/2, sqrt(2))`, with the rounding of `1 + x`
/// corrected, and `ln(m)` from the polynomial in `s = (m - 1)/(m + 1)`.
#[inline(always)]
fn ln_1p8(x: &[f64; LANES]) -> [f64; LANES] {
    let mut out = [0.0; LANES];
    for (o, &x) in out.iter_mut().zip(x) {
        *o = ln_1p(x);
    }
    out
}

/// One lane of [`ln_1p8`].
#[inline(always)]
pub(super) fn ln_1p(x: f64) -> f64 {
    let u = 1.0 + x;
    let high = (u.to_bits() >> 32) + (0x3ff0_0000 - 0x3fe6_a09e);
    let k = (high >> 20) as i64 - 0x3ff;
    // k as a double, exact (0 <= k < 1024)
    let dk = f64::from_bits(0x4330_0000_0000_0000 | (k as u64 & 0x7ff)) - 4_503_599_627_370_496.0;
    // the rounding of 1 + x, relative: ln(1 + x) = ln(u) + c (c below an ulp: over u to 2 %)
    let c = pick(k >= 2, 1.0 - (u - x), x - (u - 1.0)) * recip(u);
    let c = pick(k < 54, c, 0.0);
    let m =
        f64::from_bits((((high & 0x000f_ffff) + 0x3fe6_a09e) << 32) | (u.to_bits() & 0xffff_ffff));
    // below sqrt(2) - 1 (k = 0) the reduction is x itself, exact
    let small = x < std::f64::consts::SQRT_2 - 1.0;
    let f = pick(small, x, m - 1.0);
    let (c, dk) = (pick(small, 0.0, c), pick(small, 0.0, dk));
    let hfsq = 0.5 * f * f;
    let s = f / (2.0 + f);
    let z = s * s;
    let w = z * z;
    let t1 = w * (LG[1] + w * (LG[3] + w * LG[5]));
    let t2 = z * (LG[0] + w * (LG[2] + w * (LG[4] + w * LG[6])));
    s * (hfsq + (t1 + t2)) + (dk * LN2_LO + c) - hfsq + f + dk * LN2_HI
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// Distance in units in the last place.
    fn ulps(a: f64, b: f64) -> u64 {
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs()
    }

    #[test]
    fn ln_1p_is_within_an_ulp_of_the_library_s() {
        // log-uniform from 1e-300 to 1e300, and the edges of its branches
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut worst = 0;
        let mut lanes = Vec::new();
        let mut check = |x: f64| {
            let (got, want) = (ln_1p(x), x.ln_1p());
            worst = worst.max(ulps(got, want));
            assert!(
                ulps(got, want) <= 1,
                "ln_1p({x:e}) = {got:e}, the library's {want:e}"
            );
            lanes.push((x, got));
        };
        for _ in 0..1_000_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let t = (state >> 11) as f64 / (1u64 << 53) as f64;
            check(10f64.powf(-300.0 + 600.0 * t));
            check(t);
            check(4.0 * t);
        }
        for x in [
            0.0,
            1e-320,
            f64::EPSILON,
            0.414_213_562_373_095,
            0.414_213_562_373_096,
            1.0,
        ] {
            check(x);
        }
        for k in 1..60 {
            let p = 2f64.powi(k);
            for x in [
                p - 1.0,
                p,
                p * (1.0 + f64::EPSILON),
                p * std::f64::consts::SQRT_2,
            ] {
                check(x);
            }
        }
        assert!(worst <= 1);
        // the AVX2 build gives the same bits
        #[cfg(target_arch = "x86_64")]
        if is_x86_feature_detected!("avx2") {
            for group in lanes.chunks_exact(4) {
                let x = std::array::from_fn(|l| group[l].0);
                // SAFETY: the CPU has AVX2.
                let got = unsafe { super::super::avx2::ln_1p_lanes(x) };
                for l in 0..4 {
                    assert_eq!(got[l].to_bits(), group[l].1.to_bits(), "ln_1p({:e})", x[l]);
                }
            }
        }
    }

    /// A nonagon (more edges than a group of lanes) and a triangle (an empty upper half).
    pub(in super::super) fn outlines() -> [Vec<[f64; 2]>; 2] {
        let nine = vec![
            [0.0, 0.0],
            [0.03, -0.004],
            [0.041, 0.016],
            [0.035, 0.027],
            [0.022, 0.031],
            [0.008, 0.029],
            [-0.003, 0.022],
            [-0.006, 0.019],
            [-0.005, 0.008],
        ];
        [nine, vec![[0.0, 0.0], [0.02, 0.0], [0.005, 0.01]]]
    }

    /// Centres of rotation about `p`: inside, outside, far, on a vertex, on an edge's line,
    /// before and across its foot, a hair off the centroid.
    pub(in super::super) fn centres(p: &Polygon) -> Vec<[f64; 2]> {
        let v = &p.vertices;
        vec![
            [0.0, 0.0],
            [0.013, -0.004],
            [0.4, 0.1],
            [-0.01, 0.05],
            v[1],
            [2.0 * v[1][0] - v[2][0], 2.0 * v[1][1] - v[2][1]],
            [0.5 * (v[0][0] + v[1][0]), 0.5 * (v[0][1] + v[1][1]) - 1e-3],
            [1e-9, -2e-9],
        ]
    }

    #[test]
    fn every_build_gives_the_same_bits() {
        let mut checked = 0;
        for outline in outlines() {
            let p = Polygon::new("p", &outline).unwrap();
            for (i, r0) in centres(&p).into_iter().enumerate() {
                let want = fan_with::<true, false>(&p, r0, [0.0; 2]).0;
                assert!(want.dist.is_finite() && want.unit.iter().all(|x| x.is_finite()));
                #[cfg(target_arch = "x86_64")]
                if is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2.
                    let got = unsafe { super::super::avx2::fan::<true, false>(&p, r0, [0.0; 2]).0 };
                    assert_eq!(got, want, "avx2, centre {i}");
                    checked += 1;
                }
                assert_eq!(fan::<true>(&p, r0), want, "the chosen build, centre {i}");
                // with a pressure gradient: the load's terms too, and the fan's unchanged
                let k = [0.9 / p.radius, -0.3 / p.radius];
                let loaded = fan_with::<true, true>(&p, r0, k);
                assert_eq!(loaded.0, want, "centre {i}");
                assert!(loaded.1.unit.iter().all(|x| x.is_finite()) && loaded.1.dist.is_finite());
                assert!(loaded.1.curvature.iter().all(|x| x.is_finite()));
                #[cfg(target_arch = "x86_64")]
                if is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2.
                    let got = unsafe { super::super::avx2::fan::<true, true>(&p, r0, k) };
                    assert_eq!(got, loaded, "avx2 loaded, centre {i}");
                    checked += 1;
                }
                assert_eq!(
                    fan_loaded::<true, true>(&p, r0, k),
                    loaded,
                    "the chosen build"
                );
            }
        }
        #[cfg(target_arch = "x86_64")]
        if is_x86_feature_detected!("avx2") {
            assert_eq!(checked, 32);
        }
    }
}
