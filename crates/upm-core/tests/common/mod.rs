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
