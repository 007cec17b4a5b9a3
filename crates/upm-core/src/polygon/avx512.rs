//! The AVX-512 build of the polygon's friction in lanes ([`super::four::evaluate_pair`]): two
//! quads' lanes (lanes 0..4 of each vector from the first, 4..8 from the second) through
//! [`super::avx2::evals_four`]'s operations, in the same order, no fused multiply–adds, masks
//! for its selections: each lane's bits are the AVX2 build's (and the portable one's).
//!
//! (Square roots and quotients from `vrsqrt14pd` and `vrcp14pd` refined to about an ulp were
//! tried: a third less time per lane in a loop of evaluations alone, none measurable in the
//! integrator, and the far field's cancellations made the solve's residual up to four times
//! larger. The exact operations stayed.)
//!
//! The float bit operations are taken on integer vectors (AVX-512F alone has no `and_pd`).

use std::arch::x86_64::*;
use std::mem::MaybeUninit;

use super::four::{Asked, Quad, EIGHT, FOUR, SIXTH};
use super::lanes::{LG, LN2_HI, LN2_LO, RECIP};
use super::newton::Evals;

/// Edges per block of [`friction_lanes`] (as the AVX2 build's).
const BLOCK: usize = 16;

type V = __m512d;

#[inline(always)]
unsafe fn set(x: f64) -> V {
    _mm512_set1_pd(x)
}

/// Lanes 0..4 from `a`, 4..8 from `b`.
#[inline(always)]
unsafe fn pair(a: &[f64; FOUR], b: &[f64; FOUR]) -> V {
    let lo = _mm512_castpd256_pd512(_mm256_loadu_pd(a.as_ptr()));
    _mm512_insertf64x4::<1>(lo, _mm256_loadu_pd(b.as_ptr()))
}

/// The lanes whose 64-bit masks in `a` (lanes 0..4) and `b` (4..8) are not zero.
#[inline(always)]
unsafe fn pair_mask(a: &[u64; FOUR], b: &[u64; FOUR]) -> __mmask8 {
    let lo = _mm512_castsi256_si512(_mm256_loadu_si256(a.as_ptr().cast()));
    let v = _mm512_inserti64x4::<1>(lo, _mm256_loadu_si256(b.as_ptr().cast()));
    _mm512_test_epi64_mask(v, v)
}

#[inline(always)]
unsafe fn bits(v: V) -> __m512i {
    _mm512_castpd_si512(v)
}

#[inline(always)]
unsafe fn float(v: __m512i) -> V {
    _mm512_castsi512_pd(v)
}

/// `-x`, by its sign bit.
#[inline(always)]
unsafe fn neg(x: V) -> V {
    float(_mm512_xor_si512(bits(x), bits(set(-0.0))))
}

/// `|x|`, by its sign bit.
#[inline(always)]
unsafe fn abs(x: V) -> V {
    float(_mm512_andnot_si512(bits(set(-0.0)), bits(x)))
}

/// `x` where `k`, `+0` elsewhere.
#[inline(always)]
unsafe fn keep(k: __mmask8, x: V) -> V {
    _mm512_maskz_mov_pd(k, x)
}

/// `b` where `k`, `a` elsewhere.
#[inline(always)]
unsafe fn pick(k: __mmask8, a: V, b: V) -> V {
    _mm512_mask_blend_pd(k, a, b)
}

/// [`super::avx2::evals_four`] of two quads at once: lanes `0..4` of `asks` and `out[0]` are
/// `q[0]`'s, `4..8` and `out[1]` `q[1]`'s (the quads of as many edges).
///
/// # Safety
/// The CPU must have AVX-512F.
#[target_feature(enable = "avx512f")]
pub(super) unsafe fn evals_eight(q: [&Quad; 2], asks: &[Asked; EIGHT], out: &mut [Evals; 2]) {
    let (m, a, sub) = (_mm512_mul_pd, _mm512_add_pd, _mm512_sub_pd);
    let lanes = |f: &dyn Fn(&Asked) -> f64| {
        let v: [f64; EIGHT] = std::array::from_fn(|l| f(&asks[l]));
        _mm512_loadu_pd(v.as_ptr())
    };
    let f = friction_lanes(q, std::array::from_fn(|l| asks[l].twist));
    let y = [0, 1, 2].map(|i| lanes(&|r| r.y[i]));
    let target = [0, 1, 2].map(|i| lanes(&|r| r.target[i]));
    let (c, kinv) = (lanes(&|r| r.c), lanes(&|r| r.kinv));
    let one = set(1.0);
    let zero = _mm512_setzero_pd();
    let scale = [one, one, kinv];
    let r = [0, 1, 2].map(|i| sub(y[i], target[i]));
    let grad = [0, 1, 2].map(|i| sub(r[i], m(m(c, f[i]), scale[i])));
    let at = |i: usize, j: usize| m(m(m(c, f[3 + i]), scale[j / 3]), scale[j % 3]);
    let h00 = a(one, at(0, 0));
    let h01 = a(zero, at(1, 1));
    let h02 = a(zero, at(2, 2));
    let h11 = a(one, at(3, 4));
    let h12 = a(zero, at(4, 5));
    let h22 = a(one, at(5, 8));
    let dot = |p: [V; 3], q: [V; 3]| a(a(m(p[0], q[0]), m(p[1], q[1])), m(p[2], q[2]));
    let value = a(m(set(0.5), dot(r, r)), m(c, f[9]));
    let c00 = sub(m(h11, h22), m(h12, h12));
    let c01 = sub(m(h02, h12), m(h01, h22));
    let c02 = sub(m(h01, h12), m(h02, h11));
    let c11 = sub(m(h00, h22), m(h02, h02));
    let c12 = sub(m(h01, h02), m(h00, h12));
    let c22 = sub(m(h00, h11), m(h01, h01));
    let d = a(a(m(h00, c00), m(h01, c01)), m(h02, c02));
    let inv = _mm512_div_pd(one, d);
    let b = grad.map(|g| neg(g));
    let x = [
        m(a(a(m(c00, b[0]), m(c01, b[1])), m(c02, b[2])), inv),
        m(a(a(m(c01, b[0]), m(c11, b[1])), m(c12, b[2])), inv),
        m(a(a(m(c02, b[0]), m(c12, b[1])), m(c22, b[2])), inv),
    ];
    let finite = |v: V| _mm512_cmp_pd_mask::<_CMP_LT_OQ>(abs(v), set(f64::INFINITY));
    let good = finite(d)
        & _mm512_cmp_pd_mask::<_CMP_GT_OQ>(abs(d), zero)
        & finite(x[0])
        & finite(x[1])
        & finite(x[2]);
    let good = good & _mm512_cmp_pd_mask::<_CMP_LT_OQ>(dot(x, grad), zero);
    let step = [0, 1, 2].map(|i| pick(good, b[i], x[i]));
    let fields = [
        value,
        _mm512_sqrt_pd(dot(grad, grad)),
        step[0],
        step[1],
        step[2],
        _mm512_sqrt_pd(dot(step, step)),
        dot(step, grad),
        _mm512_sqrt_pd(dot(y, y)),
    ];
    let [lo, hi] = out;
    for ((l, h), v) in lo.0.iter_mut().zip(hi.0.iter_mut()).zip(fields) {
        _mm256_storeu_pd(l.as_mut_ptr(), _mm512_castpd512_pd256(v));
        _mm256_storeu_pd(h.as_mut_ptr(), _mm512_extractf64x4_pd::<1>(v));
    }
}

/// [`super::avx2`]'s `friction_lanes` in eight lanes: the wrench (3), the Hessian's upper
/// triangle (xx xy x3 yy y3 33) and the rate of work.
#[inline(always)]
unsafe fn friction_lanes(q: [&Quad; 2], twists: [[f64; 3]; EIGHT]) -> [V; 10] {
    let (m, a) = (_mm512_mul_pd, _mm512_add_pd);
    let zero = _mm512_setzero_pd();
    let lanes = |i: usize| {
        let v: [f64; EIGHT] = std::array::from_fn(|l| twists[l][i]);
        _mm512_loadu_pd(v.as_ptr())
    };
    let (vx, vy, omega) = (lanes(0), lanes(1), lanes(2));
    let inv = _mm512_div_pd(set(1.0), omega);
    let (x0, y0) = (m(neg(vy), inv), m(vx, inv));
    let n = q[0].edges();
    let mut acc = [zero; 6];
    let mut ends = [const { MaybeUninit::<[V; 4]>::uninit() }; BLOCK + 1];
    let mut geo = [const { MaybeUninit::<Geometry>::uninit() }; BLOCK];
    let mut logs = [const { MaybeUninit::<V>::uninit() }; BLOCK];
    ends[0].write(about(q, 0, x0, y0));
    let mut k0 = 0;
    while k0 < n {
        let count = BLOCK.min(n - k0);
        for j in 1..=count {
            ends[j].write(about(q, k0 + j, x0, y0));
        }
        // SAFETY (the reads below): ends[0..=count] and geo and logs [0..count] were written
        // just before they are read.
        for j in 0..count {
            let (at, next) = (ends[j].assume_init(), ends[j + 1].assume_init());
            geo[j].write(geometry(q, k0 + j, at, next));
        }
        for j in 0..count {
            logs[j].write(ln_1p(geo[j].assume_init().arg));
        }
        for j in 0..count {
            let (at, next) = (ends[j].assume_init(), ends[j + 1].assume_init());
            let (g, d) = (geo[j].assume_init(), logs[j].assume_init());
            let terms = sums(q, k0 + j, at, next, &g, d);
            for (acc, t) in acc.iter_mut().zip(terms) {
                *acc = _mm512_mask_add_pd(*acc, g.area, *acc, t);
            }
        }
        ends[0] = ends[count];
        k0 += count;
    }
    let [dist, ux, uy, gxx, gxy, gyy] = acc;
    let area = pair(&q[0].inv_area, &q[1].inv_area);
    let s = float(_mm512_or_si512(
        _mm512_and_si512(bits(omega), bits(set(-0.0))),
        bits(area),
    ));
    let w = [
        m(s, uy),
        neg(m(s, ux)),
        neg(m(s, a(a(dist, m(x0, ux)), m(y0, uy)))),
    ];
    let scale = m(abs(inv), area);
    let (px, py) = (neg(y0), x0);
    let (g3x, g3y) = (a(m(px, gxx), m(py, gxy)), a(m(px, gxy), m(py, gyy)));
    let h = [gxx, gxy, g3x, gyy, g3y, a(m(px, g3x), m(py, g3y))].map(|g| m(scale, g));
    let work = m(m(abs(omega), dist), area);
    [w[0], w[1], w[2], h[0], h[1], h[2], h[3], h[4], h[5], work]
}

/// Vertex `k` about the centres `(x0, y0)`: `(dx, dy, r, 1 / r)`.
#[inline(always)]
unsafe fn about(q: [&Quad; 2], k: usize, x0: V, y0: V) -> [V; 4] {
    let (m, a, sub) = (_mm512_mul_pd, _mm512_add_pd, _mm512_sub_pd);
    let (vx, vy) = (pair(&q[0].x[k], &q[1].x[k]), pair(&q[0].y[k], &q[1].y[k]));
    let (dx, dy) = (sub(vx, x0), sub(vy, y0));
    let r = _mm512_sqrt_pd(a(m(dx, dx), m(dy, dy)));
    [dx, dy, r, _mm512_div_pd(set(1.0), r)]
}

/// An edge's line ([`super::avx2`]'s `edge_line`): `h` (zero where it spans no area), `ta`,
/// `drho`, the lanes that span area, and the logarithm's argument.
#[derive(Clone, Copy)]
struct Geometry {
    h: V,
    ta: V,
    drho: V,
    area: __mmask8,
    arg: V,
}

/// Edge `k` from its ends `at` and `next` ([`about`]).
#[inline(always)]
unsafe fn geometry(q: [&Quad; 2], k: usize, at: [V; 4], next: [V; 4]) -> Geometry {
    let (m, a, sub, div) = (_mm512_mul_pd, _mm512_add_pd, _mm512_sub_pd, _mm512_div_pd);
    let zero = _mm512_setzero_pd();
    let (ex, ey, len) = edge(q, k);
    let [ax, ay, ra, _] = at;
    let [_, _, rb, _] = next;
    let live = pair_mask(&q[0].live[k], &q[1].live[k]);
    let h = sub(m(ax, ey), m(ay, ex));
    let area = live & _mm512_cmp_pd_mask::<_CMP_NEQ_UQ>(h, zero);
    let ta = a(m(ax, ex), m(ay, ey));
    let tb = a(ta, len);
    let drho = div(m(len, a(ta, tb)), a(ra, rb));
    let after = _mm512_cmp_pd_mask::<_CMP_GE_OQ>(ta, zero);
    let before = _mm512_cmp_pd_mask::<_CMP_LE_OQ>(tb, zero);
    let across = !after & !before;
    let hh0 = abs(h);
    let hh = pick(across, hh0, _mm512_max_pd(hh0, m(set(1e-100), len)));
    let mid_num = m(tb, a(a(hh, rb), tb));
    let mid_den = m(hh, a(hh, rb));
    let n1 = pick(after, pick(before, mid_num, sub(len, drho)), a(len, drho));
    let d1 = pick(after, pick(before, mid_den, sub(rb, tb)), a(ta, ra));
    let (n2, d2) = (m(neg(ta), sub(a(hh, ra), ta)), m(hh, a(hh, ra)));
    let num = pick(across, n1, a(m(n1, d2), m(n2, a(d1, n1))));
    let den = pick(across, d1, m(d1, d2));
    Geometry {
        h: keep(area, h),
        ta,
        drho,
        area,
        arg: keep(area, div(num, den)),
    }
}

/// Edge `k`'s terms of the fan's six sums from its ends, [`geometry`] and the logarithm `d`.
#[inline(always)]
unsafe fn sums(q: [&Quad; 2], k: usize, at: [V; 4], next: [V; 4], g: &Geometry, d: V) -> [V; 6] {
    let (m, a, sub) = (_mm512_mul_pd, _mm512_add_pd, _mm512_sub_pd);
    let (ex, ey, len) = edge(q, k);
    let [_, _, ra, ia] = at;
    let [_, _, rb, ib] = next;
    let (h, ta, drho) = (g.h, g.ta, g.drho);
    let h2 = m(h, h);
    let dist = m(m(h, set(SIXTH)), a(a(m(len, rb), m(ta, drho)), m(h2, d)));
    let (half, hd) = (m(set(0.5), h), m(h, d));
    let ux = m(half, a(m(hd, ey), m(ex, drho)));
    let uy = m(half, sub(m(ey, drho), m(hd, ex)));
    let s = m(m(sub(m(len, ra), m(ta, drho)), ia), ib);
    let c = sub(ia, ib);
    let (nn, ne, ee) = (m(h, s), m(h2, c), m(h, sub(d, s)));
    let sq = |i: usize| pair(&q[0].squares[k][i], &q[1].squares[k][i]);
    let [xx, yy, xy, twice, diff] = [0, 1, 2, 3, 4].map(sq);
    let gxx = a(a(m(nn, yy), m(ne, twice)), m(ee, xx));
    let gxy = a(m(sub(ee, nn), xy), m(ne, diff));
    let gyy = a(sub(m(nn, xx), m(ne, twice)), m(ee, yy));
    [dist, ux, uy, gxx, gxy, gyy]
}

/// Edge `k`'s `(ex, ey, len)` in lanes.
#[inline(always)]
unsafe fn edge(q: [&Quad; 2], k: usize) -> (V, V, V) {
    (
        pair(&q[0].ex[k], &q[1].ex[k]),
        pair(&q[0].ey[k], &q[1].ey[k]),
        pair(&q[0].len[k], &q[1].len[k]),
    )
}

/// [`super::lanes::ln_1p`] in eight lanes (as the AVX2 build's, operation for operation).
#[inline(always)]
unsafe fn ln_1p(x: V) -> V {
    let (m, a, sub) = (_mm512_mul_pd, _mm512_add_pd, _mm512_sub_pd);
    let int = _mm512_set1_epi64;
    let one = set(1.0);
    let u = a(one, x);
    let ub = bits(u);
    let high = _mm512_add_epi64(_mm512_srli_epi64::<32>(ub), int(0x3ff0_0000 - 0x3fe6_a09e));
    let k = _mm512_sub_epi64(_mm512_srli_epi64::<20>(high), int(0x3ff));
    let dk = sub(
        float(_mm512_or_si512(
            int(0x4330_0000_0000_0000),
            _mm512_and_si512(k, int(0x7ff)),
        )),
        set(4_503_599_627_370_496.0),
    );
    let big = _mm512_cmpgt_epi64_mask(k, int(1));
    let r = float(_mm512_sub_epi64(int(RECIP as i64), ub));
    let c = m(
        pick(big, sub(x, sub(u, one)), sub(one, sub(u, x))),
        m(r, sub(set(2.0), m(u, r))),
    );
    let c = keep(_mm512_cmpgt_epi64_mask(int(54), k), c);
    let mant = float(_mm512_or_si512(
        _mm512_slli_epi64::<32>(_mm512_add_epi64(
            _mm512_and_si512(high, int(0x000f_ffff)),
            int(0x3fe6_a09e),
        )),
        _mm512_and_si512(ub, int(0xffff_ffff)),
    ));
    let small = _mm512_cmp_pd_mask::<_CMP_LT_OQ>(x, set(std::f64::consts::SQRT_2 - 1.0));
    let f = pick(small, sub(mant, one), x);
    let (c, dk) = (keep(!small, c), keep(!small, dk));
    let hfsq = m(m(set(0.5), f), f);
    let s = _mm512_div_pd(f, a(set(2.0), f));
    let z = m(s, s);
    let w = m(z, z);
    let t1 = m(w, a(set(LG[1]), m(w, a(set(LG[3]), m(w, set(LG[5]))))));
    let t2 = m(
        z,
        a(
            set(LG[0]),
            m(w, a(set(LG[2]), m(w, a(set(LG[4]), m(w, set(LG[6])))))),
        ),
    );
    let r = a(m(s, a(hfsq, a(t1, t2))), a(m(dk, set(LN2_LO)), c));
    a(a(sub(r, hfsq), f), m(dk, set(LN2_HI)))
}
