//! Binding of `upm_core::actuation`: kinematics, plate dynamics, harmonic fits and the
//! accelerometer centre of rotation.

use numpy::{PyArray1, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use upm_core::actuation::{self as act, Axis, Plate};
use upm_core::stroke;

use crate::arrays::{pair_view, pairs, to_2d, view};
use crate::errors::{core, detached, shape_error, Failure};

fn plate(py: Python<'_>, mass: f64, inertia: f64, lever: f64) -> PyResult<Plate> {
    core(py, Plate::new(mass, inertia, lever))
}

/// Motor amplitudes `(X1, X2, Y1, Y2)` for velocity amplitudes `u` (see `Plate::motors_for`).
#[pyfunction]
#[pyo3(signature = (mass, inertia, lever, u, limit))]
pub fn motors_for(
    py: Python<'_>,
    mass: f64,
    inertia: f64,
    lever: f64,
    u: [f64; 3],
    limit: Option<f64>,
) -> PyResult<[f64; 4]> {
    let p = plate(py, mass, inertia, lever)?;
    core(py, p.motors_for(u, limit))
}

/// Velocity amplitudes `(fx/M, fy/M, tau/I)` of motor amplitudes (5.8, 5.10).
#[pyfunction]
pub fn velocity_amplitudes(
    py: Python<'_>,
    mass: f64,
    inertia: f64,
    lever: f64,
    motors: [f64; 4],
) -> PyResult<[f64; 3]> {
    Ok(plate(py, mass, inertia, lever)?.velocity_amplitudes(motors))
}

/// `(center, omega)` of a plate velocity (4.6, 5.7).
#[pyfunction]
pub fn center_of_rotation(py: Python<'_>, u: [f64; 3]) -> PyResult<([f64; 2], f64)> {
    core(py, act::center_of_rotation(u))
}

/// Resonance (if any) and the real and imaginary velocity response.
type Response<'py> = (
    Option<f64>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
);

/// `(resonance or None, re, im)` of one axis's velocity response at angular frequencies `w`.
#[pyfunction]
pub fn axis_response<'py>(
    py: Python<'py>,
    mass: f64,
    damping: f64,
    stiffness: f64,
    w: PyReadonlyArray1<'py, f64>,
) -> PyResult<Response<'py>> {
    let axis = core(py, Axis::new(mass, damping, stiffness))?;
    let (re, im): (Vec<f64>, Vec<f64>) = w
        .as_array()
        .iter()
        .map(|&x| {
            let r = axis.velocity_response(x);
            (r[0], r[1])
        })
        .unzip();
    Ok((
        axis.resonance(),
        PyArray1::from_vec(py, re),
        PyArray1::from_vec(py, im),
    ))
}

/// Three `(N, T)` arrays.
type Three<'py> = (Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>);

/// Acceleration, velocity and position `(N, T)` of `N` runs of one axis under forces `(N, T)`
/// sampled every `dt`, from positions `q0 (N,)` and velocities `v0 (N,)` (semi-implicit Euler).
#[pyfunction]
pub fn axis_steps<'py>(
    py: Python<'py>,
    mass: f64,
    damping: f64,
    stiffness: f64,
    forces: PyReadonlyArray2<'py, f64>,
    dt: f64,
    q0: PyReadonlyArray1<'py, f64>,
    v0: PyReadonlyArray1<'py, f64>,
) -> PyResult<Three<'py>> {
    let axis = core(py, Axis::new(mass, damping, stiffness))?;
    core(py, upm_core::error::positive("dt", dt).map(|_| ()))?;
    let (n, t) = forces.as_array().dim();
    let (q0, v0) = (view(&q0), view(&v0));
    if q0.len() != n || v0.len() != n {
        return Err(shape_error(
            py,
            format!(
                "q0 and v0 must hold one value per run ({n}); got {} and {}",
                q0.len(),
                v0.len()
            ),
        ));
    }
    let f = view(&forces);
    let (acc, vel, pos) = detached(py, || {
        let (mut acc, mut vel, mut pos) = (vec![0.0; n * t], vec![0.0; n * t], vec![0.0; n * t]);
        for r in 0..n {
            let s = r * t..(r + 1) * t;
            axis.steps(
                &f[s.clone()],
                dt,
                q0[r],
                v0[r],
                &mut acc[s.clone()],
                &mut vel[s.clone()],
                &mut pos[s],
            );
        }
        Ok::<_, Failure>((acc, vel, pos))
    })?;
    Ok((
        to_2d(py, acc, n, t)?,
        to_2d(py, vel, n, t)?,
        to_2d(py, pos, n, t)?,
    ))
}

/// `(coefficients, offset, rms residual)` of a harmonic fit (5.13).
#[pyfunction]
pub fn harmonic_fit<'py>(
    py: Python<'py>,
    samples: PyReadonlyArray1<'py, f64>,
    sample_rate: f64,
    frequency: f64,
    multiples: Vec<f64>,
) -> PyResult<(Bound<'py, PyArray1<f64>>, f64, f64)> {
    let s = samples.as_array().to_vec();
    let fit = detached(py, || {
        act::harmonic_fit(&s, sample_rate, frequency, &multiples).map_err(Failure::from)
    })?;
    Ok((
        PyArray1::from_vec(py, fit.coefficients),
        fit.offset,
        fit.residual,
    ))
}

/// Velocity coefficients from acceleration coefficients (5.14).
#[pyfunction]
pub fn velocity_from_fit<'py>(
    py: Python<'py>,
    coefficients: PyReadonlyArray1<'py, f64>,
    frequency: f64,
    multiples: Vec<f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let c = coefficients.as_array().to_vec();
    Ok(PyArray1::from_vec(
        py,
        core(py, act::velocity_from_fit(&c, frequency, &multiples))?,
    ))
}

/// The positive-force test (5.15) on rows `[c1, s1, c2, s2]` of acceleration coefficients.
#[pyfunction]
pub fn positive_force<'py>(
    py: Python<'py>,
    coefficients: PyReadonlyArray2<'py, f64>,
) -> PyResult<Bound<'py, PyArray1<bool>>> {
    let a = coefficients.as_array();
    if a.shape()[1] != 4 {
        return Err(shape_error(
            py,
            format!(
                "coefficients must have shape (..., 4) = [c1, s1, c2, s2]; got {:?}",
                a.shape()
            ),
        ));
    }
    let out: Vec<bool> = a
        .rows()
        .into_iter()
        .map(|r| act::positive_force([r[0], r[1], r[2], r[3]]))
        .collect();
    Ok(PyArray1::from_vec(py, out))
}

/// `(center, omega coefficients, rms residual)` from two accelerometer records (5.11–5.12).
#[pyfunction]
pub fn cor_from_accelerometers<'py>(
    py: Python<'py>,
    first: PyReadonlyArray2<'py, f64>,
    second: PyReadonlyArray2<'py, f64>,
    r1: [f64; 2],
    sample_rate: f64,
    frequency: f64,
    multiples: Vec<f64>,
) -> PyResult<([f64; 2], Bound<'py, PyArray1<f64>>, f64)> {
    let a = pairs(py, "first", &first)?;
    let b = pairs(py, "second", &second)?;
    let rot = detached(py, || {
        act::cor_from_accelerometers(&a, &b, r1, sample_rate, frequency, &multiples)
            .map_err(Failure::from)
    })?;
    Ok((rot.center, PyArray1::from_vec(py, rot.omega), rot.residual))
}

/// Largest corner excursion [m] of each pulse: wrench phasors `w_re`, `w_im` (`n * 9`, pulse,
/// harmonic, axis), unit responses `g_re`, `g_im` (`9 * samples`, harmonic, axis, sample) and the
/// plate's `corners (K, 2)` (see `upm_core::stroke`).
#[pyfunction]
pub fn corner_excursions<'py>(
    py: Python<'py>,
    w_re: PyReadonlyArray1<'py, f64>,
    w_im: PyReadonlyArray1<'py, f64>,
    g_re: PyReadonlyArray1<'py, f64>,
    g_im: PyReadonlyArray1<'py, f64>,
    samples: usize,
    corners: PyReadonlyArray2<'py, f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let k = pair_view(py, "corners", &corners)?;
    let (wr, wi, gr, gi) = (view(&w_re), view(&w_im), view(&g_re), view(&g_im));
    let g = stroke::Responses {
        re: &gr,
        im: &gi,
        samples,
    };
    let out = detached(py, || {
        stroke::corner_excursions(&wr, &wi, &g, &k).map_err(Failure::from)
    })?;
    Ok(PyArray1::from_vec(py, out))
}
