//! Kernels of the predictive planner's scoring (`upm.plan`): displacement tables of long pulses
//! applied to many layouts at once, and the penalty for parts near or past the plate's edges.
//!
//! A rotation about `C` moves a resting part at `P` by a displacement that depends only on
//! `r = |P - C|`, turned with `P - C`; a translation moves every resting part alike. The planner
//! simulates each long pulse once on a ray of parts at increasing radii from 0, and here
//! applies the tables to every part of every candidate layout by linear interpolation in `r`
//! (metres, the plate frame). Layouts are independent, so any thread count gives the same bits.

use rayon::prelude::*;

use crate::error::{Error, Result};

/// Displacement tables on a ray (see the module docs).
pub struct RayTables<'a> {
    /// Radii `[0, r1, r2, ...]` [m], increasing, `n >= 2` of them.
    pub radii: &'a [f64],
    /// Centres `(R, 2)` of the rotations [m].
    pub centres: &'a [[f64; 2]],
    /// Displacement `(R, n, 2)` of a part at `(r, 0)` from each rotation's centre [m].
    pub turn: &'a [[f64; 2]],
    /// Displacement `(T, 2)` of every part under each translation [m].
    pub shift: &'a [[f64; 2]],
}

impl RayTables<'_> {
    fn check(&self) -> Result<()> {
        let n = self.radii.len();
        let increasing = n >= 2
            && self.radii[0] == 0.0
            && self.radii.windows(2).all(|w| w[1] > w[0])
            && self.radii.iter().all(|r| r.is_finite());
        if !increasing {
            return Err(Error::parameter(
                "radii",
                format!("must be finite, increasing from 0 and hold >= 2 values; got {n} values"),
            ));
        }
        if self.turn.len() != self.centres.len() * n {
            return Err(Error::Shape(format!(
                "turn must hold R x n = {} x {n} displacements; got {}",
                self.centres.len(),
                self.turn.len()
            )));
        }
        Ok(())
    }

    /// Tables (rotations, then translations).
    pub fn len(&self) -> usize {
        self.centres.len() + self.shift.len()
    }

    /// Whether there is no table.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The positions `(L, R + T, M, 2)` after each table from each layout `q (L, M, 2)` (`m` parts a
/// layout) into `out`. A part at NaN stays NaN.
pub fn apply_rays(
    tables: &RayTables,
    q: &[[f64; 2]],
    m: usize,
    out: &mut [[f64; 2]],
) -> Result<()> {
    tables.check()?;
    let k = tables.len();
    if m == 0 || !q.len().is_multiple_of(m) || out.len() != q.len() * k {
        return Err(Error::Shape(format!(
            "layouts of {m} parts: q holds {} positions, out must hold {} x {k}; got {}",
            q.len(),
            q.len(),
            out.len()
        )));
    }
    let radii = tables.radii;
    let n = radii.len();
    // the interval [radii[j], radii[j + 1]] that holds r (the last one beyond the table)
    let interval = |r: f64| radii.partition_point(|&x| x <= r).clamp(1, n - 1) - 1;
    out.par_chunks_mut(k * m)
        .zip(q.par_chunks(m))
        .with_min_len(crate::parallel::min_len())
        .for_each(|(o, layout)| {
            for (c, &[cx, cy]) in tables.centres.iter().enumerate() {
                let row = &tables.turn[c * n..(c + 1) * n];
                for (i, &[x, y]) in layout.iter().enumerate() {
                    let (dx, dy) = (x - cx, y - cy);
                    let r = dx.hypot(dy);
                    if !r.is_finite() {
                        o[c * m + i] = [f64::NAN; 2];
                        continue;
                    }
                    let (cos, sin) = if r > 0.0 {
                        (dx / r, dy / r)
                    } else {
                        (1.0, 0.0)
                    };
                    let j = interval(r);
                    let (lo, hi) = (radii[j], radii[j + 1]);
                    let w = ((r - lo) / (hi - lo)).clamp(0.0, 1.0);
                    let (a, b) = (row[j], row[j + 1]);
                    let ux = a[0] * (1.0 - w) + b[0] * w;
                    let uy = a[1] * (1.0 - w) + b[1] * w;
                    o[c * m + i] = [x + (cos * ux - sin * uy), y + (sin * ux + cos * uy)];
                }
            }
            let base = tables.centres.len() * m;
            for (t, &[sx, sy]) in tables.shift.iter().enumerate() {
                for (i, &[x, y]) in layout.iter().enumerate() {
                    o[base + t * m + i] = [x + sx, y + sy];
                }
            }
        });
    Ok(())
}

/// The planner's edge penalty of parts near the plate's edges.
#[derive(Clone, Copy, Debug)]
pub struct Edges {
    /// Half the plate's side [m]: a part beyond it (or NaN) is lost.
    pub half: f64,
    /// Width of the band inside the edges that is penalised [m].
    pub band: f64,
    /// Penalty per metre inside the band; the band's outer half counts five times more.
    pub weight: f64,
    /// Penalty of a lost part.
    pub lost: f64,
    /// A part within this of an edge [m] counts half lost (the prediction's margin of error).
    pub guard: f64,
}

/// Where the parts of scored layouts started: each is scored at its worst case, `factor` times
/// its way from there further out (`x + sign(x) factor |q - start|` per coordinate).
#[derive(Clone, Copy, Debug)]
pub struct Spread<'a> {
    /// `S` start layouts of `m` parts; layout `l` of `L` started at start layout `l / (L / S)`
    /// (`S` divides `L`: each start serves as many consecutive layouts).
    pub start: &'a [[f64; 2]],
    /// How much further out than its way a part is scored.
    pub factor: f64,
}

/// The sign of `x`, 0 at 0 (NaN stays NaN through the product it enters).
fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Checks that `q` holds `out.len()` layouts of `m > 0` parts.
fn check_layouts(q: &[[f64; 2]], m: usize, out: &[f64]) -> Result<()> {
    if m == 0 || q.len() != out.len() * m {
        return Err(Error::Shape(format!(
            "layouts of {m} parts: q holds {} positions for {} layouts",
            q.len(),
            out.len()
        )));
    }
    Ok(())
}

/// How many consecutive layouts of `l` each of the `S` layouts of `m` points in `src` serves
/// (`S` must divide `l`), or a shape error naming `what`.
fn per_layout(what: &str, src: &[[f64; 2]], m: usize, l: usize) -> Result<usize> {
    let s = src.len() / m;
    if s == 0 || !src.len().is_multiple_of(m) || !l.is_multiple_of(s) {
        return Err(Error::Shape(format!(
            "{what} must hold S layouts of {m} points with S dividing the {l} layouts; got {} points",
            src.len()
        )));
    }
    Ok(l / s)
}

/// Edge penalty of each layout `q (L, M, 2)` (`m` parts a layout) into `out (L,)`: `lost` per
/// part off the plate or NaN; else `weight` times, per coordinate, its depth in the band plus
/// five times its depth in the band's outer half, and half of `lost` more within `guard` of an
/// edge; with `spread`, each part scored where its worst case puts it (see [`Spread`]).
pub fn edge_penalty(
    edges: &Edges,
    q: &[[f64; 2]],
    m: usize,
    spread: Option<Spread>,
    out: &mut [f64],
) -> Result<()> {
    check_layouts(q, m, out)?;
    // each layout's start and the factor (none: the layout itself, factor 0)
    let per = match spread {
        Some(Spread { start, factor }) => {
            let each = per_layout("start", start, m, out.len())?;
            if !factor.is_finite() {
                return Err(Error::parameter(
                    "spread",
                    format!("must be finite; got {factor}"),
                ));
            }
            Some((start, each, factor))
        }
        None => None,
    };
    let Edges {
        half,
        band,
        weight,
        lost,
        guard,
    } = *edges;
    let (inner, outer, keep) = (half - band, half - 0.5 * band, half - guard);
    out.par_iter_mut()
        .zip(q.par_chunks(m))
        .enumerate()
        .with_min_len(crate::parallel::min_len())
        .for_each(|(l, (o, layout))| {
            let (mut gone, mut over) = (0.0, 0.0);
            let from = per.map(|(start, each, factor)| (&start[(l / each) * m..][..m], factor));
            for (i, &p) in layout.iter().enumerate() {
                let p = match from {
                    Some((start, factor)) => {
                        let way = factor * (p[0] - start[i][0]).hypot(p[1] - start[i][1]);
                        [p[0] + sign(p[0]) * way, p[1] + sign(p[1]) * way]
                    }
                    None => p,
                };
                let (ax, ay) = (p[0].abs(), p[1].abs());
                if !(ax <= half && ay <= half) {
                    gone += 1.0; // NaN fails both comparisons
                    continue;
                }
                if !(ax <= keep && ay <= keep) {
                    // on the plate but within the guard: half lost, and deeper is worse (a part
                    // already there must not cost as much at rest as pushed off the plate, or
                    // no pulse is kept from pushing it off)
                    gone += 0.5;
                }
                for a in [ax, ay] {
                    over += (a - inner).max(0.0) + 5.0 * (a - outer).max(0.0);
                }
            }
            *o = lost * gone + weight * over;
        });
    Ok(())
}

/// Overlap penalty of each layout `q (L, M, 2)` (`m` parts a layout) into `out (L,)`: the sum
/// over pairs of parts closer than `reach` [m] of `reach - distance`; parts at NaN take no part.
/// Pairs are found by sweeping the parts sorted along x (a pair farther apart in x than `reach`
/// cannot overlap), so a layout costs `O(M log M)` plus its close pairs, not `O(M^2)`.
pub fn overlap_penalty(reach: f64, q: &[[f64; 2]], m: usize, out: &mut [f64]) -> Result<()> {
    check_layouts(q, m, out)?;
    if !(reach.is_finite() && reach >= 0.0) {
        return Err(Error::parameter(
            "reach",
            format!("must be finite and >= 0 [m]; got {reach}"),
        ));
    }
    out.par_iter_mut()
        .zip(q.par_chunks(m))
        .with_min_len(crate::parallel::min_len())
        .for_each_init(Vec::new, |order: &mut Vec<[f64; 2]>, (o, layout)| {
            order.clear();
            order.extend(
                layout
                    .iter()
                    .filter(|p| p[0].is_finite() && p[1].is_finite()),
            );
            order.sort_unstable_by(|a, b| a[0].total_cmp(&b[0]));
            let mut sum = 0.0;
            for (i, a) in order.iter().enumerate() {
                for b in &order[i + 1..] {
                    if b[0] - a[0] >= reach {
                        break;
                    }
                    let gap = (b[0] - a[0]).hypot(b[1] - a[1]);
                    if gap < reach {
                        sum += reach - gap;
                    }
                }
            }
            *o = sum;
        });
    Ok(())
}

/// How a part's distance to its point counts in [`distance_sum`].
#[derive(Clone, Copy, Debug)]
pub struct Reach {
    /// Distance within which a part counts 0; beyond it, its excess `e` [m].
    pub slack: f64,
    /// With `bend > 0`, an excess below it counts `e^2 / (2 bend)` and one beyond `e - bend / 2`
    /// (a Huber loss) [m].
    pub bend: f64,
}

/// Sum over the parts of each layout `q (L, M, 2)` (`m` parts a layout) of their distances to
/// their points counted by `reach` into `out (L,)`: `targets` holds `T` layouts of points, `T`
/// dividing `L`, each for `L / T` consecutive layouts (`T = 1`: the same points for all). A part
/// whose point is NaN is left out; a part at NaN (lost) counts 1 m.
pub fn distance_sum(
    targets: &[[f64; 2]],
    m: usize,
    reach: Reach,
    q: &[[f64; 2]],
    out: &mut [f64],
) -> Result<()> {
    check_layouts(q, m, out)?;
    let each = per_layout("targets", targets, m, out.len())?;
    let Reach { slack, bend } = reach;
    if !(slack.is_finite() && slack >= 0.0 && bend.is_finite() && bend >= 0.0) {
        return Err(Error::parameter(
            "slack",
            format!("slack and bend must be finite and >= 0 [m]; got {slack} and {bend}"),
        ));
    }
    out.par_iter_mut()
        .zip(q.par_chunks(m))
        .enumerate()
        .with_min_len(crate::parallel::min_len())
        .for_each(|(l, (o, layout))| {
            let mut sum = 0.0;
            for (p, t) in layout.iter().zip(&targets[(l / each) * m..][..m]) {
                if !(t[0].is_finite() && t[1].is_finite()) {
                    continue;
                }
                let r = (p[0] - t[0]).hypot(p[1] - t[1]);
                if !r.is_finite() {
                    sum += 1.0;
                    continue;
                }
                let e = (r - slack).max(0.0);
                sum += if bend > 0.0 && e < bend {
                    e * e / (2.0 * bend)
                } else if bend > 0.0 {
                    e - 0.5 * bend
                } else {
                    e
                };
            }
            *o = sum;
        });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_overlap_penalty_is_every_close_pair_by_brute_force() {
        // layouts of 40 parts crowded in a small square, a few lost; the sweep must find every
        // pair the all-pairs loop finds
        let (l, m, reach) = (7, 40, 0.02);
        let mut seed = 12345_u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut q: Vec<[f64; 2]> = (0..l * m).map(|_| [0.1 * next(), 0.1 * next()]).collect();
        q[3] = [f64::NAN, 0.0];
        q[50] = [0.0, f64::NAN];
        let mut out = vec![0.0; l];
        overlap_penalty(reach, &q, m, &mut out).unwrap();
        for (k, layout) in q.chunks(m).enumerate() {
            let mut want = 0.0;
            for i in 0..m {
                for j in i + 1..m {
                    let (a, b) = (layout[i], layout[j]);
                    let gap = (a[0] - b[0]).hypot(a[1] - b[1]);
                    if gap < reach {
                        want += reach - gap; // NaN compares false: skipped
                    }
                }
            }
            assert!(want > 0.0);
            assert!(
                (out[k] - want).abs() < 1e-12 * want,
                "{k}: {} against {want}",
                out[k]
            );
        }
        assert!(overlap_penalty(reach, &q, m, &mut vec![0.0; l + 1]).is_err());
        assert!(overlap_penalty(f64::NAN, &q, m, &mut out).is_err());
    }

    #[test]
    fn a_table_on_its_own_ray_gives_its_own_rows_and_turns_with_the_part() {
        let radii = [0.0, 0.01, 0.02, 0.04, 0.08];
        let turn: Vec<[f64; 2]> = (0..5)
            .map(|j| [0.001 * j as f64, 0.002 * j as f64])
            .collect();
        let tables = RayTables {
            radii: &radii,
            centres: &[[0.1, -0.05]],
            turn: &turn,
            shift: &[[0.003, -0.004]],
        };
        // on the ray (along +x from the centre): the row; a quarter turn round: turned with it;
        // half way between two radii: the mean; NaN stays NaN; the shift moves every part
        let q = [[0.14, -0.05], [0.1, -0.01], [0.13, -0.05], [f64::NAN, 0.0]];
        let mut out = vec![[0.0; 2]; 8];
        apply_rays(&tables, &q, 4, &mut out).unwrap();
        let close =
            |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-15 && (a[1] - b[1]).abs() < 1e-15;
        assert!(close(out[0], [0.14 + 0.003, -0.05 + 0.006]), "{:?}", out[0]);
        assert!(close(out[1], [0.1 - 0.006, -0.01 + 0.003]), "{:?}", out[1]);
        assert!(
            close(out[2], [0.13 + 0.0025, -0.05 + 0.005]),
            "{:?}",
            out[2]
        );
        assert!(out[3][0].is_nan() && out[3][1].is_nan());
        assert!(close(out[4], [0.143, -0.054]) && close(out[6], [0.133, -0.054]));
        assert!(out[7][0].is_nan());
        let mut short = vec![[0.0; 2]; 7];
        assert!(apply_rays(&tables, &q, 4, &mut short).is_err());
    }

    #[test]
    fn the_edge_penalty_counts_depth_in_the_band_and_lost_parts() {
        let edges = Edges {
            half: 0.2,
            band: 0.04,
            weight: 2.0,
            lost: 1.0,
            guard: 0.005,
        };
        let q = [
            [0.0, 0.0],
            [0.17, 0.0],
            [0.0, -0.19],
            [0.25, 0.0],
            [f64::NAN, 0.0],
            [0.19, 0.19],
            [0.0, 0.197],
        ];
        let mut out = vec![0.0; 7];
        edge_penalty(&edges, &q, 1, None, &mut out).unwrap();
        let want = [
            0.0,
            2.0 * 0.01,
            2.0 * (0.03 + 5.0 * 0.01),
            1.0,
            1.0,
            2.0 * 2.0 * (0.03 + 0.05),
            // within the guard: half lost, and its depth (37 mm in the band, 17 in its outer half)
            0.5 + 2.0 * (0.037 + 5.0 * 0.017),
        ];
        for (a, b) in out.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{out:?} against {want:?}");
        }
    }

    #[test]
    fn the_distance_sum_counts_slack_bend_lost_parts_and_parts_without_a_target() {
        let targets = [[0.0, 0.0], [0.1, 0.0], [f64::NAN, 0.0]];
        // layout 0: 5 mm, 30 mm from their points and one without a target; layout 1: one lost
        let q = [
            [0.003, 0.004],
            [0.1, 0.03],
            [0.5, 0.5],
            [0.0, 0.0],
            [f64::NAN, 0.0],
            [0.0, 0.0],
        ];
        let mut out = vec![0.0; 2];
        let straight = Reach {
            slack: 0.0,
            bend: 0.0,
        };
        distance_sum(&targets, 3, straight, &q, &mut out).unwrap();
        assert!((out[0] - 0.035).abs() < 1e-15 && out[1] == 1.0, "{out:?}");
        // slack 2 mm, bend 10 mm: 3 mm of excess counts 9e-6 / 0.02; 28 mm counts 28 - 5
        let bent = Reach {
            slack: 0.002,
            bend: 0.01,
        };
        distance_sum(&targets, 3, bent, &q, &mut out).unwrap();
        let want = 0.003 * 0.003 / 0.02 + (0.028 - 0.005);
        assert!((out[0] - want).abs() < 1e-15, "{} against {want}", out[0]);
        assert!(distance_sum(&targets, 3, bent, &q[..5], &mut out).is_err());
        // one layout of points per layout
        let both = [targets, [[0.0, 0.0], [0.0, 0.0], [f64::NAN, 0.0]]].concat();
        distance_sum(&both, 3, straight, &q, &mut out).unwrap();
        assert!((out[0] - 0.035).abs() < 1e-15 && out[1] == 1.0, "{out:?}");
        let three = [[0.0; 2]; 9];
        assert!(distance_sum(&three, 3, straight, &q, &mut out).is_err());
        let bad = Reach {
            slack: -1.0,
            bend: 0.0,
        };
        assert!(distance_sum(&targets, 3, bad, &q, &mut out).is_err());
    }

    #[test]
    fn a_spread_scores_each_part_further_out_by_its_way_from_its_own_start() {
        let edges = Edges {
            half: 0.2,
            band: 0.04,
            weight: 1.0,
            lost: 1.0,
            guard: 0.0,
        };
        // two starts, each for two consecutive layouts of one part: a part that went 10 mm is
        // scored 20 mm further out at factor 2 (x = 0.15 -> 0.17: 10 mm into the band), one
        // that stayed put where it is, one at 0 in x keeps its x
        let start = [[0.14, 0.0], [0.0, 0.0]];
        let q = [[0.15, 0.0], [0.14, 0.0], [0.0, 0.17], [0.0, 0.0]];
        let mut out = vec![0.0; 4];
        let spread = Spread {
            start: &start,
            factor: 2.0,
        };
        edge_penalty(&edges, &q, 1, Some(spread), &mut out).unwrap();
        // layout 2: y 0.17 went 0.17, scored at 0.17 + 0.34 = 0.51: off the plate, lost
        let want = [0.01, 0.0, 1.0, 0.0];
        for (a, b) in out.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{out:?} against {want:?}");
        }
        let three = [[0.0; 2]; 3];
        let odd = Spread {
            start: &three,
            factor: 2.0,
        };
        assert!(edge_penalty(&edges, &q, 1, Some(odd), &mut out).is_err());
    }
}
