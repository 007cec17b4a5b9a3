//! Binding of the solvers (`upm_core::solve`) and the force fields (`upm_core::field`).

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use upm_core::solve::{self as core_solve, Curls, Options, Plan};
use upm_core::Error;

use crate::arrays::{concat_pairs, pairs};
use crate::errors::{batch, detached, shape_error, Failure};

/// `(B, K, 2)` as B lists of points.
fn stacks(
    py: Python<'_>,
    name: &str,
    a: &PyReadonlyArray3<'_, f64>,
) -> PyResult<Vec<Vec<[f64; 2]>>> {
    let a = a.as_array();
    if a.shape()[2] != 2 {
        return Err(shape_error(
            py,
            format!("{name} must have shape (B, K, 2); got {:?}", a.shape()),
        ));
    }
    Ok(a.outer_iter()
        .map(|m| m.rows().into_iter().map(|r| [r[0], r[1]]).collect())
        .collect())
}

fn options(rcond: Option<f64>, damping: f64, max_strength: Option<f64>) -> Options {
    Options {
        rcond,
        damping,
        max_strength,
    }
}

fn solve_one(
    parts: &[[f64; 2]],
    targets: &[[f64; 2]],
    centers: &[[f64; 2]],
    curl_points: &[[f64; 2]],
    curls: &[f64],
    mu_m_g: Option<f64>,
    opts: &Options,
) -> upm_core::Result<Plan> {
    match mu_m_g {
        Some(s) => core_solve::solve_rotations(
            parts,
            targets,
            centers,
            Curls {
                points: curl_points,
                values: curls,
            },
            s,
            opts,
        ),
        None if curls.is_empty() => core_solve::solve_displacements(parts, targets, centers, opts),
        None => Err(Error::parameter(
            "curls",
            "apply to force plans only (solve_rotations)",
        )),
    }
}

/// Solved systems, each array with a leading batch axis (B systems, M parts, N centres, Q curl
/// points, S singular values): what `solve` and `solve_batch` return.
#[pyclass(frozen, module = "upm._core")]
pub struct Plans {
    /// `(B, N)`.
    #[pyo3(get)]
    strengths: Py<PyAny>,
    /// `(B, N)`: the order of execution (4.2.4).
    #[pyo3(get)]
    order: Py<PyAny>,
    /// `(B, M, 2)`: each part's predicted force or step.
    #[pyo3(get)]
    predicted: Py<PyAny>,
    /// `(B, Q)`.
    #[pyo3(get)]
    predicted_curls: Py<PyAny>,
    /// `(B,)`: `|A x - b|`.
    #[pyo3(get)]
    residual: Py<PyAny>,
    /// `(B,)`: the residual the strength bound costs.
    #[pyo3(get)]
    bound_cost: Py<PyAny>,
    /// `(B, S)`, descending.
    #[pyo3(get)]
    singular_values: Py<PyAny>,
    /// `(B,)`.
    #[pyo3(get)]
    rank: Py<PyAny>,
    /// `(B,)`.
    #[pyo3(get)]
    condition_number: Py<PyAny>,
}

/// Stacks plans into [`Plans`] with a leading batch axis of `plans.len()`.
fn plans_to_py(py: Python<'_>, plans: Vec<Plan>, m: usize, n: usize) -> PyResult<Plans> {
    let b = plans.len();
    let q = plans.first().map_or(0, |p| p.predicted_curls.len());
    let s = plans.first().map_or(0, |p| p.singular_values.len());
    let mut strengths: Vec<f64> = Vec::with_capacity(b * n);
    let mut order = Vec::with_capacity(b * n);
    let mut predicted = Vec::with_capacity(b * m * 2);
    let mut curls: Vec<f64> = Vec::with_capacity(b * q);
    let mut sv: Vec<f64> = Vec::with_capacity(b * s);
    let (mut residual, mut cost, mut cond): (Vec<f64>, Vec<f64>, Vec<f64>) =
        (vec![], vec![], vec![]);
    let mut rank: Vec<i64> = Vec::with_capacity(b);
    for p in &plans {
        strengths.extend(&p.strengths);
        order.extend(p.order.iter().map(|&i| i as i64));
        predicted.extend(concat_pairs(&p.predicted));
        curls.extend(&p.predicted_curls);
        sv.extend(&p.singular_values);
        residual.push(p.residual);
        cost.push(p.bound_cost);
        rank.push(p.rank as i64);
        cond.push(p.condition_number());
    }
    Ok(Plans {
        strengths: PyArray1::from_vec(py, strengths)
            .reshape([b, n])?
            .into_any()
            .unbind(),
        order: PyArray1::from_vec(py, order)
            .reshape([b, n])?
            .into_any()
            .unbind(),
        predicted: PyArray1::from_vec(py, predicted)
            .reshape([b, m, 2])?
            .into_any()
            .unbind(),
        predicted_curls: PyArray1::from_vec(py, curls)
            .reshape([b, q])?
            .into_any()
            .unbind(),
        residual: PyArray1::from_vec(py, residual).into_any().unbind(),
        bound_cost: PyArray1::from_vec(py, cost).into_any().unbind(),
        singular_values: PyArray1::from_vec(py, sv)
            .reshape([b, s])?
            .into_any()
            .unbind(),
        rank: PyArray1::from_vec(py, rank).into_any().unbind(),
        condition_number: PyArray1::from_vec(py, cond).into_any().unbind(),
    })
}

/// One system: forces when `mu_m_g` is given (4.10, 4.12), else steps (5.3). See `plans_to_py`
/// for what it returns (batch axis of length 1).
#[pyfunction]
#[pyo3(signature = (parts, targets, centers, curl_points, curls, mu_m_g, rcond, damping, max_strength))]
pub fn solve<'py>(
    py: Python<'py>,
    parts: PyReadonlyArray2<'py, f64>,
    targets: PyReadonlyArray2<'py, f64>,
    centers: PyReadonlyArray2<'py, f64>,
    curl_points: PyReadonlyArray2<'py, f64>,
    curls: PyReadonlyArray1<'py, f64>,
    mu_m_g: Option<f64>,
    rcond: Option<f64>,
    damping: f64,
    max_strength: Option<f64>,
) -> PyResult<Plans> {
    let p = pairs(py, "parts", &parts)?;
    let t = pairs(py, "targets", &targets)?;
    let c = pairs(py, "centers", &centers)?;
    let q = pairs(py, "curl_points", &curl_points)?;
    let k = curls.as_array().to_vec();
    let opts = options(rcond, damping, max_strength);
    let plan = detached(py, || {
        solve_one(&p, &t, &c, &q, &k, mu_m_g, &opts).map_err(Failure::from)
    })?;
    plans_to_py(py, vec![plan], p.len(), c.len())
}

/// B systems of equal size in parallel (GIL released, Ctrl-C between chunks).
#[pyfunction]
#[pyo3(signature = (parts, targets, centers, curl_points, curls, mu_m_g, rcond, damping, max_strength))]
pub fn solve_batch<'py>(
    py: Python<'py>,
    parts: PyReadonlyArray3<'py, f64>,
    targets: PyReadonlyArray3<'py, f64>,
    centers: PyReadonlyArray3<'py, f64>,
    curl_points: PyReadonlyArray3<'py, f64>,
    curls: PyReadonlyArray2<'py, f64>,
    mu_m_g: Option<f64>,
    rcond: Option<f64>,
    damping: f64,
    max_strength: Option<f64>,
) -> PyResult<Plans> {
    let p = stacks(py, "parts", &parts)?;
    let t = stacks(py, "targets", &targets)?;
    let c = stacks(py, "centers", &centers)?;
    let q = stacks(py, "curl_points", &curl_points)?;
    let k: Vec<Vec<f64>> = curls.as_array().outer_iter().map(|r| r.to_vec()).collect();
    let b = p.len();
    if [t.len(), c.len(), q.len(), k.len()].iter().any(|&l| l != b) {
        return Err(shape_error(
            py,
            format!(
                "solve_rotations_batch: batch sizes differ: parts {b}, targets {}, centers {}, curl_points {}, curls {}",
                t.len(),
                c.len(),
                q.len(),
                k.len()
            ),
        ));
    }
    let opts = options(rcond, damping, max_strength);
    let plans = batch(py, b, |i| {
        solve_one(&p[i], &t[i], &c[i], &q[i], &k[i], mu_m_g, &opts)
    })?;
    let m = p.first().map_or(0, Vec::len);
    let n = c.first().map_or(0, Vec::len);
    plans_to_py(py, plans, m, n)
}

/// Priorities of 4.2.4, `|k_j| / min_i |P_i - C_j|`.
#[pyfunction]
pub fn priorities<'py>(
    py: Python<'py>,
    strengths: PyReadonlyArray1<'py, f64>,
    parts: PyReadonlyArray2<'py, f64>,
    centers: PyReadonlyArray2<'py, f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let p = pairs(py, "parts", &parts)?;
    let c = pairs(py, "centers", &centers)?;
    let k = strengths.as_array().to_vec();
    if k.len() != c.len() {
        return Err(shape_error(
            py,
            format!("strengths has {} entries; centers has {}", k.len(), c.len()),
        ));
    }
    Ok(PyArray1::from_vec(py, core_solve::priorities(&k, &p, &c)))
}

/// Second-order error of the flows in `order` (`exact`: the exact end points instead).
#[pyfunction]
pub fn flow_error<'py>(
    py: Python<'py>,
    strengths: PyReadonlyArray1<'py, f64>,
    parts: PyReadonlyArray2<'py, f64>,
    centers: PyReadonlyArray2<'py, f64>,
    order: Vec<usize>,
    exact: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let p = pairs(py, "parts", &parts)?;
    let c = pairs(py, "centers", &centers)?;
    let k = strengths.as_array().to_vec();
    let out = detached(py, || {
        if exact {
            core_solve::flow_exact(&k, &p, &c, &order)
        } else {
            core_solve::flow_error(&k, &p, &c, &order)
        }
        .map_err(Failure::from)
    })?;
    let m = out.len();
    Ok(PyArray1::from_vec(py, concat_pairs(&out))
        .reshape([m, 2])?
        .into_any())
}
