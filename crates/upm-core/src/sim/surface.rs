//! A plate whose friction varies over its surface ([`FrictionMap`]): a grid of factors on every
//! part's own `mu` and `mu_s`, looked up under each part as the run goes. The integrator takes a
//! part's friction thresholds as constants of a block, so a run on a map goes in blocks of at
//! most [`REFRESH`] of plate time, each part's thresholds set from the map where it will be
//! halfway through the block at its present velocity (a midpoint rule: the error of holding them
//! for the block is second order in its length; a part moves at most millimetres in it, and a
//! map varies over centimetres).

use crate::error::{Error, Result};

/// Plate time [s] between two looks at the map under each part.
pub const REFRESH: f64 = 1e-3;

/// Friction factors on a regular grid over a square centred at the origin: `values[j * nx + i]`
/// at `x = -half + i * side / (nx - 1)`, `y = -half + j * side / (ny - 1)`; bilinear between the
/// nodes, the edge's value beyond it.
#[derive(Debug, Clone, PartialEq)]
pub struct FrictionMap {
    nx: usize,
    ny: usize,
    half: f64,
    values: Vec<f64>,
}

impl FrictionMap {
    /// A map of `ny` rows of `nx` factors (row 0 at `y = -side / 2`) over a square of `side`
    /// [m]. Each factor must be finite and > 0, and there must be at least 2 x 2 of them.
    pub fn new(values: Vec<f64>, nx: usize, ny: usize, side: f64) -> Result<Self> {
        if nx < 2 || ny < 2 || nx.checked_mul(ny) != Some(values.len()) {
            return Err(Error::Shape(format!(
                "friction_map must be a grid of at least 2 x 2 factors; got {} values for {ny} x {nx}",
                values.len()
            )));
        }
        if !(side.is_finite() && side > 0.0) {
            return Err(Error::parameter(
                "friction_map",
                format!("covers the plate: its side must be finite and > 0 m; got {side}"),
            ));
        }
        if let Some(bad) = values.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
            return Err(Error::parameter(
                "friction_map",
                format!("factors must be finite and > 0; got {bad}"),
            ));
        }
        Ok(FrictionMap {
            nx,
            ny,
            half: side / 2.0,
            values,
        })
    }

    /// The factor at `(x, y)` [m].
    pub fn factor(&self, x: f64, y: f64) -> f64 {
        let (fx, i) = Self::cell(x, self.half, self.nx);
        let (fy, j) = Self::cell(y, self.half, self.ny);
        let v = |i: usize, j: usize| self.values[j * self.nx + i];
        let low = v(i, j) + fx * (v(i + 1, j) - v(i, j));
        let high = v(i, j + 1) + fx * (v(i + 1, j + 1) - v(i, j + 1));
        low + fy * (high - low)
    }

    /// The cell of `x` along an axis of `n` nodes over `[-half, half]` and the fraction across
    /// it (clamped to the grid; a NaN coordinate reads the first node).
    fn cell(x: f64, half: f64, n: usize) -> (f64, usize) {
        let s = ((x + half) / (2.0 * half) * (n - 1) as f64).clamp(0.0, (n - 1) as f64);
        let s = if s.is_nan() { 0.0 } else { s };
        let i = (s.floor() as usize).min(n - 2);
        (s - i as f64, i)
    }

    /// Steps of `dt` between two looks at the map (at least one).
    pub(super) fn refresh_steps(dt: f64) -> usize {
        ((REFRESH / dt).floor() as usize).max(1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_between_the_nodes_and_the_edge_beyond() {
        // 3 x 2 over a 0.4 m square: x nodes -0.2, 0, 0.2; y nodes -0.2, 0.2
        let m = FrictionMap::new(vec![1.0, 2.0, 3.0, 3.0, 4.0, 5.0], 3, 2, 0.4).unwrap();
        assert_eq!(m.factor(-0.2, -0.2), 1.0);
        assert_eq!(m.factor(0.2, 0.2), 5.0);
        assert!((m.factor(0.1, -0.2) - 2.5).abs() < 1e-12);
        assert!((m.factor(0.0, 0.0) - 3.0).abs() < 1e-12);
        assert!((m.factor(-0.1, 0.1) - (0.25 * 1.5 + 0.75 * 3.5)).abs() < 1e-12);
        assert_eq!(m.factor(9.0, -9.0), 3.0);
        assert_eq!(m.factor(f64::NAN, -0.2), 1.0);
    }

    #[test]
    fn bad_maps_are_refused() {
        assert!(FrictionMap::new(vec![1.0; 3], 3, 1, 0.4).is_err());
        assert!(FrictionMap::new(vec![1.0; 4], 2, 3, 0.4).is_err());
        assert!(FrictionMap::new(vec![1.0, 0.0, 1.0, 1.0], 2, 2, 0.4).is_err());
        assert!(FrictionMap::new(vec![1.0; 4], 2, 2, f64::NAN).is_err());
    }
}
