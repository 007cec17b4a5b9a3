//! Binding of plate motion programs and the point-part integrator.

use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use upm_core::motion::PlateMotion as CoreMotion;
use upm_core::{Error, Waveform};

use crate::errors::{core, detached, shape_error, Failure};
use crate::waveform::WaveformBatch;

/// A plate motion program (see `upm.PlateMotion`).
#[pyclass(frozen, module = "upm._core")]
pub struct PlateMotion {
    pub inner: CoreMotion,
}

fn one_wave(py: Python<'_>, w: &WaveformBatch) -> PyResult<Waveform> {
    match w.waves.as_slice() {
        [single] => Ok(single.clone()),
        many => Err(shape_error(
            py,
            format!(
                "waveform must be a single waveform (shape ()); got {} of them",
                many.len()
            ),
        )),
    }
}

fn wrap(py: Python<'_>, r: upm_core::Result<CoreMotion>) -> PyResult<PlateMotion> {
    core(py, r).map(|inner| PlateMotion { inner })
}

#[pymethods]
impl PlateMotion {
    #[staticmethod]
    fn translation(
        py: Python<'_>,
        direction: [f64; 2],
        waveform: &WaveformBatch,
    ) -> PyResult<Self> {
        let w = one_wave(py, waveform)?;
        wrap(py, CoreMotion::translation(direction, w))
    }

    #[staticmethod]
    fn rotation(py: Python<'_>, center: [f64; 2], waveform: &WaveformBatch) -> PyResult<Self> {
        let w = one_wave(py, waveform)?;
        wrap(py, CoreMotion::rotation(center, w))
    }

    #[staticmethod]
    fn jet(
        py: Python<'_>,
        center: [f64; 2],
        direction: [f64; 2],
        rho: f64,
        amplitude: f64,
        frequency: f64,
    ) -> PyResult<Self> {
        wrap(
            py,
            CoreMotion::jet(center, direction, rho, amplitude, frequency),
        )
    }

    /// Harmonic accelerations of the six axes `(x, y, z, rx, ry, rz)`: each a list of
    /// `(harmonic, amplitude, phase)` terms `A sin(k w t + p)`.
    #[staticmethod]
    fn spatial(py: Python<'_>, frequency: f64, terms: [Vec<(u32, f64, f64)>; 6]) -> PyResult<Self> {
        let terms = terms.map(|axis| {
            axis.into_iter()
                .map(|(harmonic, amplitude, phase)| upm_core::motion::Term {
                    harmonic,
                    amplitude,
                    phase,
                })
                .collect()
        });
        let sp = core(py, upm_core::motion::Spatial::new(frequency, terms))?;
        Ok(PlateMotion {
            inner: CoreMotion::spatial(sp),
        })
    }

    /// Whether the plate moves out of its plane.
    fn is_spatial(&self) -> bool {
        self.inner.is_spatial()
    }

    /// `(z'', alpha'', beta'')` (N, 3) at times `t (N,)`.
    fn normal<'py>(
        &self,
        py: Python<'py>,
        t: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let a: Vec<[f64; 3]> = t.as_array().iter().map(|&s| self.inner.normal(s)).collect();
        let n = a.len();
        PyArray1::from_vec(py, a.concat()).reshape([n, 3])
    }

    /// `B` enveloped pulses in one call (the environments' batch of actions): `kind` 0 a
    /// translation along `direction` and 1 a rotation about `center`, each at speed
    /// `amplitude (cos wt - cos 2wt / 2)`; 2 a jet of radius `rho`; 3 a rest of the pulse's
    /// length. Raised-cosine `attack`, `sustain`, and a decay as long as the attack.
    #[staticmethod]
    fn pulses(
        py: Python<'_>,
        kind: PyReadonlyArray1<'_, i64>,
        center: PyReadonlyArray2<'_, f64>,
        direction: PyReadonlyArray2<'_, f64>,
        amplitude: PyReadonlyArray1<'_, f64>,
        frequency: PyReadonlyArray1<'_, f64>,
        attack: PyReadonlyArray1<'_, f64>,
        sustain: PyReadonlyArray1<'_, f64>,
        rho: f64,
    ) -> PyResult<Vec<Self>> {
        let (kind, center, direction) = (kind.as_array(), center.as_array(), direction.as_array());
        let (amplitude, frequency) = (amplitude.as_array(), frequency.as_array());
        let (attack, sustain) = (attack.as_array(), sustain.as_array());
        let n = kind.len();
        let rows = [
            center.shape()[0],
            direction.shape()[0],
            amplitude.len(),
            frequency.len(),
            attack.len(),
            sustain.len(),
        ];
        if rows.iter().any(|&r| r != n) || center.shape()[1] != 2 || direction.shape()[1] != 2 {
            return Err(shape_error(
                py,
                format!("pulses: every argument needs {n} rows (center and direction (B, 2)); got {rows:?}"),
            ));
        }
        (0..n)
            .map(|i| {
                let (a, s, f, amp) = (attack[i], sustain[i], frequency[i], amplitude[i]);
                let c = [center[[i, 0]], center[[i, 1]]];
                let d = [direction[[i, 0]], direction[[i, 1]]];
                let wave = || -> upm_core::Result<Waveform> {
                    Ok(upm_core::Harmonics::new(vec![amp, -amp / 2.0], vec![0.0; 2], f)?.into())
                };
                let m = match kind[i] {
                    0 => wave().and_then(|w| CoreMotion::translation(d, w)),
                    1 => wave().and_then(|w| CoreMotion::rotation(c, w)),
                    2 => CoreMotion::jet(c, d, rho, amp, f),
                    3 => return wrap(py, CoreMotion::rest(2.0 * a + s)),
                    k => Err(Error::parameter(
                        "kind",
                        format!("must be 0, 1, 2 or 3; got {k}"),
                    )),
                };
                wrap(py, m.and_then(|m| m.with_envelope(a, s, a)))
            })
            .collect()
    }

    #[staticmethod]
    fn rest(py: Python<'_>, duration: f64) -> PyResult<Self> {
        wrap(py, CoreMotion::rest(duration))
    }

    #[staticmethod]
    fn from_samples(
        py: Python<'_>,
        t: PyReadonlyArray1<'_, f64>,
        u: PyReadonlyArray2<'_, f64>,
    ) -> PyResult<Self> {
        let u = u.as_array();
        if u.shape()[1] != 3 {
            return Err(shape_error(
                py,
                format!(
                    "u must have shape (N, 3) for (u1, u2, u3); got {:?}",
                    u.shape()
                ),
            ));
        }
        let rows: Vec<[f64; 3]> = u.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect();
        wrap(py, CoreMotion::from_samples(&t.as_array().to_vec(), &rows))
    }

    #[staticmethod]
    fn sequence(py: Python<'_>, motions: Vec<PyRef<'_, PlateMotion>>) -> PyResult<Self> {
        wrap(
            py,
            CoreMotion::sequence(motions.iter().map(|m| m.inner.clone()).collect()),
        )
    }

    fn for_duration(&self, py: Python<'_>, seconds: f64) -> PyResult<Self> {
        wrap(py, self.inner.clone().for_duration(seconds))
    }

    fn with_envelope(
        &self,
        py: Python<'_>,
        attack: f64,
        sustain: f64,
        decay: f64,
    ) -> PyResult<Self> {
        wrap(py, self.inner.clone().with_envelope(attack, sustain, decay))
    }

    fn duration(&self) -> Option<f64> {
        self.inner.duration()
    }

    fn max_frequency(&self) -> f64 {
        self.inner.max_frequency()
    }

    fn __len__(&self) -> usize {
        self.inner.items().len()
    }

    /// `(u (N, 3), du/dt (N, 3))` at times `t (N,)`.
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        t: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let t = t.as_array().to_vec();
        let (u, a): (Vec<[f64; 3]>, Vec<[f64; 3]>) = t.iter().map(|&s| self.inner.at(s)).unzip();
        let n = t.len();
        let u = PyArray1::from_vec(py, u.concat()).reshape([n, 3])?;
        let a = PyArray1::from_vec(py, a.concat()).reshape([n, 3])?;
        PyTuple::new(py, [u, a])
    }

    fn displacement(&self, py: Python<'_>) -> PyResult<[f64; 3]> {
        detached(py, || self.inner.displacement().map_err(Failure::from))
    }
}
