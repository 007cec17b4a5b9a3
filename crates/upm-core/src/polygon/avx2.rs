//! The AVX2 build of the fan integrals ([`super::lanes`]), taken on AVX2 and AVX-512 machines:
//! a group of eight edges as two vectors of four (the second left out when none of its edges is
//! live), the same operations in the same order as the portable lanes (no fused multiply–adds),
//! so the same bits.

use std::arch::x86_64::*;

use super::lanes::{from_sums, Edges, LG, LN2_HI, LN2_LO, THIRD};
use super::load::Linear;
use super::{Fan, Polygon};

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
    let h = sub(m(ax, ey), m(ay, ex));
    // the lanes that span area: live, and h != 0 (unordered counts, as !(h == 0) does)
    let area = _mm256_and_pd(live, _mm256_cmp_pd::<_CMP_NEQ_UQ>(h, zero));
    let ta = a(m(ax, ex), m(ay, ey));
    let tb = a(ta, len);
    let drho = div(m(len, a(ta, tb)), a(ra, rb));
    let hh = _mm256_andnot_pd(set(-0.0), h);
    let after = _mm256_cmp_pd::<_CMP_GE_OQ>(ta, zero);
    let before = _mm256_cmp_pd::<_CMP_LE_OQ>(tb, zero);
    let mid_num = m(tb, a(a(hh, rb), tb));
    let mid_den = m(hh, a(hh, rb));
    let num = _mm256_blendv_pd(
        _mm256_blendv_pd(mid_num, sub(len, drho), before),
        a(len, drho),
        after,
    );
    let den = _mm256_blendv_pd(
        _mm256_blendv_pd(mid_den, sub(rb, tb), before),
        a(ta, ra),
        after,
    );
    let across = _mm256_andnot_pd(after, _mm256_andnot_pd(before, area));
    let arg1 = _mm256_and_pd(area, div(num, den));
    let neg_ta = _mm256_xor_pd(ta, set(-0.0));
    let arg2 = _mm256_and_pd(across, div(m(neg_ta, sub(a(hh, ra), ta)), m(hh, a(hh, ra))));
    let h = _mm256_and_pd(area, h);
    // ln(1 + arg1) + ln(1 + arg2), both arguments >= 0: one logarithm of the product
    let d = ln_1p(a(a(arg1, arg2), m(arg1, arg2)));
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
    let c = _mm256_div_pd(
        _mm256_blendv_pd(sub(x, sub(u, one)), sub(one, sub(u, x)), big),
        u,
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
