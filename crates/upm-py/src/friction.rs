//! Binding of `upm_core::friction`: exact average forces.

use numpy::PyReadonlyArray1;
use pyo3::prelude::*;
use upm_core::friction;

use crate::arrays::elementwise_on;
use crate::errors::core;

/// Exact average force / (mu m g) at rest under `cos(n1 t) - b cos(n2 (t - psi))`.
#[pyfunction]
#[pyo3(signature = (n1, n2, psi, b, threads=None))]
pub fn force_table<'py>(
    py: Python<'py>,
    n1: i64,
    n2: i64,
    psi: PyReadonlyArray1<'py, f64>,
    b: PyReadonlyArray1<'py, f64>,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyAny>> {
    core(py, friction::check_pair(n1, n2))?;
    elementwise_on(
        py,
        "force_table",
        [("psi", psi), ("b", b)],
        threads,
        |[p, b]| Ok([friction::two_sinusoid_force(n1, n2, p, b)?]),
    )
}
