//! Binding of `upm_core::centroid` (the coverage centroids of `upm.vision`).

use numpy::{PyArray1, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use upm_core::centroid;

use crate::arrays::{pairs, to_2d};
use crate::errors::{detached, Failure};

/// Coverage centroids: `cover (N, P, P)` float32 windows at `origins (N, 2)`, starting
/// `centres (N, 2)`; returns refined centres `(N, 2)`, areas `(N,)` and ring coverages `(N,)`.
#[pyfunction]
#[pyo3(signature = (cover, origins, centres, radius, iterations))]
pub fn coverage_centroids<'py>(
    py: Python<'py>,
    cover: PyReadonlyArray3<'py, f32>,
    origins: PyReadonlyArray2<'py, f64>,
    centres: PyReadonlyArray2<'py, f64>,
    radius: f64,
    iterations: usize,
) -> PyResult<Bound<'py, PyTuple>> {
    let shape = cover.shape().to_vec();
    if shape[1] != shape[2] {
        return Err(crate::errors::shape_error(
            py,
            format!("cover must hold square windows (N, P, P); got {shape:?}"),
        ));
    }
    let values: Vec<f32> = match cover.as_slice() {
        Ok(contiguous) => contiguous.to_vec(),
        Err(_) => cover.as_array().iter().copied().collect(),
    };
    let o = pairs(py, "origins", &origins)?;
    let c = pairs(py, "centres", &centres)?;
    let n = c.len();
    let out = detached(py, || {
        centroid::coverage_centroids(&values, shape[1], &o, &c, radius, iterations)
            .map_err(Failure::from)
    })?;
    let flat: Vec<f64> = out.centres.iter().flat_map(|p| [p[0], p[1]]).collect();
    PyTuple::new(
        py,
        [
            to_2d(py, flat, n, 2)?,
            PyArray1::from_vec(py, out.area).into_any(),
            PyArray1::from_vec(py, out.ring).into_any(),
        ],
    )
}
