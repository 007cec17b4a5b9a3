//! Shapes and numbers the polygon tests share.
#![allow(dead_code)] // (each test file uses some)

use upm_core::polygon::Polygon;

/// An irregular pentagon of about 4 cm.
pub fn pentagon() -> Polygon {
    Polygon::new(
        "p",
        &[
            [0.0, 0.0],
            [0.030, -0.004],
            [0.041, 0.016],
            [0.022, 0.031],
            [-0.006, 0.019],
        ],
    )
    .unwrap()
}

/// Uniform numbers in [-1, 1) from a 64-bit LCG.
pub fn uniform(n: usize, seed: u64) -> Vec<f64> {
    let mut state = seed;
    (0..n)
        .map(|_| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        })
        .collect()
}

/// Relative twists of the steps that slid on that the integrator extrapolates for the next
/// sliding solve's start, and its solves in a row that trust a contraction measured before them
/// (docs/polygons.md).
pub const HISTORY: usize = 7;
pub const TRUSTED: usize = 32;

/// A part's last sliding twists (the latest first, `slid` of them in a row) extrapolated to the
/// next step by the polynomial through them: weights `(-1)^j C(slid, j + 1)`, summed in order.
pub fn extrapolate(history: &[[f64; 3]; HISTORY], slid: usize) -> [f64; 3] {
    let weights: [f64; HISTORY] = std::array::from_fn(|j| {
        if j >= slid {
            return 0.0;
        }
        let binomial = (0..=j).fold(1.0, |b, q| b * (slid - q) as f64 / (q + 1) as f64);
        binomial * if j % 2 == 0 { 1.0 } else { -1.0 }
    });
    std::array::from_fn(|i| (0..HISTORY).fold(0.0, |sum, q| sum + weights[q] * history[q][i]))
}
