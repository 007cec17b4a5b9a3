//! Binding of the velocity fields of a plate that moves out of its plane (`upm_core::ppod`).

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2};
use pyo3::prelude::*;
use upm_core::ppod::{self, DriftConfig, FieldPoint};

use crate::arrays::pairs;
use crate::errors::batch_on;
use crate::motion::PlateMotion;

/// Points per task: the unit of parallel work and of the Ctrl-C check.
const CHUNK: usize = 16;

/// `field` on the points in chunks of [`CHUNK`], in parallel, Ctrl-C checked between chunks.
fn chunked<F>(
    py: Python<'_>,
    p: &[[f64; 2]],
    threads: Option<usize>,
    field: F,
) -> PyResult<Vec<Vec<FieldPoint>>>
where
    F: Fn(&[[f64; 2]]) -> upm_core::Result<Vec<FieldPoint>> + Sync + Send,
{
    batch_on(py, p.len().div_ceil(CHUNK), threads, |c| {
        field(&p[c * CHUNK..((c + 1) * CHUNK).min(p.len())])
    })
}

/// A field at M points (what `drift_field` and `asymptotic_field` return).
#[pyclass(frozen, module = "upm._core")]
pub struct Field {
    /// `(M, 2)` [m/s].
    #[pyo3(get)]
    velocity: Py<PyAny>,
    /// `(M,)`: the largest horizontal acceleration of the surface over a cycle [m/s^2].
    #[pyo3(get)]
    max_accel: Py<PyAny>,
    /// `(M,)`: the fraction of the cycle a part there is in the air.
    #[pyo3(get)]
    lift: Py<PyAny>,
    /// `(M,)`: the periods (or iterations) each point took.
    #[pyo3(get)]
    work: Py<PyAny>,
    /// `(M,)`, whether each point converged.
    #[pyo3(get)]
    converged: Py<PyAny>,
}

/// The points' results as a [`Field`].
fn arrays(py: Python<'_>, out: Vec<Vec<FieldPoint>>) -> PyResult<Field> {
    let all: Vec<FieldPoint> = out.into_iter().flatten().collect();
    let m = all.len();
    let v = PyArray1::from_iter(py, all.iter().flat_map(|f| f.v)).reshape([m, 2])?;
    let accel = PyArray1::from_iter(py, all.iter().map(|f| f.max_accel));
    let lift = PyArray1::from_iter(py, all.iter().map(|f| f.lift));
    let work = PyArray1::from_iter(py, all.iter().map(|f| f.work as u64));
    let ok = PyArray1::from_iter(py, all.iter().map(|f| f.converged));
    Ok(Field {
        velocity: v.into_any().unbind(),
        max_accel: accel.into_any().unbind(),
        lift: lift.into_any().unbind(),
        work: work.into_any().unbind(),
        converged: ok.into_any().unbind(),
    })
}

/// The drift field at `points (M, 2)`.
#[pyfunction]
#[pyo3(signature = (motion, points, *, mu, mu_s, g, steps, tol, max_periods, threads=None))]
pub fn drift_field<'py>(
    py: Python<'py>,
    motion: PyRef<'py, PlateMotion>,
    points: PyReadonlyArray2<'py, f64>,
    mu: f64,
    mu_s: f64,
    g: f64,
    steps: usize,
    tol: f64,
    max_periods: usize,
    threads: Option<usize>,
) -> PyResult<Field> {
    let p = pairs(py, "points", &points)?;
    let m = motion.inner.clone();
    let cfg = DriftConfig {
        mu,
        mu_s,
        g,
        steps,
        tol,
        max_periods,
    };
    let out = chunked(py, &p, threads, |q| ppod::drift(&m, q, &cfg))?;
    arrays(py, out)
}

/// The asymptotic field at `points (M, 2)`.
#[pyfunction]
#[pyo3(signature = (motion, points, *, g, samples, threads=None))]
pub fn asymptotic_field<'py>(
    py: Python<'py>,
    motion: PyRef<'py, PlateMotion>,
    points: PyReadonlyArray2<'py, f64>,
    g: f64,
    samples: usize,
    threads: Option<usize>,
) -> PyResult<Field> {
    let p = pairs(py, "points", &points)?;
    let m = motion.inner.clone();
    let out = chunked(py, &p, threads, |q| ppod::asymptotic(&m, q, g, samples))?;
    arrays(py, out)
}
