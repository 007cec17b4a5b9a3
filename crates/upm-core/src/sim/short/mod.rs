//! A short run of point parts in one pass, on the AVX2 and AVX-512 builds: each register tile
//! reads its parts straight from the caller's arrays, records their initial state, steps them
//! through the whole run recording each recorded row as it comes, and writes when they left the
//! plate. No chunk state is built and read back. A chunk otherwise reads its parts into arrays of
//! its own ([`Source::fill`]), records from those, and the kernel loads them, steps and stores
//! them back: a 2-step call spent more on that than on its steps. The operations are those of
//! [`Source::fill`], the kernel's vector step and [`Rec::points_run`], so the results are the
//! same to the bit (tested).

use std::sync::atomic::AtomicBool;
#[cfg(test)]
use std::sync::atomic::Ordering;

use super::record::Rec;
use super::source::Source;
use crate::simd::Simd;

mod avx2;
mod avx512;

/// Set to run every chunk the general way (the tests compare the two).
pub(super) static OFF: AtomicBool = AtomicBool::new(false);

impl Source<'_> {
    /// Runs the points `start .. start + k` in one pass on the vector build `simd` (all the
    /// world's parts are points, in order; the run is one block of the steps `table`, each of
    /// `dt`, on a plate in its plane), in whole vectors, recording through `rec`; returns how
    /// many it ran (a multiple of the vector's width: the rest are the caller's).
    ///
    /// # Safety
    /// The CPU has the build's features; the points are within the source and the result, and
    /// no one else writes their cells.
    pub(super) unsafe fn short(
        &self,
        simd: Simd,
        start: usize,
        k: usize,
        table: &[[f64; 3]],
        dt: f64,
        rec: &Rec,
    ) -> usize {
        let width = match simd {
            Simd::Avx2 => 4,
            Simd::Avx512 => 8,
            Simd::Portable => return 0,
        };
        let end = start + k / width * width;
        match (simd, self.half.is_finite()) {
            (Simd::Avx512, true) => avx512::tiles::<true>(self, start, end, table, dt, rec),
            (Simd::Avx512, false) => avx512::tiles::<false>(self, start, end, table, dt, rec),
            (_, true) => self.tiles::<true>(start, end, table, dt, rec),
            (_, false) => self.tiles::<false>(start, end, table, dt, rec),
        }
        // (the AVX-512 build streams a large result)
        rec.fence();
        end - start
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
        if crate::simd::simd() == crate::simd::Simd::Portable {
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
        for n in [
            1, 3, 4, 5, 8, 9, 13, 16, 31, 32, 33, 64, 67, 72, 256, 259, 600, 300_001, 300_002,
            300_003,
        ] {
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
                            surface: None,
                        };
                        let steps = if big { 2 } else { 50 };
                        let cfg = Config {
                            dt,
                            duration: steps as f64 * dt,
                            g: 9.81,
                            plate_size,
                            record_every: every,
                            tilt: [0.0; 2],
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
            surface: None,
        };
        let cfg = Config {
            dt: 1e-4,
            duration: 2e-4,
            g: 9.81,
            plate_size: None,
            record_every: 1,
            tilt: [0.0; 2],
        };
        let err = run(&rest, &parts, &cfg).unwrap_err();
        assert!(err.to_string().contains("17"), "{err}");
    }
}
