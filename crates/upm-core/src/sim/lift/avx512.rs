//! The AVX-512 build of the out-of-plane step ([`super::step`]): eight parts per instruction,
//! tiles of [`TILE`] vectors in registers through every step of a segment, flags in mask
//! registers, and `1/|w|` from the planar kernel's refined reciprocal square root (no square root,
//! no division). It agrees with the portable build to a few ulp (the stick decision differs only
//! where `|w|` is within rounding of the threshold), as the planar builds do.

use std::arch::x86_64::*;

use super::{Air, Reach, Steps};
use crate::sim::kernel::avx512::{first_lanes, leaving, mark_left, rsqrt};
use crate::sim::kernel::Lanes;

/// Vectors per tile: 64 parts, enough to hide the step's dependency chain (8 measured best of 2,
/// 4 and 8 on an Intel Xeon).
const TILE: usize = 8;

/// Advances every part of `l` through `steps`.
///
/// # Safety
/// The CPU must support AVX-512F.
#[target_feature(enable = "avx512f")]
pub(super) unsafe fn run(steps: &Steps, l: &mut Lanes, air: &mut Air) {
    if steps.half.is_finite() {
        tiles::<true>(steps, l, air)
    } else {
        tiles::<false>(steps, l, air)
    }
}

#[target_feature(enable = "avx512f")]
unsafe fn tiles<const EDGE: bool>(steps: &Steps, l: &mut Lanes, air: &mut Air) {
    let n = l.x.len();
    let mut start = 0;
    while start < n {
        start += 8 * match (n - start).div_ceil(8) {
            1 => tile::<EDGE, 1>(steps, l, air, start),
            2 => tile::<EDGE, 2>(steps, l, air, start),
            _ => tile::<EDGE, TILE>(steps, l, air, start),
        };
    }
}

/// The parts `start .. start + 8 T` (fewer at the end) through every step; returns `T`.
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn tile<const EDGE: bool, const T: usize>(
    steps: &Steps,
    l: &mut Lanes,
    air: &mut Air,
    start: usize,
) -> usize {
    let n = l.x.len();
    let zero = _mm512_setzero_pd();
    let one = _mm512_set1_pd(1.0);
    let dt = _mm512_set1_pd(steps.dt);
    let hdt = _mm512_set1_pd(0.5 * steps.dt);
    let halfv = _mm512_set1_pd(steps.half);
    let inv_g = _mm512_set1_pd(1.0 / steps.g);
    let at = |j: usize| start + 8 * j;
    let mut live = [0 as __mmask8; T];
    for (j, k) in live.iter_mut().enumerate() {
        *k = if at(j) < n { first_lanes(n - at(j)) } else { 0 };
    }
    let (mut x, mut y, mut vx, mut vy) = ([zero; T], [zero; T], [zero; T], [zero; T]);
    let (mut h, mut hv, mut flown) = ([zero; T], [zero; T], [zero; T]);
    let (mut slide, mut s2, mut h2) = ([zero; T], [zero; T], [zero; T]);
    let (mut stuck, mut act) = ([0 as __mmask8; T], [0 as __mmask8; T]);
    for j in 0..T {
        let k = live[j];
        let load = |a: &[f64]| _mm512_maskz_loadu_pd(k, a.as_ptr().add(at(j)));
        (x[j], y[j], vx[j], vy[j]) = (load(l.x), load(l.y), load(l.vx), load(l.vy));
        (h[j], hv[j]) = (load(air.h), load(air.hv));
        // mu dt, (mu dt)^2 and (mu_s dt)^2: the limits are these times g + a_z (and its square)
        slide[j] = _mm512_mul_pd(load(l.slide), inv_g);
        s2[j] = _mm512_mul_pd(slide[j], slide[j]);
        let hold = _mm512_mul_pd(load(l.hold), inv_g);
        h2[j] = _mm512_mul_pd(hold, hold);
        stuck[j] = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(load(l.stuck), zero);
        act[j] = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(load(l.active), zero) & k;
    }
    let mut airborne = [false; T];
    for j in 0..T {
        airborne[j] = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(h[j], zero) != 0;
    }
    let reach_of = |x: &[__m512d; T],
                    y: &[__m512d; T],
                    vx: &[__m512d; T],
                    vy: &[__m512d; T],
                    act: &[__mmask8; T]| {
        let (mut r, mut v) = (zero, zero);
        for j in 0..T {
            let far = _mm512_max_pd(_mm512_abs_pd(x[j]), _mm512_abs_pd(y[j]));
            let fast = _mm512_add_pd(_mm512_abs_pd(vx[j]), _mm512_abs_pd(vy[j]));
            // a NaN (a broken part) is dropped by max_pd: such a part flies in neither path
            r = _mm512_mask_max_pd(r, act[j], far, r);
            v = _mm512_mask_max_pd(v, act[j], fast, v);
        }
        Reach::new(_mm512_reduce_max_pd(r), _mm512_reduce_max_pd(v))
    };
    let mut in_air = airborne.iter().any(|&a| a);
    let mut reach = reach_of(&x, &y, &vx, &vy, &act);
    for (k, (u, nz)) in steps.u.iter().zip(steps.normals).enumerate() {
        // no part of the tile in the air nor able to leave: the flight test is skipped
        let grounded = reach.step(in_air, u, nz, steps, || reach_of(&x, &y, &vx, &vy, &act));
        let &[u1, u2, u3] = u;
        let (u1, u2, u3) = (_mm512_set1_pd(u1), _mm512_set1_pd(u2), _mm512_set1_pd(u3));
        let base = _mm512_set1_pd(steps.g + nz[0]);
        let (ra, rb) = (_mm512_set1_pd(nz[1]), _mm512_set1_pd(nz[2]));
        // the step of vector j, specialised for steps without flight ($fly = false)
        macro_rules! vector_step {
            ($j:expr, $fly:expr) => {{
                let j = $j;
                // normal acceleration g + z'' + y rx'' - x ry'' at the part
                let nrm = _mm512_fnmadd_pd(x[j], rb, _mm512_fmadd_pd(y[j], ra, base));
                // flight: in the air, or leaving now (lanes off the plate never fly)
                let a = act[j];
                let flying = if !$fly {
                    0
                } else {
                    (_mm512_cmp_pd_mask::<_CMP_GT_OQ>(h[j], zero)
                        | _mm512_cmp_pd_mask::<_CMP_LT_OQ>(nrm, zero))
                        & a
                };
                // contact: the planar step with mu (g + a_z) dt
                let sx = _mm512_fnmadd_pd(u3, y[j], u1);
                let sy = _mm512_fmadd_pd(u3, x[j], u2);
                let (wx, wy) = (_mm512_sub_pd(vx[j], sx), _mm512_sub_pd(vy[j], sy));
                let q = _mm512_fmadd_pd(wx, wx, _mm512_mul_pd(wy, wy));
                let sl = _mm512_mul_pd(slide[j], nrm); // mu (g + a_z) dt
                                                       // |w| <= mu N dt, or (stuck) <= mu_s N dt: q <= (stuck ? max(s2, h2) : s2) N^2
                let limit = _mm512_mask_max_pd(s2[j], stuck[j], s2[j], h2[j]);
                let stick =
                    _mm512_cmp_pd_mask::<_CMP_LE_OQ>(q, _mm512_mul_pd(limit, _mm512_mul_pd(nrm, nrm)));
                let keep = _mm512_maskz_fnmadd_pd(!stick, sl, rsqrt(q), one);
                let mut nvx = _mm512_fmadd_pd(wx, keep, sx);
                let mut nvy = _mm512_fmadd_pd(wy, keep, sy);
                if flying != 0 {
                    // the flight half (rare: a tile's parts are mostly on the plate)
                    let rate = _mm512_fnmadd_pd(nrm, dt, hv[j]);
                    let height = _mm512_fmadd_pd(rate, dt, h[j]);
                    let up = flying & _mm512_cmp_pd_mask::<_CMP_GT_OQ>(height, zero);
                    nvx = _mm512_mask_mov_pd(nvx, flying, vx[j]);
                    nvy = _mm512_mask_mov_pd(nvy, flying, vy[j]);
                    h[j] = _mm512_mask_mov_pd(h[j], flying, _mm512_maskz_mov_pd(up, height));
                    hv[j] = _mm512_mask_mov_pd(hv[j], flying, _mm512_maskz_mov_pd(up, rate));
                    flown[j] = _mm512_mask_add_pd(flown[j], flying, flown[j], one);
                    airborne[j] = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(h[j], zero) != 0;
                }
                let nx = _mm512_fmadd_pd(_mm512_add_pd(vx[j], nvx), hdt, x[j]);
                let ny = _mm512_fmadd_pd(_mm512_add_pd(vy[j], nvy), hdt, y[j]);
                if !EDGE {
                    (x[j], y[j], vx[j], vy[j]) = (nx, ny, nvx, nvy);
                    stuck[j] = stick & !flying;
                    continue;
                }
                // parts that left the plate keep their state
                x[j] = _mm512_mask_mov_pd(x[j], a, nx);
                y[j] = _mm512_mask_mov_pd(y[j], a, ny);
                vx[j] = _mm512_mask_mov_pd(vx[j], a, nvx);
                vy[j] = _mm512_mask_mov_pd(vy[j], a, nvy);
                stuck[j] = (stick & !flying & a) | (stuck[j] & !a);
                let off = leaving(nx, ny, halfv, a);
                if off != 0 {
                    act[j] &= !off;
                    mark_left(off, l.left, at(j), steps.first + k + 1);
                }
            }};
        }
        if grounded {
            for j in 0..T {
                vector_step!(j, false);
            }
        } else {
            for j in 0..T {
                vector_step!(j, true);
            }
        }
        if !grounded {
            in_air = airborne.iter().any(|&a| a);
        }
    }
    for j in 0..T {
        let k = live[j];
        let store =
            |a: &mut [f64], v: __m512d| _mm512_mask_storeu_pd(a.as_mut_ptr().add(at(j)), k, v);
        store(l.x, x[j]);
        store(l.y, y[j]);
        store(l.vx, vx[j]);
        store(l.vy, vy[j]);
        store(air.h, h[j]);
        store(air.hv, hv[j]);
        let before = _mm512_maskz_loadu_pd(k, air.flight.as_ptr().add(at(j)));
        store(air.flight, _mm512_add_pd(before, flown[j]));
        store(l.stuck, _mm512_maskz_mov_pd(stuck[j], one));
        store(l.active, _mm512_maskz_mov_pd(act[j], one));
    }
    T
}
