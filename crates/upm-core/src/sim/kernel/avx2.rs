//! The AVX2 + FMA build of [`super::run`]: four parts per instruction, tiles of [`TILE`] vectors
//! held in registers through every step of a segment, and `1/|w|` from the single-precision
//! estimate `rsqrtps` refined in double precision (see [`rsqrt`]); no square root, no division
//! but for the rare vector whose `|w|^2` lies outside single precision's range.

use std::arch::x86_64::*;

use super::{Lanes, Plate};

/// Vectors (of four parts) per register tile: 32 parts whose steps are independent, enough to hide
/// the step's long dependency chain (about 80 cycles with the conversions to and from single
/// precision). 8 measured best of 1, 2, 3, 4, 6 and 8 on an Intel Xeon (9.0, 4.1, 3.1, 2.3, 2.6
/// and 2.0 ns per part-step); what does not fit in the 16 registers is re-read from L1.
const TILE: usize = 8;

/// `|w|^2` between these has a single-precision estimate (`rsqrtps` is defined on normal floats).
const Q_MIN: f64 = 1e-36;
const Q_MAX: f64 = 1e36;

/// `1/sqrt(q)` to about one ulp in the lanes of `slides` (the others are not used): the 12-bit
/// estimate `r` (`rsqrtps`, relative error below `1.5 * 2^-12`) corrected by the series of
/// `(1 - e)^(-1/2)` in `e = 1 - q r^2` up to `e^4`; the first omitted term is
/// `63 e^5 / 256 < 2^-54`. A vector with a sliding lane outside `[Q_MIN, Q_MAX]` takes the
/// correctly rounded `1 / sqrt(q)` instead.
#[inline(always)]
pub(in crate::sim) unsafe fn rsqrt(q: __m256d, slides: __m256d) -> __m256d {
    let inside = _mm256_and_pd(
        _mm256_cmp_pd::<_CMP_GE_OQ>(q, _mm256_set1_pd(Q_MIN)),
        _mm256_cmp_pd::<_CMP_LE_OQ>(q, _mm256_set1_pd(Q_MAX)),
    );
    let one = _mm256_set1_pd(1.0);
    if _mm256_movemask_pd(_mm256_andnot_pd(inside, slides)) != 0 {
        return _mm256_div_pd(one, _mm256_sqrt_pd(q));
    }
    let r = _mm256_cvtps_pd(_mm_rsqrt_ps(_mm256_cvtpd_ps(q)));
    let e = _mm256_fnmadd_pd(_mm256_mul_pd(q, r), r, one);
    let p = _mm256_fmadd_pd(e, _mm256_set1_pd(35.0 / 128.0), _mm256_set1_pd(5.0 / 16.0));
    let p = _mm256_fmadd_pd(p, e, _mm256_set1_pd(3.0 / 8.0));
    let p = _mm256_fmadd_pd(p, e, _mm256_set1_pd(0.5));
    _mm256_fmadd_pd(_mm256_mul_pd(r, e), p, r)
}

/// `1/sqrt(q)` as the AVX2 build computes it, every lane sliding (for the tests).
#[cfg(test)]
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn rsqrt_lanes(q: [f64; 4]) -> [f64; 4] {
    let mut out = [0.0; 4];
    let all = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
    _mm256_storeu_pd(out.as_mut_ptr(), rsqrt(_mm256_loadu_pd(q.as_ptr()), all));
    out
}

/// The lanes of `active` whose new position `(nx, ny)` is past the plate's half side `half` in x
/// or y (`abs` clears the sign bit).
#[inline(always)]
pub(in crate::sim) unsafe fn leaving(
    nx: __m256d,
    ny: __m256d,
    abs: __m256d,
    half: __m256d,
    active: __m256d,
) -> __m256d {
    _mm256_and_pd(
        _mm256_or_pd(
            _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_and_pd(nx, abs), half),
            _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_and_pd(ny, abs), half),
        ),
        active,
    )
}

/// Records step `step` (1-based count) in `left` for the lanes set in `bits` (a movemask) of
/// the vector at `at`.
#[inline]
pub(in crate::sim) fn mark_left(bits: i32, left: &mut [f64], at: usize, step: usize) {
    for b in 0..4 {
        if bits >> b & 1 == 1 {
            left[at + b] = step as f64;
        }
    }
}

/// The AVX2 build of [`super::run`].
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
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
        let vectors = (n - start).div_ceil(4);
        start += 4 * match vectors {
            1 => tile::<EDGE, 1>(plate, first, dt, half, s, start),
            2 => tile::<EDGE, 2>(plate, first, dt, half, s, start),
            3 | 4 => tile::<EDGE, 4>(plate, first, dt, half, s, start),
            _ => tile::<EDGE, TILE>(plate, first, dt, half, s, start),
        };
    }
}

/// One tile of `T` vectors: the parts `start .. start + 4 T` (fewer at the end) through every
/// step of `plate`; returns `T`.
#[target_feature(enable = "avx2,fma")]
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
    let zero = _mm256_setzero_pd();
    let one = _mm256_set1_pd(1.0);
    let hdt = _mm256_set1_pd(0.5 * dt);
    let halfv = _mm256_set1_pd(half);
    let abs = _mm256_castsi256_pd(_mm256_set1_epi64x(i64::MAX));
    let mut live = [_mm256_setzero_si256(); T];
    for (j, l) in live.iter_mut().enumerate() {
        let lo = start + 4 * j;
        let k = n.saturating_sub(lo).min(4) as i64;
        *l = _mm256_cmpgt_epi64(_mm256_set1_epi64x(k), _mm256_set_epi64x(3, 2, 1, 0));
    }
    let at = |j: usize| start + 4 * j;
    let (mut x, mut y, mut vx, mut vy) = ([zero; T], [zero; T], [zero; T], [zero; T]);
    let (mut slide, mut s2, mut h2) = ([zero; T], [zero; T], [zero; T]);
    let (mut stuck, mut act) = ([zero; T], [zero; T]);
    for j in 0..T {
        let k = live[j];
        x[j] = _mm256_maskload_pd(s.x.as_ptr().add(at(j)), k);
        y[j] = _mm256_maskload_pd(s.y.as_ptr().add(at(j)), k);
        vx[j] = _mm256_maskload_pd(s.vx.as_ptr().add(at(j)), k);
        vy[j] = _mm256_maskload_pd(s.vy.as_ptr().add(at(j)), k);
        let st = _mm256_maskload_pd(s.stuck.as_ptr().add(at(j)), k);
        stuck[j] = _mm256_cmp_pd::<_CMP_GT_OQ>(st, zero);
        act[j] = if EDGE {
            let a = _mm256_maskload_pd(s.active.as_ptr().add(at(j)), k);
            _mm256_cmp_pd::<_CMP_GT_OQ>(a, zero)
        } else {
            _mm256_castsi256_pd(k)
        };
        slide[j] = _mm256_maskload_pd(s.slide.as_ptr().add(at(j)), k);
        s2[j] = _mm256_mul_pd(slide[j], slide[j]);
        let hold = _mm256_maskload_pd(s.hold.as_ptr().add(at(j)), k);
        h2[j] = _mm256_mul_pd(hold, hold);
    }
    // Each vector's table (one for all, or its world's); every table has `steps` rows.
    // (one table for all without a call per vector: a call a tile was 2 % of a 2-step call)
    let mut rows: [&[[f64; 3]]; T] = [plate.tables[0]; T];
    if plate.tables.len() > 1 {
        for (j, r) in rows.iter_mut().enumerate() {
            *r = plate.row(at(j));
        }
    }
    for k in 0..plate.steps() {
        for j in 0..T {
            // SAFETY: k < steps, the length of every table (`Plate`).
            let [u1, u2, u3] = *rows[j].get_unchecked(k);
            let (u1, u2, u3) = (_mm256_set1_pd(u1), _mm256_set1_pd(u2), _mm256_set1_pd(u3));
            let sx = _mm256_fnmadd_pd(u3, y[j], u1);
            let sy = _mm256_fmadd_pd(u3, x[j], u2);
            let (wx, wy) = (_mm256_sub_pd(vx[j], sx), _mm256_sub_pd(vy[j], sy));
            let q = _mm256_fmadd_pd(wx, wx, _mm256_mul_pd(wy, wy));
            let stick = _mm256_or_pd(
                _mm256_cmp_pd::<_CMP_LE_OQ>(q, s2[j]),
                _mm256_and_pd(stuck[j], _mm256_cmp_pd::<_CMP_LE_OQ>(q, h2[j])),
            );
            let slides = _mm256_andnot_pd(stick, act[j]);
            let keep = _mm256_and_pd(slides, _mm256_fnmadd_pd(slide[j], rsqrt(q, slides), one));
            let nvx = _mm256_fmadd_pd(wx, keep, sx);
            let nvy = _mm256_fmadd_pd(wy, keep, sy);
            let nx = _mm256_fmadd_pd(_mm256_add_pd(vx[j], nvx), hdt, x[j]);
            let ny = _mm256_fmadd_pd(_mm256_add_pd(vy[j], nvy), hdt, y[j]);
            if EDGE {
                let a = act[j];
                x[j] = _mm256_blendv_pd(x[j], nx, a);
                y[j] = _mm256_blendv_pd(y[j], ny, a);
                vx[j] = _mm256_blendv_pd(vx[j], nvx, a);
                vy[j] = _mm256_blendv_pd(vy[j], nvy, a);
                stuck[j] = _mm256_blendv_pd(stuck[j], stick, a);
                let off = leaving(nx, ny, abs, halfv, a);
                let bits = _mm256_movemask_pd(off);
                if bits != 0 {
                    act[j] = _mm256_andnot_pd(off, a);
                    mark_left(bits, s.left, at(j), first + k + 1);
                }
            } else {
                (x[j], y[j], vx[j], vy[j], stuck[j]) = (nx, ny, nvx, nvy, stick);
            }
        }
    }
    for j in 0..T {
        // Whole vectors with plain stores: a masked store is microcoded on AMD Zen (about 12
        // cycles each), which made a 2-step call on many parts spend more time storing than
        // stepping.
        let store = |a: *mut f64, v: __m256d| {
            if at(j) + 4 <= n {
                _mm256_storeu_pd(a, v);
            } else {
                _mm256_maskstore_pd(a, live[j], v);
            }
        };
        store(s.x.as_mut_ptr().add(at(j)), x[j]);
        store(s.y.as_mut_ptr().add(at(j)), y[j]);
        store(s.vx.as_mut_ptr().add(at(j)), vx[j]);
        store(s.vy.as_mut_ptr().add(at(j)), vy[j]);
        store(
            s.stuck.as_mut_ptr().add(at(j)),
            _mm256_and_pd(stuck[j], one),
        );
        if EDGE {
            store(s.active.as_mut_ptr().add(at(j)), _mm256_and_pd(act[j], one));
        }
    }
    T
}
