//! The AVX2 build of the fan integrals ([`super::lanes`]), taken on AVX2 and AVX-512 machines:
//! a group of eight edges as two vectors of four (the second left out when none of its edges is
//! live), the same operations in the same order as the portable lanes (no fused multiply–adds),
//! so the same bits.

use std::arch::x86_64::*;
use std::mem::MaybeUninit;

use super::four::{Asked, Quad, FOUR, SIXTH};
use super::lanes::{from_sums, Edges, LG, LN2_HI, LN2_LO, RECIP, THIRD};
use super::load::Linear;
use super::newton::Evals;
use super::{Fan, Friction, Polygon};

/// [`super::lanes::fan_loaded`] on AVX2.
///
/// # Safety
/// The CPU must have AVX2.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn fan<const CURVATURE: bool, const LOADED: bool>(
    p: &Polygon,
    r0: [f64; 2],
    k: [f64; 2],
) -> (Fan, Linear) {
    let zero = _mm256_setzero_pd();
    // lanes 0..4 and 4..8 of each sum
    let (mut lo, mut hi) = ([zero; 12], [zero; 12]);
    // only the last group can leave its upper half out (the loops are kept free of a branch
    // between the halves: with one, the compiler no longer interleaves them)
    let (full, last) = match p.lanes.split_last() {
        Some((last, rest)) if !last.upper => (rest, Some(last)),
        _ => (&p.lanes[..], None),
    };
    for e in full {
        half::<CURVATURE, LOADED>(e, 0, r0, k, &mut lo);
        half::<CURVATURE, LOADED>(e, 4, r0, k, &mut hi);
    }
    if let Some(e) = last {
        half::<CURVATURE, LOADED>(e, 0, r0, k, &mut lo);
    }
    let sum = |l: __m256d, h: __m256d| {
        // the portable lanes' pairwise order: (a0 + a4) ... first
        let mut q = [0.0; 4];
        _mm256_storeu_pd(q.as_mut_ptr(), _mm256_add_pd(l, h));
        (q[0] + q[2]) + (q[1] + q[3])
    };
    from_sums(std::array::from_fn(|i| sum(lo[i], hi[i])))
}

/// The lanes `at..at + 4` of the group `e` added to `acc` (the fan's sums, then the load's).
#[inline(always)]
unsafe fn half<const CURVATURE: bool, const LOADED: bool>(
    e: &Edges,
    at: usize,
    r0: [f64; 2],
    k: [f64; 2],
    acc: &mut [__m256d; 12],
) {
    let load = |a: &[f64; 8]| _mm256_loadu_pd(a[at..].as_ptr());
    let (m, a, sub, div) = (_mm256_mul_pd, _mm256_add_pd, _mm256_sub_pd, _mm256_div_pd);
    let set = _mm256_set1_pd;
    let zero = _mm256_setzero_pd();
    let (x0, y0) = (set(r0[0]), set(r0[1]));
    let (ax, ay) = (sub(load(&e.ax), x0), sub(load(&e.ay), y0));
    let (bx, by) = (sub(load(&e.bx), x0), sub(load(&e.by), y0));
    let (ex, ey, len) = (load(&e.ex), load(&e.ey), load(&e.len));
    let live = _mm256_castsi256_pd(_mm256_loadu_si256(e.bits[at..].as_ptr().cast()));
    let ra = _mm256_sqrt_pd(a(m(ax, ax), m(ay, ay)));
    let rb = _mm256_sqrt_pd(a(m(bx, bx), m(by, by)));
    let [h, area, ta, drho, arg] = edge_line(live, [ax, ay], [ex, ey, len], [ra, rb]);
    let d = ln_1p(arg);
    let (nx, ny) = (ey, _mm256_xor_pd(ex, set(-0.0)));
    let h2 = m(h, h);
    // (h/6) (len rb + ta drho + h² d)
    let dist = m(div(h, set(6.0)), a(a(m(len, rb), m(ta, drho)), m(h2, d)));
    acc[0] = a(acc[0], dist);
    // (h/2) (h n d + e drho)
    let half = m(set(0.5), h);
    acc[1] = a(acc[1], m(half, a(m(m(h, nx), d), m(ex, drho))));
    acc[2] = a(acc[2], m(half, a(m(m(h, ny), d), m(ey, drho))));
    let (mut ia, mut ib, mut s) = (zero, zero, zero);
    if CURVATURE {
        (ia, ib) = (div(set(1.0), ra), div(set(1.0), rb));
        s = m(m(sub(m(len, ra), m(ta, drho)), ia), ib);
        let c = sub(ia, ib);
        let (nn, ne, ee) = (m(h, s), m(h2, c), m(h, sub(d, s)));
        let two_ne = m(set(2.0), ne);
        let gxx = a(a(m(m(nn, nx), nx), m(m(two_ne, nx), ex)), m(m(ee, ex), ex));
        let gxy = a(
            a(m(m(nn, nx), ny), m(ne, a(m(nx, ey), m(ex, ny)))),
            m(m(ee, ex), ey),
        );
        let gyy = a(a(m(m(nn, ny), ny), m(m(two_ne, ny), ey)), m(m(ee, ey), ey));
        // a lane of no area may hold infinities (r0 at a vertex): it adds nothing
        acc[3] = a(acc[3], _mm256_and_pd(area, gxx));
        acc[4] = a(acc[4], _mm256_and_pd(area, gxy));
        acc[5] = a(acc[5], _mm256_and_pd(area, gyy));
    }
    if LOADED {
        // the portable lanes' load terms, operation for operation
        let third = set(THIRD);
        let (kn, kt) = (
            a(m(set(k[0]), nx), m(set(k[1]), ny)),
            a(m(set(k[0]), ex), m(set(k[1]), ey)),
        );
        let dtr = a(m(len, rb), m(ta, drho));
        let i2 = m(set(0.5), sub(dtr, m(h2, d)));
        let snn = m(m(m(h, h2), d), third);
        let snt = m(m(h2, drho), third);
        let stt = m(m(h, i2), third);
        let cn = a(m(snn, kn), m(snt, kt));
        let ct = a(m(snt, kn), m(stt, kt));
        acc[6] = a(acc[6], a(m(cn, nx), m(ct, ex)));
        acc[7] = a(acc[7], a(m(cn, ny), m(ct, ey)));
        let j0 = m(set(0.5), a(dtr, m(h2, d)));
        let j1 = m(m(drho, a(a(m(ra, ra), m(ra, rb)), m(rb, rb))), third);
        acc[8] = a(acc[8], m(m(set(0.25), h), a(m(m(h, kn), j0), m(kt, j1))));
        if CURVATURE {
            let k0 = div(s, h2);
            let k1 = m(m(drho, ia), ib);
            let k2 = sub(d, s);
            let k3 = sub(drho, m(h2, k1));
            let hh2 = m(set(0.5), h);
            let cnn = m(hh2, a(m(m(m(h2, h), kn), k0), m(m(h2, kt), k1)));
            let cnt = m(hh2, a(m(m(h2, kn), k1), m(m(h, kt), k2)));
            let ctt = m(hh2, a(m(m(h, kn), k2), m(kt, k3)));
            let two_cnt = m(set(2.0), cnt);
            let lxx = a(
                a(m(m(cnn, nx), nx), m(m(two_cnt, nx), ex)),
                m(m(ctt, ex), ex),
            );
            let lxy = a(
                a(m(m(cnn, nx), ny), m(cnt, a(m(nx, ey), m(ex, ny)))),
                m(m(ctt, ex), ey),
            );
            let lyy = a(
                a(m(m(cnn, ny), ny), m(m(two_cnt, ny), ey)),
                m(m(ctt, ey), ey),
            );
            acc[9] = a(acc[9], _mm256_and_pd(area, lxx));
            acc[10] = a(acc[10], _mm256_and_pd(area, lxy));
            acc[11] = a(acc[11], _mm256_and_pd(area, lyy));
        }
    }
}

/// [`super::four::friction_four`] on AVX2.
///
/// # Safety
/// The CPU must have AVX2.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn friction_four(q: &Quad, twists: [[f64; 3]; FOUR]) -> [Friction; FOUR] {
    let f = friction_lanes(q, twists);
    let mut out = [[0.0; FOUR]; 10];
    for (o, v) in out.iter_mut().zip(f) {
        _mm256_storeu_pd(o.as_mut_ptr(), v);
    }
    std::array::from_fn(|l| {
        let o = |i: usize| out[i][l];
        Friction {
            wrench: [o(0), o(1), o(2)],
            work: o(9),
            hessian: [[o(3), o(4), o(5)], [o(4), o(6), o(7)], [o(5), o(7), o(8)]],
        }
    })
}

/// [`super::Quad::evaluate`] on AVX2: [`super::newton::Eval::of`] in lanes, operation for
/// operation.
///
/// # Safety
/// The CPU must have AVX2.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn evals_four(q: &Quad, asks: &[Asked; FOUR], out: &mut Evals) {
    let (m, a, sub) = (_mm256_mul_pd, _mm256_add_pd, _mm256_sub_pd);
    let set = _mm256_set1_pd;
    let lanes = |f: &dyn Fn(&Asked) -> f64| {
        _mm256_setr_pd(f(&asks[0]), f(&asks[1]), f(&asks[2]), f(&asks[3]))
    };
    let f = friction_lanes(q, std::array::from_fn(|l| asks[l].twist));
    let y = [0, 1, 2].map(|i| lanes(&|r| r.y[i]));
    let target = [0, 1, 2].map(|i| lanes(&|r| r.target[i]));
    let (c, kinv) = (lanes(&|r| r.c), lanes(&|r| r.kinv));
    let one = set(1.0);
    let zero = _mm256_setzero_pd();
    let scale = [one, one, kinv];
    let r = [0, 1, 2].map(|i| sub(y[i], target[i]));
    let grad = [0, 1, 2].map(|i| sub(r[i], m(m(c, f[i]), scale[i])));
    // the Hessian's upper triangle, xx xy x3 yy y3 33 (f[3..9])
    let at = |i: usize, j: usize| m(m(m(c, f[3 + i]), scale[j / 3]), scale[j % 3]);
    let h00 = a(one, at(0, 0));
    // (the off-diagonal terms plus zero, as Eval::of adds its identity's)
    let h01 = a(zero, at(1, 1));
    let h02 = a(zero, at(2, 2));
    let h11 = a(one, at(3, 4));
    let h12 = a(zero, at(4, 5));
    let h22 = a(one, at(5, 8));
    let dot = |p: [__m256d; 3], q: [__m256d; 3]| a(a(m(p[0], q[0]), m(p[1], q[1])), m(p[2], q[2]));
    let value = a(m(set(0.5), dot(r, r)), m(c, f[9]));
    // solve3: the adjugate, one division, the descent direction checked
    let c00 = sub(m(h11, h22), m(h12, h12));
    let c01 = sub(m(h02, h12), m(h01, h22));
    let c02 = sub(m(h01, h12), m(h02, h11));
    let c11 = sub(m(h00, h22), m(h02, h02));
    let c12 = sub(m(h01, h02), m(h00, h12));
    let c22 = sub(m(h00, h11), m(h01, h01));
    let d = a(a(m(h00, c00), m(h01, c01)), m(h02, c02));
    let inv = _mm256_div_pd(one, d);
    let b = grad.map(|g| _mm256_xor_pd(g, set(-0.0)));
    let x = [
        m(a(a(m(c00, b[0]), m(c01, b[1])), m(c02, b[2])), inv),
        m(a(a(m(c01, b[0]), m(c11, b[1])), m(c12, b[2])), inv),
        m(a(a(m(c02, b[0]), m(c12, b[1])), m(c22, b[2])), inv),
    ];
    let finite = |v: __m256d| {
        _mm256_cmp_pd::<_CMP_LT_OQ>(_mm256_andnot_pd(set(-0.0), v), set(f64::INFINITY))
    };
    let good = _mm256_and_pd(
        _mm256_and_pd(
            finite(d),
            _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_andnot_pd(set(-0.0), d), zero),
        ),
        _mm256_and_pd(_mm256_and_pd(finite(x[0]), finite(x[1])), finite(x[2])),
    );
    let good = _mm256_and_pd(good, _mm256_cmp_pd::<_CMP_LT_OQ>(dot(x, grad), zero));
    let step = [0, 1, 2].map(|i| _mm256_blendv_pd(b[i], x[i], good));
    let lanes = [
        value,
        _mm256_sqrt_pd(dot(grad, grad)),
        step[0],
        step[1],
        step[2],
        _mm256_sqrt_pd(dot(step, step)),
        dot(step, grad),
        _mm256_sqrt_pd(dot(y, y)),
    ];
    for (o, v) in out.0.iter_mut().zip(lanes) {
        _mm256_storeu_pd(o.as_mut_ptr(), v);
    }
}

/// The friction of [`friction_four`] in registers: the wrench (3), the Hessian's upper
/// triangle (xx xy x3 yy y3 33) and the rate of work.
///
/// [`super::four::friction_four`] on AVX2: a twist in each lane, the edges one after another, in
/// blocks of [`BLOCK`] taken in passes (the vertices' square roots and reciprocals, the edges'
/// divisions, their logarithms, then the sums), so that many edges' chains of square roots,
/// divisions and logarithms are in flight at once.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
// (one index runs through the ends, the edges' geometry and their logarithms together)
unsafe fn friction_lanes(q: &Quad, twists: [[f64; 3]; FOUR]) -> [__m256d; 10] {
    let (m, a) = (_mm256_mul_pd, _mm256_add_pd);
    let (neg, abs) = (
        |x| _mm256_xor_pd(x, _mm256_set1_pd(-0.0)),
        |x| _mm256_andnot_pd(_mm256_set1_pd(-0.0), x),
    );
    let zero = _mm256_setzero_pd();
    let lanes = |i: usize| _mm256_setr_pd(twists[0][i], twists[1][i], twists[2][i], twists[3][i]);
    let (vx, vy, omega) = (lanes(0), lanes(1), lanes(2));
    // the centres of rotation
    let inv = _mm256_div_pd(_mm256_set1_pd(1.0), omega);
    let (x0, y0) = (m(neg(vy), inv), m(vx, inv));
    let n = q.edges();
    let first = about(q, 0, x0, y0);
    let mut acc = [zero; 6];
    // (left uninitialised: each is written before it is read, and zeroing them cost more than
    // a hexagon's edges)
    let mut ends = [const { MaybeUninit::<[__m256d; 4]>::uninit() }; BLOCK + 1];
    let mut geo = [const { MaybeUninit::<[__m256d; 6]>::uninit() }; BLOCK];
    let mut logs = [const { MaybeUninit::<__m256d>::uninit() }; BLOCK];
    ends[0].write(first);
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
            logs[j].write(ln_1p(geo[j].assume_init()[5]));
        }
        for j in 0..count {
            let (at, next) = (ends[j].assume_init(), ends[j + 1].assume_init());
            let (g, d) = (geo[j].assume_init(), logs[j].assume_init());
            let terms = sums(q, k0 + j, at, next, g, d);
            // (a lane of no area keeps its sums as they are, to the bit)
            for (acc, t) in acc.iter_mut().zip(terms) {
                *acc = _mm256_blendv_pd(*acc, _mm256_add_pd(*acc, t), g[3]);
            }
        }
        ends[0] = ends[count];
        k0 += count;
    }
    // the friction from the fan (`Polygon::friction_about`, with the reciprocals of omega and of
    // the area)
    let [dist, ux, uy, gxx, gxy, gyy] = acc;
    let area = _mm256_loadu_pd(q.inv_area.as_ptr());
    let s = _mm256_or_pd(_mm256_and_pd(omega, _mm256_set1_pd(-0.0)), area);
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

/// Edges per block of [`friction_four`].
const BLOCK: usize = 16;

/// Vertex `k` about the centres `(x0, y0)`: `(dx, dy, r, 1 / r)`.
#[inline(always)]
unsafe fn about(q: &Quad, k: usize, x0: __m256d, y0: __m256d) -> [__m256d; 4] {
    let (m, a, sub) = (_mm256_mul_pd, _mm256_add_pd, _mm256_sub_pd);
    let (vx, vy) = (
        _mm256_loadu_pd(q.x[k].as_ptr()),
        _mm256_loadu_pd(q.y[k].as_ptr()),
    );
    let (dx, dy) = (sub(vx, x0), sub(vy, y0));
    let r = _mm256_sqrt_pd(a(m(dx, dx), m(dy, dy)));
    [dx, dy, r, _mm256_div_pd(_mm256_set1_pd(1.0), r)]
}

/// Edge `k` from its ends `at` and `next` ([`about`]): `h` (zero where it spans no area), `ta`,
/// `drho`, the mask of the lanes that span area (edges of their polygons, `h != 0`), and the
/// logarithm's argument.
#[inline(always)]
unsafe fn geometry(q: &Quad, k: usize, at: [__m256d; 4], next: [__m256d; 4]) -> [__m256d; 6] {
    let (ex, ey, len) = edge(q, k);
    let [ax, ay, ra, _] = at;
    let [_, _, rb, _] = next;
    let live = _mm256_castsi256_pd(_mm256_loadu_si256(q.live[k].as_ptr().cast()));
    let [h, area, ta, drho, arg] = edge_line(live, [ax, ay], [ex, ey, len], [ra, rb]);
    [h, ta, drho, area, _mm256_setzero_pd(), arg]
}

/// An edge from `(ax, ay)` (about the centre, at distance `ra`; the other end at `rb`) along
/// `(ex, ey)` for `len`, in the lanes that are `live`: its line's signed distance `h` (zero
/// where it spans no area), the mask of the lanes that span area (live, `h != 0`), `ta`, `rb -
/// ra` without cancellation, and the logarithm's argument of its `asinh` difference
/// ([`super::lanes`]: `ln(1 + a1) + ln(1 + a2)`, both `>= 0`, as one logarithm of the product).
#[inline(always)]
unsafe fn edge_line(
    live: __m256d,
    [ax, ay]: [__m256d; 2],
    [ex, ey, len]: [__m256d; 3],
    [ra, rb]: [__m256d; 2],
) -> [__m256d; 5] {
    let (m, a, sub, div) = (_mm256_mul_pd, _mm256_add_pd, _mm256_sub_pd, _mm256_div_pd);
    let set = _mm256_set1_pd;
    let zero = _mm256_setzero_pd();
    let h = sub(m(ax, ey), m(ay, ex));
    // the lanes that span area: live, and h != 0 (unordered counts, as !(h == 0) does)
    let area = _mm256_and_pd(live, _mm256_cmp_pd::<_CMP_NEQ_UQ>(h, zero));
    let ta = a(m(ax, ex), m(ay, ey));
    let tb = a(ta, len);
    let drho = div(m(len, a(ta, tb)), a(ra, rb));
    let after = _mm256_cmp_pd::<_CMP_GE_OQ>(ta, zero);
    let before = _mm256_cmp_pd::<_CMP_LE_OQ>(tb, zero);
    let across = _mm256_andnot_pd(after, before_not(before));
    let abs = _mm256_andnot_pd(set(-0.0), h);
    // (max_pd returns its second operand where the first is not a number, as f64::max does not;
    // |h| is one here)
    let hh = _mm256_blendv_pd(abs, _mm256_max_pd(abs, m(set(1e-100), len)), across);
    let mid_num = m(tb, a(a(hh, rb), tb));
    let mid_den = m(hh, a(hh, rb));
    let n1 = _mm256_blendv_pd(
        _mm256_blendv_pd(mid_num, sub(len, drho), before),
        a(len, drho),
        after,
    );
    let d1 = _mm256_blendv_pd(
        _mm256_blendv_pd(mid_den, sub(rb, tb), before),
        a(ta, ra),
        after,
    );
    let neg_ta = _mm256_xor_pd(ta, set(-0.0));
    let (n2, d2) = (m(neg_ta, sub(a(hh, ra), ta)), m(hh, a(hh, ra)));
    let num = _mm256_blendv_pd(n1, a(m(n1, d2), m(n2, a(d1, n1))), across);
    let den = _mm256_blendv_pd(d1, m(d1, d2), across);
    let arg = _mm256_and_pd(area, div(num, den));
    let h = _mm256_and_pd(area, h);
    [h, area, ta, drho, arg]
}

/// The lanes not set in the mask `before`.
#[inline(always)]
unsafe fn before_not(before: __m256d) -> __m256d {
    _mm256_xor_pd(before, _mm256_castsi256_pd(_mm256_set1_epi64x(-1)))
}

/// Edge `k`'s terms of the fan's six sums from its ends, [`geometry`] and the logarithm `d`.
#[inline(always)]
unsafe fn sums(
    q: &Quad,
    k: usize,
    at: [__m256d; 4],
    next: [__m256d; 4],
    geo: [__m256d; 6],
    d: __m256d,
) -> [__m256d; 6] {
    let (m, a, sub) = (_mm256_mul_pd, _mm256_add_pd, _mm256_sub_pd);
    let set = _mm256_set1_pd;
    let (ex, ey, len) = edge(q, k);
    let [_, _, ra, ia] = at;
    let [_, _, rb, ib] = next;
    let [h, ta, drho, _, _, _] = geo;
    let h2 = m(h, h);
    let dist = m(m(h, set(SIXTH)), a(a(m(len, rb), m(ta, drho)), m(h2, d)));
    let (half, hd) = (m(set(0.5), h), m(h, d));
    let ux = m(half, a(m(hd, ey), m(ex, drho)));
    let uy = m(half, sub(m(ey, drho), m(hd, ex)));
    let s = m(m(sub(m(len, ra), m(ta, drho)), ia), ib);
    let c = sub(ia, ib);
    let (nn, ne, ee) = (m(h, s), m(h2, c), m(h, sub(d, s)));
    let [xx, yy, xy, twice, diff] = q.squares[k].map(|v| _mm256_loadu_pd(v.as_ptr()));
    let gxx = a(a(m(nn, yy), m(ne, twice)), m(ee, xx));
    let gxy = a(m(sub(ee, nn), xy), m(ne, diff));
    let gyy = a(sub(m(nn, xx), m(ne, twice)), m(ee, yy));
    [dist, ux, uy, gxx, gxy, gyy]
}

/// Edge `k`'s `(ex, ey, len)` in lanes.
#[inline(always)]
unsafe fn edge(q: &Quad, k: usize) -> (__m256d, __m256d, __m256d) {
    let load = |a: &[f64; FOUR]| _mm256_loadu_pd(a.as_ptr());
    (load(&q.ex[k]), load(&q.ey[k]), load(&q.len[k]))
}

/// [`ln_1p`] of four values (for the tests).
#[cfg(test)]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn ln_1p_lanes(x: [f64; 4]) -> [f64; 4] {
    let mut out = [0.0; 4];
    _mm256_storeu_pd(out.as_mut_ptr(), ln_1p(_mm256_loadu_pd(x.as_ptr())));
    out
}

/// [`super::lanes::ln_1p`] in four lanes.
#[inline(always)]
unsafe fn ln_1p(x: __m256d) -> __m256d {
    let (m, a, sub) = (_mm256_mul_pd, _mm256_add_pd, _mm256_sub_pd);
    let set = _mm256_set1_pd;
    let int = _mm256_set1_epi64x;
    let one = set(1.0);
    let u = a(one, x);
    let ub = _mm256_castpd_si256(u);
    let high = _mm256_add_epi64(_mm256_srli_epi64::<32>(ub), int(0x3ff0_0000 - 0x3fe6_a09e));
    let k = _mm256_sub_epi64(_mm256_srli_epi64::<20>(high), int(0x3ff));
    let dk = sub(
        _mm256_castsi256_pd(_mm256_or_si256(
            int(0x4330_0000_0000_0000),
            _mm256_and_si256(k, int(0x7ff)),
        )),
        set(4_503_599_627_370_496.0),
    );
    let big = _mm256_castsi256_pd(_mm256_cmpgt_epi64(k, int(1)));
    let r = _mm256_castsi256_pd(_mm256_sub_epi64(int(RECIP as i64), ub));
    let c = m(
        _mm256_blendv_pd(sub(x, sub(u, one)), sub(one, sub(u, x)), big),
        m(r, sub(set(2.0), m(u, r))),
    );
    let c = _mm256_and_pd(_mm256_castsi256_pd(_mm256_cmpgt_epi64(int(54), k)), c);
    let mant = _mm256_castsi256_pd(_mm256_or_si256(
        _mm256_slli_epi64::<32>(_mm256_add_epi64(
            _mm256_and_si256(high, int(0x000f_ffff)),
            int(0x3fe6_a09e),
        )),
        _mm256_and_si256(ub, int(0xffff_ffff)),
    ));
    let small = _mm256_cmp_pd::<_CMP_LT_OQ>(x, set(std::f64::consts::SQRT_2 - 1.0));
    let f = _mm256_blendv_pd(sub(mant, one), x, small);
    let (c, dk) = (_mm256_andnot_pd(small, c), _mm256_andnot_pd(small, dk));
    let hfsq = m(m(set(0.5), f), f);
    let s = _mm256_div_pd(f, a(set(2.0), f));
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
