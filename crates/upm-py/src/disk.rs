//! Binding of `upm_core::disk`: a sliding, spinning disk's friction.

use numpy::PyReadonlyArray1;
use pyo3::prelude::*;

use crate::arrays::elementwise;

/// Friction of a sliding, spinning disk under uniform pressure at `phi = atan2(R |W|, |w|)` in
/// `[0, pi/2]`: force / (mu m g) and torque / (mu m g R), by quadrature (`upm_core::disk`).
#[pyfunction]
pub fn disk_friction<'py>(
    py: Python<'py>,
    phi: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyAny>> {
    elementwise(py, "disk_friction", [("phi", phi)], |[p]| {
        let (f, t) = upm_core::disk::force_torque(upm_core::error::finite("phi", p)?);
        Ok([f, t])
    })
}
