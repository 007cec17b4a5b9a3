//! The M-Chip resonator array of thesis chapter 2 (docs/spec.md §9), simulated with the rapier3d physics
//! engine (f64): a design tool for impact-driven microactuator arrays.
//!
//! Model: an `rows x cols` interleaved array of resonators (odd rows shifted by half a column).
//! Each is a silicon slab (`slab` = length along the feed axis x, width along y, thickness) with a
//! ridge of height `H` across its rear end at distance `L` behind its midpoint, on a revolute
//! joint about y through the midpoint. A torsional spring and damper (natural frequency `f0`,
//! quality factor `Q`) and a positive square-wave drive torque act at the joint; positive angles
//! raise the ridge, whose tip then moves forward (+x) and up, so impacts push the part along +x.
//! A rectangular part (silicon by default) lies on the ridges under gravity; an optional
//! external force acts on it. One friction and one restitution coefficient for every contact.
//!
//! ## Units
//! rapier's tolerances and contact softness are absolute (tuned for metre-sized bodies at 60 Hz);
//! an inertia of 4e-18 kg m^2 would also sit below its epsilons. The world is therefore given to
//! rapier in units of 10 µm, 0.1 ms and 1e-10 kg (force unit 1e-7 N, energy unit 1e-12 J): the
//! slab is 28 x 18 x 0.5 units, its mass ~6 units, the drive period 2 units, gravity 9.81e-3
//! units. Contact softness is set per step (natural frequency `0.5 / dt`), sleeping is off, and
//! resonators collide with the part only. Results are returned in SI units.
//!
//! The spring, damper and drive torques are applied explicitly each step (the joint keeps the
//! rotation about y); with `dt` 1/200 of a drive period, `omega0 dt` is 0.03. rapier holds them
//! over its substeps, so the spring is read a little ahead of the step's start (`spring_lead`):
//! the quality factor then comes out as set (to 0.1% in the tests).

use rapier3d_f64::prelude::*;

use crate::error::{positive, Error, Result};

mod world;
pub use world::{simulate, simulate_with, CHECK_EVERY, REJOIN};

/// Length, time and mass units of the rapier world [m, s, kg].
const UL: f64 = 1e-5;
const UT: f64 = 1e-4;
const UM: f64 = 1e-10;

/// Geometry and materials of the array and the part (SI units).
#[derive(Debug, Clone, PartialEq)]
pub struct Design {
    /// Rows along the feed axis x, resonators per row.
    pub rows: usize,
    /// Columns (resonators per row, across y).
    pub cols: usize,
    /// Slab length (x), width (y) and thickness [m].
    pub slab: [f64; 3],
    /// Gap between neighbouring slabs [m].
    pub gap: f64,
    /// Ridge distance `L` behind the slab's midpoint [m].
    pub ridge_distance: f64,
    /// Ridge height `H` above the slab [m].
    pub ridge_height: f64,
    /// Ridge width along x [m].
    pub ridge_width: f64,
    /// Density of slabs and ridges [kg/m^3].
    pub density: f64,
    /// Natural frequency of a resonator on its joint [Hz].
    pub natural_frequency: f64,
    /// Quality factor of a resonator (damping ratio `1 / (2 Q)`).
    pub quality: f64,
    /// Part length (x), width (y), thickness [m].
    pub part_size: [f64; 3],
    /// Part mass [kg].
    pub part_mass: f64,
    /// Friction coefficient of every contact.
    pub friction: f64,
    /// Restitution coefficient of every contact.
    pub restitution: f64,
}

impl Default for Design {
    fn default() -> Self {
        let part_size = [1150e-6, 400e-6, 50e-6];
        Design {
            rows: 8,
            cols: 5,
            slab: [280e-6, 180e-6, 5e-6],
            gap: 20e-6,
            ridge_distance: 130e-6,
            ridge_height: 5e-6,
            ridge_width: 10e-6,
            density: 2330.0,
            natural_frequency: 5000.0,
            quality: 0.8,
            part_mass: 2330.0 * part_size.iter().product::<f64>(),
            part_size,
            friction: 1.0,
            restitution: 0.5,
        }
    }
}

/// How the rows are driven.
#[derive(Debug, Clone, PartialEq)]
pub enum Scheme {
    /// Every row on.
    AllOn,
    /// Row-strobing: rows labelled 0.. along the feed; wavefronts `delta` rows apart, each row
    /// switched off for `tau` cycles, moving against the feed (row `rows - 1` first).
    Strobe {
        /// Cycles a row stays off.
        tau: usize,
        /// Rows between wavefronts.
        delta: usize,
    },
    /// Per-row phase offsets [cycles] of the square wave.
    Phases(Vec<f64>),
    /// No drive (the resonators only ring down).
    Off,
}

/// The drive torque.
#[derive(Debug, Clone, PartialEq)]
pub struct Drive {
    /// Square-wave frequency [Hz].
    pub frequency: f64,
    /// Fraction of each period the torque is on, in (0, 1].
    pub duty: f64,
    /// Torque amplitude [N m]; `None`: the one whose free steady oscillation peaks at
    /// `peak_angle`.
    pub torque: Option<f64>,
    /// Peak angle of the free steady oscillation [rad] (when `torque` is `None`).
    pub peak_angle: f64,
    /// Which rows are on when.
    pub scheme: Scheme,
}

impl Default for Drive {
    fn default() -> Self {
        Drive {
            frequency: 5000.0,
            duty: 0.5,
            torque: None,
            peak_angle: 0.08,
            scheme: Scheme::AllOn,
        }
    }
}

/// Run settings.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Time step [s].
    pub dt: f64,
    /// Simulated time [s].
    pub duration: f64,
    /// Record the part every this many steps.
    pub record_every: usize,
    /// External force on the part along x and y [N].
    pub external_force: [f64; 2],
    /// rapier solver iterations per step.
    pub iterations: usize,
    /// Part centre (x, y) at the start [m], over the array (x = 0 at the first row's midpoint).
    pub part_start: [f64; 2],
    /// Height of the part's underside above the ridges' tops at rest at the start [m].
    pub drop_height: f64,
    /// Initial angle of every resonator [rad] (for ring-down checks).
    pub initial_angle: f64,
    /// Whether there is a part (false: the array alone).
    pub part: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            dt: 1e-6,
            duration: 0.02,
            record_every: 10,
            external_force: [0.0; 2],
            iterations: 4,
            part_start: [600e-6, 400e-6],
            drop_height: 2e-6,
            initial_angle: 0.0,
            part: true,
        }
    }
}

/// One part–resonator collision (a contact episode: the steps with an impulse, gaps shorter than
/// [`REJOIN`] included).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Collision {
    /// When it began [s].
    pub time: f64,
    /// Resonator index (`row * cols + col`).
    pub resonator: usize,
    /// The resonator's angle [rad] as it came in (at the start of the step it began in).
    pub angle: f64,
    /// Angular speed [rad/s] as it came in (before the impact).
    pub angular_speed: f64,
    /// Impulse given to the part along x over the episode [N s] (the part's momentum change net
    /// of gravity and the external force, shared among the resonators touching it by their
    /// normal impulses).
    pub impulse_x: f64,
    /// Normal impulse over the episode [N s].
    pub impulse_normal: f64,
}

/// Time-averaged energy per degree of freedom [J].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Energy {
    /// The part's translational kinetic energy along x, y, z.
    pub part_translation: [f64; 3],
    /// The part's rotational kinetic energy.
    pub part_rotation: f64,
    /// The resonators' kinetic energy (all of them).
    pub resonator_kinetic: f64,
    /// The resonators' spring energy (all of them).
    pub resonator_spring: f64,
}

/// What a run recorded (SI units).
#[derive(Debug, Clone, PartialEq)]
pub struct Output {
    /// Recorded times [s].
    pub t: Vec<f64>,
    /// Part centre [m] at those times.
    pub position: Vec<[f64; 3]>,
    /// Part velocity [m/s] at those times.
    pub velocity: Vec<[f64; 3]>,
    /// Part orientation at those times: the unit quaternion `(x, y, z, w)` of its rotation from
    /// the start (axes as the world's: x along the feed, z up).
    pub orientation: Vec<[f64; 4]>,
    /// Part angular velocity [rad/s] at those times.
    pub angular_velocity: Vec<[f64; 3]>,
    /// Angle of every resonator [rad] at those times, `(rows, resonators)`.
    pub angles: Vec<f64>,
    /// Collisions in the order they began.
    pub collisions: Vec<Collision>,
    /// Energy per degree of freedom, averaged over the run.
    pub energy: Energy,
    /// The drive torque amplitude used [N m].
    pub torque: f64,
    /// Spring stiffness of each joint [N m/rad].
    pub stiffness: f64,
    /// Damping [N m s / rad].
    pub damping: f64,
    /// Inertia about the joint [kg m^2].
    pub inertia: f64,
}

impl Design {
    fn check(&self) -> Result<()> {
        if self.rows == 0 || self.cols == 0 || self.rows * self.cols > 10_000 {
            return Err(Error::parameter(
                "rows",
                format!(
                    "rows x cols must be between 1 and 10000; got {} x {}",
                    self.rows, self.cols
                ),
            ));
        }
        for (name, v) in [
            ("slab", self.slab[0]),
            ("slab", self.slab[1]),
            ("slab", self.slab[2]),
            ("ridge_height", self.ridge_height),
            ("ridge_width", self.ridge_width),
            ("density", self.density),
            ("natural_frequency", self.natural_frequency),
            ("quality", self.quality),
            ("part_size", self.part_size[0]),
            ("part_size", self.part_size[1]),
            ("part_size", self.part_size[2]),
            ("part_mass", self.part_mass),
        ] {
            positive(name, v)?;
        }
        if !(self.gap.is_finite() && self.gap >= 0.0) {
            return Err(Error::parameter(
                "gap",
                format!("must be >= 0; got {}", self.gap),
            ));
        }
        let half = 0.5 * self.slab[0] - 0.5 * self.ridge_width;
        if !(self.ridge_distance.is_finite()
            && self.ridge_distance >= 0.0
            // The edge itself, however it rounds.
            && self.ridge_distance <= half * (1.0 + 1e-12))
        {
            return Err(Error::parameter(
                "ridge_distance",
                format!(
                    "must be in [0, {half:.3e}] m (the ridge must sit on the slab); got {}",
                    self.ridge_distance
                ),
            ));
        }
        if !(self.friction.is_finite() && self.friction >= 0.0) {
            return Err(Error::parameter(
                "friction",
                format!("must be >= 0; got {}", self.friction),
            ));
        }
        if !(self.restitution.is_finite() && (0.0..=1.0).contains(&self.restitution)) {
            return Err(Error::parameter(
                "restitution",
                format!("must be in [0, 1]; got {}", self.restitution),
            ));
        }
        Ok(())
    }

    /// Pitch of the array along x and y [m].
    fn pitch(&self) -> [f64; 2] {
        [self.slab[0] + self.gap, self.slab[1] + self.gap]
    }

    /// Joint position (slab midpoint, mid-thickness) of resonator `(row, col)` [m].
    pub fn joint(&self, row: usize, col: usize) -> [f64; 3] {
        let [px, py] = self.pitch();
        let shift = if row % 2 == 1 { 0.5 * py } else { 0.0 };
        [
            row as f64 * px,
            col as f64 * py + shift,
            -0.5 * self.slab[2],
        ]
    }

    /// Masses [kg] of the slab and the ridge, and the inertia about the joint axis [kg m^2].
    pub fn inertia(&self) -> (f64, f64, f64) {
        let [lx, ly, lz] = self.slab;
        let ms = self.density * lx * ly * lz;
        let (w, h) = (self.ridge_width, self.ridge_height);
        let mr = self.density * w * ly * h;
        let dz = 0.5 * lz + 0.5 * h;
        let i = ms * (lx * lx + lz * lz) / 12.0
            + mr * ((w * w + h * h) / 12.0 + self.ridge_distance.powi(2) + dz * dz);
        (ms, mr, i)
    }
}

impl Drive {
    fn check(&self, rows: usize) -> Result<()> {
        positive("frequency", self.frequency)?;
        if !(self.duty > 0.0 && self.duty <= 1.0) {
            return Err(Error::parameter(
                "duty",
                format!("must be in (0, 1]; got {}", self.duty),
            ));
        }
        match self.torque {
            Some(t) => {
                positive("torque", t)?;
            }
            None => {
                positive("peak_angle", self.peak_angle)?;
            }
        }
        match &self.scheme {
            Scheme::Strobe { tau, delta } => {
                if *tau == 0 || *delta == 0 {
                    return Err(Error::parameter(
                        "scheme",
                        format!("strobe needs tau >= 1 cycles and delta >= 1 rows; got tau = {tau}, delta = {delta}"),
                    ));
                }
            }
            Scheme::Phases(p) => {
                if p.len() != rows || !p.iter().all(|v| v.is_finite()) {
                    return Err(Error::parameter(
                        "phases",
                        format!("must hold one finite phase [cycles] per row ({rows}); got {p:?}"),
                    ));
                }
            }
            Scheme::AllOn | Scheme::Off => {}
        }
        Ok(())
    }

    /// Whether row `row` of `rows` has its torque on at time `t`.
    fn on(&self, row: usize, rows: usize, t: f64) -> bool {
        let cycles = t * self.frequency;
        let (phase, enabled) = match &self.scheme {
            Scheme::AllOn => (0.0, true),
            Scheme::Off => (0.0, false),
            Scheme::Phases(p) => (p[row], true),
            Scheme::Strobe { tau, delta } => {
                let wave = (cycles.floor() as usize / tau) % delta;
                (0.0, (rows - 1 - row) % delta != wave)
            }
        };
        enabled && (cycles - phase).rem_euclid(1.0) < self.duty
    }
}

/// Peak angle of the free steady oscillation per unit torque amplitude of a square wave of
/// `duty` at `frequency` on a resonator (`inertia`, `stiffness`, `damping`), from its Fourier
/// series (200 harmonics, the peak over 2000 phases).
pub fn peak_per_torque(
    frequency: f64,
    duty: f64,
    inertia: f64,
    stiffness: f64,
    damping: f64,
) -> f64 {
    let w = std::f64::consts::TAU * frequency;
    let mut peak = f64::MIN;
    let (mut re, mut im) = (vec![0.0; 200], vec![0.0; 200]);
    for n in 1..=200 {
        // c_n = (1 - e^{-i 2 pi n duty}) / (i 2 pi n); response c_n H(n w), H = 1/(k - I w^2 + i c w).
        let a = std::f64::consts::TAU * n as f64 * duty;
        let (cr, ci) = (
            a.sin() / (std::f64::consts::TAU * n as f64),
            (a.cos() - 1.0) / (std::f64::consts::TAU * n as f64),
        );
        let wn = n as f64 * w;
        let (hr, hi) = (stiffness - inertia * wn * wn, damping * wn);
        let den = hr * hr + hi * hi;
        let (inv_r, inv_i) = (hr / den, -hi / den);
        re[n - 1] = cr * inv_r - ci * inv_i;
        im[n - 1] = cr * inv_i + ci * inv_r;
    }
    for s in 0..2000 {
        let phase = std::f64::consts::TAU * s as f64 / 2000.0;
        let mut theta = duty / stiffness;
        for n in 1..=200 {
            let (sn, cs) = (n as f64 * phase).sin_cos();
            theta += 2.0 * (re[n - 1] * cs - im[n - 1] * sn);
        }
        peak = peak.max(theta);
    }
    peak
}

/// Checks every input; the number of steps.
fn validate(design: &Design, drive: &Drive, settings: &Settings) -> Result<usize> {
    design.check()?;
    drive.check(design.rows)?;
    positive("dt", settings.dt)?;
    positive("duration", settings.duration)?;
    if settings.record_every == 0 {
        return Err(Error::parameter("record_every", "must be >= 1; got 0"));
    }
    if settings.dt > 0.02 / drive.frequency.max(design.natural_frequency) {
        return Err(Error::parameter(
            "dt",
            format!(
                "must resolve the drive and the resonance with 50 steps a period: dt <= {:.3e} s; got {}",
                0.02 / drive.frequency.max(design.natural_frequency),
                settings.dt
            ),
        ));
    }
    let steps = (settings.duration / settings.dt).round().max(1.0) as usize;
    if steps > 50_000_000 {
        return Err(Error::parameter(
            "duration",
            format!("gives {steps} steps; at most 5e7 (raise dt or shorten the run)"),
        ));
    }
    if !(settings.iterations >= 1 && settings.iterations <= 100) {
        return Err(Error::parameter(
            "iterations",
            format!("must be in [1, 100]; got {}", settings.iterations),
        ));
    }
    for v in [
        settings.external_force[0],
        settings.external_force[1],
        settings.part_start[0],
        settings.part_start[1],
        settings.drop_height,
        settings.initial_angle,
    ] {
        crate::error::finite("settings", v)?;
    }

    Ok(steps)
}

/// Where in a step the joint spring is read, as a fraction of the step ahead of its start, for
/// rapier's `substeps` substeps with the torque held constant over the step.
///
/// Substepping integrates the angle as `theta + dt omega + beta dt^2 a` with
/// `beta = (n + 1) / (2 n)` (n = 1 is symplectic Euler). With the spring read at
/// `theta + gamma dt omega` the one-step map of the undamped oscillator has determinant
/// `1 + (omega0 dt)^2 (1 - beta - gamma)`, so `gamma = 1 - beta = (n - 1) / (2 n)` keeps it
/// area-preserving and the damping ratio comes out as set, up to `O((omega0 dt)^2)`.
fn spring_lead(substeps: usize) -> f64 {
    let n = substeps as f64;
    (n - 1.0) / (2.0 * n)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ridge flush with the slab's rear edge is allowed, however `140e-6 - 5e-6` rounds.
    #[test]
    fn the_ridge_may_sit_at_the_slab_edge() {
        let edge = Design {
            ridge_distance: 135e-6,
            ..Design::default()
        };
        assert!(edge.check().is_ok());
        let beyond = Design {
            ridge_distance: 135.01e-6,
            ..Design::default()
        };
        assert!(beyond
            .check()
            .unwrap_err()
            .to_string()
            .starts_with("ridge_distance"));
    }
}
