//! The AVX-512 build of [`super::run`]: eight parts per instruction, tiles of [`TILE`] vectors
//! held in registers through every step of a segment, stick flags and plate-edge flags in mask
//! registers, and `1/|w|` from `vrsqrt14pd` refined in double precision (no square root, no
//! division; see [`rsqrt`]).

use std::arch::x86_64::*;

use super::{Lanes, Plate};

/// Vectors (of eight parts) per register tile: 64 parts whose steps are independent, enough to
/// hide the step's long dependency chain (about 60 cycles). 8 measured best of 2, 4, 6, 8 and 12
/// on an Intel Xeon; what does not fit in the 32 registers is re-read from L1.
const TILE: usize = 8;

/// `1/sqrt(q)` to about one ulp: the 14-bit estimate `r` (`vrsqrt14pd`, relative error below
/// `2^-14`) corrected by the series of `(1 - e)^(-1/2)` in `e = 1 - q r^2` up to `e^3`; the
/// first omitted term is `35 e^4 / 128 < 2^-53.8`. `q r` is formed first so that `r^2` cannot
/// overflow for tiny `q`. Lanes with `q = 0` give NaN (their parts stick; the caller masks them).
#[inline(always)]
pub(in crate::sim) unsafe fn rsqrt(q: __m512d) -> __m512d {
    let r = _mm512_rsqrt14_pd(q);
    let e = _mm512_fnmadd_pd(_mm512_mul_pd(q, r), r, _mm512_set1_pd(1.0));
    let p = _mm512_fmadd_pd(e, _mm512_set1_pd(5.0 / 16.0), _mm512_set1_pd(3.0 / 8.0));
    let p = _mm512_fmadd_pd(p, e, _mm512_set1_pd(0.5));
    _mm512_fmadd_pd(_mm512_mul_pd(r, e), p, r)
}

/// `1/sqrt(q)` as the AVX-512 build computes it (for the tests).
#[cfg(test)]
#[target_feature(enable = "avx512f")]
pub(super) unsafe fn rsqrt_lanes(q: [f64; 8]) -> [f64; 8] {
    let mut out = [0.0; 8];
    _mm512_storeu_pd(out.as_mut_ptr(), rsqrt(_mm512_loadu_pd(q.as_ptr())));
    out
}

/// Lanes `0..k` of eight.
pub(in crate::sim) fn first_lanes(k: usize) -> __mmask8 {
    if k >= 8 {
        0xff
    } else {
        ((1u16 << k) - 1) as __mmask8
    }
}

/// Records step `step` (1-based count) in `left` for the lanes of `off` of the vector at `at`.
#[inline]
pub(in crate::sim) fn mark_left(off: __mmask8, left: &mut [f64], at: usize, step: usize) {
    for b in 0..8 {
        if off >> b & 1 == 1 {
            left[at + b] = step as f64;
        }
    }
}

/// The AVX-512 build of [`super::run`].
///
/// # Safety
/// The CPU must support AVX-512F.
#[target_feature(enable = "avx512f")]
pub(super) unsafe fn run<const EDGE: bool>(
    plate: Plate,
    first: usize,
    dt: f64,
    half: f64,
    s: &mut Lanes,
) {
    s.check();
    let n = s.x.len();
    let mut start = 0;
    while start < n {
        // the last parts in the narrowest tile that holds them (a world of a few parts does
        // not pay for a full tile)
        let vectors = (n - start).div_ceil(8);
        start += 8 * match vectors {
            1 => tile::<EDGE, 1>(plate, first, dt, half, s, start),
            2 => tile::<EDGE, 2>(plate, first, dt, half, s, start),
            3 | 4 => tile::<EDGE, 4>(plate, first, dt, half, s, start),
            _ => tile::<EDGE, TILE>(plate, first, dt, half, s, start),
        };
    }
}

/// One tile of `T` vectors: the parts `start .. start + 8 T` (fewer at the end) through every
/// step of `plate`; returns `T`.
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn tile<const EDGE: bool, const T: usize>(
    plate: Plate,
    first: usize,
    dt: f64,
    half: f64,
    s: &mut Lanes,
    start: usize,
) -> usize {
    let n = s.x.len();
    let zero = _mm512_setzero_pd();
    let one = _mm512_set1_pd(1.0);
    let hdt = _mm512_set1_pd(0.5 * dt);
    let halfv = _mm512_set1_pd(half);
    let mut live = [0 as __mmask8; T];
    for (j, l) in live.iter_mut().enumerate() {
        let lo = start + 8 * j;
        *l = if lo < n { first_lanes(n - lo) } else { 0 };
    }
    let at = |j: usize| start + 8 * j;
    let (mut x, mut y, mut vx, mut vy) = ([zero; T], [zero; T], [zero; T], [zero; T]);
    let (mut slide, mut s2, mut h2) = ([zero; T], [zero; T], [zero; T]);
    let (mut stuck, mut act) = ([0 as __mmask8; T], [0 as __mmask8; T]);
    for j in 0..T {
        let k = live[j];
        x[j] = _mm512_maskz_loadu_pd(k, s.x.as_ptr().add(at(j)));
        y[j] = _mm512_maskz_loadu_pd(k, s.y.as_ptr().add(at(j)));
        vx[j] = _mm512_maskz_loadu_pd(k, s.vx.as_ptr().add(at(j)));
        vy[j] = _mm512_maskz_loadu_pd(k, s.vy.as_ptr().add(at(j)));
        let st = _mm512_maskz_loadu_pd(k, s.stuck.as_ptr().add(at(j)));
        stuck[j] = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(st, zero);
        act[j] = if EDGE {
            let a = _mm512_maskz_loadu_pd(k, s.active.as_ptr().add(at(j)));
            _mm512_cmp_pd_mask::<_CMP_GT_OQ>(a, zero)
        } else {
            k
        };
        slide[j] = _mm512_maskz_loadu_pd(k, s.slide.as_ptr().add(at(j)));
        s2[j] = _mm512_mul_pd(slide[j], slide[j]);
        let hold = _mm512_maskz_loadu_pd(k, s.hold.as_ptr().add(at(j)));
        h2[j] = _mm512_mul_pd(hold, hold);
    }
    // Each vector's table (one for all, or its world's); every table has `steps` rows.
    let rows: [&[[f64; 3]]; T] = std::array::from_fn(|j| plate.row(at(j)));
    for k in 0..plate.steps() {
        for j in 0..T {
            // SAFETY: k < steps, the length of every table (`Plate`).
            let [u1, u2, u3] = *rows[j].get_unchecked(k);
            let (u1, u2, u3) = (_mm512_set1_pd(u1), _mm512_set1_pd(u2), _mm512_set1_pd(u3));
            let sx = _mm512_fnmadd_pd(u3, y[j], u1);
            let sy = _mm512_fmadd_pd(u3, x[j], u2);
            let (wx, wy) = (_mm512_sub_pd(vx[j], sx), _mm512_sub_pd(vy[j], sy));
            let q = _mm512_fmadd_pd(wx, wx, _mm512_mul_pd(wy, wy));
            // |w| <= mu g dt, or stuck and |w| <= mu_s g dt, compared squared.
            let stick = _mm512_cmp_pd_mask::<_CMP_LE_OQ>(q, s2[j])
                | (stuck[j] & _mm512_cmp_pd_mask::<_CMP_LE_OQ>(q, h2[j]));
            // Sliding parts keep the share 1 - mu g dt / |w| of w; stuck ones none.
            let keep = _mm512_maskz_fnmadd_pd(!stick, slide[j], rsqrt(q), one);
            let nvx = _mm512_fmadd_pd(wx, keep, sx);
            let nvy = _mm512_fmadd_pd(wy, keep, sy);
            let nx = _mm512_fmadd_pd(_mm512_add_pd(vx[j], nvx), hdt, x[j]);
            let ny = _mm512_fmadd_pd(_mm512_add_pd(vy[j], nvy), hdt, y[j]);
            if EDGE {
                // Parts that left the plate keep their state.
                let a = act[j];
                x[j] = _mm512_mask_mov_pd(x[j], a, nx);
                y[j] = _mm512_mask_mov_pd(y[j], a, ny);
                vx[j] = _mm512_mask_mov_pd(vx[j], a, nvx);
                vy[j] = _mm512_mask_mov_pd(vy[j], a, nvy);
                stuck[j] = (stick & a) | (stuck[j] & !a);
                let off = (_mm512_cmp_pd_mask::<_CMP_GT_OQ>(_mm512_abs_pd(nx), halfv)
                    | _mm512_cmp_pd_mask::<_CMP_GT_OQ>(_mm512_abs_pd(ny), halfv))
                    & a;
                if off != 0 {
                    act[j] &= !off;
                    mark_left(off, s.left, at(j), first + k + 1);
                }
            } else {
                (x[j], y[j], vx[j], vy[j], stuck[j]) = (nx, ny, nvx, nvy, stick);
            }
        }
    }
    for j in 0..T {
        let k = live[j];
        _mm512_mask_storeu_pd(s.x.as_mut_ptr().add(at(j)), k, x[j]);
        _mm512_mask_storeu_pd(s.y.as_mut_ptr().add(at(j)), k, y[j]);
        _mm512_mask_storeu_pd(s.vx.as_mut_ptr().add(at(j)), k, vx[j]);
        _mm512_mask_storeu_pd(s.vy.as_mut_ptr().add(at(j)), k, vy[j]);
        let st = _mm512_maskz_mov_pd(stuck[j], one);
        _mm512_mask_storeu_pd(s.stuck.as_mut_ptr().add(at(j)), k, st);
        if EDGE {
            let a = _mm512_maskz_mov_pd(act[j], one);
            _mm512_mask_storeu_pd(s.active.as_mut_ptr().add(at(j)), k, a);
        }
    }
    T
}
