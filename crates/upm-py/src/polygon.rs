//! Binding of convex polygon parts (`upm_core::polygon`).

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use upm_core::polygon::Polygon;

use crate::arrays::pairs;
use crate::errors::{batch_on, core, shape_error};

/// Twists per task: the unit of parallel work and of the Ctrl-C check.
const CHUNK: usize = 256;

/// The convex polygon `vertices (K, 2)`, resting on the three feet `support (3, 2)` (in the
/// vertices' frame) if given; `ParameterError` naming `name` (or `{name}` with `.support` for
/// the feet) and the reason otherwise.
pub(crate) fn polygon(
    py: Python<'_>,
    name: &str,
    vertices: &PyReadonlyArray2<'_, f64>,
    support: Option<&PyReadonlyArray2<'_, f64>>,
) -> PyResult<Polygon> {
    let v = pairs(py, name, vertices)?;
    let mut p = core(py, Polygon::new(name, &v))?;
    if let Some(s) = support {
        let feet_name = match name.strip_suffix(".vertices") {
            Some(part) => format!("{part}.support"),
            None => "support".to_string(),
        };
        let f = pairs(py, &feet_name, s)?;
        let Ok(feet) = <[[f64; 2]; 3]>::try_from(f.as_slice()) else {
            return Err(shape_error(
                py,
                format!(
                    "{feet_name} must have shape (3, 2): three feet; got {} rows",
                    f.len()
                ),
            ));
        };
        core(py, p.set_feet(&feet_name, Some(feet)))?;
    }
    Ok(p)
}

/// A polygon part as the Python layer passes it: its index, its vertices `(K, 2)` in its frame
/// and its three feet `(3, 2)` there, if it stands on them.
pub(crate) type PolygonArg<'py> = (
    usize,
    PyReadonlyArray2<'py, f64>,
    Option<PyReadonlyArray2<'py, f64>>,
);

/// The polygon parts `(part, vertices (K, 2), feet (3, 2) or None)` of a simulation, each as
/// [`polygon`] builds it (errors naming `parts[i].vertices`); parts of one outline on the same
/// feet (to the bit) share one construction, cloned (its far field's quadrature points take
/// tens of microseconds a polygon, and a clone shares them: a 1-step call on 200 hexagons spent
/// 3.9 ms building them one by one).
pub(crate) fn polygons(
    py: Python<'_>,
    items: &[PolygonArg<'_>],
) -> PyResult<Vec<(usize, Polygon)>> {
    let mut built: std::collections::HashMap<Vec<u64>, Polygon> = Default::default();
    let mut out = Vec::with_capacity(items.len());
    for (i, v, feet) in items {
        // (the shapes first: arrays of other shapes, with or without feet, never meet, and one
        // of a wrong shape is built, and refused, on its own)
        let shape_of = |a: &PyReadonlyArray2<'_, f64>| a.as_array().shape().to_vec();
        let feet_shape = feet.as_ref().map_or(vec![usize::MAX], shape_of);
        let feet_bits = feet
            .iter()
            .flat_map(|f| f.as_array().iter().map(|x| x.to_bits()).collect::<Vec<_>>());
        let key: Vec<u64> = shape_of(v)
            .into_iter()
            .chain(feet_shape)
            .map(|n| n as u64)
            .chain(v.as_array().iter().map(|x| x.to_bits()))
            .chain(feet_bits)
            .collect();
        let shape = match built.get(&key) {
            Some(p) => p.clone(),
            None => {
                let name = format!("parts[{i}].vertices");
                let p = polygon(py, &name, v, feet.as_ref())?;
                built.insert(key, p.clone());
                p
            }
        };
        out.push((*i, shape));
    }
    Ok(out)
}

/// An `(M, 3)` array as rows; `ShapeError` naming `name` otherwise.
fn triples(py: Python<'_>, name: &str, a: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<[f64; 3]>> {
    let t = a.as_array();
    if t.shape()[1] != 3 {
        return Err(shape_error(
            py,
            format!("{name} must have shape (M, 3); got {:?}", t.shape()),
        ));
    }
    Ok(t.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect())
}

/// `f(index, row)` for every row, in chunks of [`CHUNK`] in parallel (Ctrl-C checked between
/// chunks), in order.
fn each_row<T, F>(
    py: Python<'_>,
    rows: &[[f64; 3]],
    threads: Option<usize>,
    f: F,
) -> PyResult<Vec<T>>
where
    T: Send,
    F: Fn(usize, [f64; 3]) -> upm_core::Result<T> + Sync + Send,
{
    let m = rows.len();
    let out = batch_on(py, m.div_ceil(CHUNK), threads, |c| {
        (c * CHUNK..((c + 1) * CHUNK).min(m))
            .map(|i| f(i, rows[i]))
            .collect::<upm_core::Result<Vec<T>>>()
    })?;
    Ok(out.into_iter().flatten().collect())
}

/// `(area, centroid (2,), polar, radius, mean_distance, vertices (K, 2) about the centroid,
/// second moments (xx, xy, yy) over the area, the feet's shares (3,) or None)` of
/// the polygon `vertices (K, 2)` on the feet `support (3, 2)` if given (then `mean_distance` is
/// the feet's, weighted by their shares); `ParameterError` naming `name` and the reason if it
/// is not a convex counter-clockwise polygon or the feet cannot carry it.
#[pyfunction]
#[pyo3(signature = (vertices, name="vertices", support=None))]
pub fn polygon_geometry<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    name: &str,
    support: Option<PyReadonlyArray2<'py, f64>>,
) -> PyResult<Bound<'py, PyTuple>> {
    let p = polygon(py, name, &vertices, support.as_ref())?;
    let shares = match p.tripod() {
        Some(t) => PyArray1::from_vec(py, t.shares.to_vec()).into_any(),
        None => py.None().into_bound(py),
    };
    let k = p.vertices.len();
    let centred = PyArray1::from_iter(py, p.vertices.iter().flatten().copied()).reshape([k, 2])?;
    PyTuple::new(
        py,
        [
            p.area.into_pyobject(py)?.into_any(),
            PyArray1::from_vec(py, p.centroid.to_vec()).into_any(),
            p.polar.into_pyobject(py)?.into_any(),
            p.radius.into_pyobject(py)?.into_any(),
            p.mean_distance().into_pyobject(py)?.into_any(),
            centred.into_any(),
            PyArray1::from_vec(py, p.second_moments().to_vec()).into_any(),
            shares,
        ],
    )
}

/// The polygon `vertices (K, 2)` (on the feet `support`, if given) under the pressure gradient
/// `load` (`k` of `p = (N / A) (1 + k . r)`, [1/m]; `ParameterError` if the pressure would be
/// negative somewhere, or a foot would pull).
fn loaded(
    py: Python<'_>,
    vertices: &PyReadonlyArray2<'_, f64>,
    support: Option<&PyReadonlyArray2<'_, f64>>,
    load: [f64; 2],
) -> PyResult<Polygon> {
    let mut p = polygon(py, "vertices", vertices, support)?;
    core(py, p.set_load(load))?;
    Ok(p)
}

/// The friction wrench `(Fx, Fy, M) / (mu N)`, `(M, 3)`, of the polygon `vertices (K, 2)` sliding
/// with the relative twists `twists (M, 3)` (`vx, vy, omega` at its centroid) under the
/// pressure gradient `load`, in parallel.
#[pyfunction]
#[pyo3(signature = (vertices, twists, threads=None, load=(0.0, 0.0), support=None))]
pub fn polygon_wrench<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    twists: PyReadonlyArray2<'py, f64>,
    threads: Option<usize>,
    load: (f64, f64),
    support: Option<PyReadonlyArray2<'py, f64>>,
) -> PyResult<Bound<'py, PyAny>> {
    let p = loaded(py, &vertices, support.as_ref(), [load.0, load.1])?;
    let rows = triples(py, "twists", &twists)?;
    let m = rows.len();
    let out = each_row(py, &rows, threads, |i, [vx, vy, w]| {
        if !(vx.is_finite() && vy.is_finite() && w.is_finite()) {
            return Err(upm_core::Error::parameter(
                "twists",
                format!("must be finite; row {i} is {:?}", [vx, vy, w]),
            ));
        }
        Ok(p.wrench([vx, vy], w))
    })?;
    Ok(PyArray1::from_iter(py, out.into_iter().flatten())
        .reshape([m, 3])?
        .into_any())
}

/// The gauges of the wrenches `wrenches (M, 3)` (`Fx, Fy, M` per `mu N`) in the limit set of
/// the polygon `vertices (K, 2)` under the pressure gradient `load`, and the sliding twists
/// `(M, 3)` they point to, in parallel.
#[pyfunction]
#[pyo3(signature = (vertices, wrenches, threads=None, load=(0.0, 0.0), support=None))]
pub fn polygon_gauge<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    wrenches: PyReadonlyArray2<'py, f64>,
    threads: Option<usize>,
    load: (f64, f64),
    support: Option<PyReadonlyArray2<'py, f64>>,
) -> PyResult<Bound<'py, PyTuple>> {
    let p = loaded(py, &vertices, support.as_ref(), [load.0, load.1])?;
    let rows = triples(py, "wrenches", &wrenches)?;
    let m = rows.len();
    let all = each_row(py, &rows, threads, |_, [fx, fy, mz]| p.gauge(fx, fy, mz))?;
    let values = PyArray1::from_iter(py, all.iter().map(|g| g.value));
    let twists = PyArray1::from_iter(py, all.iter().flat_map(|g| g.twist)).reshape([m, 3])?;
    PyTuple::new(py, [values.into_any(), twists.into_any()])
}
