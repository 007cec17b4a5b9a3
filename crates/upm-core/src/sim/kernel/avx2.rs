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
pub(super) unsafe fn run<const EDGE: bool, const WORLDS: bool>(
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
            1 => tile::<EDGE, WORLDS, 1>(plate, first, dt, half, s, start),
            2 => tile::<EDGE, WORLDS, 2>(plate, first, dt, half, s, start),
            3 | 4 => tile::<EDGE, WORLDS, 4>(plate, first, dt, half, s, start),
            _ => tile::<EDGE, WORLDS, TILE>(plate, first, dt, half, s, start),
        };
    }
}

/// One tile of `T` vectors: the parts `start .. start + 4 T` (fewer at the end) through every
/// step of `plate`; returns `T`.
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn tile<const EDGE: bool, const WORLDS: bool, const T: usize>(
    plate: Plate,
    first: usize,
    dt: f64,
    half: f64,
    s: &mut Lanes,
    start: usize,
) -> usize {
    let n = s.x.len();
    let zero = _mm256_setzero_pd();
    let mut live = [_mm256_setzero_si256(); T];
    for (j, l) in live.iter_mut().enumerate() {
        let lo = start + 4 * j;
        let k = n.saturating_sub(lo).min(4) as i64;
        *l = _mm256_cmpgt_epi64(_mm256_set1_epi64x(k), _mm256_set_epi64x(3, 2, 1, 0));
    }
    let at = |j: usize| start + 4 * j;
    let c = Consts::new(dt, half, s.kick);
    let mut v = [Four::zero(); T];
    for (j, v) in v.iter_mut().enumerate() {
        let k = live[j];
        let load = |a: &[f64]| _mm256_maskload_pd(a.as_ptr().add(at(j)), k);
        let hold = load(s.hold);
        *v = Four {
            x: load(s.x),
            y: load(s.y),
            vx: load(s.vx),
            vy: load(s.vy),
            stuck: _mm256_cmp_pd::<_CMP_GT_OQ>(load(s.stuck), zero),
            act: if EDGE {
                _mm256_cmp_pd::<_CMP_GT_OQ>(load(s.active), zero)
            } else {
                _mm256_castsi256_pd(k)
            },
            slide: load(s.slide),
            s2: zero,
            h2: _mm256_mul_pd(hold, hold),
        };
        v.s2 = _mm256_mul_pd(v.slide, v.slide);
    }
    // Each vector's first column (one table for all, or its first world's: it reads four), and
    // the table's width: the constant 1 for one table, so that its loads are the table's own.
    let width = if WORLDS { plate.width() } else { 1 };
    let mut cols = [0; T];
    if WORLDS {
        for (j, col) in cols.iter_mut().enumerate() {
            // (a vector past the parts holds none: it reads the first columns)
            *col = if at(j) < n { plate.column(at(j)) } else { 0 };
            assert!(*col + 4 <= width, "a vector's columns within the table");
        }
    }
    for k in 0..plate.steps() {
        for j in 0..T {
            // SAFETY: k < steps, every vector's columns are within the width, which is the
            // plate's (checked above).
            let u = if WORLDS {
                let p = plate.cell(width, cols[j], k);
                [
                    _mm256_loadu_pd(p),
                    _mm256_loadu_pd(p.add(width)),
                    _mm256_loadu_pd(p.add(2 * width)),
                ]
            } else {
                splat(plate.at(1, 0, k))
            };
            let off = step::<EDGE>(&mut v[j], u, &c);
            if EDGE {
                let bits = _mm256_movemask_pd(off);
                if bits != 0 {
                    mark_left(bits, s.left, at(j), first + k + 1);
                }
            }
        }
    }
    let one = _mm256_set1_pd(1.0);
    for (j, v) in v.iter().enumerate() {
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
        store(s.x.as_mut_ptr().add(at(j)), v.x);
        store(s.y.as_mut_ptr().add(at(j)), v.y);
        store(s.vx.as_mut_ptr().add(at(j)), v.vx);
        store(s.vy.as_mut_ptr().add(at(j)), v.vy);
        store(s.stuck.as_mut_ptr().add(at(j)), _mm256_and_pd(v.stuck, one));
        if EDGE {
            store(s.active.as_mut_ptr().add(at(j)), _mm256_and_pd(v.act, one));
        }
    }
    T
}

/// One vector of four parts through the steps, as the tiles hold it: position, velocity, the
/// stuck and the active lanes (all ones where true), and the friction thresholds (`mu g dt`,
/// its square and the square of `mu_s g dt`).
#[derive(Clone, Copy)]
pub(in crate::sim) struct Four {
    pub x: __m256d,
    pub y: __m256d,
    pub vx: __m256d,
    pub vy: __m256d,
    pub stuck: __m256d,
    pub act: __m256d,
    pub slide: __m256d,
    pub s2: __m256d,
    pub h2: __m256d,
}

impl Four {
    /// Every lane zero.
    ///
    /// # Safety
    /// The CPU has AVX.
    #[inline(always)]
    pub(in crate::sim) unsafe fn zero() -> Self {
        let zero = _mm256_setzero_pd();
        Four {
            x: zero,
            y: zero,
            vx: zero,
            vy: zero,
            stuck: zero,
            act: zero,
            slide: zero,
            s2: zero,
            h2: zero,
        }
    }
}

/// What every vector's step takes: one, half the step, the plate's half side and the mask of
/// every bit but the sign.
#[derive(Clone, Copy)]
pub(in crate::sim) struct Consts {
    one: __m256d,
    hdt: __m256d,
    half: __m256d,
    /// The in-plane gravity's velocity a step, x and y ([`super::Lanes::kick`]).
    kx: __m256d,
    ky: __m256d,
    abs: __m256d,
}

impl Consts {
    /// For steps of `dt` on a plate of half side `half`, gravity's in-plane part adding `kick`
    /// to every part's velocity a step.
    #[inline(always)]
    pub(in crate::sim) unsafe fn new(dt: f64, half: f64, kick: [f64; 2]) -> Self {
        Consts {
            kx: _mm256_set1_pd(kick[0]),
            ky: _mm256_set1_pd(kick[1]),
            one: _mm256_set1_pd(1.0),
            hdt: _mm256_set1_pd(0.5 * dt),
            half: _mm256_set1_pd(half),
            abs: _mm256_castsi256_pd(_mm256_set1_epi64x(i64::MAX)),
        }
    }
}

/// Each component of `u` in every lane.
#[inline(always)]
pub(in crate::sim) unsafe fn splat([u1, u2, u3]: [f64; 3]) -> [__m256d; 3] {
    [_mm256_set1_pd(u1), _mm256_set1_pd(u2), _mm256_set1_pd(u3)]
}

/// The exact implicit step of the vector `v` under the plate velocity `[u1, u2, u3]` (each
/// lane's own: [`splat`] for one plate), in place; with a plate edge (`EDGE`) the lanes that
/// leave it are frozen: returns them (all ones; none without an edge).
#[inline(always)]
pub(in crate::sim) unsafe fn step<const EDGE: bool>(
    v: &mut Four,
    [u1, u2, u3]: [__m256d; 3],
    c: &Consts,
) -> __m256d {
    let sx = _mm256_fnmadd_pd(u3, v.y, u1);
    let sy = _mm256_fmadd_pd(u3, v.x, u2);
    let (wx, wy) = (
        _mm256_sub_pd(_mm256_add_pd(v.vx, c.kx), sx),
        _mm256_sub_pd(_mm256_add_pd(v.vy, c.ky), sy),
    );
    let q = _mm256_fmadd_pd(wx, wx, _mm256_mul_pd(wy, wy));
    let stick = _mm256_or_pd(
        _mm256_cmp_pd::<_CMP_LE_OQ>(q, v.s2),
        _mm256_and_pd(v.stuck, _mm256_cmp_pd::<_CMP_LE_OQ>(q, v.h2)),
    );
    let slides = _mm256_andnot_pd(stick, v.act);
    let keep = _mm256_and_pd(slides, _mm256_fnmadd_pd(v.slide, rsqrt(q, slides), c.one));
    let nvx = _mm256_fmadd_pd(wx, keep, sx);
    let nvy = _mm256_fmadd_pd(wy, keep, sy);
    let nx = _mm256_fmadd_pd(_mm256_add_pd(v.vx, nvx), c.hdt, v.x);
    let ny = _mm256_fmadd_pd(_mm256_add_pd(v.vy, nvy), c.hdt, v.y);
    if EDGE {
        let a = v.act;
        v.x = _mm256_blendv_pd(v.x, nx, a);
        v.y = _mm256_blendv_pd(v.y, ny, a);
        v.vx = _mm256_blendv_pd(v.vx, nvx, a);
        v.vy = _mm256_blendv_pd(v.vy, nvy, a);
        v.stuck = _mm256_blendv_pd(v.stuck, stick, a);
        let off = leaving(nx, ny, c.abs, c.half, a);
        v.act = _mm256_andnot_pd(off, a);
        off
    } else {
        (v.x, v.y, v.vx, v.vy, v.stuck) = (nx, ny, nvx, nvy, stick);
        _mm256_setzero_pd()
    }
}
