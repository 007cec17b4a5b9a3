//! Arrays in and out, shared by every binding file: columns, points, flat views, and
//! [`elementwise`] (equal-length float64 columns through a core function, in parallel).

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::errors::{batch_on, shape_error};

pub(crate) fn column(a: &PyReadonlyArray1<'_, f64>) -> Vec<f64> {
    a.as_array().to_vec()
}

pub(crate) fn same_len(py: Python<'_>, what: &str, lens: &[(&str, usize)]) -> PyResult<usize> {
    let n = lens[0].1;
    if lens.iter().any(|(_, l)| *l != n) {
        let listed: Vec<String> = lens
            .iter()
            .map(|(name, l)| format!("{name}: {l}"))
            .collect();
        return Err(shape_error(
            py,
            format!(
                "{what}: inputs must have equal lengths; got {}",
                listed.join(", ")
            ),
        ));
    }
    Ok(n)
}

/// An `(N, 2)` float64 array as a list of points; `ShapeError` naming `name` otherwise.
pub(crate) fn pairs(
    py: Python<'_>,
    name: &str,
    a: &PyReadonlyArray2<'_, f64>,
) -> PyResult<Vec<[f64; 2]>> {
    let a = a.as_array();
    if a.shape()[1] != 2 {
        return Err(shape_error(
            py,
            format!("{name} must have shape (N, 2); got {:?}", a.shape()),
        ));
    }
    Ok(a.rows().into_iter().map(|r| [r[0], r[1]]).collect())
}

/// An `(N, 2)` array as pairs, borrowed when it is C-contiguous (copied otherwise).
pub(crate) fn pair_view<'a>(
    py: Python<'_>,
    name: &str,
    a: &'a PyReadonlyArray2<'_, f64>,
) -> PyResult<std::borrow::Cow<'a, [[f64; 2]]>> {
    if a.shape()[1] != 2 {
        return Err(shape_error(
            py,
            format!("{name} must have shape (N, 2); got {:?}", a.shape()),
        ));
    }
    Ok(flat_pairs(a))
}

/// The consecutive pairs of an array whose last axis is 2 (checked by the caller), borrowed when
/// it is C-contiguous (copied otherwise).
pub(crate) fn flat_pairs<'a, D: numpy::ndarray::Dimension>(
    a: &'a numpy::PyReadonlyArray<'_, f64, D>,
) -> std::borrow::Cow<'a, [[f64; 2]]> {
    match a.as_slice() {
        Ok(flat) => std::borrow::Cow::Borrowed(flat.as_chunks::<2>().0),
        Err(_) => std::borrow::Cow::Owned(
            a.as_array()
                .iter()
                .copied()
                .collect::<Vec<f64>>()
                .as_chunks::<2>()
                .0
                .to_vec(),
        ),
    }
}

/// An array's values in row-major order, borrowed when it is C-contiguous (copied otherwise).
pub(crate) fn view<'a, D: numpy::ndarray::Dimension>(
    a: &'a numpy::PyReadonlyArray<'_, f64, D>,
) -> std::borrow::Cow<'a, [f64]> {
    match a.as_slice() {
        Ok(s) => std::borrow::Cow::Borrowed(s),
        Err(_) => std::borrow::Cow::Owned(a.as_array().iter().copied().collect()),
    }
}

pub(crate) fn to_2d<'py>(
    py: Python<'py>,
    flat: Vec<f64>,
    rows: usize,
    cols: usize,
) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_vec(py, flat)
        .reshape([rows, cols])?
        .into_any())
}

/// Applies `f` to equal-length float64 columns in parallel; returns one array per output.
pub(crate) fn elementwise<'py, const N: usize, const M: usize, F>(
    py: Python<'py>,
    what: &str,
    inputs: [(&str, PyReadonlyArray1<'py, f64>); N],
    f: F,
) -> PyResult<Bound<'py, PyAny>>
where
    F: Fn([f64; N]) -> upm_core::Result<[f64; M]> + Sync + Send,
{
    elementwise_on(py, what, inputs, None, f)
}

/// [`elementwise`] on a pool of `threads` threads.
pub(crate) fn elementwise_on<'py, const N: usize, const M: usize, F>(
    py: Python<'py>,
    what: &str,
    inputs: [(&str, PyReadonlyArray1<'py, f64>); N],
    threads: Option<usize>,
    f: F,
) -> PyResult<Bound<'py, PyAny>>
where
    F: Fn([f64; N]) -> upm_core::Result<[f64; M]> + Sync + Send,
{
    let lens: Vec<(&str, usize)> = inputs.iter().map(|(name, a)| (*name, a.len())).collect();
    let n = same_len(py, what, &lens)?;
    let cols: Vec<Vec<f64>> = inputs.iter().map(|(_, a)| column(a)).collect();
    let out = batch_on(py, n, threads, |i| f(std::array::from_fn(|k| cols[k][i])))?;
    let arrays: Vec<Bound<'py, PyArray1<f64>>> = (0..M)
        .map(|m| PyArray1::from_vec(py, out.iter().map(|r| r[m]).collect()))
        .collect();
    if M == 1 {
        Ok(arrays[0].clone().into_any())
    } else {
        Ok(PyTuple::new(py, arrays)?.into_any())
    }
}

/// Points as one flat `[x0, y0, x1, y1, ...]` vector.
pub(crate) fn concat_pairs(p: &[[f64; 2]]) -> Vec<f64> {
    p.iter().flatten().copied().collect()
}
