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

/// Simulates the array and the part.
pub fn simulate(design: &Design, drive: &Drive, settings: &Settings) -> Result<Output> {
    simulate_with(design, drive, settings, |_| Ok::<(), Error>(()))
}

/// Contact gaps shorter than this [s] do not end a collision: rapier's soft contacts resolve a
/// resonator's impact on the part over a few steps and may let go for a step or two in between
/// (at the default 1 µs step such re-contacts cluster 2–5 µs after an impact's start). A real
/// rebound takes longer: the drive must first turn the resonator back up (thesis 2.2.2: 20 µs).
pub const REJOIN: f64 = 5e-6;

/// Steps between calls of the `between` callback of [`simulate_with`].
pub const CHECK_EVERY: usize = 20_000;

/// [`simulate`], calling `between(steps_done)` every [`CHECK_EVERY`] steps; an error from it (an
/// interrupt) stops the run.
pub fn simulate_with<E, B>(
    design: &Design,
    drive: &Drive,
    settings: &Settings,
    mut between: B,
) -> std::result::Result<Output, E>
where
    E: From<Error>,
    B: FnMut(usize) -> std::result::Result<(), E>,
{
    let steps = validate(design, drive, settings)?;
    let (ms, mr, inertia) = design.inertia();
    let w0 = std::f64::consts::TAU * design.natural_frequency;
    let stiffness = inertia * w0 * w0;
    let damping = inertia * w0 / design.quality;
    let torque = match drive.torque {
        Some(t) => t,
        None => {
            drive.peak_angle
                / peak_per_torque(drive.frequency, drive.duty, inertia, stiffness, damping)
        }
    };

    // Scaled units.
    let l = |x: f64| x / UL;
    let force_unit = UM * UL / (UT * UT);
    let torque_unit = force_unit * UL;
    let dt = settings.dt / UT;
    let mut world = PhysicsWorld::new();
    world.gravity = Vector::new(0.0, 0.0, -9.81 * UT * UT / UL);
    let p = &mut world.integration_parameters;
    p.dt = dt;
    p.num_solver_iterations = settings.iterations;
    p.contact_softness = SpringCoefficients::new(0.5 / dt, 10.0);
    p.static_contact_softness = SpringCoefficients::new(1.0 / dt, 10.0);
    p.normalized_max_linear_velocity = 1e6;
    p.contact_recycling = false;
    let ground = world.insert_body(RigidBodyBuilder::fixed());
    let res_group =
        InteractionGroups::new(Group::GROUP_1, Group::GROUP_2, InteractionTestMode::And);
    let part_group =
        InteractionGroups::new(Group::GROUP_2, Group::GROUP_1, InteractionTestMode::And);
    let n_res = design.rows * design.cols;
    let mut resonators = Vec::with_capacity(n_res);
    let [lx, ly, lz] = design.slab;
    for row in 0..design.rows {
        for col in 0..design.cols {
            let [x, y, z] = design.joint(row, col);
            let body = RigidBodyBuilder::dynamic()
                .translation(Vector::new(l(x), l(y), l(z)))
                .rotation(Vector::new(0.0, settings.initial_angle, 0.0))
                .can_sleep(false);
            let h = world.insert_body(body);
            // Colliders carry their resonator's index (the contact loop reads it).
            let index = (row * design.cols + col) as u128;
            let slab = ColliderBuilder::cuboid(l(lx) / 2.0, l(ly) / 2.0, l(lz) / 2.0)
                .user_data(index)
                .mass(ms / UM)
                .friction(design.friction)
                .restitution(design.restitution)
                .collision_groups(res_group);
            world.insert_collider(slab, Some(h));
            let ridge = ColliderBuilder::cuboid(
                l(design.ridge_width) / 2.0,
                l(ly) / 2.0,
                l(design.ridge_height) / 2.0,
            )
            .translation(Vector::new(
                -l(design.ridge_distance),
                0.0,
                l(lz) / 2.0 + l(design.ridge_height) / 2.0,
            ))
            .user_data(index)
            .mass(mr / UM)
            .friction(design.friction)
            .restitution(design.restitution)
            .collision_groups(res_group);
            world.insert_collider(ridge, Some(h));
            let joint = RevoluteJointBuilder::new(Vector::Y)
                .local_anchor1(Vector::new(l(x), l(y), l(z)))
                .local_anchor2(Vector::ZERO);
            world.insert_impulse_joint(ground, h, joint);
            resonators.push(h);
        }
    }
    let [px, py, pz] = design.part_size;
    let top = design.ridge_height;
    let part = world.insert_body(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(
                l(settings.part_start[0]),
                l(settings.part_start[1]),
                l(top + settings.drop_height + pz / 2.0),
            ))
            .can_sleep(false),
    );
    let part_collider = world.insert_collider(
        ColliderBuilder::cuboid(l(px) / 2.0, l(py) / 2.0, l(pz) / 2.0)
            .mass(design.part_mass / UM)
            .friction(design.friction)
            .restitution(design.restitution)
            .collision_groups(part_group),
        Some(part),
    );

    if !settings.part {
        world.bodies[part].set_enabled(false);
    }
    let angle_of = |b: &RigidBody| {
        let q = b.rotation();
        2.0 * q.y.atan2(q.w)
    };
    let mut out = Output {
        t: Vec::new(),
        position: Vec::new(),
        velocity: Vec::new(),
        orientation: Vec::new(),
        angular_velocity: Vec::new(),
        angles: Vec::new(),
        collisions: Vec::new(),
        energy: Energy::default(),
        torque,
        stiffness,
        damping,
        inertia,
    };
    let record = |world: &PhysicsWorld, out: &mut Output, t: f64| {
        let b = &world.bodies[part];
        let (tr, v) = (b.translation(), b.linvel());
        out.t.push(t);
        out.position.push([tr.x * UL, tr.y * UL, tr.z * UL]);
        out.velocity
            .push([v.x * UL / UT, v.y * UL / UT, v.z * UL / UT]);
        let (q, w) = (b.rotation(), b.angvel());
        out.orientation.push([q.x, q.y, q.z, q.w]);
        out.angular_velocity.push([w.x / UT, w.y / UT, w.z / UT]);
        for &h in &resonators {
            out.angles.push(angle_of(&world.bodies[h]));
        }
    };
    record(&world, &mut out, 0.0);
    let m_part = design.part_mass / UM;
    let fx_ext = settings.external_force[0] / force_unit;
    let fy_ext = settings.external_force[1] / force_unit;
    // Open contact episodes per resonator: index into out.collisions.
    let mut open: Vec<Option<usize>> = vec![None; n_res];
    let mut touching = vec![0.0; n_res];
    let mut energy = Energy::default();
    let lead = spring_lead(settings.iterations) * dt;
    let energy_unit = UM * UL * UL / (UT * UT);
    // Every resonator's (angle, angular speed) at the current step's start: read once after each
    // step, for the collision log, the energies and the next step's torques.
    let read = |world: &PhysicsWorld, h: RigidBodyHandle| {
        let b = &world.bodies[h];
        (angle_of(b), b.angvel().y)
    };
    let mut joint_state: Vec<(f64, f64)> = resonators.iter().map(|&h| read(&world, h)).collect();
    // The state at the step's start, kept for the collision log: a collision's angle and angular
    // speed are the resonator's as it came in, before the impact reversed it.
    let mut before = joint_state.clone();
    // A contact that breaks off and resumes within `REJOIN` is the same impact (the soft contact
    // resolving it over a few steps), not a new collision.
    let rejoin = (REJOIN / settings.dt).ceil() as usize;
    let mut last_touch = vec![0usize; n_res];
    for s in 0..steps {
        let t = s as f64 * settings.dt;
        for (i, (&h, &(theta, omega))) in resonators.iter().zip(&joint_state).enumerate() {
            let row = i / design.cols;
            let b = &mut world.bodies[h];
            let drive_t = if drive.on(row, design.rows, t) {
                torque
            } else {
                0.0
            };
            // SI torque from the spring, damper and drive, then to rapier's unit. rapier holds the
            // torque over its `n` substeps, which would feed energy in (about
            // `0.19 omega0 dt` off the damping ratio at n = 4); the spring is read at
            // `theta + gamma dt omega`, which makes the step area-preserving (see `spring_lead`).
            let ahead = theta + lead * omega;
            let tau = (drive_t - stiffness * ahead - damping * omega / UT) / torque_unit;
            b.reset_torques(false);
            b.add_torque(Vector::new(0.0, tau, 0.0), true);
        }
        let v_before = {
            let b = &mut world.bodies[part];
            b.reset_forces(false);
            b.add_force(Vector::new(fx_ext, fy_ext, 0.0), true);
            b.linvel()
        };
        world.step();
        before.copy_from_slice(&joint_state);
        for (state, &h) in joint_state.iter_mut().zip(&resonators) {
            *state = read(&world, h);
        }
        let t_end = (s + 1) as f64 * settings.dt;
        // Contact impulses on the part this step, per resonator.
        touching.iter_mut().for_each(|v| *v = 0.0);
        for pair in world.narrow_phase.contact_pairs_with(part_collider) {
            let other = if pair.collider1 == part_collider {
                pair.collider2
            } else {
                pair.collider1
            };
            touching[world.colliders[other].user_data as usize] += pair.total_impulse_magnitude();
        }
        let total: f64 = touching.iter().sum();
        let b = &world.bodies[part];
        let dpx = m_part * (b.linvel().x - v_before.x) - fx_ext * dt;
        for i in 0..n_res {
            if open[i].is_some() && s - last_touch[i] > rejoin {
                open[i] = None;
            }
            if touching[i] > 0.0 {
                last_touch[i] = s;
                let k = *open[i].get_or_insert_with(|| {
                    let (angle, omega) = before[i];
                    out.collisions.push(Collision {
                        time: t_end,
                        resonator: i,
                        angle,
                        angular_speed: omega / UT,
                        impulse_x: 0.0,
                        impulse_normal: 0.0,
                    });
                    out.collisions.len() - 1
                });
                let c = &mut out.collisions[k];
                c.impulse_normal += touching[i] * force_unit * UT;
                c.impulse_x += dpx * touching[i] / total * force_unit * UT;
            }
        }
        // Energies (scaled units, converted at the end).
        let v = b.linvel();
        energy.part_translation[0] += 0.5 * m_part * v.x * v.x;
        energy.part_translation[1] += 0.5 * m_part * v.y * v.y;
        energy.part_translation[2] += 0.5 * m_part * v.z * v.z;
        energy.part_rotation += b.kinetic_energy() - 0.5 * m_part * v.length_squared();
        for &(theta, omega) in &joint_state {
            energy.resonator_kinetic += 0.5 * (inertia / (UM * UL * UL)) * omega * omega;
            energy.resonator_spring += 0.5 * (stiffness / torque_unit) * theta * theta;
        }
        if (s + 1) % settings.record_every == 0 || s + 1 == steps {
            record(&world, &mut out, t_end);
        }
        if (s + 1) % CHECK_EVERY == 0 {
            between(s + 1)?;
        }
    }
    let scale = energy_unit / steps as f64;
    out.energy = Energy {
        part_translation: energy.part_translation.map(|e| e * scale),
        part_rotation: energy.part_rotation * scale,
        resonator_kinetic: energy.resonator_kinetic * scale,
        resonator_spring: energy.resonator_spring * scale,
    };
    Ok(out)
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
