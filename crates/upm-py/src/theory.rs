//! Binding of `upm_core::theory`: the closed forms of chapter 3 and Theorem 1, row by row.

use numpy::PyReadonlyArray1;
use pyo3::prelude::*;
use upm_core::{friction, theory};

use crate::arrays::elementwise;
use crate::errors::core;

/// Theorem 1 closed form, `Tri(n1 n2 psi) / (n2^2 - n1^2)` (0 when both are odd, Lemma 1).
#[pyfunction]
pub fn theorem1_force<'py>(
    py: Python<'py>,
    n1: i64,
    n2: i64,
    psi: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyAny>> {
    core(py, friction::check_pair(n1, n2))?;
    elementwise(py, "theorem1_force", [("psi", psi)], |[p]| {
        Ok([theory::theorem1_force(n1, n2, p)?])
    })
}

/// A `#[pyfunction]` taking equal-length float64 columns named like the Rust parameters and
/// applying a `upm_core::theory` closed form to each row.
macro_rules! elementwise_fn {
    ($(#[$doc:meta])* $name:ident($($arg:ident),+) => |$row:pat_param| $body:expr) => {
        $(#[$doc])*
        #[pyfunction]
        pub fn $name<'py>(py: Python<'py>, $($arg: PyReadonlyArray1<'py, f64>),+) -> PyResult<Bound<'py, PyAny>> {
            elementwise(py, stringify!($name), [$((stringify!($arg), $arg)),+], |$row| $body)
        }
    };
}

elementwise_fn!(
    /// Bang-bang feed rate (3.11).
    bang_bang_feed_rate(z, a_max, period) => |[z, a, p]| Ok([theory::bang_bang_feed_rate(z, a, p)?])
);
elementwise_fn!(
    /// Bang-bang force at a part velocity (3.10).
    bang_bang_force(z, part_velocity, a_max, period) =>
        |[z, v, a, p]| Ok([theory::bang_bang_force(z, v, a, p)?])
);
elementwise_fn!(
    /// Bang-bang velocity range (3.8) -> (v_min, v_max).
    bang_bang_velocity_range(z, a_max, period) => |[z, a, p]| {
        let (lo, hi) = theory::bang_bang_velocity_range(z, a, p)?;
        Ok([lo, hi])
    }
);
elementwise_fn!(
    /// Bang-bang efficiencies (3.5) -> (eta1, eta2).
    bang_bang_efficiency(z) => |[z]| {
        let (e1, e2) = theory::bang_bang_efficiency(z)?;
        Ok([e1, e2])
    }
);
elementwise_fn!(
    /// Gain of the viscous model (3.12).
    viscous_gain(a_max, period, mu_m_g) => |[a, p, m]| Ok([theory::viscous_gain(a, p, m)?])
);
elementwise_fn!(
    /// Two-harmonic feed rate (3.16)-(3.17).
    two_harmonic_feed_rate(b, phi, amplitude) =>
        |[b, phi, a]| Ok([theory::two_harmonic_feed_rate(b, phi, a)?])
);
elementwise_fn!(
    /// Force at rest under sin t + b cos 2t (3.15).
    two_harmonic_force_at_rest(b) => |[b]| Ok([theory::two_harmonic_force_at_rest(b)?])
);
elementwise_fn!(
    /// max |cos t - 2b sin 2t| (3.18).
    gamma(b) => |[b]| Ok([theory::gamma(b)?])
);
elementwise_fn!(
    /// The normalised drive (3.18)-(3.20) -> (gamma, v_min, v_max, v_eq, eta1, eta2).
    normalized_drive(b, a_max, period) => |[b, a, p]| {
        let d = theory::normalized_drive(b, a, p)?;
        Ok([d.gamma, d.v_min, d.v_max, d.v_eq, d.eta1, d.eta2])
    }
);
