//! A short run of point parts in one pass, on the AVX2 build: each register tile reads its parts
//! straight from the caller's arrays, records their initial state, steps them through the whole
//! run recording each recorded row as it comes, and writes when they left the plate. No chunk
//! state is built and read back. A chunk otherwise reads its parts into arrays of its own
//! ([`Source::fill`]), records from those, and the kernel loads them, steps and stores them back:
//! a 2-step call spent more on that than on its steps. The operations are those of
//! [`Source::fill`], the kernel's [`step`] and [`Rec::points_run`], so the results are the same
//! to the bit (tested).

use std::arch::x86_64::*;
use std::sync::atomic::{AtomicBool, Ordering};

use super::kernel::avx2::{leaving, step, Consts, Four};
use super::kernel::NEVER;
use super::points::Source;
use super::record::{cells, left_times, Rec, FLAG_BYTES};

/// Set to run every chunk the general way (the tests compare the two).
pub(super) static OFF: AtomicBool = AtomicBool::new(false);

impl Source<'_> {
    /// Runs the points `start .. start + k` (all the world's parts are points, in order; the run
    /// is one block of the steps `table`, each of `dt`, on a plate in its plane), in whole
    /// vectors of four, recording through `rec`; returns how many it ran (a multiple of four:
    /// the rest, fewer than four, are the caller's).
    ///
    /// # Safety
    /// The CPU has AVX2 and FMA; the points are within the source and the result, and no one
    /// else writes their cells.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn short(
        &self,
        start: usize,
        k: usize,
        table: &[[f64; 3]],
        dt: f64,
        rec: &Rec,
    ) -> usize {
        let end = start + k / 4 * 4;
        if self.half.is_finite() {
            self.tiles::<true>(start, end, table, dt, rec);
        } else {
            self.tiles::<false>(start, end, table, dt, rec);
        }
        end - start
    }

    /// The points `start .. end` (whole vectors) in tiles of up to eight vectors.
    #[target_feature(enable = "avx2,fma")]
    unsafe fn tiles<const EDGE: bool>(
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
        let c = Consts::new(dt, self.half);
        let mut next = rec.next_after(0);
        for (k, &u) in table.iter().enumerate() {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::PlateMotion;
    use crate::sim::{simulate_stacked, Config, PartsView, Stacked};
    use crate::waveform::{Harmonics, Waveform};

    fn run(motion: &PlateMotion, parts: &PartsView, cfg: &Config) -> crate::Result<Stacked> {
        simulate_stacked::<crate::Error, _>(
            std::slice::from_ref(motion),
            parts,
            cfg,
            None,
            None,
            |_| Ok(()),
        )
    }

    /// The one-pass run records what the general one records, to the bit: every remainder of
    /// the tiles and of the vectors, a plate edge that parts leave (some start off it) or none,
    /// parts at rest or moving (some with the plate surface: they start stuck), friction per
    /// part or one value, rows recorded every step, every third step or only at the end, and a
    /// result large enough to be streamed to memory.
    #[test]
    fn one_pass_records_what_the_general_run_records() {
        if crate::sim::kernel::simd() != crate::sim::kernel::Simd::Avx2 {
            return;
        }
        let f = 35.0;
        // (moving at the start: a part moving with the plate surface has a velocity to match)
        let rot = PlateMotion::rotation(
            [0.03, -0.02],
            Waveform::Harmonics(Harmonics::new(vec![0.3, 0.1], vec![0.5, -0.25], f).unwrap()),
        )
        .unwrap();
        let dt = 1.0 / f / 400.0;
        let u0 = rot.velocity(0.0);
        let mut cases = 0;
        for n in [1, 3, 4, 5, 8, 13, 31, 32, 33, 67, 256, 259, 600, 300_001] {
            let r = crate::sim::kernel::noise(n as u64, 5 * n);
            let position: Vec<[f64; 2]> = (0..n).map(|i| [0.12 * r[i], 0.12 * r[n + i]]).collect();
            let moving: Vec<[f64; 2]> = (0..n)
                .map(|i| match i % 5 {
                    0 => {
                        let [x, y] = position[i];
                        [u0[0] - u0[2] * y, u0[1] + u0[2] * x]
                    }
                    _ => [3.0 * r[2 * n + i], 3.0 * r[3 * n + i]],
                })
                .collect();
            let mu: Vec<f64> = (0..n).map(|i| 0.3 + 0.1 * r[4 * n + i]).collect();
            let mu_s: Vec<f64> = mu.iter().map(|m| m + 0.05).collect();
            let big = n > 1000;
            for (velocity, per_part) in [(None, false), (Some(&moving[..]), true)] {
                for plate_size in [None, Some(0.2)] {
                    for every in if big { vec![2] } else { vec![1, 3, 50] } {
                        let parts = PartsView {
                            position: &position,
                            velocity,
                            mu: if per_part { &mu } else { &[0.3] },
                            mu_s: if per_part { &mu_s } else { &[0.4] },
                            radius: None,
                            angle: None,
                            spin: None,
                            polygons: &[],
                        };
                        let steps = if big { 2 } else { 50 };
                        let cfg = Config {
                            dt,
                            duration: steps as f64 * dt,
                            g: 9.81,
                            plate_size,
                            record_every: every,
                        };
                        OFF.store(true, Ordering::Relaxed);
                        let general = run(&rot, &parts, &cfg).unwrap();
                        OFF.store(false, Ordering::Relaxed);
                        let one = run(&rot, &parts, &cfg).unwrap();
                        let what =
                            format!("n {n} every {every} plate {plate_size:?} moving {per_part}");
                        let bits = |a: &[[f64; 2]]| {
                            a.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>()
                        };
                        assert_eq!(bits(&one.positions), bits(&general.positions), "{what}");
                        assert_eq!(bits(&one.velocities), bits(&general.velocities), "{what}");
                        assert_eq!(one.stuck, general.stuck, "{what}");
                        let times =
                            |s: &Stacked| s.left.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                        assert_eq!(times(&one), times(&general), "{what}");
                        assert_eq!(one.left_plate, general.left_plate, "{what}");
                        assert_eq!(one.t, general.t, "{what}");
                        if per_part && n > 30 {
                            // (the parts moving with the plate start stuck)
                            assert!(one.stuck[..n].iter().any(|&s| s), "{what}");
                        }
                        if plate_size.is_some() && n > 30 {
                            // (some parts start off the plate, some moving ones leave it)
                            assert!(one.left.contains(&0.0), "{what}");
                            if per_part && n >= 256 && !big {
                                assert!(one.left.iter().any(|&t| t > 0.0), "{what}");
                            }
                        }
                        cases += 1;
                    }
                }
            }
        }
        assert!(cases > 100);
    }

    /// A part whose position is not a number is reported, as by the general run.
    #[test]
    fn one_pass_reports_a_position_that_is_not_a_number() {
        let rest = PlateMotion::rest(1.0).unwrap();
        let mut position = vec![[0.01, 0.02]; 40];
        position[17] = [f64::NAN, 0.0];
        let parts = PartsView {
            position: &position,
            velocity: None,
            mu: &[0.3],
            mu_s: &[0.3],
            radius: None,
            angle: None,
            spin: None,
            polygons: &[],
        };
        let cfg = Config {
            dt: 1e-4,
            duration: 2e-4,
            g: 9.81,
            plate_size: None,
            record_every: 1,
        };
        let err = run(&rest, &parts, &cfg).unwrap_err();
        assert!(err.to_string().contains("17"), "{err}");
    }
}
