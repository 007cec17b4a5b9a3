//! Binding of `upm_core::field`: rotation, jet and average force fields at points.

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2};
use pyo3::prelude::*;

use upm_core::field;

use crate::arrays::{concat_pairs, pairs};
use crate::errors::{batch_on, shape_error};
use crate::motion::PlateMotion;

fn field_out<'py>(py: Python<'py>, v: Vec<[f64; 2]>) -> PyResult<Bound<'py, PyAny>> {
    let k = v.len();
    Ok(PyArray1::from_vec(py, concat_pairs(&v))
        .reshape([k, 2])?
        .into_any())
}

/// `(K, 2)` unit tangential field about `center`.
#[pyfunction]
pub fn rotation_field<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    center: [f64; 2],
) -> PyResult<Bound<'py, PyAny>> {
    let p = pairs(py, "points", &points)?;
    field_out(
        py,
        p.iter()
            .map(|&x| field::rotation_field(x, center))
            .collect(),
    )
}

/// `(K,)` curl `1/|P - C|`.
#[pyfunction]
pub fn rotation_curl<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    center: [f64; 2],
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let p = pairs(py, "points", &points)?;
    Ok(PyArray1::from_vec(
        py,
        p.iter().map(|&x| field::rotation_curl(x, center)).collect(),
    ))
}

/// `(K, 2)` exact jet field, in parallel.
#[pyfunction]
#[pyo3(signature = (points, center, direction, rho, tol, threads=None))]
pub fn jet_field<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    center: [f64; 2],
    direction: [f64; 2],
    rho: f64,
    tol: f64,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyAny>> {
    let p = pairs(py, "points", &points)?;
    let out = batch_on(py, p.len(), threads, |i| {
        field::jet_field(p[i], center, direction, rho, tol)
    })?;
    field_out(py, out)
}

/// `(K, 2)` average field of `motion` at `points` for parts moving at `part_velocity (K, 2)`.
#[pyfunction]
#[pyo3(signature = (motion, points, part_velocity, tol, threads=None))]
pub fn average_field<'py>(
    py: Python<'py>,
    motion: PyRef<'py, PlateMotion>,
    points: PyReadonlyArray2<'py, f64>,
    part_velocity: PyReadonlyArray2<'py, f64>,
    tol: f64,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyAny>> {
    let p = pairs(py, "points", &points)?;
    let v = pairs(py, "part_velocity", &part_velocity)?;
    if v.len() != p.len() {
        return Err(shape_error(
            py,
            format!(
                "part_velocity must have shape ({}, 2) like points; got ({}, 2)",
                p.len(),
                v.len()
            ),
        ));
    }
    let m = motion.inner.clone();
    let out = batch_on(py, p.len(), threads, |i| {
        field::average_field(&m, p[i], v[i], tol)
    })?;
    field_out(py, out)
}
