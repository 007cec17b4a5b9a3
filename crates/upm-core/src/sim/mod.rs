//! The sliding-friction integrator for point and disk parts (docs/spec.md §1).
//!
//! Units: metres, seconds; world frame (see [`crate::motion`]). Each step applies the exact,
//! unconditionally stable implicit Coulomb step to the part's velocity relative to the plate
//! surface under it, `w = v_p - v_s(P, t + dt)`:
//!
//! * stuck after the step (`v_p = v_s`) if `|w| <= mu g dt`, or if the part was stuck and
//!   `|w| <= mu_s g dt` (static friction holds it);
//! * otherwise it slides: `v_p = v_s + w (1 - mu g dt / |w|)`.
//!
//! Then `P += (v_p(t) + v_p(t + dt)) dt / 2`. There is no regularisation: a part on a still plate
//! stops in finite time and never creeps, at any `dt`. The scheme is first order in `dt` at
//! stick–slip events; where the relative velocity passes *near* zero (2-D motion on a rotating
//! plate) the step sticks whenever the miss is closer than `mu g dt`, an `O(dt)` error whose sign
//! depends on the step grid.
//!
//! Disk parts ([`Parts::radius`] > 0) take the coupled translation–spin step of [`crate::disk`]
//! instead, one disk at a time (in parallel over disks).
//!
//! Layout for speed: point parts are processed in chunks of [`CHUNK_PARTS`] with structure-of-arrays
//! state and the time loop inside, so the state stays in cache; [`kernel`] is the per-step update
//! (portable, and an explicit AVX2 build chosen at run time). The plate velocity is tabulated once
//! per block of steps and shared by all chunks. Chunks run on rayon threads; each part is
//! independent, so results are bitwise identical for any thread count. Disks may collide with
//! each other and with walls: [`contact`] (rapier2d) runs after each friction step when contacts
//! are asked for.

pub mod contact;
mod kernel;

use rayon::prelude::*;

use crate::buffer;
use crate::error::{positive, Error, Result};
use crate::motion::PlateMotion;
pub use contact::Contacts;

/// Parts per chunk (a multiple of any SIMD width).
pub const CHUNK_PARTS: usize = 64;
/// Steps of plate velocity tabulated at a time, at most.
const BLOCK_STEPS: usize = 4096;
/// Work of one block, in point-steps and disk-steps: about 0.1 s on one core, so that the
/// caller's check between blocks (Ctrl-C) comes often enough whatever the number of parts.
const BLOCK_POINT_STEPS: usize = 50_000_000;
const BLOCK_DISK_STEPS: usize = 200_000;

/// Steps per block for `worlds` worlds of `points` points and `disks` disks (1..=BLOCK_STEPS).
/// The block length changes only when the caller checks for signals, never the results.
fn block_steps(worlds: usize, points: usize, disks: usize) -> usize {
    let by_points = BLOCK_POINT_STEPS / (worlds * points).max(1);
    let by_disks = BLOCK_DISK_STEPS / (worlds * disks).max(1);
    by_points.min(by_disks).clamp(1, BLOCK_STEPS)
}
/// Largest number of recorded values (rows x parts) a simulation may allocate.
const MAX_RECORDED: usize = 1 << 30;

/// Parts (points and disks): initial state and friction coefficients, one entry per part.
#[derive(Debug, Clone, PartialEq)]
pub struct Parts {
    /// Positions [m].
    pub position: Vec<[f64; 2]>,
    /// Velocities [m/s].
    pub velocity: Vec<[f64; 2]>,
    /// Sliding friction coefficient.
    pub mu: Vec<f64>,
    /// Static friction coefficient, `>= mu`.
    pub mu_s: Vec<f64>,
    /// Disk radius [m]; 0 for a point part.
    pub radius: Vec<f64>,
    /// Orientation [rad] (disks; points keep 0).
    pub angle: Vec<f64>,
    /// Angular velocity [rad/s] (disks; points keep 0).
    pub spin: Vec<f64>,
}

/// Integration settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Config {
    /// Time step [s].
    pub dt: f64,
    /// Simulated time [s]; the run takes `ceil(duration / dt)` steps.
    pub duration: f64,
    /// Gravity [m/s^2].
    pub g: f64,
    /// Side of the square plate centred at the origin [m]; parts whose centre leaves it stop
    /// being simulated. `None`: an unbounded plate.
    pub plate_size: Option<f64>,
    /// Record every this many steps (the initial state is always recorded).
    pub record_every: usize,
}

/// Whether step `s` (1-based) is recorded: every `every`-th step, and always the last one.
#[inline]
fn recorded(s: usize, steps: usize, every: usize) -> bool {
    s.is_multiple_of(every) || s == steps
}

/// Rows recorded for `steps` steps: the initial state, every `every`-th step and the last step.
fn recorded_rows(steps: usize, every: usize) -> usize {
    steps / every + 1 + usize::from(!steps.is_multiple_of(every))
}

/// What a simulation recorded. Arrays are row-major `(rows, parts)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Recorded times [s], `(rows,)`.
    pub t: Vec<f64>,
    /// Positions [m], `(rows, parts)`.
    pub positions: Vec<[f64; 2]>,
    /// Velocities [m/s], `(rows, parts)`.
    pub velocities: Vec<[f64; 2]>,
    /// Whether each part was stuck to the plate, `(rows, parts)`.
    pub stuck: Vec<bool>,
    /// Orientations [rad], `(rows, parts)` (0 for points).
    pub angles: Vec<f64>,
    /// Angular velocities [rad/s], `(rows, parts)` (0 for points).
    pub spins: Vec<f64>,
    /// Time each part's centre left the plate [s], if it did.
    pub left_plate: Vec<Option<f64>>,
}

impl Config {
    /// Number of steps, after checking every setting against the motion.
    pub fn steps(&self, motion: &PlateMotion, parts: usize) -> Result<usize> {
        positive("dt", self.dt)?;
        positive("duration", self.duration)?;
        positive("g", self.g)?;
        if let Some(size) = self.plate_size {
            positive("plate_size", size)?;
        }
        if self.record_every == 0 {
            return Err(Error::parameter("record_every", "must be >= 1; got 0"));
        }
        let f_max = motion.max_frequency();
        let dt_max = 1.0 / (20.0 * f_max);
        if f_max > 0.0 && self.dt > dt_max {
            return Err(Error::parameter(
                "dt",
                format!(
                    "is too large for the motion's highest frequency {f_max:.6e} Hz: at least 20 steps per \
                     period are needed, so dt <= {dt_max:.6e} s; got {}",
                    self.dt
                ),
            ));
        }
        let steps = (self.duration / self.dt - 1e-9).ceil().max(1.0);
        if steps > 1e12 {
            return Err(Error::parameter(
                "dt",
                format!(
                    "gives {steps:e} steps for duration {}; at most 1e12",
                    self.duration
                ),
            ));
        }
        let steps = steps as usize;
        let rows = recorded_rows(steps, self.record_every);
        if rows.saturating_mul(parts.max(1)) > MAX_RECORDED {
            return Err(Error::parameter(
                "record_every",
                format!(
                    "is too small: {rows} recorded rows x {parts} parts exceeds {MAX_RECORDED} values; \
                     record every {} steps or more",
                    (steps * parts.max(1)) / MAX_RECORDED + 1
                ),
            ));
        }
        Ok(steps)
    }
}

impl Parts {
    /// Point parts at `position` with `velocity`, friction `mu` and `mu_s`.
    pub fn points(
        position: Vec<[f64; 2]>,
        velocity: Vec<[f64; 2]>,
        mu: Vec<f64>,
        mu_s: Vec<f64>,
    ) -> Self {
        let m = position.len();
        Parts {
            position,
            velocity,
            mu,
            mu_s,
            radius: vec![0.0; m],
            angle: vec![0.0; m],
            spin: vec![0.0; m],
        }
    }

    /// The parts at `idx`, in that order.
    fn subset(&self, idx: &[usize]) -> Parts {
        Parts {
            position: idx.iter().map(|&i| self.position[i]).collect(),
            velocity: idx.iter().map(|&i| self.velocity[i]).collect(),
            mu: idx.iter().map(|&i| self.mu[i]).collect(),
            mu_s: idx.iter().map(|&i| self.mu_s[i]).collect(),
            radius: idx.iter().map(|&i| self.radius[i]).collect(),
            angle: idx.iter().map(|&i| self.angle[i]).collect(),
            spin: idx.iter().map(|&i| self.spin[i]).collect(),
        }
    }

    /// Checks lengths, finiteness, `mu_s >= mu > 0` and `radius >= 0`.
    pub fn check(&self) -> Result<()> {
        let m = self.position.len();
        let lens = [
            self.velocity.len(),
            self.mu.len(),
            self.mu_s.len(),
            self.radius.len(),
            self.angle.len(),
            self.spin.len(),
        ];
        if lens.iter().any(|&l| l != m) {
            return Err(Error::Shape(format!(
                "parts: {m} positions but {lens:?} velocities, mu, mu_s, radius, angle, spin; all must be equal"
            )));
        }
        for i in 0..m {
            let at = |e: Error| e.with_context(&format!("part {i}"));
            for (name, v) in [
                ("position", self.position[i]),
                ("velocity", self.velocity[i]),
            ] {
                if !(v[0].is_finite() && v[1].is_finite()) {
                    return Err(at(Error::parameter(
                        name,
                        format!("must be finite; got ({}, {})", v[0], v[1]),
                    )));
                }
            }
            positive("mu", self.mu[i]).map_err(at)?;
            if !(self.radius[i].is_finite() && self.radius[i] >= 0.0) {
                return Err(at(Error::parameter(
                    "radius",
                    format!("must be finite and >= 0; got {}", self.radius[i]),
                )));
            }
            for (name, v) in [("angle", self.angle[i]), ("spin", self.spin[i])] {
                crate::error::finite(name, v).map_err(at)?;
            }
            if !(self.mu_s[i].is_finite() && self.mu_s[i] >= self.mu[i]) {
                return Err(at(Error::parameter(
                    "mu_s",
                    format!(
                        "must be finite and >= mu = {}; got {}",
                        self.mu[i], self.mu_s[i]
                    ),
                )));
            }
        }
        Ok(())
    }
}

/// Whether a part at `p` with velocity `v` moves with the plate surface of velocity `u`
/// (such a part starts stuck).
fn moves_with_plate(p: [f64; 2], v: [f64; 2], u: [f64; 3]) -> bool {
    v[0] == u[0] - u[2] * p[1] && v[1] == u[1] + u[2] * p[0]
}

/// Whether a centre at `(x, y)` is off the square plate of half-side `half`.
fn off_plate(x: f64, y: f64, half: f64) -> bool {
    x.abs() > half || y.abs() > half
}

/// Half the plate's side [m], infinite for an unbounded plate.
fn half_side(cfg: &Config) -> f64 {
    cfg.plate_size.map_or(f64::INFINITY, |s| 0.5 * s)
}

/// State of one chunk of parts, structure of arrays. Flags are f64 masks (0 or 1) so the step is
/// branch-free and vectorises.
struct Chunk {
    x: Vec<f64>,
    y: Vec<f64>,
    vx: Vec<f64>,
    vy: Vec<f64>,
    stuck: Vec<f64>,
    active: Vec<f64>,
    left: Vec<Option<f64>>,
    slide: Vec<f64>,  // mu g dt
    hold: Vec<f64>,   // mu_s g dt
    record: Vec<Row>, // rows recorded during the current block
}

#[derive(Clone)]
struct Row {
    pos: Vec<[f64; 2]>,
    vel: Vec<[f64; 2]>,
    stuck: Vec<bool>,
}

impl Chunk {
    fn row(&self) -> Row {
        Row {
            pos: self.x.iter().zip(&self.y).map(|(&x, &y)| [x, y]).collect(),
            vel: self
                .vx
                .iter()
                .zip(&self.vy)
                .map(|(&x, &y)| [x, y])
                .collect(),
            stuck: self.stuck.iter().map(|&s| s > 0.0).collect(),
        }
    }

    /// Advances through one block: `table[k] = (u1, u2, u3)` at the end of step `first + k`.
    fn run(&mut self, table: &[[f64; 3]], first: usize, cfg: &Config, steps: usize) {
        let half = half_side(cfg);
        for (k, &u) in table.iter().enumerate() {
            let mut lanes = kernel::Lanes {
                x: &mut self.x,
                y: &mut self.y,
                vx: &mut self.vx,
                vy: &mut self.vy,
                stuck: &mut self.stuck,
                active: &self.active,
                slide: &self.slide,
                hold: &self.hold,
            };
            if kernel::step(u, cfg.dt, half, &mut lanes) {
                for i in 0..self.x.len() {
                    if self.active[i] > 0.0 && off_plate(self.x[i], self.y[i], half) {
                        self.active[i] = 0.0;
                        self.left[i] = Some((first + k + 1) as f64 * cfg.dt);
                    }
                }
            }
            if recorded(first + k + 1, steps, cfg.record_every) {
                self.record.push(self.row());
            }
        }
    }
}

/// A recorded disk state: position, velocity, angle, spin, stuck.
type DiskRow = ([f64; 2], [f64; 2], f64, f64, bool);

/// One disk part: its state, friction thresholds and the rows recorded in the current block.
struct DiskState {
    p: [f64; 2],
    v: [f64; 2],
    angle: f64,
    spin: f64,
    radius: f64,
    stuck: bool,
    active: bool,
    left: Option<f64>,
    slide: f64,
    hold: f64,
    record: Vec<DiskRow>,
}

impl DiskState {
    fn new(parts: &Parts, i: usize, cfg: &Config, u0: [f64; 3]) -> Self {
        let (p, v, spin) = (parts.position[i], parts.velocity[i], parts.spin[i]);
        let outside = off_plate(p[0], p[1], half_side(cfg));
        DiskState {
            p,
            v,
            angle: parts.angle[i],
            spin,
            radius: parts.radius[i],
            // A disk that starts moving with the plate surface starts stuck.
            stuck: moves_with_plate(p, v, u0) && spin == u0[2],
            active: !outside,
            left: outside.then_some(0.0),
            slide: parts.mu[i] * cfg.g * cfg.dt,
            hold: parts.mu_s[i] * cfg.g * cfg.dt,
            record: Vec::new(),
        }
    }

    fn row(&self) -> DiskRow {
        (self.p, self.v, self.angle, self.spin, self.stuck)
    }

    /// The disk's velocity, spin and stuck flag after the implicit friction step
    /// ([`crate::disk::implicit_step`]) under the plate velocity `u`; the state is not changed.
    fn friction(&self, [u1, u2, u3]: [f64; 3]) -> ([f64; 2], f64, bool) {
        let [x, y] = self.p;
        let (sx, sy) = (u1 - u3 * y, u2 + u3 * x);
        let free = [self.v[0] - sx, self.v[1] - sy];
        let r = self.radius;
        let st = crate::disk::implicit_step(
            free,
            r * (self.spin - u3),
            self.slide,
            self.hold,
            self.stuck,
        );
        ([sx + st.w[0], sy + st.w[1]], u3 + st.s / r, st.stuck)
    }

    /// Moves to velocity `v` and spin `spin` over one step, positions by the trapezoid.
    fn advance(&mut self, v: [f64; 2], spin: f64, stuck: bool, dt: f64) {
        let [x, y] = self.p;
        self.p = [
            x + 0.5 * (self.v[0] + v[0]) * dt,
            y + 0.5 * (self.v[1] + v[1]) * dt,
        ];
        self.angle += 0.5 * (self.spin + spin) * dt;
        (self.v, self.spin, self.stuck) = (v, spin, stuck);
    }

    /// Whether the disk's centre left the plate in step `s` (0-based); it is then frozen.
    fn leaves(&mut self, s: usize, cfg: &Config) -> bool {
        let out = self.active && off_plate(self.p[0], self.p[1], half_side(cfg));
        if out {
            self.active = false;
            self.left = Some((s + 1) as f64 * cfg.dt);
        }
        out
    }

    /// Records the state after step `s` (0-based) if that step is recorded.
    fn record_step(&mut self, s: usize, cfg: &Config, steps: usize) {
        if recorded(s + 1, steps, cfg.record_every) {
            self.record.push(self.row());
        }
    }

    /// Step `s` (0-based) under the plate velocity `u` without contacts, if the disk is still on
    /// the plate; whether it left it in this step.
    fn step(&mut self, u: [f64; 3], s: usize, cfg: &Config) -> bool {
        if !self.active {
            return false;
        }
        let (v, spin, stuck) = self.friction(u);
        self.advance(v, spin, stuck, cfg.dt);
        self.leaves(s, cfg)
    }

    /// Advances through one block with the disk's implicit step ([`crate::disk::implicit_step`]).
    fn run(&mut self, table: &[[f64; 3]], first: usize, cfg: &Config, steps: usize) {
        for (k, &u) in table.iter().enumerate() {
            self.step(u, first + k, cfg);
            self.record_step(first + k, cfg, steps);
        }
    }
}

/// The parts of one world and what has been recorded of it.
struct World<'a> {
    motion: &'a PlateMotion,
    /// Point parts in chunks; `points[j]` is the index of the j-th point among all parts.
    chunks: Vec<Chunk>,
    points: &'a [usize],
    /// Disk parts; `disk_index[j]` is the index of the j-th disk among all parts.
    disks: Vec<DiskState>,
    disk_index: &'a [usize],
    /// The disks' rapier world when contacts are on.
    contact: Option<contact::ContactWorld>,
    out: Trajectory,
    table: Vec<[f64; 3]>,
}

impl World<'_> {
    /// Appends the rows recorded since the last flush, in the parts' original order.
    fn flush(&mut self, m: usize) {
        let n = self.chunks.first().map_or_else(
            || self.disks.first().map_or(0, |d| d.record.len()),
            |c| c.record.len(),
        );
        if self.disks.is_empty() {
            // Points only, in their original order (chunks of consecutive parts): append each
            // row as it is, with no zero fill and no index lookup.
            for r in 0..n {
                for c in &self.chunks {
                    let row = &c.record[r];
                    self.out.positions.extend_from_slice(&row.pos);
                    self.out.velocities.extend_from_slice(&row.vel);
                    self.out.stuck.extend_from_slice(&row.stuck);
                }
                let len = self.out.positions.len();
                self.out.angles.resize(len, 0.0);
                self.out.spins.resize(len, 0.0);
            }
            for c in &mut self.chunks {
                c.record.clear();
            }
            return;
        }
        for r in 0..n {
            let base = self.out.positions.len();
            self.out.positions.resize(base + m, [0.0; 2]);
            self.out.velocities.resize(base + m, [0.0; 2]);
            self.out.stuck.resize(base + m, false);
            self.out.angles.resize(base + m, 0.0);
            self.out.spins.resize(base + m, 0.0);
            let mut j = 0;
            for c in &self.chunks {
                let row = &c.record[r];
                for q in 0..row.pos.len() {
                    let i = base + self.points[j];
                    self.out.positions[i] = row.pos[q];
                    self.out.velocities[i] = row.vel[q];
                    self.out.stuck[i] = row.stuck[q];
                    j += 1;
                }
            }
            for (d, &idx) in self.disks.iter().zip(self.disk_index) {
                let (p, v, angle, spin, stuck) = d.record[r];
                let i = base + idx;
                (
                    self.out.positions[i],
                    self.out.velocities[i],
                    self.out.stuck[i],
                ) = (p, v, stuck);
                (self.out.angles[i], self.out.spins[i]) = (angle, spin);
            }
        }
        for c in &mut self.chunks {
            c.record.clear();
        }
        for d in &mut self.disks {
            d.record.clear();
        }
    }
}

fn chunks(parts: &Parts, cfg: &Config, u0: [f64; 3]) -> Vec<Chunk> {
    let m = parts.position.len();
    let half = half_side(cfg);
    (0..m)
        .step_by(CHUNK_PARTS)
        .map(|start| {
            let r = start..(start + CHUNK_PARTS).min(m);
            let pos = &parts.position[r.clone()];
            let vel = &parts.velocity[r.clone()];
            // A part that starts moving with the plate surface starts stuck.
            let stuck = pos
                .iter()
                .zip(vel)
                .map(|(&p, &v)| f64::from(u8::from(moves_with_plate(p, v, u0))))
                .collect();
            let outside: Vec<bool> = pos.iter().map(|p| off_plate(p[0], p[1], half)).collect();
            Chunk {
                x: pos.iter().map(|p| p[0]).collect(),
                y: pos.iter().map(|p| p[1]).collect(),
                vx: vel.iter().map(|v| v[0]).collect(),
                vy: vel.iter().map(|v| v[1]).collect(),
                stuck,
                active: outside.iter().map(|&o| if o { 0.0 } else { 1.0 }).collect(),
                left: outside
                    .iter()
                    .map(|&o| if o { Some(0.0) } else { None })
                    .collect(),
                slide: parts.mu[r.clone()]
                    .iter()
                    .map(|mu| mu * cfg.g * cfg.dt)
                    .collect(),
                hold: parts.mu_s[r].iter().map(|mu| mu * cfg.g * cfg.dt).collect(),
                record: Vec::new(),
            }
        })
        .collect()
}

/// Simulates `parts` (points and disks) on a plate driven by `motion`.
pub fn simulate(motion: &PlateMotion, parts: &Parts, cfg: &Config) -> Result<Trajectory> {
    let mut runs = simulate_worlds(std::slice::from_ref(motion), parts, cfg, |_| {
        Ok::<(), Error>(())
    })?;
    Ok(runs.remove(0))
}

/// Simulates `B` independent worlds, one motion each, all starting from `parts`, in parallel.
pub fn simulate_batch(
    motions: &[PlateMotion],
    parts: &Parts,
    cfg: &Config,
) -> Result<Vec<Trajectory>> {
    simulate_worlds(motions, parts, cfg, |_| Ok::<(), Error>(()))
}

/// The worlds of [`simulate_batch`], advanced together one block of steps at a time (every chunk
/// of every world in parallel), calling `between(steps_done)` on the calling thread after each
/// block; an error from it (an interrupt) stops the run.
pub fn simulate_worlds<E, B>(
    motions: &[PlateMotion],
    parts: &Parts,
    cfg: &Config,
    between: B,
) -> std::result::Result<Vec<Trajectory>, E>
where
    E: From<Error>,
    B: FnMut(usize) -> std::result::Result<(), E>,
{
    simulate_worlds_with(motions, parts, cfg, None, between)
}

/// [`simulate_worlds`] with part–part and wall contacts of the disks resolved by rapier
/// ([`contact`]) when `contacts` is given.
pub fn simulate_worlds_with<E, B>(
    motions: &[PlateMotion],
    parts: &Parts,
    cfg: &Config,
    contacts: Option<&Contacts>,
    mut between: B,
) -> std::result::Result<Vec<Trajectory>, E>
where
    E: From<Error>,
    B: FnMut(usize) -> std::result::Result<(), E>,
{
    parts.check()?;
    let m = parts.position.len();
    let mut steps = 0;
    for (b, motion) in motions.iter().enumerate() {
        steps = cfg.steps(motion, m).map_err(|e| {
            if motions.len() > 1 {
                e.with_context(&format!("world {b}"))
            } else {
                e
            }
        })?;
    }
    let rows = recorded_rows(steps, cfg.record_every);
    let (points, disk_index): (Vec<usize>, Vec<usize>) =
        (0..m).partition(|&i| parts.radius[i] == 0.0);
    let point_parts = parts.subset(&points);
    let disk_mass: Vec<f64> = match contacts {
        None => Vec::new(),
        Some(c) => {
            let disks: Vec<_> = disk_index
                .iter()
                .map(|&i| (parts.position[i], parts.radius[i], i))
                .collect();
            c.check(&disks, m)?;
            disk_index
                .iter()
                .map(|&i| {
                    c.mass
                        .as_ref()
                        .map_or(parts.radius[i] * parts.radius[i], |mass| mass[i])
                })
                .collect()
        }
    };
    let cells = rows.checked_mul(m).ok_or_else(|| {
        Error::parameter(
            "record_every",
            "is too small: the number of records overflows",
        )
    })?;
    let block = block_steps(motions.len(), points.len(), disk_index.len());
    let mut worlds: Vec<World> = Vec::with_capacity(motions.len());
    for motion in motions {
        let u0 = motion.velocity(0.0);
        let disks: Vec<DiskState> = disk_index
            .iter()
            .map(|&i| DiskState::new(parts, i, cfg, u0))
            .collect();
        // Reserved fallibly (an error, not an abort, when it cannot fit), on huge pages.
        let mut out = Trajectory {
            t: Vec::new(),
            positions: Vec::new(),
            velocities: Vec::new(),
            stuck: Vec::new(),
            angles: Vec::new(),
            spins: Vec::new(),
            left_plate: Vec::new(),
        };
        buffer::reserve(&mut out.t, rows, "the recorded times")?;
        buffer::reserve(&mut out.positions, cells, "the positions")?;
        buffer::reserve(&mut out.velocities, cells, "the velocities")?;
        buffer::reserve(&mut out.stuck, cells, "the stuck flags")?;
        buffer::reserve(&mut out.angles, cells, "the angles")?;
        buffer::reserve(&mut out.spins, cells, "the spins")?;
        worlds.push(World {
            motion,
            chunks: chunks(&point_parts, cfg, u0),
            points: &points,
            contact: contacts.map(|c| contact::ContactWorld::new(&disks, &disk_mass, c, cfg)),
            disks,
            disk_index: &disk_index,
            out,
            table: Vec::with_capacity(block),
        });
    }
    for w in &mut worlds {
        w.out.t.push(0.0);
        for c in &mut w.chunks {
            c.record.push(c.row());
        }
        for d in &mut w.disks {
            d.record.push(d.row());
        }
        w.flush(m);
    }
    let mut first = 0;
    while first < steps {
        let end = (first + block).min(steps);
        worlds.par_iter_mut().for_each(|w| {
            w.table.clear();
            // Sampled a hair before each step's end: a program boundary that falls on a step end
            // (the usual case: durations in whole steps) then always belongs to the step before
            // it, whatever the rounding of (s + 1) dt.
            let motion = w.motion;
            w.table
                .extend((first..end).map(|s| motion.velocity(((s + 1) as f64 - 1e-6) * cfg.dt)));
            let table = &w.table;
            w.chunks
                .par_iter_mut()
                .for_each(|c| c.run(table, first, cfg, steps));
            match &mut w.contact {
                Some(c) => c.run(&mut w.disks, table, first, cfg, steps),
                None => w
                    .disks
                    .par_iter_mut()
                    .for_each(|d| d.run(table, first, cfg, steps)),
            }
            w.out.t.extend(
                ((first + 1)..=end)
                    .filter(|&s| recorded(s, steps, cfg.record_every))
                    .map(|s| s as f64 * cfg.dt),
            );
            w.flush(m);
        });
        between(end)?;
        first = end;
    }
    Ok(worlds
        .into_iter()
        .map(|mut w| {
            let mut left = vec![None; m];
            let point_left = w.chunks.iter().flat_map(|c| c.left.iter().copied());
            for (j, l) in point_left.enumerate() {
                left[w.points[j]] = l;
            }
            for (d, &i) in w.disks.iter().zip(w.disk_index) {
                left[i] = d.left;
            }
            w.out.left_plate = left;
            w.out
        })
        .collect())
}
