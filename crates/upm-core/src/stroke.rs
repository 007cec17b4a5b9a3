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
use crate::simd::{simd, Simd};

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
        * (1.0
            + t2 * (-1.0 / 6.0
                + t2 * (1.0 / 120.0 + t2 * (-1.0 / 5040.0 + t2 * (1.0 / 362880.0)))));
    (cm1, s)
}

/// Samples in flight at once in the series path.
const LANES: usize = 8;

/// Samples per block of the pose, formed axis by axis over contiguous samples (vectorised).
const BLOCK: usize = 128;
/// Pulses taken through each block of samples together: the block's responses (18 KiB) are read
/// from memory once for all of them, not once per pulse.
const GROUP: usize = 8;

/// For each pulse of a group whose wrench phasors are `(wr, wi)` (`[pulse][h][a]`), the largest
/// squared corner distance and the largest `|theta|` met, into `out`: compiled for the widest
/// vectors the CPU has ([`simd`]; the same arithmetic, so the same bits, in every build).
fn farthest(
    wr: &[f64],
    wi: &[f64],
    g: &Responses,
    corners: &[[f64; 2]],
    exact: bool,
    out: &mut [(f64, f64)],
) {
    match simd() {
        // SAFETY: `simd()` names a build only when the CPU has its features.
        #[cfg(target_arch = "x86_64")]
        Simd::Avx512 => unsafe { farthest_avx512(wr, wi, g, corners, exact, out) },
        #[cfg(target_arch = "x86_64")]
        Simd::Avx2 => unsafe { farthest_avx2(wr, wi, g, corners, exact, out) },
        _ => farthest_in(wr, wi, g, corners, exact, out),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn farthest_avx512(
    wr: &[f64],
    wi: &[f64],
    g: &Responses,
    corners: &[[f64; 2]],
    exact: bool,
    out: &mut [(f64, f64)],
) {
    farthest_in(wr, wi, g, corners, exact, out);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn farthest_avx2(
    wr: &[f64],
    wi: &[f64],
    g: &Responses,
    corners: &[[f64; 2]],
    exact: bool,
    out: &mut [(f64, f64)],
) {
    farthest_in(wr, wi, g, corners, exact, out);
}

#[inline(always)]
fn farthest_in(
    wr: &[f64],
    wi: &[f64],
    g: &Responses,
    corners: &[[f64; 2]],
    exact: bool,
    out: &mut [(f64, f64)],
) {
    let t = g.samples;
    out.fill((0.0, 0.0));
    let mut pose = [[0.0; BLOCK]; A];
    let mut start = 0;
    while start < t {
        let len = BLOCK.min(t - start);
        for (p, (best, widest)) in out.iter_mut().enumerate() {
            let (wr, wi) = (&wr[p * H * A..][..H * A], &wi[p * H * A..][..H * A]);
            for (a, v) in pose.iter_mut().enumerate() {
                let v = &mut v[..len];
                v.fill(0.0);
                for h in 0..H {
                    let k = (h * A + a) * t + start;
                    let (re, im) = (&g.re[k..k + len], &g.im[k..k + len]);
                    let (cr, ci) = (wr[h * A + a], wi[h * A + a]);
                    for ((v, r), i) in v.iter_mut().zip(re).zip(im) {
                        *v += cr * r - ci * i;
                    }
                }
            }
            scan(&pose, len, corners, exact, best, widest);
        }
        start += len;
    }
}

/// The farthest corner and the widest angle over the first `len` samples of `pose`, folded into
/// `best` and `widest`: the turn of every sample first, then each corner over all samples
/// (contiguous loops that vectorise).
#[inline(always)]
fn scan(
    pose: &[[f64; BLOCK]; A],
    len: usize,
    corners: &[[f64; 2]],
    exact: bool,
    best: &mut f64,
    widest: &mut f64,
) {
    let [x, y, theta] = pose;
    let (mut cm1, mut sn, mut far) = ([0.0f64; BLOCK], [0.0f64; BLOCK], [0.0f64; BLOCK]);
    if exact {
        for s in 0..len {
            let (sin, cos) = theta[s].sin_cos();
            (cm1[s], sn[s]) = (cos - 1.0, sin);
        }
    } else {
        for s in 0..len {
            (cm1[s], sn[s]) = turn(theta[s]);
        }
    }
    for &[kx, ky] in corners {
        for s in 0..len {
            let dx = cm1[s] * kx - sn[s] * ky + x[s];
            let dy = sn[s] * kx + cm1[s] * ky + y[s];
            let d2 = dx * dx + dy * dy;
            far[s] = if d2 > far[s] { d2 } else { far[s] };
        }
    }
    *best = most(&far[..len], *best);
    let mut wide = [0.0f64; BLOCK];
    for s in 0..len {
        wide[s] = theta[s].abs();
    }
    *widest = most(&wide[..len], *widest);
}

/// The largest of `v` and `start`, in lanes (so that it vectorises).
#[inline(always)]
fn most(v: &[f64], start: f64) -> f64 {
    let mut lanes = [start; LANES];
    let mut chunks = v.chunks_exact(LANES);
    for c in &mut chunks {
        for l in 0..LANES {
            lanes[l] = if c[l] > lanes[l] { c[l] } else { lanes[l] };
        }
    }
    let tail = chunks.remainder().iter().fold(start, |m, &x| m.max(x));
    lanes.iter().fold(tail, |m, &x| m.max(x))
}

/// Largest distance [m] any of `corners` moves from home under each of `n` pulses, whose wrench
/// phasors are `w_re`, `w_im` (`(n, 3, 3)` row-major: pulse, harmonic, axis), through the unit
/// responses `g`. In parallel over groups of pulses; each result depends on its pulse alone.
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
    let n = w_re.len() / (H * A);
    let mut out = vec![(0.0, 0.0); n];
    out.par_chunks_mut(GROUP)
        .zip(
            w_re.par_chunks(H * A * GROUP)
                .zip(w_im.par_chunks(H * A * GROUP)),
        )
        .with_min_len(crate::parallel::min_len())
        .for_each(|(out, (wr, wi))| {
            farthest(wr, wi, g, corners, false, out);
            // a pulse that turns the plate beyond the series' range: again with `sin_cos`
            for (p, o) in out.iter_mut().enumerate() {
                if o.1 > SERIES {
                    let one = p * H * A..(p + 1) * H * A;
                    farthest(
                        &wr[one.clone()],
                        &wi[one],
                        g,
                        corners,
                        true,
                        std::slice::from_mut(o),
                    );
                }
            }
        });
    Ok(out.into_iter().map(|(best, _)| best.sqrt()).collect())
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
        let n = 43; // five whole groups of pulses and a part of one
                    // amplitudes from small (angles of a milliradian) to large (beyond the series' range)
        let w_re: Vec<f64> = (0..9 * n)
            .map(|i| (1.3 * i as f64).cos() * 10f64.powf((i / 9) as f64 / 8.6))
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
            let mut series = [(0.0, 0.0)];
            farthest(wr, wi, &g, &corners, false, &mut series);
            large += usize::from(series[0].1 > SERIES);
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
