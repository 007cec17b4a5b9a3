//! Binding of the M-Chip resonator array (`upm_core::mchip`).

use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use upm_core::mchip::{self, Design, Drive, Scheme, Settings};
use upm_core::Error;

use crate::errors::{detached, interrupted};

/// An M-Chip run's arrays (what `mchip_simulate` returns; `upm.mchip.simulate` makes an
/// `MChipResult` of them).
#[pyclass(frozen, module = "upm._core")]
pub struct MChipRun {
    /// Recorded times [s], `(T,)`.
    #[pyo3(get)]
    t: Py<PyAny>,
    /// The part's centre, `(T, 3)` [m].
    #[pyo3(get)]
    positions: Py<PyAny>,
    /// `(T, 3)` [m/s].
    #[pyo3(get)]
    velocities: Py<PyAny>,
    /// The part's orientation as unit quaternions `(w, x, y, z)`, `(T, 4)`.
    #[pyo3(get)]
    orientations: Py<PyAny>,
    /// `(T, 3)` [rad/s].
    #[pyo3(get)]
    angular_velocities: Py<PyAny>,
    /// Every resonator's angle, `(T, rows * cols)` [rad].
    #[pyo3(get)]
    angles: Py<PyAny>,
    /// One row per collision: time, resonator, angle, angular speed, impulse along x and normal.
    #[pyo3(get)]
    collisions: Py<PyAny>,
    /// The energy at the end: the part's translation (x, y, z), its rotation, the resonators'
    /// kinetic and spring energy [J].
    #[pyo3(get)]
    energy: Py<PyAny>,
    /// The resonators' joint: torque, stiffness, damping and inertia.
    #[pyo3(get)]
    joint: [f64; 4],
}

/// Simulates the array; returns `(t, position, velocity, orientation, angular_velocity, angles,
/// collisions, energy, joint)`: arrays `(T,)`, `(T, 3)`, `(T, 3)`, `(T, 4)` (quaternion x, y, z,
/// w), `(T, 3)`, `(T, R*C)`, `(K, 6)` (time, resonator, angle, angular speed, x impulse, normal
/// impulse), `(6,)` (part x, y, z, rotation, resonators' kinetic and spring energy) and
/// `(torque, stiffness, damping, inertia)`.
#[pyfunction]
#[pyo3(signature = (*, rows, cols, slab, gap, ridge_distance, ridge_height, ridge_width, density, natural_frequency, quality, part_size, part_mass, friction, restitution, frequency, duty, torque, peak_angle, scheme, tau, delta, phases, dt, duration, record_every, external_force, iterations, part_start, drop_height, initial_angle, part))]
pub fn mchip_simulate<'py>(
    py: Python<'py>,
    rows: usize,
    cols: usize,
    slab: [f64; 3],
    gap: f64,
    ridge_distance: f64,
    ridge_height: f64,
    ridge_width: f64,
    density: f64,
    natural_frequency: f64,
    quality: f64,
    part_size: [f64; 3],
    part_mass: f64,
    friction: f64,
    restitution: f64,
    frequency: f64,
    duty: f64,
    torque: Option<f64>,
    peak_angle: f64,
    scheme: &str,
    tau: usize,
    delta: usize,
    phases: Vec<f64>,
    dt: f64,
    duration: f64,
    record_every: usize,
    external_force: [f64; 2],
    iterations: usize,
    part_start: [f64; 2],
    drop_height: f64,
    initial_angle: f64,
    part: bool,
) -> PyResult<MChipRun> {
    let scheme = match scheme {
        "all" => Scheme::AllOn,
        "off" => Scheme::Off,
        "strobe" => Scheme::Strobe { tau, delta },
        "phases" => Scheme::Phases(phases),
        other => {
            return Err(crate::errors::to_py(
                py,
                Error::parameter(
                    "scheme",
                    format!("must be 'all', 'strobe', 'phases' or 'off'; got {other:?}"),
                ),
            ))
        }
    };
    let design = Design {
        rows,
        cols,
        slab,
        gap,
        ridge_distance,
        ridge_height,
        ridge_width,
        density,
        natural_frequency,
        quality,
        part_size,
        part_mass,
        friction,
        restitution,
    };
    let drive = Drive {
        frequency,
        duty,
        torque,
        peak_angle,
        scheme,
    };
    let settings = Settings {
        dt,
        duration,
        record_every,
        external_force,
        iterations,
        part_start,
        drop_height,
        initial_angle,
        part,
    };
    let out = detached(py, || {
        mchip::simulate_with(&design, &drive, &settings, interrupted)
    })?;
    let rows_t = out.t.len();
    let n_res = design.rows * design.cols;
    let t = PyArray1::from_vec(py, out.t);
    let pos = PyArray1::from_vec(py, out.position.into_iter().flatten().collect())
        .reshape([rows_t, 3])?;
    let vel = PyArray1::from_vec(py, out.velocity.into_iter().flatten().collect())
        .reshape([rows_t, 3])?;
    let orientation = PyArray1::from_vec(py, out.orientation.into_iter().flatten().collect())
        .reshape([rows_t, 4])?;
    let angular_velocity =
        PyArray1::from_vec(py, out.angular_velocity.into_iter().flatten().collect())
            .reshape([rows_t, 3])?;
    let angles = PyArray1::from_vec(py, out.angles).reshape([rows_t, n_res])?;
    let k = out.collisions.len();
    let coll: Vec<f64> = out
        .collisions
        .iter()
        .flat_map(|c| {
            [
                c.time,
                c.resonator as f64,
                c.angle,
                c.angular_speed,
                c.impulse_x,
                c.impulse_normal,
            ]
        })
        .collect();
    let coll = PyArray1::from_vec(py, coll).reshape([k, 6])?;
    let e = out.energy;
    let energy = PyArray1::from_vec(
        py,
        vec![
            e.part_translation[0],
            e.part_translation[1],
            e.part_translation[2],
            e.part_rotation,
            e.resonator_kinetic,
            e.resonator_spring,
        ],
    );
    Ok(MChipRun {
        t: t.into_any().unbind(),
        positions: pos.into_any().unbind(),
        velocities: vel.into_any().unbind(),
        orientations: orientation.into_any().unbind(),
        angular_velocities: angular_velocity.into_any().unbind(),
        angles: angles.into_any().unbind(),
        collisions: coll.into_any().unbind(),
        energy: energy.into_any().unbind(),
        joint: [out.torque, out.stiffness, out.damping, out.inertia],
    })
}
