//! Binding of `upm_core::waveform`: a batch of periodic plate velocities, their feed rates
//! and forces.

use numpy::{PyArray1, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use upm_core::{friction, BangBang, Harmonics, Waveform};

use crate::arrays::{column, same_len, to_2d};
use crate::errors::{batch, batch_on, shape_error};

/// A batch of validated periodic plate velocities (one per row), built once and reused.
#[pyclass(frozen, module = "upm._core")]
pub struct WaveformBatch {
    pub waves: Vec<Waveform>,
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
            return Err(crate::errors::to_py(
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
