//! Pressure that varies linearly across a part's footprint, `p(r) = (N / A) (1 + k . r)` with
//! `r` from the centroid: the load of a part on a plate that rocks (docs/spec.md §10, each
//! element pressed by `g + a_z` where it lies, `k` the gradient of `a_z` over `g + a_z` at the
//! centroid). `∫ p dA = N` still, since `∫ r dA = 0` about the centroid.
//!
//! About the instantaneous centre `r0`, with `d = r - r0`, `rho = |d|`, the weight is
//! `w = w0 + k . d`, `w0 = 1 + k . r0`, and the fan's integrals gain the terms of `k . d`:
//!
//! ```text
//! ∫ w d/rho dA      = w0 ∫ d/rho dA      + (∫ d d^T / rho dA) k
//! ∫ w rho dA        = w0 ∫ rho dA        + k . ∫ d rho dA
//! ∫ w d d^T/rho³ dA = w0 ∫ d d^T/rho³ dA + ∫ (k . d) d d^T / rho³ dA
//! ```
//!
//! Each new integral has a closed form over each triangle fanning from `r0` to an edge: with the
//! edge at signed distance `h` from `r0` (unit normal `n`, direction `t`, from `t1` to `t2`
//! along it), its points are `s (h n + t tau)`, `dA = s h ds dt`, and a term homogeneous of
//! degree `m` in `d` integrates to `h / (m + 2)` times its integral along the edge; those are
//! `∫ t^j / rho^q dt` for `q = -1, 1, 3`, in `rho`, `t` and `asinh(t / |h|)`.
//!
//! They are computed in the fan's own pass over the edges ([`super::lanes::fan_loaded`], and its
//! AVX2 build), from the same distances, differences between an edge's ends (formed without
//! cancellation) and logarithm.

/// The terms a pressure gradient `k` adds to the fan about `r0` (module docs), unscaled by `w0`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Linear {
    /// `(∫ d d^T / rho dA) k` [m⁴·k].
    pub unit: [f64; 2],
    /// `k . ∫ d rho dA`.
    pub dist: f64,
    /// `∫ (k . d) d d^T / rho³ dA` as `(xx, xy, yy)` (zero unless asked for).
    pub curvature: [f64; 3],
}
