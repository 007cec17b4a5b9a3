//! Binding of `upm_core::plan`: the predictive planner's scoring kernels.

use numpy::{
    PyArray1, PyArray4, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use upm_core::plan;

use crate::arrays::{flat_pairs, pair_view, view};
use crate::errors::{detached, shape_error, Failure};

/// Positions `(L, R + T, M, 2)` after each displacement table from each layout `q (L, M, 2)`:
/// rotations about `centres (R, 2)` tabulated on `radii (n,)` as `turn (R, n, 2)`, and
/// translations `shift (T, 2)` (see `upm_core::plan`).
#[pyfunction]
pub fn apply_rays<'py>(
    py: Python<'py>,
    q: PyReadonlyArray3<'py, f64>,
    radii: PyReadonlyArray1<'py, f64>,
    centres: PyReadonlyArray2<'py, f64>,
    turn: PyReadonlyArray3<'py, f64>,
    shift: PyReadonlyArray2<'py, f64>,
) -> PyResult<Bound<'py, PyArray4<f64>>> {
    let (l, m) = (q.shape()[0], q.shape()[1]);
    if q.shape()[2] != 2 || turn.shape()[2] != 2 {
        return Err(shape_error(
            py,
            "q and turn must end in a coordinate axis of 2".to_string(),
        ));
    }
    let c = pair_view(py, "centres", &centres)?;
    let s = pair_view(py, "shift", &shift)?;
    let k = c.len() + s.len();
    if m == 0 || l == 0 {
        return PyArray1::from_vec(py, Vec::<f64>::new()).reshape([l, k, m, 2]);
    }
    let qs = flat_pairs(&q);
    let ts = flat_pairs(&turn);
    let r = view(&radii);
    let out = detached(py, || {
        let tables = plan::RayTables {
            radii: &r,
            centres: &c,
            turn: &ts,
            shift: &s,
        };
        let mut out = vec![[0.0; 2]; l * k * m];
        plan::apply_rays(&tables, &qs, m, &mut out).map_err(Failure::from)?;
        Ok(out)
    })?;
    PyArray1::from_vec(py, out.into_flattened()).reshape([l, k, m, 2])
}

/// `L` layouts of `M` parts, and their positions laid flat.
type Layouts<'a> = (usize, usize, std::borrow::Cow<'a, [[f64; 2]]>);

/// Layouts `q (L, M, 2)` as `(L, M, positions)`, or a shape error naming what was expected.
fn layouts<'a>(py: Python<'_>, q: &'a PyReadonlyArray3<'_, f64>) -> PyResult<Layouts<'a>> {
    let shape = q.shape();
    if shape[2] != 2 {
        return Err(shape_error(
            py,
            format!("q must have shape (L, M, 2); got {shape:?}"),
        ));
    }
    Ok((shape[0], shape[1], flat_pairs(q)))
}

/// Layouts of `m` parts like `q`'s, as pairs laid flat, or a shape error naming `name`.
fn layouts_like<'a>(
    py: Python<'_>,
    name: &str,
    a: &'a PyReadonlyArray3<'_, f64>,
    m: usize,
) -> PyResult<std::borrow::Cow<'a, [[f64; 2]]>> {
    let (_, ma, flat) = layouts(py, a)?;
    if ma != m {
        return Err(shape_error(
            py,
            format!("{name} must hold layouts of {m} points like q; got {ma}"),
        ));
    }
    Ok(flat)
}

/// One sum a layout, `(L,)`, written by `sum` with the GIL released (zeros when the layouts hold
/// no part).
fn per_layout<'py>(
    py: Python<'py>,
    l: usize,
    m: usize,
    sum: impl FnOnce(&mut [f64]) -> upm_core::error::Result<()> + Send,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let out = detached(py, || {
        let mut out = vec![0.0; l];
        if m > 0 {
            sum(&mut out).map_err(Failure::from)?;
        }
        Ok(out)
    })?;
    Ok(PyArray1::from_vec(py, out))
}

/// The predictive planner's edge penalty `(L,)` of layouts `q (L, M, 2)`; with `start (S, M, 2)`,
/// each part scored `spread` times its way from its layout's start further out (see
/// `upm_core::plan::edge_penalty` and `Spread`).
#[pyfunction]
#[pyo3(signature = (q, half, band, weight, lost, guard, start=None, spread=0.0))]
pub fn edge_penalty<'py>(
    py: Python<'py>,
    q: PyReadonlyArray3<'py, f64>,
    half: f64,
    band: f64,
    weight: f64,
    lost: f64,
    guard: f64,
    start: Option<PyReadonlyArray3<'py, f64>>,
    spread: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let (l, m, qs) = layouts(py, &q)?;
    let from = match &start {
        Some(s) => Some(layouts_like(py, "start", s, m)?),
        None => None,
    };
    let edges = plan::Edges {
        half,
        band,
        weight,
        lost,
        guard,
    };
    per_layout(py, l, m, |out| {
        let spread = from.as_deref().map(|start| plan::Spread {
            start,
            factor: spread,
        });
        plan::edge_penalty(&edges, &qs, m, spread, out)
    })
}

/// Sum over the parts of each layout `q (L, M, 2)` of their distances to `targets (T, M, 2)`
/// (each for `L / T` consecutive layouts), less `slack` and bent over `bend` (see
/// `upm_core::plan::distance_sum`), `(L,)`.
#[pyfunction]
pub fn distance_sum<'py>(
    py: Python<'py>,
    q: PyReadonlyArray3<'py, f64>,
    targets: PyReadonlyArray3<'py, f64>,
    slack: f64,
    bend: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let (l, m, qs) = layouts(py, &q)?;
    let t = layouts_like(py, "targets", &targets, m)?;
    per_layout(py, l, m, |out| {
        plan::distance_sum(&t, m, plan::Reach { slack, bend }, &qs, out)
    })
}

/// The predictive planner's overlap penalty `(L,)` of layouts `q (L, M, 2)`: over pairs closer
/// than `reach` [m], the sum of `reach - distance` (see `upm_core::plan::overlap_penalty`).
#[pyfunction]
pub fn overlap_penalty<'py>(
    py: Python<'py>,
    q: PyReadonlyArray3<'py, f64>,
    reach: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let (l, m, qs) = layouts(py, &q)?;
    per_layout(py, l, m, |out| plan::overlap_penalty(reach, &qs, m, out))
}
