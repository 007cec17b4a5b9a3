//! The AVX2 + FMA build of the out-of-plane step ([`super::step`]): four parts per instruction,
//! tiles of [`TILE`] vectors in registers through every step of a segment, and `1/|w|` from the
//! planar kernel's refined single-precision estimate (no square root, no division but for the
//! rare vector outside single precision's range). It agrees with the portable build to a few ulp,
//! as the AVX-512 build does.

use std::arch::x86_64::*;

use super::{Air, Steps};
use crate::sim::kernel::avx2::{mark_left, rsqrt};
use crate::sim::kernel::Lanes;

/// Vectors per tile: 32 parts (as the planar AVX2 build).
const TILE: usize = 8;

/// Advances every part of `l` through `steps`.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn run(steps: &Steps, l: &mut Lanes, air: &mut Air) {
    if steps.half.is_finite() {
        tiles::<true>(steps, l, air)
    } else {
        tiles::<false>(steps, l, air)
    }
}

/// Without an edge (`EDGE = false`) no part leaves, so no lane keeps its state: the step writes
/// its results without a blend, as the planar build does.
#[target_feature(enable = "avx2,fma")]
unsafe fn tiles<const EDGE: bool>(steps: &Steps, l: &mut Lanes, air: &mut Air) {
    let n = l.x.len();
    let mut start = 0;
    while start < n {
        start += 4 * match (n - start).div_ceil(4) {
            1 => tile::<EDGE, 1>(steps, l, air, start),
            2 => tile::<EDGE, 2>(steps, l, air, start),
            3 | 4 => tile::<EDGE, 4>(steps, l, air, start),
            _ => tile::<EDGE, TILE>(steps, l, air, start),
        };
    }
}

/// The parts `start .. start + 4 T` (fewer at the end) through every step; returns `T`.
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn tile<const EDGE: bool, const T: usize>(
    steps: &Steps,
    l: &mut Lanes,
    air: &mut Air,
    start: usize,
) -> usize {
    let n = l.x.len();
    let zero = _mm256_setzero_pd();
    let one = _mm256_set1_pd(1.0);
    let dt = _mm256_set1_pd(steps.dt);
    let hdt = _mm256_set1_pd(0.5 * steps.dt);
    let halfv = _mm256_set1_pd(steps.half);
    let inv_g = _mm256_set1_pd(1.0 / steps.g);
    let abs = _mm256_castsi256_pd(_mm256_set1_epi64x(i64::MAX));
    let at = |j: usize| start + 4 * j;
    let mut live = [_mm256_setzero_si256(); T];
    for (j, k) in live.iter_mut().enumerate() {
        let count = n.saturating_sub(at(j)).min(4) as i64;
        *k = _mm256_cmpgt_epi64(_mm256_set1_epi64x(count), _mm256_set_epi64x(3, 2, 1, 0));
    }
    let (mut x, mut y, mut vx, mut vy) = ([zero; T], [zero; T], [zero; T], [zero; T]);
    // the air state stays in memory, read only for a vector with a part in the air: sixteen
    // registers cannot hold it beside the rest for a whole tile, and parts seldom fly
    let mut airborne = [false; T];
    let (mut slide, mut h2) = ([zero; T], [zero; T]);
    let (mut stuck, mut act) = ([zero; T], [zero; T]);
    for j in 0..T {
        let k = live[j];
        let load = |a: &[f64]| _mm256_maskload_pd(a.as_ptr().add(at(j)), k);
        (x[j], y[j], vx[j], vy[j]) = (load(l.x), load(l.y), load(l.vx), load(l.vy));
        airborne[j] = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_GT_OQ>(load(air.h), zero)) != 0;
        // mu dt and (mu_s dt)^2: the limits are these times g + a_z
        slide[j] = _mm256_mul_pd(load(l.slide), inv_g);
        let hold = _mm256_mul_pd(load(l.hold), inv_g);
        h2[j] = _mm256_mul_pd(hold, hold);
        stuck[j] = _mm256_cmp_pd::<_CMP_GT_OQ>(load(l.stuck), zero);
        act[j] = _mm256_and_pd(
            _mm256_cmp_pd::<_CMP_GT_OQ>(load(l.active), zero),
            _mm256_castsi256_pd(k),
        );
    }
    for (k, (&[u1, u2, u3], nz)) in steps.u.iter().zip(steps.normals).enumerate() {
        let (u1, u2, u3) = (_mm256_set1_pd(u1), _mm256_set1_pd(u2), _mm256_set1_pd(u3));
        let base = _mm256_set1_pd(steps.g + nz[0]);
        let (ra, rb) = (_mm256_set1_pd(nz[1]), _mm256_set1_pd(nz[2]));
        for j in 0..T {
            let a = act[j];
            let nrm = _mm256_fnmadd_pd(x[j], rb, _mm256_fmadd_pd(y[j], ra, base));
            let (ph, phv) = (
                air.h.as_mut_ptr().add(at(j)),
                air.hv.as_mut_ptr().add(at(j)),
            );
            let mut up_now = _mm256_cmp_pd::<_CMP_LT_OQ>(nrm, zero);
            if airborne[j] {
                let h = _mm256_maskload_pd(ph, live[j]);
                up_now = _mm256_or_pd(up_now, _mm256_cmp_pd::<_CMP_GT_OQ>(h, zero));
            }
            let flying = _mm256_and_pd(up_now, a);
            let sx = _mm256_fnmadd_pd(u3, y[j], u1);
            let sy = _mm256_fmadd_pd(u3, x[j], u2);
            let (wx, wy) = (_mm256_sub_pd(vx[j], sx), _mm256_sub_pd(vy[j], sy));
            let q = _mm256_fmadd_pd(wx, wx, _mm256_mul_pd(wy, wy));
            let sl = _mm256_mul_pd(slide[j], nrm);
            let n2 = _mm256_mul_pd(nrm, nrm);
            let stick = _mm256_or_pd(
                _mm256_cmp_pd::<_CMP_LE_OQ>(q, _mm256_mul_pd(sl, sl)),
                _mm256_and_pd(
                    stuck[j],
                    _mm256_cmp_pd::<_CMP_LE_OQ>(q, _mm256_mul_pd(h2[j], n2)),
                ),
            );
            let slides = _mm256_andnot_pd(flying, _mm256_andnot_pd(stick, a));
            let keep = _mm256_and_pd(slides, _mm256_fnmadd_pd(sl, rsqrt(q, slides), one));
            let mut nvx = _mm256_fmadd_pd(wx, keep, sx);
            let mut nvy = _mm256_fmadd_pd(wy, keep, sy);
            if _mm256_movemask_pd(flying) != 0 {
                let pf = air.flight.as_mut_ptr().add(at(j));
                let (h, hv) = (
                    _mm256_maskload_pd(ph, live[j]),
                    _mm256_maskload_pd(phv, live[j]),
                );
                let rate = _mm256_fnmadd_pd(nrm, dt, hv);
                let height = _mm256_fmadd_pd(rate, dt, h);
                let up = _mm256_and_pd(flying, _mm256_cmp_pd::<_CMP_GT_OQ>(height, zero));
                nvx = _mm256_blendv_pd(nvx, vx[j], flying);
                nvy = _mm256_blendv_pd(nvy, vy[j], flying);
                let h = _mm256_blendv_pd(h, _mm256_and_pd(up, height), flying);
                _mm256_maskstore_pd(ph, live[j], h);
                _mm256_maskstore_pd(
                    phv,
                    live[j],
                    _mm256_blendv_pd(hv, _mm256_and_pd(up, rate), flying),
                );
                let flown =
                    _mm256_add_pd(_mm256_maskload_pd(pf, live[j]), _mm256_and_pd(flying, one));
                _mm256_maskstore_pd(pf, live[j], flown);
                airborne[j] = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_GT_OQ>(h, zero)) != 0;
            }
            let nx = _mm256_fmadd_pd(_mm256_add_pd(vx[j], nvx), hdt, x[j]);
            let ny = _mm256_fmadd_pd(_mm256_add_pd(vy[j], nvy), hdt, y[j]);
            if !EDGE {
                (x[j], y[j], vx[j], vy[j]) = (nx, ny, nvx, nvy);
                stuck[j] = _mm256_andnot_pd(flying, stick);
                continue;
            }
            // parts that left the plate keep their state
            x[j] = _mm256_blendv_pd(x[j], nx, a);
            y[j] = _mm256_blendv_pd(y[j], ny, a);
            vx[j] = _mm256_blendv_pd(vx[j], nvx, a);
            vy[j] = _mm256_blendv_pd(vy[j], nvy, a);
            stuck[j] = _mm256_blendv_pd(stuck[j], _mm256_andnot_pd(flying, stick), a);
            let off = _mm256_and_pd(
                _mm256_or_pd(
                    _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_and_pd(nx, abs), halfv),
                    _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_and_pd(ny, abs), halfv),
                ),
                a,
            );
            let bits = _mm256_movemask_pd(off);
            if bits != 0 {
                act[j] = _mm256_andnot_pd(off, a);
                mark_left(bits, l.left, at(j), steps.first + k + 1);
            }
        }
    }
    for j in 0..T {
        let k = live[j];
        let store =
            |a: &mut [f64], v: __m256d| _mm256_maskstore_pd(a.as_mut_ptr().add(at(j)), k, v);
        store(l.x, x[j]);
        store(l.y, y[j]);
        store(l.vx, vx[j]);
        store(l.vy, vy[j]);
        store(l.stuck, _mm256_and_pd(stuck[j], one));
        store(l.active, _mm256_and_pd(act[j], one));
    }
    T
}
