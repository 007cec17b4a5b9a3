//! The AVX-512 build of [`super::run`]: eight parts per instruction, tiles of [`TILE`] vectors
//! held in registers through every step of a segment, stick flags and plate-edge flags in mask
//! registers, and `1/|w|` from `vrsqrt14pd` refined in double precision (no square root, no
//! division; see [`rsqrt`]).

use std::arch::x86_64::*;

use super::{Lanes, Plate};
use crate::motion::Sample;

/// Vectors (of eight parts) per register tile: 64 parts whose steps are independent, enough to
/// hide the step's long dependency chain (about 60 cycles). 8 measured best of 2, 4, 6, 8 and 12
/// on an Intel Xeon; what does not fit in the 32 registers is re-read from L1.
const TILE: usize = 8;

/// The vectors the next tile takes when `left` remain: a full tile, but the last ones in the
/// narrowest tile that holds them (a world of a few parts does not pay for a full tile), split
/// in two tiles of at least four when fewer than twelve remain (so no tile of one or two vectors
/// waits on its own step's latency behind full ones: 1000 parts were 15 tiles of eight, one of
/// four and one of one).
pub(in crate::sim) fn tile_width(left: usize) -> usize {
    if left <= TILE || left >= TILE + 4 {
        left.min(TILE)
    } else {
        left.div_ceil(2)
    }
}

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
        let vectors = tile_width((n - start).div_ceil(8));
        start += 8 * match vectors {
            1 => tile::<EDGE, WORLDS, 1>(plate, first, dt, half, s, start),
            2 => tile::<EDGE, WORLDS, 2>(plate, first, dt, half, s, start),
            3 => tile::<EDGE, WORLDS, 3>(plate, first, dt, half, s, start),
            4 => tile::<EDGE, WORLDS, 4>(plate, first, dt, half, s, start),
            5 => tile::<EDGE, WORLDS, 5>(plate, first, dt, half, s, start),
            6 => tile::<EDGE, WORLDS, 6>(plate, first, dt, half, s, start),
            7 => tile::<EDGE, WORLDS, 7>(plate, first, dt, half, s, start),
            _ => tile::<EDGE, WORLDS, TILE>(plate, first, dt, half, s, start),
        };
    }
}

/// One tile of `T` vectors: the parts `start .. start + 8 T` (fewer at the end) through every
/// step of `plate`; returns `T`.
#[target_feature(enable = "avx512f")]
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
    let zero = _mm512_setzero_pd();
    let one = _mm512_set1_pd(1.0);
    let mut live = [0 as __mmask8; T];
    for (j, l) in live.iter_mut().enumerate() {
        let lo = start + 8 * j;
        *l = if lo < n { first_lanes(n - lo) } else { 0 };
    }
    let at = |j: usize| start + 8 * j;
    let c = Consts::new(dt, half, s.kick);
    let mut v = [Eight::zero(); T];
    for (j, v) in v.iter_mut().enumerate() {
        let k = live[j];
        let load = |a: &[f64]| _mm512_maskz_loadu_pd(k, a.as_ptr().add(at(j)));
        let (slide, hold) = (load(s.slide), load(s.hold));
        *v = Eight {
            x: load(s.x),
            y: load(s.y),
            vx: load(s.vx),
            vy: load(s.vy),
            stuck: _mm512_cmp_pd_mask::<_CMP_GT_OQ>(load(s.stuck), zero),
            act: if EDGE {
                _mm512_cmp_pd_mask::<_CMP_GT_OQ>(load(s.active), zero)
            } else {
                k
            },
            slide,
            s2: _mm512_mul_pd(slide, slide),
            h2: _mm512_mul_pd(hold, hold),
        };
    }
    // Each vector's first column (one table for all, or its first world's: it reads eight), and
    // the table's width: the constant 1 for one table, so that its loads are the table's own.
    let width = if WORLDS { plate.width() } else { 1 };
    let mut cols = [0; T];
    if WORLDS {
        for (j, col) in cols.iter_mut().enumerate() {
            // (a vector past the parts holds none: it reads the first columns)
            *col = if at(j) < n { plate.column(at(j)) } else { 0 };
            assert!(*col + 8 <= width, "a vector's columns within the table");
        }
    }
    // Every step of every vector under the velocity `u`: of vector `j` at step `k` (`each`), or
    // of the whole tile at step `k` (`tile`: evaluated once a step, before its vectors).
    macro_rules! steps {
        (each $j:ident, $k:ident => $u:expr) => {
            for $k in 0..plate.steps() {
                for $j in 0..T {
                    let off = step::<EDGE>(&mut v[$j], $u, &c);
                    if EDGE && off != 0 {
                        mark_left(off, s.left, at($j), first + $k + 1);
                    }
                }
            }
        };
        (tile $k:ident => $u:expr) => {
            for $k in 0..plate.steps() {
                let u = $u;
                for j in 0..T {
                    let off = step::<EDGE>(&mut v[j], u, &c);
                    if EDGE && off != 0 {
                        mark_left(off, s.left, at(j), first + $k + 1);
                    }
                }
            }
        };
    }
    // SAFETY (of each `cell`): k < steps, and every vector's columns are within the width,
    // which is the plate's (checked above).
    if !WORLDS {
        steps!(tile k => splat(plate.at(1, 0, k)));
    } else if let Some(jets) = plate.jets_of() {
        // Each vector's set of eight worlds (its lanes), whose velocity a step serves it.
        let sets: [usize; T] = std::array::from_fn(|j| cols[j] / 8);
        assert!(
            sets.iter().all(|&g| g < jets.coef.len()),
            "a vector's set within the jets"
        );
        // (g is one of `sets`: within the coefficients, checked)
        let load = |g: usize| (jets.coef.get_unchecked(g)).map(|c| _mm512_loadu_pd(c.as_ptr()));
        if sets.iter().all(|&g| g == sets[0]) {
            // one set: one velocity a step serves the tile (t < steps = the samples)
            let coef = load(sets[0]);
            steps!(tile t => jet(coef, jets.samples.get_unchecked(t)));
        } else {
            // several: each set's velocity evaluated a step before its vectors (a run of them;
            // `v` indexed only by the tile's loop, which the compiler unrolls, so that it may
            // keep the vectors in registers: indexed at run time, it kept them in memory for
            // every loop of the tile, and worlds of 5 points cost 1.35x one world a part-step
            // instead of 1.1x)
            for (t, p) in jets.samples.iter().enumerate() {
                let mut u = jet(load(sets[0]), p);
                for j in 0..T {
                    if j > 0 && sets[j] != sets[j - 1] {
                        u = jet(load(sets[j]), p);
                    }
                    let off = step::<EDGE>(&mut v[j], u, &c);
                    if EDGE && off != 0 {
                        mark_left(off, s.left, at(j), first + t + 1);
                    }
                }
            }
        }
    } else if cols.iter().all(|&c| c == cols[0]) {
        // (every vector reads the same eight worlds: one load a component serves the tile)
        steps!(tile k => columns(plate.cell(width, cols[0], k), width));
    } else {
        steps!(each j, k => columns(plate.cell(width, cols[j], k), width));
    }
    for (j, v) in v.iter().enumerate() {
        let k = live[j];
        let store =
            |a: &mut [f64], x: __m512d| _mm512_mask_storeu_pd(a.as_mut_ptr().add(at(j)), k, x);
        store(s.x, v.x);
        store(s.y, v.y);
        store(s.vx, v.vx);
        store(s.vy, v.vy);
        store(s.stuck, _mm512_maskz_mov_pd(v.stuck, one));
        if EDGE {
            store(s.active, _mm512_maskz_mov_pd(v.act, one));
        }
    }
    T
}

/// The velocity of eight worlds' jets (coefficients `[k, ax, ay, cx, cy]` lane by lane) at the
/// sample `p`: `jet`'s operations in its order, so the table's bits.
#[inline(always)]
unsafe fn jet([k, ax, ay, cx, cy]: [__m512d; 5], p: &Sample) -> [__m512d; 3] {
    let g = _mm512_set1_pd(p.feed);
    let w = _mm512_mul_pd(k, _mm512_set1_pd(p.spin));
    [
        _mm512_add_pd(_mm512_mul_pd(ax, g), _mm512_mul_pd(w, cy)),
        _mm512_sub_pd(_mm512_mul_pd(ay, g), _mm512_mul_pd(w, cx)),
        w,
    ]
}

/// One vector of eight parts through the steps, as the tiles hold it: position, velocity, the
/// stuck and the active lanes (mask bits), and the friction thresholds (`mu g dt`, its square
/// and the square of `mu_s g dt`).
#[derive(Clone, Copy)]
pub(in crate::sim) struct Eight {
    pub x: __m512d,
    pub y: __m512d,
    pub vx: __m512d,
    pub vy: __m512d,
    pub stuck: __mmask8,
    pub act: __mmask8,
    pub slide: __m512d,
    pub s2: __m512d,
    pub h2: __m512d,
}

impl Eight {
    /// Every lane zero.
    ///
    /// # Safety
    /// The CPU has AVX-512F.
    #[inline(always)]
    pub(in crate::sim) unsafe fn zero() -> Self {
        let zero = _mm512_setzero_pd();
        Eight {
            x: zero,
            y: zero,
            vx: zero,
            vy: zero,
            stuck: 0,
            act: 0,
            slide: zero,
            s2: zero,
            h2: zero,
        }
    }
}

/// What every vector's step takes: one, half the step and the plate's half side.
#[derive(Clone, Copy)]
pub(in crate::sim) struct Consts {
    one: __m512d,
    hdt: __m512d,
    half: __m512d,
    /// The in-plane gravity's velocity a step, x and y ([`super::Lanes::kick`]).
    kx: __m512d,
    ky: __m512d,
}

impl Consts {
    /// For steps of `dt` on a plate of half side `half`, gravity's in-plane part adding `kick`
    /// to every part's velocity a step.
    #[inline(always)]
    pub(in crate::sim) unsafe fn new(dt: f64, half: f64, kick: [f64; 2]) -> Self {
        Consts {
            kx: _mm512_set1_pd(kick[0]),
            ky: _mm512_set1_pd(kick[1]),
            one: _mm512_set1_pd(1.0),
            hdt: _mm512_set1_pd(0.5 * dt),
            half: _mm512_set1_pd(half),
        }
    }
}

/// The lanes of `active` whose position `(x, y)` is past the plate's half side `half` in x or y.
#[inline(always)]
pub(in crate::sim) unsafe fn leaving(
    x: __m512d,
    y: __m512d,
    half: __m512d,
    active: __mmask8,
) -> __mmask8 {
    (_mm512_cmp_pd_mask::<_CMP_GT_OQ>(_mm512_abs_pd(x), half)
        | _mm512_cmp_pd_mask::<_CMP_GT_OQ>(_mm512_abs_pd(y), half))
        & active
}

/// Each component of `u` in every lane.
#[inline(always)]
pub(in crate::sim) unsafe fn splat([u1, u2, u3]: [f64; 3]) -> [__m512d; 3] {
    [_mm512_set1_pd(u1), _mm512_set1_pd(u2), _mm512_set1_pd(u3)]
}

/// The three components of eight neighbouring columns from component 0's at `p`, in a table
/// of `width` columns.
#[inline(always)]
unsafe fn columns(p: *const f64, width: usize) -> [__m512d; 3] {
    [
        _mm512_loadu_pd(p),
        _mm512_loadu_pd(p.add(width)),
        _mm512_loadu_pd(p.add(2 * width)),
    ]
}

/// The exact implicit step of the vector `v` under the plate velocity `[u1, u2, u3]` (each
/// lane's own: [`splat`] for one plate), in place; with a plate edge (`EDGE`) the lanes that
/// leave it are frozen: returns them (none without an edge).
#[inline(always)]
pub(in crate::sim) unsafe fn step<const EDGE: bool>(
    v: &mut Eight,
    [u1, u2, u3]: [__m512d; 3],
    c: &Consts,
) -> __mmask8 {
    let sx = _mm512_fnmadd_pd(u3, v.y, u1);
    let sy = _mm512_fmadd_pd(u3, v.x, u2);
    let (wx, wy) = (
        _mm512_sub_pd(_mm512_add_pd(v.vx, c.kx), sx),
        _mm512_sub_pd(_mm512_add_pd(v.vy, c.ky), sy),
    );
    let q = _mm512_fmadd_pd(wx, wx, _mm512_mul_pd(wy, wy));
    // |w| <= mu g dt, or stuck and |w| <= mu_s g dt, compared squared.
    let stick = _mm512_cmp_pd_mask::<_CMP_LE_OQ>(q, v.s2)
        | (v.stuck & _mm512_cmp_pd_mask::<_CMP_LE_OQ>(q, v.h2));
    // Sliding parts keep the share 1 - mu g dt / |w| of w; stuck ones none.
    let keep = _mm512_maskz_fnmadd_pd(!stick, v.slide, rsqrt(q), c.one);
    let nvx = _mm512_fmadd_pd(wx, keep, sx);
    let nvy = _mm512_fmadd_pd(wy, keep, sy);
    let nx = _mm512_fmadd_pd(_mm512_add_pd(v.vx, nvx), c.hdt, v.x);
    let ny = _mm512_fmadd_pd(_mm512_add_pd(v.vy, nvy), c.hdt, v.y);
    if EDGE {
        // Parts that left the plate keep their state.
        let a = v.act;
        v.x = _mm512_mask_mov_pd(v.x, a, nx);
        v.y = _mm512_mask_mov_pd(v.y, a, ny);
        v.vx = _mm512_mask_mov_pd(v.vx, a, nvx);
        v.vy = _mm512_mask_mov_pd(v.vy, a, nvy);
        v.stuck = (stick & a) | (v.stuck & !a);
        let off = leaving(nx, ny, c.half, a);
        v.act = a & !off;
        off
    } else {
        (v.x, v.y, v.vx, v.vy, v.stuck) = (nx, ny, nvx, nvy, stick);
        0
    }
}
