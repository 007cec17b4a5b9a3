//! Globally adaptive Gauss–Kronrod (7/15-point) quadrature of 2-vector integrands.
//!
//! The interval with the largest error estimate is bisected until the summed estimate meets the
//! tolerance (the QUADPACK `qag` strategy). Jumps are allowed: the interval holding one keeps being
//! bisected and its error halves each time, so callers pass the points they know about as
//! breakpoints and the rest is found by refinement. A jump hidden between an end of an interval
//! and its outermost node is caught by comparing the two; a pair of jumps closer together than the
//! spacing of the nodes (a sliver) can still be missed, so callers start from fine partitions.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use crate::error::{Error, Result};

/// Kronrod abscissae on `[-1, 1]` (non-negative half; odd indices are the Gauss points).
const XGK: [f64; 8] = [
    0.991_455_371_120_812_6,
    0.949_107_912_342_758_5,
    0.864_864_423_359_769_1,
    0.741_531_185_599_394_4,
    0.586_087_235_467_691_1,
    0.405_845_151_377_397_2,
    0.207_784_955_007_898_5,
    0.0,
];
/// Kronrod weights.
const WGK: [f64; 8] = [
    0.022_935_322_010_529_22,
    0.063_092_092_629_978_55,
    0.104_790_010_322_250_2,
    0.140_653_259_715_525_9,
    0.169_004_726_639_267_9,
    0.190_350_578_064_785_4,
    0.204_432_940_075_298_9,
    0.209_482_141_084_727_8,
];
/// Gauss weights of `XGK[1], XGK[3], XGK[5], XGK[7]`.
const WG: [f64; 4] = [
    0.129_484_966_168_869_7,
    0.279_705_391_489_276_7,
    0.381_830_050_505_118_9,
    0.417_959_183_673_469_4,
];

/// Most bisections before giving up, beyond eight per starting interval.
const MAX_INTERVALS: usize = 50_000;

struct Piece {
    a: f64,
    b: f64,
    value: [f64; 2],
    error: f64,
}

impl PartialEq for Piece {
    fn eq(&self, other: &Self) -> bool {
        self.error == other.error
    }
}
impl Eq for Piece {}
impl PartialOrd for Piece {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Piece {
    fn cmp(&self, other: &Self) -> Ordering {
        self.error.total_cmp(&other.error)
    }
}

fn kronrod<F: Fn(f64) -> [f64; 2]>(f: &F, a: f64, b: f64) -> Piece {
    let c = 0.5 * (a + b);
    let h = 0.5 * (b - a);
    let mid = f(c);
    let mut k = [WGK[7] * mid[0], WGK[7] * mid[1]];
    let mut g = [WG[3] * mid[0], WG[3] * mid[1]];
    for i in 0..7 {
        let lo = f(c - h * XGK[i]);
        let hi = f(c + h * XGK[i]);
        for d in 0..2 {
            k[d] += WGK[i] * (lo[d] + hi[d]);
            if i % 2 == 1 {
                g[d] += WG[i / 2] * (lo[d] + hi[d]);
            }
        }
    }
    let value = [k[0] * h, k[1] * h];
    let mut error = ((k[0] - g[0]).abs() + (k[1] - g[1]).abs()) * h.abs();
    // A jump between an end and the outermost node is invisible to both rules: compare the ends
    // with their nearest nodes and charge a jump found there for the sliver it may hide.
    let sliver = (1.0 - XGK[0]) * h.abs();
    for (end, node) in [(a, c - h * XGK[0]), (b, c + h * XGK[0])] {
        let (fe, fn_) = (f(end), f(node));
        let jump = (fe[0] - fn_[0]).abs() + (fe[1] - fn_[1]).abs();
        let size = fe[0]
            .abs()
            .max(fe[1].abs())
            .max(fn_[0].abs())
            .max(fn_[1].abs());
        if jump > 0.25 * size {
            error += jump * sliver;
        }
    }
    Piece { a, b, value, error }
}

/// `integral f` over `[breaks[0], breaks[last]]`, each interval between consecutive breakpoints
/// refined until the summed error estimate is below `tol` (absolute).
pub(crate) fn integrate<F: Fn(f64) -> [f64; 2]>(
    f: F,
    breaks: &[f64],
    tol: f64,
) -> Result<[f64; 2]> {
    let mut heap: BinaryHeap<Piece> = breaks
        .windows(2)
        .filter(|w| w[1] > w[0])
        .map(|w| kronrod(&f, w[0], w[1]))
        .collect();
    let mut intervals = heap.len();
    let cap = MAX_INTERVALS + 8 * intervals;
    let mut error: f64 = heap.iter().map(|p| p.error).sum();
    while error > tol {
        let worst = heap
            .pop()
            .expect("a positive error comes from some interval");
        let m = 0.5 * (worst.a + worst.b);
        if intervals >= cap || m <= worst.a || m >= worst.b {
            return Err(Error::Convergence(format!(
                "adaptive quadrature reached {intervals} intervals with error estimate {error:.3e} above tol = {tol:.3e}"
            )));
        }
        let (left, right) = (kronrod(&f, worst.a, m), kronrod(&f, m, worst.b));
        error += left.error + right.error - worst.error;
        heap.push(left);
        heap.push(right);
        intervals += 1;
        if intervals.is_multiple_of(256) {
            // Re-sum now and then so rounding in the running total cannot stall or end the loop.
            error = heap.iter().map(|p| p.error).sum();
        }
    }
    Ok(heap
        .iter()
        .fold([0.0; 2], |s, p| [s[0] + p.value[0], s[1] + p.value[1]]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_for_polynomials_and_converges_across_a_jump() {
        // Degree 21 is integrated exactly by one 15-point Kronrod rule.
        let v = integrate(|x| [x.powi(21) + x.powi(20), 1.0], &[-1.0, 1.0], 1e-14).unwrap();
        assert!((v[0] - 2.0 / 21.0).abs() < 1e-14 && (v[1] - 2.0).abs() < 1e-15);
        // A jump at an irrational point, away from every node.
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let v = integrate(
            |x| [if x < s { -1.0 } else { 1.0 }, x.exp()],
            &[0.0, 1.0],
            1e-12,
        )
        .unwrap();
        assert!((v[0] - (1.0 - 2.0 * s)).abs() < 1e-12, "{}", v[0]);
        assert!((v[1] - (1f64.exp() - 1.0)).abs() < 1e-13);
        // A jump between the last node and the end of the interval.
        let v = integrate(
            |x| [if x < 0.999 { 1.0 } else { -1.0 }, 0.0],
            &[0.0, 1.0],
            1e-12,
        )
        .unwrap();
        assert!((v[0] - 0.998).abs() < 1e-12, "{}", v[0]);
    }
}
