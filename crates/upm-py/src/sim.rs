//! Binding of `upm_core::sim`: the integrator of point, disk and polygon parts, its results
//! handed to NumPy without a copy (the buffers recycled when the arrays go).

use numpy::{PyArray1, PyArrayDyn, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use upm_core::motion::PlateMotion as CoreMotion;
use upm_core::sim::{self, Config, FrictionMap, PartsView, Stacked};
use upm_core::Error;

use crate::arrays::{pair_view, view};
use crate::errors::{detached, on_threads, shape_error, Failure};
use crate::motion::PlateMotion;
use crate::polygon::PolygonArg;

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
            crate::errors::internal(py, format!("one zero does not broadcast to {shape:?}"))
        })?;
        // SAFETY: the one zero is static, so it outlives the array; the array is made read-only,
        // and as it does not own the zero, Python cannot make it writeable again.
        let zeros = unsafe { PyArrayDyn::borrow_from_array(&view, py.None().into_bound(py)) };
        zeros.readwrite().make_nonwriteable();
        return Ok(zeros.into_any());
    }
    Ok(recycled(py, v)?.reshape(shape.to_vec())?.into_any())
}

/// A simulation's arrays, batch axis first, as the core wrote them (no copy): what
/// `upm.simulate` and `upm.simulate_batch` turn into a `SimResult`.
#[pyclass(frozen, module = "upm._core")]
pub struct Run {
    /// Recorded times [s], `(T,)`.
    #[pyo3(get)]
    t: Py<PyAny>,
    /// `(B, T, M, 2)` [m].
    #[pyo3(get)]
    positions: Py<PyAny>,
    /// `(B, T, M, 2)` [m/s].
    #[pyo3(get)]
    velocities: Py<PyAny>,
    /// `(B, T, M)`, whether each part sticks to the plate.
    #[pyo3(get)]
    stuck: Py<PyAny>,
    /// `(B, T, M)` [rad]; zeros where no part turns.
    #[pyo3(get)]
    angles: Py<PyAny>,
    /// `(B, T, M)` [rad/s]; zeros where no part turns.
    #[pyo3(get)]
    spins: Py<PyAny>,
    /// `(B, M)`: when each part left the plate [s] (infinite: never).
    #[pyo3(get)]
    left_time: Py<PyAny>,
    /// `(B, M)`, whether each part left the plate.
    #[pyo3(get)]
    left_plate: Py<PyAny>,
    /// `(B, M)`: the time each part spent in the air [s] (zeros on a planar plate).
    #[pyo3(get)]
    flight: Py<PyAny>,
}

/// The run's results (B worlds, M parts) as a [`Run`] of numpy arrays that own the core's
/// buffers where they are, no copy.
fn to_arrays(py: Python<'_>, run: Stacked, b: usize, m: usize) -> PyResult<Run> {
    let rows = run.t.len();
    let t = PyArray1::from_vec(py, run.t);
    let pos = recycled(py, run.positions.into_flattened())?.reshape([b, rows, m, 2])?;
    let vel = recycled(py, run.velocities.into_flattened())?.reshape([b, rows, m, 2])?;
    let stuck = recycled(py, run.stuck)?.reshape([b, rows, m])?;
    Ok(Run {
        t: t.into_any().unbind(),
        positions: pos.into_any().unbind(),
        velocities: vel.into_any().unbind(),
        stuck: stuck.into_any().unbind(),
        angles: or_zeros(py, run.angles, &[b, rows, m])?.unbind(),
        spins: or_zeros(py, run.spins, &[b, rows, m])?.unbind(),
        left_time: recycled(py, run.left)?.reshape([b, m])?.into_any().unbind(),
        left_plate: recycled(py, run.left_plate)?
            .reshape([b, m])?
            .into_any()
            .unbind(),
        flight: or_zeros(py, run.flight, &[b, m])?.unbind(),
    })
}

/// Simulates point and disk parts under each of `motions` (B worlds); arrays carry a batch axis.
#[pyfunction]
#[pyo3(signature = (motions, positions, velocities, mu, mu_s, radius, angle, spin, *, dt, duration, g, plate_size, record_every, threads=None, progress=None, contacts=false, restitution=0.5, part_friction=0.3, walls=None, walls_move_with_plate=false, mass=None, contact_iterations=4, world_mu=None, world_mu_s=None, polygons=None, world_positions=None, world_angles=None, tilt=(0.0, 0.0), friction_map=None))]
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
    friction_map: Option<PyReadonlyArray2<'py, f64>>,
) -> PyResult<Run> {
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
    // The plate's friction over its surface: a grid of factors over the plate (rows along y).
    let surface = match &friction_map {
        None => None,
        Some(grid) => {
            let side = plate_size.ok_or_else(|| {
                crate::errors::to_py(
                    py,
                    Error::parameter("friction_map", "covers the plate: give plate_size"),
                )
            })?;
            let a = grid.as_array();
            let (ny, nx) = (a.shape()[0], a.shape()[1]);
            let values = a.iter().copied().collect();
            Some(FrictionMap::new(values, nx, ny, side).map_err(|e| crate::errors::to_py(py, e))?)
        }
    };
    let parts = PartsView {
        position: &position,
        velocity: velocity.as_deref(),
        mu: &mu,
        mu_s: &mu_s,
        radius: radius.as_deref(),
        angle: angle.as_deref(),
        spin: spin.as_deref(),
        polygons: &polygons,
        surface: surface.as_ref(),
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
            Some((view(a), view(b), width))
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
