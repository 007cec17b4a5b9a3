//! Binding of plate motion programs and the point-part integrator.

use numpy::{PyArray1, PyArray2, PyArrayDyn, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use upm_core::motion::PlateMotion as CoreMotion;
use upm_core::sim::{self, Config, PartsView, Stacked};
use upm_core::{Error, Waveform};

use crate::errors::{core, detached, on_threads, shape_error, Failure};
use crate::polygon::PolygonArg;
use crate::{pair_view, view, WaveformBatch};

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

/// The owner of a result buffer behind a NumPy array (the array's base): when the array goes,
/// the buffer goes back to the core's pool for the next result ([`upm_core::buffer::recycle`],
/// [`upm_core::buffer::recycle_flags`]), so a caller simulating again and again writes into
/// memory already mapped.
#[pyclass(frozen, module = "upm._core")]
struct Recycled {
    /// The buffer's raw parts (pointer as an address: NumPy writes through it, Rust never reads).
    ptr: usize,
    len: usize,
    capacity: usize,
    /// A buffer of flags (`bool`), else of values (`f64`).
    flags: bool,
}

impl Drop for Recycled {
    fn drop(&mut self) {
        // SAFETY: the raw parts come from one `Vec` of the element type `flags` names, taken apart
        // in `recycled`, rebuilt once.
        unsafe {
            if self.flags {
                let v = Vec::from_raw_parts(self.ptr as *mut bool, self.len, self.capacity);
                upm_core::buffer::recycle_flags(v);
            } else {
                let v = Vec::from_raw_parts(self.ptr as *mut f64, self.len, self.capacity);
                upm_core::buffer::recycle(v);
            }
        }
    }
}

/// An element of the result buffers the core's pools keep: values or flags.
trait Pooled: numpy::Element {
    const FLAGS: bool;
}

impl Pooled for f64 {
    const FLAGS: bool = false;
}

impl Pooled for bool {
    const FLAGS: bool = true;
}

/// `v` as a 1-D NumPy array over the same memory, recycled when the array goes.
fn recycled<T: Pooled>(py: Python<'_>, v: Vec<T>) -> PyResult<Bound<'_, PyArray1<T>>> {
    let mut v = std::mem::ManuallyDrop::new(v);
    let (ptr, len, capacity) = (v.as_mut_ptr(), v.len(), v.capacity());
    let owner = Bound::new(
        py,
        Recycled {
            ptr: ptr as usize,
            len,
            capacity,
            flags: T::FLAGS,
        },
    )?;
    // SAFETY: `len` initialised elements at `ptr`, owned by `owner`, which the array keeps alive
    // as its base and which frees (recycles) them only when the array is gone.
    unsafe {
        let view = numpy::ndarray::ArrayView1::from_shape_ptr(len, ptr.cast_const());
        Ok(PyArray1::borrow_from_array(&view, owner.into_any()))
    }
}

/// `v` as an array of `shape`, recycled when it goes; where the core left it out (empty: zero
/// throughout), a read-only view of one zero broadcast to `shape` (no memory to clear or map),
/// as `numpy.broadcast_to` makes it but built here (a small call paid that function's 4 us
/// three times).
fn or_zeros<'py>(py: Python<'py>, v: Vec<f64>, shape: &[usize]) -> PyResult<Bound<'py, PyAny>> {
    if v.is_empty() && shape.iter().product::<usize>() > 0 {
        static ZERO: [f64; 1] = [0.0];
        let one = numpy::ndarray::ArrayView1::from(&ZERO[..]);
        let view = one.broadcast(shape.to_vec()).ok_or_else(|| {
            PyRuntimeError::new_err(format!("one zero does not broadcast to {shape:?}"))
        })?;
        // SAFETY: the one zero is static, so it outlives the array; the array is made read-only,
        // and as it does not own the zero, Python cannot make it writeable again.
        let zeros = unsafe { PyArrayDyn::borrow_from_array(&view, py.None().into_bound(py)) };
        zeros.readwrite().make_nonwriteable();
        return Ok(zeros.into_any());
    }
    Ok(recycled(py, v)?.reshape(shape.to_vec())?.into_any())
}

/// The stacked trajectory of `b` worlds as NumPy arrays: its buffers become the arrays as they
/// are, no copy: `(t, positions, velocities, stuck, angles, spins, left_time, left_plate,
/// flight)`.
fn to_arrays<'py>(
    py: Python<'py>,
    run: Stacked,
    b: usize,
    m: usize,
) -> PyResult<Bound<'py, PyTuple>> {
    let rows = run.t.len();
    let t = PyArray1::from_vec(py, run.t);
    let pos = recycled(py, run.positions.into_flattened())?.reshape([b, rows, m, 2])?;
    let vel = recycled(py, run.velocities.into_flattened())?.reshape([b, rows, m, 2])?;
    let stuck = recycled(py, run.stuck)?.reshape([b, rows, m])?;
    let angles = or_zeros(py, run.angles, &[b, rows, m])?;
    let spins = or_zeros(py, run.spins, &[b, rows, m])?;
    let left = recycled(py, run.left)?.reshape([b, m])?;
    let left_plate = recycled(py, run.left_plate)?.reshape([b, m])?;
    let flight = or_zeros(py, run.flight, &[b, m])?;
    PyTuple::new(
        py,
        [
            t.into_any(),
            pos.into_any(),
            vel.into_any(),
            stuck.into_any(),
            angles.into_any(),
            spins.into_any(),
            left.into_any(),
            left_plate.into_any(),
            flight.into_any(),
        ],
    )
}

/// A 2-D array's values in row-major order, borrowed when it is C-contiguous (copied otherwise).
fn view2<'a>(a: &'a PyReadonlyArray2<'_, f64>) -> std::borrow::Cow<'a, [f64]> {
    match a.as_slice() {
        Ok(s) => std::borrow::Cow::Borrowed(s),
        Err(_) => std::borrow::Cow::Owned(a.as_array().iter().copied().collect()),
    }
}

/// Simulates point and disk parts under each of `motions` (B worlds); arrays carry a batch axis.
#[pyfunction]
#[pyo3(signature = (motions, positions, velocities, mu, mu_s, radius, angle, spin, *, dt, duration, g, plate_size, record_every, threads=None, progress=None, contacts=false, restitution=0.5, part_friction=0.3, walls=None, walls_move_with_plate=false, mass=None, contact_iterations=4, world_mu=None, world_mu_s=None, polygons=None, world_positions=None, world_angles=None, tilt=(0.0, 0.0)))]
pub fn simulate<'py>(
    py: Python<'py>,
    motions: Vec<PyRef<'py, PlateMotion>>,
    positions: PyReadonlyArray2<'py, f64>,
    velocities: Option<PyReadonlyArray2<'py, f64>>,
    mu: PyReadonlyArray1<'py, f64>,
    mu_s: PyReadonlyArray1<'py, f64>,
    radius: Option<PyReadonlyArray1<'py, f64>>,
    angle: Option<PyReadonlyArray1<'py, f64>>,
    spin: Option<PyReadonlyArray1<'py, f64>>,
    dt: f64,
    duration: f64,
    g: f64,
    plate_size: Option<f64>,
    record_every: usize,
    threads: Option<usize>,
    progress: Option<Py<PyAny>>,
    contacts: bool,
    restitution: f64,
    part_friction: f64,
    walls: Option<PyReadonlyArray2<'py, f64>>,
    walls_move_with_plate: bool,
    mass: Option<PyReadonlyArray1<'py, f64>>,
    contact_iterations: usize,
    world_mu: Option<PyReadonlyArray2<'py, f64>>,
    world_mu_s: Option<PyReadonlyArray2<'py, f64>>,
    polygons: Option<Vec<PolygonArg<'py>>>,
    world_positions: Option<PyReadonlyArray2<'py, f64>>,
    world_angles: Option<PyReadonlyArray1<'py, f64>>,
    tilt: (f64, f64),
) -> PyResult<Bound<'py, PyTuple>> {
    // Polygon parts: (part, vertices (K, 2) in its frame, three feet (3, 2) or None), checked
    // convex and counter-clockwise, the feet carrying it.
    let polygons = crate::polygon::polygons(py, polygons.as_deref().unwrap_or_default())?;
    // The caller's arrays as they are: no copy of a contiguous array.
    let position = pair_view(py, "positions", &positions)?;
    let velocity = velocities
        .as_ref()
        .map(|v| pair_view(py, "velocities", v))
        .transpose()?;
    let (mu, mu_s) = (view(&mu), view(&mu_s));
    let (radius, angle, spin) = (
        radius.as_ref().map(view),
        angle.as_ref().map(view),
        spin.as_ref().map(view),
    );
    let parts = PartsView {
        position: &position,
        velocity: velocity.as_deref(),
        mu: &mu,
        mu_s: &mu_s,
        radius: radius.as_deref(),
        angle: angle.as_deref(),
        spin: spin.as_deref(),
        polygons: &polygons,
    };
    let m = parts.len();
    let cfg = Config {
        dt,
        duration,
        g,
        plate_size,
        record_every,
        tilt: [tilt.0, tilt.1],
    };
    // (lent, not copied: the Python objects stay borrowed for the call)
    let motions: Vec<&CoreMotion> = motions.iter().map(|p| &p.inner).collect();
    if motions.is_empty() {
        return Err(crate::errors::to_py(
            py,
            Error::parameter("motions", "must contain at least one motion"),
        ));
    }
    let contacts = if contacts {
        let walls = match &walls {
            None => Vec::new(),
            Some(w) => {
                let w = w.as_array();
                if w.shape()[1] != 4 {
                    return Err(shape_error(
                        py,
                        format!("walls must have shape (K, 2, 2); got (K, {})", w.shape()[1]),
                    ));
                }
                w.rows()
                    .into_iter()
                    .map(|r| [[r[0], r[1]], [r[2], r[3]]])
                    .collect()
            }
        };
        Some(sim::Contacts {
            restitution,
            part_friction,
            walls,
            walls_move_with_plate,
            mass: mass.map(|m| m.as_array().to_vec()),
            iterations: contact_iterations,
        })
    } else {
        None
    };
    // Friction per world: (B, M) or (B, 1) rows, both or neither.
    let worlds = match (&world_mu, &world_mu_s) {
        (Some(a), Some(b)) => {
            let width = a.as_array().shape()[1];
            if b.as_array().shape()[1] != width {
                return Err(shape_error(
                    py,
                    "world_mu and world_mu_s must have the same shape".to_string(),
                ));
            }
            Some((view2(a), view2(b), width))
        }
        (None, None) => None,
        _ => {
            return Err(crate::errors::to_py(
                py,
                Error::parameter("world_mu", "and world_mu_s must be given together"),
            ))
        }
    };
    // Start positions per world, (B * M, 2): with the friction rows only (the Python layer gives both).
    let world_start = world_positions
        .as_ref()
        .map(|p| pair_view(py, "world_positions", p))
        .transpose()?;
    if world_start.is_some() && worlds.is_none() {
        return Err(crate::errors::to_py(
            py,
            Error::parameter("world_positions", "need world_mu and world_mu_s"),
        ));
    }
    // Start angles per world, (B * M,): with the positions only.
    let world_turn = world_angles.as_ref().map(view);
    if world_turn.is_some() && world_start.is_none() {
        return Err(crate::errors::to_py(
            py,
            Error::parameter("world_angles", "need world_positions"),
        ));
    }
    let friction = worlds.as_ref().map(|(mu, mu_s, width)| sim::WorldRows {
        mu,
        mu_s,
        width: *width,
        position: world_start.as_deref(),
        angle: world_turn.as_deref(),
    });
    // A run of little work runs on this thread (the core keeps it there on any pool; a kept pool
    // of `threads` would only add its hand-off).
    let threads = match threads {
        Some(n) if n > 1 && sim::little_work(motions.len(), &parts, &cfg) => Some(1),
        _ => threads,
    };
    let run = detached(py, || {
        // Every world advances one block at a time; Ctrl-C is honoured between blocks.
        // `progress(steps_done)` after each block too; an exception from it stops the run.
        on_threads(threads, |between| {
            let report = |done: usize| -> Result<(), Failure> {
                between(done)?;
                match &progress {
                    Some(cb) => Python::attach(|py| cb.bind(py).call1((done,)).map(|_| ()))
                        .map_err(Failure::from),
                    None => Ok(()),
                }
            };
            sim::simulate_stacked_refs(
                &motions,
                &parts,
                &cfg,
                contacts.as_ref(),
                friction.as_ref(),
                report,
            )
        })
    })?;
    to_arrays(py, run, motions.len(), m)
}
