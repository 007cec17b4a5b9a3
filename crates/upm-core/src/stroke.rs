//! The largest plate-corner excursion of many pulses at once (the predictive planner sizes a few
//! hundred candidates a cycle against the stroke).
//!
//! A pulse's pose is linear in its wrench phasors: each axis `a` (x, y, rotation) moves as
//! `pose_a(t) = sum_h Re(W[h, a] g[h, a](t))`, where `g[h, a]` is the enveloped response of axis
//! `a` to a unit phasor of harmonic `h` (sampled once per envelope and frequency by the caller,
//! `upm.drive`). The corners then move rigidly: a corner `k` goes to `R(theta) k + (x, y)`. Here
//! each pulse's pose is formed sample by sample and the farthest corner tracked, without storing
//! the pose; `cos` and `sin` of the small plate angles come from their Taylor series (to
//! `theta^8` and `theta^9`: below `1e-10` of the corner's distance for `|theta| <= 0.2`), and a
//! pulse that turns the plate further is evaluated again with `sin_cos`.

use rayon::prelude::*;

use crate::error::{Error, Result};

/// Harmonics and axes of a wrench phasor.
const H: usize = 3;
const A: usize = 3;
/// Plate angles up to this [rad] use the series.
const SERIES: f64 = 0.2;

/// The unit responses `g[h, a](t)`, real and imaginary parts, each `(3, 3, T)` row-major.
pub struct Responses<'a> {
    /// Real parts.
    pub re: &'a [f64],
    /// Imaginary parts.
    pub im: &'a [f64],
    /// Samples `T` per response.
    pub samples: usize,
}

/// `(cos theta - 1, sin theta)` by their series (see the module docs).
#[inline(always)]
fn turn(theta: f64) -> (f64, f64) {
    let t2 = theta * theta;
    let cm1 = t2 * (-0.5 + t2 * (1.0 / 24.0 + t2 * (-1.0 / 720.0 + t2 * (1.0 / 40320.0))));
    let s = theta
        * (1.0 + t2 * (-1.0 / 6.0 + t2 * (1.0 / 120.0 + t2 * (-1.0 / 5040.0 + t2 / 362880.0))));
    (cm1, s)
}

/// Samples in flight at once in the series path.
const LANES: usize = 8;

/// Largest squared distance of a corner from home when the plate is at `(x, y)`, turned by
/// `theta` (`cm1 = cos theta - 1`, `sn = sin theta`).
#[inline(always)]
fn corner_max(cm1: f64, sn: f64, x: f64, y: f64, corners: &[[f64; 2]]) -> f64 {
    let mut best = 0.0f64;
    for &[kx, ky] in corners {
        let dx = cm1 * kx - sn * ky + x;
        let dy = sn * kx + cm1 * ky + y;
        let d2 = dx * dx + dy * dy;
        best = if d2 > best { d2 } else { best };
    }
    best
}

/// Samples per block of the pose, formed axis by axis over contiguous samples (vectorised).
const BLOCK: usize = 256;

/// Largest squared corner distance of one pulse whose wrench phasors are `(wr, wi)` (`[h][a]`),
/// and the largest `|theta|` met.
fn farthest(
    wr: &[f64],
    wi: &[f64],
    g: &Responses,
    corners: &[[f64; 2]],
    exact: bool,
) -> (f64, f64) {
    let t = g.samples;
    let (mut best, mut widest) = (0.0f64, 0.0f64);
    let mut pose = [[0.0; BLOCK]; A];
    let mut start = 0;
    while start < t {
        let len = BLOCK.min(t - start);
        for (a, p) in pose.iter_mut().enumerate() {
            let p = &mut p[..len];
            p.fill(0.0);
            for h in 0..H {
                let k = (h * A + a) * t + start;
                let (re, im) = (&g.re[k..k + len], &g.im[k..k + len]);
                let (cr, ci) = (wr[h * A + a], wi[h * A + a]);
                for ((v, r), i) in p.iter_mut().zip(re).zip(im) {
                    *v += cr * r - ci * i;
                }
            }
        }
        let [x, y, theta] = &pose;
        if exact {
            for s in 0..len {
                widest = widest.max(theta[s].abs());
                let (sn, c) = theta[s].sin_cos();
                best = best.max(corner_max(c - 1.0, sn, x[s], y[s], corners));
            }
        } else {
            // in lanes, so that the series and the corners vectorise
            let mut far = [0.0f64; LANES];
            let mut wide = [0.0f64; LANES];
            let whole = len / LANES * LANES;
            for s0 in (0..whole).step_by(LANES) {
                for l in 0..LANES {
                    let s = s0 + l;
                    let (cm1, sn) = turn(theta[s]);
                    let (w, f) = (theta[s].abs(), corner_max(cm1, sn, x[s], y[s], corners));
                    wide[l] = if w > wide[l] { w } else { wide[l] };
                    far[l] = if f > far[l] { f } else { far[l] };
                }
            }
            for s in whole..len {
                let (cm1, sn) = turn(theta[s]);
                widest = widest.max(theta[s].abs());
                best = best.max(corner_max(cm1, sn, x[s], y[s], corners));
            }
            best = far.iter().fold(best, |m, &v| m.max(v));
            widest = wide.iter().fold(widest, |m, &v| m.max(v));
        }
        start += len;
    }
    (best, widest)
}

/// Largest distance [m] any of `corners` moves from home under each of `n` pulses, whose wrench
/// phasors are `w_re`, `w_im` (`(n, 3, 3)` row-major: pulse, harmonic, axis), through the unit
/// responses `g`. In parallel over the pulses; each result depends on its pulse alone.
pub fn corner_excursions(
    w_re: &[f64],
    w_im: &[f64],
    g: &Responses,
    corners: &[[f64; 2]],
) -> Result<Vec<f64>> {
    if w_re.len() != w_im.len() || !w_re.len().is_multiple_of(H * A) {
        return Err(Error::parameter(
            "wrench",
            format!(
                "real and imaginary parts must both hold (n, 3, 3) values; got {} and {}",
                w_re.len(),
                w_im.len()
            ),
        ));
    }
    let cells = H * A * g.samples;
    if g.samples == 0 || g.re.len() != cells || g.im.len() != cells {
        return Err(Error::parameter(
            "responses",
            format!(
                "real and imaginary parts must both hold (3, 3, {}) values; got {} and {}",
                g.samples,
                g.re.len(),
                g.im.len()
            ),
        ));
    }
    if let Some(bad) = w_re
        .iter()
        .chain(w_im)
        .chain(g.re)
        .chain(g.im)
        .chain(corners.iter().flatten())
        .find(|v| !v.is_finite())
    {
        return Err(Error::parameter(
            "wrench, responses, corners",
            format!("must be finite; got {bad}"),
        ));
    }
    Ok(w_re
        .par_chunks(H * A)
        .zip(w_im.par_chunks(H * A))
        .with_min_len(8)
        .map(|(wr, wi)| {
            let (best, widest) = farthest(wr, wi, g, corners, false);
            let best = if widest > SERIES {
                farthest(wr, wi, g, corners, true).0
            } else {
                best
            };
            best.sqrt()
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The same excursion from the pose written out in full, with `sin_cos` everywhere.
    fn direct(wr: &[f64], wi: &[f64], g: &Responses, corners: &[[f64; 2]]) -> f64 {
        let t = g.samples;
        let mut best = 0.0f64;
        for s in 0..t {
            let pose: Vec<f64> = (0..A)
                .map(|a| {
                    (0..H)
                        .map(|h| {
                            let k = (h * A + a) * t + s;
                            wr[h * A + a] * g.re[k] - wi[h * A + a] * g.im[k]
                        })
                        .sum()
                })
                .collect();
            let (sn, c) = pose[2].sin_cos();
            for &[kx, ky] in corners {
                let px = c * kx - sn * ky + pose[0];
                let py = sn * kx + c * ky + pose[1];
                best = best.max((px - kx).hypot(py - ky));
            }
        }
        best
    }

    fn responses(samples: usize) -> (Vec<f64>, Vec<f64>) {
        let cells = H * A * samples;
        let re = (0..cells).map(|i| (0.37 * i as f64).sin() * 1e-3).collect();
        let im = (0..cells).map(|i| (0.23 * i as f64).cos() * 1e-3).collect();
        (re, im)
    }

    #[test]
    fn matches_the_direct_evaluation_small_and_large_angles() {
        let samples = 257;
        let (re, im) = responses(samples);
        let g = Responses {
            re: &re,
            im: &im,
            samples,
        };
        let corners = [[-0.2, -0.2], [0.2, -0.2], [0.2, 0.2], [-0.2, 0.2]];
        let n = 40;
        // amplitudes from small (angles of a milliradian) to large (beyond the series' range)
        let w_re: Vec<f64> = (0..9 * n)
            .map(|i| (1.3 * i as f64).cos() * 10f64.powf((i / 9) as f64 / 8.0))
            .collect();
        let w_im: Vec<f64> = (0..9 * n).map(|i| (0.7 * i as f64).sin()).collect();
        let got = corner_excursions(&w_re, &w_im, &g, &corners).unwrap();
        let mut large = 0;
        for i in 0..n {
            let (wr, wi) = (&w_re[9 * i..9 * i + 9], &w_im[9 * i..9 * i + 9]);
            let want = direct(wr, wi, &g, &corners);
            assert!(
                (got[i] - want).abs() <= 1e-10 * want.max(1e-3),
                "{i}: {} vs {want}",
                got[i]
            );
            large += usize::from(farthest(wr, wi, &g, &corners, false).1 > SERIES);
        }
        assert!(
            large > 0 && large < n,
            "both paths are exercised: {large} of {n}"
        );
    }

    #[test]
    fn bad_shapes_and_values_are_errors() {
        let (re, im) = responses(4);
        let g = Responses {
            re: &re,
            im: &im,
            samples: 4,
        };
        let c = [[0.2, 0.2]];
        assert!(corner_excursions(&[0.0; 9], &[0.0; 8], &g, &c).is_err());
        assert!(corner_excursions(&[0.0; 10], &[0.0; 10], &g, &c).is_err());
        let mut w = [0.0; 9];
        w[3] = f64::NAN;
        assert!(corner_excursions(&w, &[0.0; 9], &g, &c).is_err());
        let short = Responses {
            re: &re[1..],
            im: &im,
            samples: 4,
        };
        assert!(corner_excursions(&[0.0; 9], &[0.0; 9], &short, &c).is_err());
        assert_eq!(
            corner_excursions(&[], &[], &g, &c).unwrap(),
            Vec::<f64>::new()
        );
    }
}
