//! `upm._core`: the thin pyo3 binding of `upm-core`.
//!
//! This crate only converts arrays, releases the GIL and maps errors; all physics lives in
//! `upm-core`. Inputs arrive from the Python layer already broadcast to equal 1-D lengths (or as
//! `(B, K)` coefficient tables), float64; outputs are new NumPy arrays.

mod actuation;
mod errors;
mod mchip;
mod motion;
mod plan;
mod polygon;
mod ppod;
mod solve;
mod vision;

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use upm_core::{friction, theory, BangBang, Harmonics, Waveform};

use errors::{batch, batch_on, core, shape_error};

/// Large blocks on cache lines: results streamed to memory a line at a time (see
/// `upm_core::aligned`).
#[global_allocator]
static ALLOCATOR: upm_core::aligned::LineAligned = upm_core::aligned::LineAligned;

/// A batch of validated periodic plate velocities (one per row), built once and reused.
#[pyclass(frozen, module = "upm._core")]
pub struct WaveformBatch {
    pub waves: Vec<Waveform>,
}

fn column(a: &PyReadonlyArray1<'_, f64>) -> Vec<f64> {
    a.as_array().to_vec()
}

fn same_len(py: Python<'_>, what: &str, lens: &[(&str, usize)]) -> PyResult<usize> {
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

/// A 1-D array, borrowed when it is contiguous (copied otherwise).
pub(crate) fn view<'a>(a: &'a PyReadonlyArray1<'_, f64>) -> std::borrow::Cow<'a, [f64]> {
    match a.as_slice() {
        Ok(s) => std::borrow::Cow::Borrowed(s),
        Err(_) => std::borrow::Cow::Owned(a.as_array().to_vec()),
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

#[pymethods]
impl WaveformBatch {
    /// Rows of harmonic coefficients `cos (B, K)`, `sin (B, K)` and base frequencies `(B,)` [Hz].
    #[staticmethod]
    fn harmonics(
        py: Python<'_>,
        cos: PyReadonlyArray2<'_, f64>,
        sin: PyReadonlyArray2<'_, f64>,
        frequency: PyReadonlyArray1<'_, f64>,
    ) -> PyResult<Self> {
        let (c, s) = (cos.as_array(), sin.as_array());
        if c.shape() != s.shape() {
            return Err(shape_error(
                py,
                format!(
                    "cos and sin must have the same shape; got {:?} and {:?}",
                    c.shape(),
                    s.shape()
                ),
            ));
        }
        let n = same_len(
            py,
            "harmonics",
            &[("cos rows", c.shape()[0]), ("frequency", frequency.len())],
        )?;
        let f = column(&frequency);
        let waves = batch(py, n, |i| {
            Ok(Harmonics::new(c.row(i).to_vec(), s.row(i).to_vec(), f[i])?.into())
        })?;
        Ok(WaveformBatch { waves })
    }

    /// Bang-bang drives from `z`, `a_max` [m/s^2] and `period` [s], each `(B,)`.
    #[staticmethod]
    fn bang_bang(
        py: Python<'_>,
        z: PyReadonlyArray1<'_, f64>,
        a_max: PyReadonlyArray1<'_, f64>,
        period: PyReadonlyArray1<'_, f64>,
    ) -> PyResult<Self> {
        let n = same_len(
            py,
            "bang_bang",
            &[
                ("z", z.len()),
                ("a_max", a_max.len()),
                ("period", period.len()),
            ],
        )?;
        let (z, a, p) = (column(&z), column(&a_max), column(&period));
        let waves = batch(py, n, |i| Ok(BangBang::new(z[i], a[i], p[i])?.into()))?;
        Ok(WaveformBatch { waves })
    }

    fn __len__(&self) -> usize {
        self.waves.len()
    }

    /// Periods [s], `(B,)`.
    fn period<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.waves.iter().map(Waveform::period).collect())
    }

    /// Velocity (`derivative = 0`) or acceleration (`1`) at times `t (B, L)` [s] -> `(B, L)`.
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        t: PyReadonlyArray2<'py, f64>,
        derivative: u8,
    ) -> PyResult<Bound<'py, PyAny>> {
        let t = t.as_array();
        let (rows, cols) = (t.shape()[0], t.shape()[1]);
        same_len(
            py,
            "evaluate",
            &[("waveforms", self.waves.len()), ("t rows", rows)],
        )?;
        if derivative > 1 {
            return Err(errors::to_py(
                py,
                upm_core::Error::parameter(
                    "derivative",
                    format!("must be 0 or 1; got {derivative}"),
                ),
            ));
        }
        let t: Vec<f64> = t.iter().copied().collect();
        let out = batch(py, rows, |i| {
            let w = &self.waves[i];
            Ok(t[i * cols..(i + 1) * cols]
                .iter()
                .map(|&x| {
                    if derivative == 0 {
                        w.velocity(x)
                    } else {
                        w.acceleration(x)
                    }
                })
                .collect::<Vec<f64>>())
        })?;
        to_2d(py, out.concat(), rows, cols)
    }

    /// Exact feed rates [m/s] (medians of the velocity), `(B,)`.
    #[pyo3(signature = (threads=None))]
    fn feed_rate<'py>(
        &self,
        py: Python<'py>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let out = batch_on(py, self.waves.len(), threads, |i| {
            friction::feed_rate(&self.waves[i])
        })?;
        Ok(PyArray1::from_vec(py, out))
    }

    /// Exact average force / (mu m g) at part velocities `(B, L)` [m/s] -> `(B, L)`.
    #[pyo3(signature = (part_velocity, threads=None))]
    fn mean_force<'py>(
        &self,
        py: Python<'py>,
        part_velocity: PyReadonlyArray2<'py, f64>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let v = part_velocity.as_array();
        let (rows, cols) = (v.shape()[0], v.shape()[1]);
        same_len(
            py,
            "mean_force",
            &[
                ("waveforms", self.waves.len()),
                ("part_velocity rows", rows),
            ],
        )?;
        let v: Vec<f64> = v.iter().copied().collect();
        let out = batch_on(py, rows, threads, |i| {
            friction::mean_forces(&self.waves[i], &v[i * cols..(i + 1) * cols])
        })?;
        to_2d(py, out.concat(), rows, cols)
    }

    /// Exact `(min, max)` of the velocity over a period [m/s], each `(B,)`.
    fn velocity_range<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let out = batch(py, self.waves.len(), |i| {
            Ok(self.waves[i].pieces()?.range())
        })?;
        let lo = PyArray1::from_vec(py, out.iter().map(|r| r.0).collect());
        let hi = PyArray1::from_vec(py, out.iter().map(|r| r.1).collect());
        PyTuple::new(py, [lo, hi])
    }
}

/// Applies `f` to equal-length float64 columns in parallel; returns one array per output.
fn elementwise<'py, const N: usize, const M: usize, F>(
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
fn elementwise_on<'py, const N: usize, const M: usize, F>(
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

/// Exact average force / (mu m g) at rest under `cos(n1 t) - b cos(n2 (t - psi))`.
#[pyfunction]
#[pyo3(signature = (n1, n2, psi, b, threads=None))]
fn force_table<'py>(
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

/// Friction of a sliding, spinning disk under uniform pressure at `phi = atan2(R |W|, |w|)` in
/// `[0, pi/2]`: force / (mu m g) and torque / (mu m g R), by quadrature (`upm_core::disk`).
#[pyfunction]
fn disk_friction<'py>(
    py: Python<'py>,
    phi: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyAny>> {
    elementwise(py, "disk_friction", [("phi", phi)], |[p]| {
        let (f, t) = upm_core::disk::force_torque(upm_core::error::finite("phi", p)?);
        Ok([f, t])
    })
}

/// Theorem 1 closed form, `Tri(n1 n2 psi) / (n2^2 - n1^2)` (0 when both are odd, Lemma 1).
#[pyfunction]
fn theorem1_force<'py>(
    py: Python<'py>,
    n1: i64,
    n2: i64,
    psi: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyAny>> {
    core(py, friction::check_pair(n1, n2))?;
    elementwise(py, "theorem1_force", [("psi", psi)], |[p]| {
        Ok([theory::theorem1_force(n1, n2, p)?])
    })
}

/// A `#[pyfunction]` taking equal-length float64 columns named like the Rust parameters and
/// applying a `upm_core::theory` closed form to each row.
macro_rules! elementwise_fn {
    ($(#[$doc:meta])* $name:ident($($arg:ident),+) => |$row:pat_param| $body:expr) => {
        $(#[$doc])*
        #[pyfunction]
        fn $name<'py>(py: Python<'py>, $($arg: PyReadonlyArray1<'py, f64>),+) -> PyResult<Bound<'py, PyAny>> {
            elementwise(py, stringify!($name), [$((stringify!($arg), $arg)),+], |$row| $body)
        }
    };
}

elementwise_fn!(
    /// Bang-bang feed rate (3.11).
    bang_bang_feed_rate(z, a_max, period) => |[z, a, p]| Ok([theory::bang_bang_feed_rate(z, a, p)?])
);
elementwise_fn!(
    /// Bang-bang force at a part velocity (3.10).
    bang_bang_force(z, part_velocity, a_max, period) =>
        |[z, v, a, p]| Ok([theory::bang_bang_force(z, v, a, p)?])
);
elementwise_fn!(
    /// Bang-bang velocity range (3.8) -> (v_min, v_max).
    bang_bang_velocity_range(z, a_max, period) => |[z, a, p]| {
        let (lo, hi) = theory::bang_bang_velocity_range(z, a, p)?;
        Ok([lo, hi])
    }
);
elementwise_fn!(
    /// Bang-bang efficiencies (3.5) -> (eta1, eta2).
    bang_bang_efficiency(z) => |[z]| {
        let (e1, e2) = theory::bang_bang_efficiency(z)?;
        Ok([e1, e2])
    }
);
elementwise_fn!(
    /// Gain of the viscous model (3.12).
    viscous_gain(a_max, period, mu_m_g) => |[a, p, m]| Ok([theory::viscous_gain(a, p, m)?])
);
elementwise_fn!(
    /// Two-harmonic feed rate (3.16)-(3.17).
    two_harmonic_feed_rate(b, phi, amplitude) =>
        |[b, phi, a]| Ok([theory::two_harmonic_feed_rate(b, phi, a)?])
);
elementwise_fn!(
    /// Force at rest under sin t + b cos 2t (3.15).
    two_harmonic_force_at_rest(b) => |[b]| Ok([theory::two_harmonic_force_at_rest(b)?])
);
elementwise_fn!(
    /// max |cos t - 2b sin 2t| (3.18).
    gamma(b) => |[b]| Ok([theory::gamma(b)?])
);
elementwise_fn!(
    /// The normalised drive (3.18)-(3.20) -> (gamma, v_min, v_max, v_eq, eta1, eta2).
    normalized_drive(b, a_max, period) => |[b, a, p]| {
        let d = theory::normalized_drive(b, a, p)?;
        Ok([d.gamma, d.v_min, d.v_max, d.v_eq, d.eta1, d.eta2])
    }
);

/// Raises a Rust panic inside the guarded helper: lets the tests prove panics never reach Python.
#[pyfunction]
fn _panic_for_test(py: Python<'_>) -> PyResult<()> {
    errors::detached(py, || -> Result<(), errors::Failure> {
        panic!("deliberate test panic")
    })
}

/// How this build runs here: the point-part step's build chosen at run time (`UPM_SIMD`
/// overrides it) and the builds this CPU has.
#[pyfunction]
fn simd_info() -> (String, Vec<String>) {
    let names = |b: upm_core::simd::Simd| b.name().to_string();
    (
        names(upm_core::simd::simd()),
        upm_core::simd::Simd::available()
            .into_iter()
            .map(names)
            .collect(),
    )
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<WaveformBatch>()?;
    m.add_class::<motion::PlateMotion>()?;
    m.add_function(wrap_pyfunction!(motion::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(simd_info, m)?)?;
    m.add_function(wrap_pyfunction!(mchip::mchip_simulate, m)?)?;
    m.add_function(wrap_pyfunction!(vision::coverage_centroids, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::motors_for, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::velocity_amplitudes, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::center_of_rotation, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::axis_response, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::harmonic_fit, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::velocity_from_fit, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::positive_force, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::corner_excursions, m)?)?;
    m.add_function(wrap_pyfunction!(plan::apply_rays, m)?)?;
    m.add_function(wrap_pyfunction!(plan::edge_penalty, m)?)?;
    m.add_function(wrap_pyfunction!(plan::overlap_penalty, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::cor_from_accelerometers, m)?)?;
    m.add_function(wrap_pyfunction!(solve::solve, m)?)?;
    m.add_function(wrap_pyfunction!(solve::solve_batch, m)?)?;
    m.add_function(wrap_pyfunction!(solve::priorities, m)?)?;
    m.add_function(wrap_pyfunction!(solve::flow_error, m)?)?;
    m.add_function(wrap_pyfunction!(solve::rotation_field, m)?)?;
    m.add_function(wrap_pyfunction!(solve::rotation_curl, m)?)?;
    m.add_function(wrap_pyfunction!(solve::jet_field, m)?)?;
    m.add_function(wrap_pyfunction!(solve::average_field, m)?)?;
    m.add_function(wrap_pyfunction!(ppod::drift_field, m)?)?;
    m.add_function(wrap_pyfunction!(polygon::polygon_geometry, m)?)?;
    m.add_function(wrap_pyfunction!(polygon::polygon_wrench, m)?)?;
    m.add_function(wrap_pyfunction!(polygon::polygon_gauge, m)?)?;
    m.add_function(wrap_pyfunction!(ppod::asymptotic_field, m)?)?;
    m.add_function(wrap_pyfunction!(force_table, m)?)?;
    m.add_function(wrap_pyfunction!(disk_friction, m)?)?;
    m.add_function(wrap_pyfunction!(theorem1_force, m)?)?;
    m.add_function(wrap_pyfunction!(bang_bang_feed_rate, m)?)?;
    m.add_function(wrap_pyfunction!(bang_bang_force, m)?)?;
    m.add_function(wrap_pyfunction!(bang_bang_velocity_range, m)?)?;
    m.add_function(wrap_pyfunction!(bang_bang_efficiency, m)?)?;
    m.add_function(wrap_pyfunction!(viscous_gain, m)?)?;
    m.add_function(wrap_pyfunction!(two_harmonic_feed_rate, m)?)?;
    m.add_function(wrap_pyfunction!(two_harmonic_force_at_rest, m)?)?;
    m.add_function(wrap_pyfunction!(gamma, m)?)?;
    m.add_function(wrap_pyfunction!(normalized_drive, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_for_test, m)?)?;
    Ok(())
}
