//! The one-pass short run on the AVX2 build: tiles of up to eight vectors of four points (see
//! [`super`]), the kernel's [`step`], plain stores.

use std::arch::x86_64::*;
use std::sync::atomic::Ordering;

use crate::sim::kernel::avx2::{leaving, splat, step, Consts, Four};
use crate::sim::kernel::NEVER;
use crate::sim::record::{cells, left_times, Rec, FLAG_BYTES};
use crate::sim::source::Source;

impl Source<'_> {
    /// The points `start .. end` (whole vectors of four) in tiles of up to eight vectors.
    ///
    /// # Safety
    /// As [`Source::short`], on a CPU with AVX2 and FMA.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn tiles<const EDGE: bool>(
        &self,
        start: usize,
        end: usize,
        table: &[[f64; 3]],
        dt: f64,
        rec: &Rec,
    ) {
        let mut at = start;
        while at < end {
            at += 4 * match (end - at) / 4 {
                1 => self.tile::<EDGE, 1>(at, table, dt, rec),
                2 | 3 => self.tile::<EDGE, 2>(at, table, dt, rec),
                4..=7 => self.tile::<EDGE, 4>(at, table, dt, rec),
                _ => self.tile::<EDGE, 8>(at, table, dt, rec),
            };
        }
    }

    /// One tile of `T` vectors: the points `at .. at + 4 T`, read, recorded and stepped; returns
    /// `T`.
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    unsafe fn tile<const EDGE: bool, const T: usize>(
        &self,
        at: usize,
        table: &[[f64; 3]],
        dt: f64,
        rec: &Rec,
    ) -> usize {
        let p = &self.parts;
        let zero = _mm256_setzero_pd();
        let ones = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
        let abs = _mm256_castsi256_pd(_mm256_set1_epi64x(i64::MAX));
        let [u1, u2, u3] = self.u0.map(|u| _mm256_set1_pd(u));
        let (half, scale) = (_mm256_set1_pd(self.half), _mm256_set1_pd(self.scale));
        let never = _mm256_set1_pd(NEVER);
        // each lane's step count when it left the plate (NEVER: it did not)
        let mut left = [never; T];
        let mut finite = ones;
        // (written in place: an array zeroed first cost a call to memset a tile, one built
        // elsewhere a call to memcpy)
        let mut place = std::mem::MaybeUninit::<[Four; T]>::uninit();
        for (j, left) in left.iter_mut().enumerate() {
            let i = at + 4 * j;
            let (x, y) = split(p.position.as_ptr().add(i));
            let (vx, vy) = p
                .velocity
                .map_or((zero, zero), |w| split(w.as_ptr().add(i)));
            for a in [x, y, vx, vy] {
                let ok = _mm256_cmp_pd::<_CMP_EQ_OQ>(_mm256_sub_pd(a, a), zero);
                finite = _mm256_and_pd(finite, ok);
            }
            // a part that starts moving with the plate surface starts stuck (`moves_with_plate`:
            // a product and a difference, not fused)
            let sx = _mm256_sub_pd(u1, _mm256_mul_pd(u3, y));
            let sy = _mm256_add_pd(u2, _mm256_mul_pd(u3, x));
            let stuck = _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_EQ_OQ>(vx, sx),
                _mm256_cmp_pd::<_CMP_EQ_OQ>(vy, sy),
            );
            // one off the plate at the start has left it at step 0 (`off_plate`)
            let off = leaving(x, y, abs, half, ones);
            *left = _mm256_blendv_pd(never, zero, off);
            let each = |a: &[f64]| {
                if a.len() == 1 {
                    _mm256_set1_pd(a[0])
                } else {
                    _mm256_loadu_pd(a.as_ptr().add(i))
                }
            };
            let (slide, hold) = (
                _mm256_mul_pd(each(p.mu), scale),
                _mm256_mul_pd(each(p.mu_s), scale),
            );
            let four = Four {
                x,
                y,
                vx,
                vy,
                stuck,
                act: _mm256_andnot_pd(off, ones),
                slide,
                s2: _mm256_mul_pd(slide, slide),
                h2: _mm256_mul_pd(hold, hold),
            };
            place.as_mut_ptr().cast::<Four>().add(j).write(four);
        }
        // SAFETY: each of the T vectors was written just now.
        let v = &mut *place.as_mut_ptr();
        if _mm256_movemask_pd(finite) != 0b1111 {
            self.not_finite.store(true, Ordering::Relaxed);
        }
        record(rec, 0, at, v);
        let c = Consts::new(dt, self.half, self.kick);
        let mut next = rec.next_after(0);
        for (k, &u) in table.iter().enumerate() {
            let u = splat(u);
            for j in 0..T {
                let off = step::<EDGE>(&mut v[j], u, &c);
                if EDGE {
                    left[j] = _mm256_blendv_pd(left[j], _mm256_set1_pd((k + 1) as f64), off);
                }
            }
            if k + 1 == next {
                if let Some(row) = rec.row(k + 1) {
                    record(rec, row, at, v);
                }
                next = rec.next_after(k + 1);
            }
        }
        // when each left (`left_time`: the step count times dt, NaN: never), and whether it did
        let (times, gone) = rec.left_cells(at);
        for (j, &l) in left.iter().enumerate() {
            let [t, did] = left_times(l, dt);
            // (plain stores: non-temporal ones in 16-byte halves, a world's times being only
            // 8-byte aligned, made a 2-step call 15 % slower)
            _mm256_storeu_pd(times.add(4 * j), t);
            flags(gone.add(4 * j), did);
        }
        T
    }
}

/// The x and y of the four pairs at `p` (`[x0, y0, x1, y1, x2, y2, x3, y3]`).
#[inline(always)]
unsafe fn split(p: *const [f64; 2]) -> (__m256d, __m256d) {
    let (a, b) = (_mm256_loadu_pd(p.cast()), _mm256_loadu_pd(p.add(2).cast()));
    // (x0 x2 x1 x3) and (y0 y2 y1 y3), then in order
    let (x, y) = (_mm256_unpacklo_pd(a, b), _mm256_unpackhi_pd(a, b));
    (
        _mm256_permute4x64_pd::<0b11_01_10_00>(x),
        _mm256_permute4x64_pd::<0b11_01_10_00>(y),
    )
}

/// The four lanes set in `mask` as four bools at `out`.
#[inline(always)]
unsafe fn flags(out: *mut bool, mask: __m256d) {
    // (four flags: the low four bytes of eight's)
    let word = FLAG_BYTES[_mm256_movemask_pd(mask) as usize] as u32;
    out.cast::<u32>().write_unaligned(word);
}

/// Writes the vectors' positions, velocities and stuck flags into `row` for the parts `at ..`,
/// with plain stores: non-temporal ones, in the short bursts a tile writes (two rows of two
/// arrays, and the flags), made a 2-step call on 1e6 parts 1.3x slower on AMD Zen 3 (11.1–11.7
/// against 8.6–8.9 ns per part, alternating runs).
#[inline(always)]
unsafe fn record<const T: usize>(rec: &Rec, row: usize, at: usize, v: &[Four; T]) {
    let (pos, vel, stuck) = rec.row_cells(row, at);
    pairs(pos, v.map(|f| [f.x, f.y]));
    pairs(vel, v.map(|f| [f.vx, f.vy]));
    for (j, f) in v.iter().enumerate() {
        flags(stuck.add(4 * j), f.stuck);
    }
}

/// `out[q] = (a, b)` of lane `q % 4` of vector `q / 4` for the `4 T` cells at `out`.
#[inline(always)]
unsafe fn pairs<const T: usize>(out: *mut [f64; 2], ab: [[__m256d; 2]; T]) {
    for (j, [a, b]) in ab.into_iter().enumerate() {
        let [c01, c23] = cells(a, b);
        _mm256_storeu_pd(out.add(4 * j).cast(), c01);
        _mm256_storeu_pd(out.add(4 * j + 2).cast(), c23);
    }
}
