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
//! instead, in groups of disks on rayon threads (the steps outside, so independent disks overlap;
//! [`disks`]), and polygon parts ([`Parts::polygons`]) the exact stick–slip step of
//! [`crate::polygon`], one part per task ([`polygons`]).
//!
//! Layout for speed: point parts are processed in chunks of [`CHUNK_PARTS`] with structure-of-arrays
//! state and the time loop inside ([`points`]); [`kernel`] is the update through a segment of
//! steps (AVX-512, AVX2 and portable builds, chosen at run time), tiles of parts in registers.
//! The plate velocity is tabulated once per block of steps and shared by all chunks; recorded
//! states go straight into the result ([`record`]). Chunks run on rayon threads; each part is
//! independent, so results are bitwise identical for any thread count. Disks may collide with
//! each other and with walls: [`contact`] (rapier2d) runs after each friction step when contacts
//! are asked for.

mod base;
mod config;
pub mod contact;
mod disks;
mod group;
pub mod kernel;
pub mod lift;
mod parts;
mod points;
mod polygons;
mod record;
#[cfg(target_arch = "x86_64")]
mod short;
mod source;
pub mod surface;
mod timing;
mod work;

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::motion::{Phases, PlateMotion};
use crate::parallel;
pub use crate::simd::{simd, Simd};
use config::half_side;
pub use config::Config;
pub use contact::Contacts;
use disks::{run_disks, DiskState};
pub use parts::{Parts, PartsView, WorldRows};
pub use points::CHUNK_PARTS;
pub use record::Stacked;
use record::{recorded_rows, Rec, Recorder};
pub use surface::FrictionMap;
pub use work::little_work;
use work::{block_steps, little, POLYGON_DISKS};

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
    /// Time each part spent in flight [s] (0 on a plate that stays in its plane), `(parts,)`.
    pub flight: Vec<f64>,
}

/// Whether a part at `p` with velocity `v` moves with the plate surface of velocity `u`
/// (such a part starts stuck).
fn moves_with_plate(p: [f64; 2], v: [f64; 2], u: [f64; 3]) -> bool {
    // (`&` and `|`, not `&&` and `||`: no branch, so the loops over many parts vectorise)
    (v[0] == u[0] - u[2] * p[1]) & (v[1] == u[1] + u[2] * p[0])
}

/// Whether a centre at `(x, y)` is off the square plate of half-side `half`.
fn off_plate(x: f64, y: f64, half: f64) -> bool {
    (x.abs() > half) | (y.abs() > half)
}

/// Whether a part still on the plate (`active`) with its centre at `c` left it in step `s`
/// (0-based): it is then frozen (`active` cleared) and its time of leaving kept in `left`.
fn leaves(active: &mut bool, left: &mut Option<f64>, c: [f64; 2], s: usize, cfg: &Config) -> bool {
    let out = *active && off_plate(c[0], c[1], half_side(cfg));
    if out {
        *active = false;
        *left = Some((s + 1) as f64 * cfg.dt);
    }
    out
}

/// The parts of one world and what has been recorded of it.
struct World<'a> {
    motion: &'a PlateMotion,
    points: points::Points<'a>,
    /// Disk parts.
    disks: Vec<DiskState>,
    /// The disks' and polygons' rapier world when contacts are on (boxed: it is large, and
    /// most worlds have none).
    contact: Option<Box<contact::ContactWorld>>,
    /// Polygon parts.
    polygons: Vec<polygons::PolygonState>,
    rec: Rec,
    /// The motion's timing class among the batch's ([`timing::classes`]).
    timing: usize,
    /// Whether the motion leaves the plane (read once: the block loop asks every block).
    spatial: bool,
    /// The out-of-plane accelerations of the block's steps (empty for a planar motion).
    normals: Vec<[f64; 3]>,
    /// The plate's friction over its surface ([`PartsView::surface`]).
    surface: Option<&'a FrictionMap>,
}

std::thread_local! {
    /// Each thread's table of plate velocity for the block of the world it runs, kept from world
    /// to world and from call to call: a table a world, freed as the call ended, was fresh
    /// memory again in the next (a page fault per 4 KiB; a batch of 63 worlds of 64 points spent
    /// a tenth of its time there).
    static TABLE: std::cell::Cell<Vec<[f64; 3]>> = const { std::cell::Cell::new(Vec::new()) };
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
    simulate_worlds_with(motions, &parts.view(), cfg, None, between)
}

/// [`simulate_worlds`] with part–part and wall contacts of the disks resolved by rapier
/// ([`contact`]) when `contacts` is given, on borrowed parts.
pub fn simulate_worlds_with<E, B>(
    motions: &[PlateMotion],
    parts: &PartsView,
    cfg: &Config,
    contacts: Option<&Contacts>,
    between: B,
) -> std::result::Result<Vec<Trajectory>, E>
where
    E: From<Error>,
    B: FnMut(usize) -> std::result::Result<(), E>,
{
    let all = simulate_stacked(motions, parts, cfg, contacts, None, between)?;
    let (b, m) = (motions.len(), parts.len());
    let cells = all.t.len() * m;
    let left = |w: usize| -> Vec<Option<f64>> {
        all.left[w * m..(w + 1) * m]
            .iter()
            .map(|&l| (!l.is_nan()).then_some(l))
            .collect()
    };
    if b == 1 {
        // One world: its buffers are the trajectory's, moved, not copied.
        let left_plate = left(0);
        return Ok(vec![Trajectory {
            t: all.t,
            positions: all.positions,
            velocities: all.velocities,
            stuck: all.stuck,
            angles: or_zeros(all.angles, cells),
            spins: or_zeros(all.spins, cells),
            left_plate,
            flight: or_zeros(all.flight, m),
        }]);
    }
    Ok((0..b)
        .map(|w| {
            let r = w * cells..(w + 1) * cells;
            // world w's rows of `a`, or zeros where the stacked result left `a` out
            let rows = |a: &[f64], r: std::ops::Range<usize>| match a {
                [] => vec![0.0; r.len()],
                _ => a[r].to_vec(),
            };
            Trajectory {
                t: all.t.clone(),
                positions: all.positions[r.clone()].to_vec(),
                velocities: all.velocities[r.clone()].to_vec(),
                stuck: all.stuck[r.clone()].to_vec(),
                angles: rows(&all.angles, r.clone()),
                spins: rows(&all.spins, r),
                left_plate: left(w),
                flight: rows(&all.flight, w * m..(w + 1) * m),
            }
        })
        .collect())
}

/// `v`, or `n` zeros where it is empty (a stacked result leaves out what is zero throughout).
fn or_zeros(v: Vec<f64>, n: usize) -> Vec<f64> {
    if v.is_empty() {
        vec![0.0; n]
    } else {
        v
    }
}

/// [`simulate_worlds_with`] with the worlds' results stacked in one [`Stacked`], written in
/// place (see there). (The binding hands these
/// buffers to NumPy as they are). With `friction`, world `b` has its own friction coefficients
/// (a friction sweep in one parallel run): `parts`' are replaced by that world's rows.
pub fn simulate_stacked<E, B>(
    motions: &[PlateMotion],
    parts: &PartsView,
    cfg: &Config,
    contacts: Option<&Contacts>,
    friction: Option<&WorldRows>,
    between: B,
) -> std::result::Result<Stacked, E>
where
    E: From<Error>,
    B: FnMut(usize) -> std::result::Result<(), E>,
{
    let motions: Vec<&PlateMotion> = motions.iter().collect();
    simulate_stacked_refs(&motions, parts, cfg, contacts, friction, between)
}

/// [`simulate_stacked`] on motions lent by reference: the binding lends the Python objects'
/// motions instead of copying them (copying and dropping 500 jets was a fifth of a 2-step call of
/// 500 worlds).
pub fn simulate_stacked_refs<E, B>(
    motions: &[&PlateMotion],
    parts: &PartsView,
    cfg: &Config,
    contacts: Option<&Contacts>,
    friction: Option<&WorldRows>,
    mut between: B,
) -> std::result::Result<Stacked, E>
where
    E: From<Error>,
    B: FnMut(usize) -> std::result::Result<(), E>,
{
    // Point parts alone: their positions and velocities are checked for finiteness as each chunk
    // reads them (one pass over the caller's arrays, not two), and a failure is reported after
    // the first block by the full check; anything else is checked here.
    let points_only =
        parts.polygons.is_empty() && parts.radius.is_none_or(|r| r.iter().all(|&v| v == 0.0));
    let (steps, spatial) = checked(motions, parts, cfg, contacts, friction, points_only)?;
    let not_finite = AtomicBool::new(false);
    let m = parts.len();
    // Some world's plate leaves its plane (parts may fly).
    let flying = spatial.iter().any(|&s| s);
    let rows = recorded_rows(steps, cfg.record_every);
    // Points only: the points are the parts, in order (no index to map them through).
    let disk_index: Vec<usize> = (0..m).filter(|&i| parts.radius(i) > 0.0).collect();
    let mut is_polygon = vec![false; if parts.polygons.is_empty() { 0 } else { m }];
    for &(i, _) in parts.polygons {
        is_polygon[i] = true;
    }
    let point_index: Option<Vec<usize>> = (!disk_index.is_empty() || !parts.polygons.is_empty())
        .then(|| {
            (0..m)
                .filter(|&i| parts.radius(i) == 0.0 && !is_polygon.get(i).copied().unwrap_or(false))
                .collect()
        });
    let index = point_index.as_deref();
    // Checked, with every disk's and then every polygon's mass.
    let mass: Vec<f64> = match contacts {
        None => Vec::new(),
        Some(c) => c.prepare(parts, &disk_index)?,
    };
    rows.checked_mul(m).ok_or_else(|| {
        Error::parameter(
            "record_every",
            "is too small: the number of records overflows",
        )
    })?;
    let n_points = m - disk_index.len() - parts.polygons.len();
    let heavy = disk_index.len() + POLYGON_DISKS * parts.polygons.len();
    let block = block_steps(motions.len(), n_points, heavy);
    // On a plate whose friction varies, each part's friction is looked up between blocks.
    let block = match parts.surface {
        Some(_) => block.min(FrictionMap::refresh_steps(cfg.dt)),
        None => block,
    };
    // A run of little work goes on this thread alone: handing it to the pool's threads and
    // waiting for one to wake cost more than they saved (20 worlds of 8 points through 100 steps
    // took 156 us on two threads, median, and 31 on one; Intel Xeon, a shared VM).
    let _alone = parallel::Alone::when(little(motions.len(), steps, n_points, heavy));
    // Small worlds of point parts alone run side by side, several to a register tile.
    let grouped = motions.len() > 1
        && n_points == m
        && m <= group::MAX_POINTS
        && contacts.is_none()
        && parts.surface.is_none()
        && !flying;
    // Reserved fallibly (an error, not an abort, when it cannot fit), reusing recycled results.
    let turning = if n_points == m {
        record::Turning::None
    } else if n_points > 0 {
        record::Turning::Some
    } else {
        record::Turning::All
    };
    let mut recorder = Recorder::new(motions.len(), rows, m, turning, flying)?;
    if grouped {
        return group::simulate(
            motions, parts, cfg, friction, steps, block, recorder, between,
        );
    }
    let recs: Vec<Rec> = (0..motions.len())
        .map(|b| recorder.rec(b, steps, cfg.record_every))
        .collect();
    // Each world set up on the thread that takes it (a batch of many small worlds); the polygons'
    // steppers built once, per distinct shape.
    let steppers = polygons::steppers(parts.polygons);
    // Worlds of one timing share each block's phasor samples (a batch's rollouts).
    let classes = timing::classes(motions);
    let count = classes.iter().max().map_or(0, |c| c + 1);
    let not_finite = &not_finite;
    let mut worlds: Vec<World> = recs
        .into_par_iter()
        .with_min_len(parallel::min_len())
        .enumerate()
        .map(|(b, rec)| {
            let motion = motions[b];
            let u0 = motion.velocity(0.0);
            let own = friction.map(|f| f.world(parts, b));
            let parts = own.as_ref().unwrap_or(parts);
            let disks: Vec<DiskState> = disk_index
                .iter()
                .map(|&i| DiskState::new(parts, i, cfg, u0))
                .collect();
            let shapes: Vec<polygons::PolygonState> = parts
                .polygons
                .iter()
                .zip(&steppers)
                .map(|((i, _), st)| polygons::PolygonState::new(parts, *i, st, cfg, u0))
                .collect();
            World {
                motion,
                points: points::Points::new(
                    parts,
                    index,
                    cfg,
                    u0,
                    spatial[b],
                    steps <= block,
                    not_finite,
                ),
                contact: contacts
                    .map(|c| Box::new(contact::ContactWorld::new(&disks, &shapes, &mass, c, cfg))),
                disks,
                polygons: shapes,
                rec,
                timing: classes[b],
                spatial: spatial[b],
                normals: Vec::with_capacity(if spatial[b] { block } else { 0 }),
                surface: parts.surface,
            }
        })
        .collect();
    recorder.times(0, 0, steps, cfg.record_every, cfg.dt);
    // (the points record their initial state as their first block reads them)
    worlds
        .par_iter_mut()
        .with_min_len(parallel::min_len())
        .for_each(|w| {
            for d in &w.disks {
                d.record_step(None, &w.rec);
            }
            for p in &w.polygons {
                p.record(0, &w.rec);
            }
        });
    let mut first = 0;
    while first < steps {
        let end = (first + block).min(steps);
        // (the planar worlds' samples: the out-of-plane ones take their own)
        let planar = (worlds.iter()).filter(|w| !w.spatial);
        let shared = timing::shared(
            planar.map(|w| (w.timing, w.motion)),
            count,
            1,
            first..end,
            cfg.dt,
        );
        worlds
            .par_iter_mut()
            .with_min_len(parallel::min_len())
            .try_for_each(|w| w.block(&shared[w.timing], first..end, cfg, index))?;
        if first == 0 && not_finite.load(Ordering::Relaxed) {
            parts.check()?; // names the first part whose state is not finite
        }
        recorder.times(first + 1, end, steps, cfg.record_every, cfg.dt);
        between(end)?;
        first = end;
    }
    // The points recorded their times of leaving the plate and of flight as their last block
    // ended; the disks and polygons record theirs now.
    for w in &worlds {
        w.ended(cfg.dt);
    }
    drop(worlds);
    // SAFETY: every row of every world was written: row 0 before the first block (by the points
    // in it), and every recorded step's row by the chunk or disk that owns each part, in the
    // block of that step; every point's times in its last block, every disk's and polygon's
    // just above.
    Ok(unsafe { recorder.finish() })
}

/// The checks of a stacked run that the blocks do not make (see [`simulate_stacked_refs`]): the
/// parts (their state too unless `points_only`), every world's friction rows, every motion
/// resolved by the step, and contacts refused on a plate that leaves its plane. The number of
/// steps and whether each world's motion leaves the plane.
fn checked(
    motions: &[&PlateMotion],
    parts: &PartsView,
    cfg: &Config,
    contacts: Option<&Contacts>,
    friction: Option<&WorldRows>,
    points_only: bool,
) -> Result<(usize, Vec<bool>)> {
    parts.check_with(!points_only)?;
    let m = parts.len();
    if let Some(f) = friction {
        f.check(motions.len(), m)?;
        for b in 0..motions.len() {
            f.world(parts, b)
                .check_with(!points_only)
                .map_err(|e| e.with_context(&format!("world {b}")))?;
        }
    }
    let world = |b: usize| {
        move |e: Error| {
            if motions.len() > 1 {
                e.with_context(&format!("world {b}"))
            } else {
                e
            }
        }
    };
    let steps = match motions.first() {
        Some(first) => cfg.steps(first, m).map_err(world(0))?,
        None => 0,
    };
    for (b, motion) in motions.iter().enumerate().skip(1) {
        cfg.resolves(motion).map_err(world(b))?;
    }
    let spatial = motions.iter().map(|m| m.is_spatial()).collect::<Vec<_>>();
    if contacts.is_some() && spatial.iter().any(|&s| s) {
        return Err(Error::parameter(
            "contacts",
            "are not supported on a plate that moves out of its plane (parts may lift off); \
             simulate without contacts",
        ));
    }
    Ok((steps, spatial))
}

impl World<'_> {
    /// Steps this world through `steps` (one block): its plate velocity tabulated (from the
    /// samples its timing class shares, `phases`, where there are), then its points, disks and
    /// polygons (or its contact world).
    fn block(
        &mut self,
        phases: &Option<Phases>,
        steps: std::ops::Range<usize>,
        cfg: &Config,
        index: Option<&[usize]>,
    ) -> Result<()> {
        let first = steps.start;
        if let Some(map) = self.surface {
            // each disk's and polygon's friction where it will be halfway through the block (the
            // points look theirs up as their chunks start the block)
            let ahead = 0.5 * steps.len() as f64 * cfg.dt;
            self.disks.iter_mut().for_each(|d| d.resurface(map, ahead));
            self.polygons
                .iter_mut()
                .for_each(|p| p.resurface(map, ahead));
            if let Some(c) = self.contact.as_mut() {
                c.resurfaced();
            }
        }
        let mut own = TABLE.take();
        own.clear();
        // Sampled a hair before each step's end (see `velocities_into`); from the samples
        // its timing shares with others, the same to the bit.
        match phases {
            Some(phases) if !self.spatial => phases.extend(self.motion, &mut own),
            _ => self.motion.velocities_into(steps.clone(), cfg.dt, &mut own),
        }
        if self.spatial {
            self.normals.clear();
            self.motion.normals_into(steps, cfg.dt, &mut self.normals);
        }
        let (table, normals, rec) = (&own, &self.normals, &self.rec);
        let (points, disks, contact) = (&mut self.points, &mut self.disks, &mut self.contact);
        let shapes = &mut self.polygons;
        // The kinds of parts run side by side only when two have work: a join called from
        // outside the pool hands its work to the pool's threads and waits for one to wake, a
        // small call's whole cost several times over.
        let alone =
            points.is_empty() || (disks.is_empty() && shapes.is_empty() && contact.is_none());
        let apart = disks.is_empty() || shapes.is_empty();
        let mut points_run = || points.run(table, normals, first, cfg, rec, index);
        let mut rest = || match contact {
            Some(c) => c.run(disks, shapes, table, first, cfg, rec),
            None if apart => {
                run_disks(disks, table, normals, first, cfg, rec);
                polygons::run(shapes, table, normals, first, cfg, rec)
            }
            None => {
                parallel::join(
                    || run_disks(disks, table, normals, first, cfg, rec),
                    || polygons::run(shapes, table, normals, first, cfg, rec),
                )
                .1
            }
        };
        let done = if alone {
            points_run();
            rest()
        } else {
            parallel::join(points_run, rest).1
        };
        TABLE.set(own);
        done
    }

    /// Records the disks' and polygons' times of leaving the plate and of flight (the points
    /// record theirs as their last block ends).
    fn ended(&self, dt: f64) {
        for d in &self.disks {
            // SAFETY: d.index < m, and this thread alone writes now.
            unsafe { self.rec.ended(d.index, d.left, d.flight as f64 * dt) };
        }
        for p in &self.polygons {
            // SAFETY: as above.
            unsafe { self.rec.ended(p.index, p.left, p.flight as f64 * dt) };
        }
    }
}
