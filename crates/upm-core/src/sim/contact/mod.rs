//! Part–part and wall contacts of disk and convex polygon parts, resolved by the rapier2d physics
//! engine (f64; polygons are its convex polygon colliders about their centroids).
//!
//! Each step is split in two (first-order operator splitting):
//!
//! 1. the exact plate-friction step of [`crate::disk`] (of [`crate::polygon`] for polygons) gives
//!    every part its new velocity and spin, as without contacts;
//! 2. rapier takes those as the bodies' velocities and runs one step of its contact solver
//!    (non-penetration, restitution, part–part and part–wall Coulomb friction), integrating the
//!    positions with the velocities it returns.
//!
//! A disk that no contact touched in the step keeps the trapezoidal position update of the
//! contact-free integrator, so separated parts move exactly as with `contacts = false`. A disk that
//! a contact touched takes rapier's position, velocity and spin, and is sliding (not stuck) on the
//! plate for the next friction step. Points have no extent: they take no part in contacts.
//!
//! ## Units and rapier's settings
//! rapier's tolerances are absolute (allowed penetration, prediction distance, maximal corrective
//! and linear speeds are in "length units" per second; its contact softness is a frequency in Hz
//! tuned for 60 Hz game steps), while our parts are millimetres to centimetres on a plate shaken
//! at tens of Hz with steps of ~1e-4 s. So:
//!
//! * lengths reach rapier in units of the mean disk radius (`scale = 1 / mean radius`), velocities
//!   likewise; time is not scaled;
//! * the contact softness is set per step: natural frequency `0.5 / dt` Hz (rapier's default of
//!   30 Hz at 1/60 s has the same `omega dt`), `1 / dt` for contacts with walls; damping ratio as
//!   rapier's default;
//! * the allowed penetration is 0.1% of the mean radius (rapier: 0.5%), the prediction distance
//!   2% (rapier's);
//! * no sleeping (every step sets the velocities anyway), no contact recycling (manifolds are
//!   recomputed every step: parts moving ~1e-3 radii per step would otherwise keep stale normals),
//!   no CCD (a step moves a part far less than its radius);
//! * the maximal linear speed is lifted to 1e6 radii/s so rapier never clamps a part.
//!
//! Masses: only their ratios matter (gravity and the plate's friction act through the friction
//! step); by default a disk's mass is proportional to its area (equal thickness and density).
//! Bodies are stepped by rapier's single-threaded pipeline, one world per rayon task, so results
//! are bitwise identical for any number of threads.

use rapier2d_f64::prelude::*;

use rapier2d_f64::parry;

mod check;
use check::{closest_pair, wall_gap};

use super::polygons::PolygonState;
use super::{Config, DiskState, Rec};
use crate::error::Result;
use crate::polygon::Polygon;

/// `shape`'s rapier (parry) shape in units of `1 / scale` metres, about its centroid.
fn convex(shape: &Polygon, scale: f64) -> Option<parry::shape::ConvexPolygon> {
    let points = shape
        .vertices
        .iter()
        .map(|v| Vector::new(v[0] * scale, v[1] * scale))
        .collect();
    parry::shape::ConvexPolygon::from_convex_polyline(points)
}

/// Contact settings of a simulation.
#[derive(Debug, Clone, PartialEq)]
pub struct Contacts {
    /// Coefficient of restitution of every contact, in `[0, 1]`.
    pub restitution: f64,
    /// Coulomb friction coefficient between parts and between a part and a wall, `>= 0`.
    pub part_friction: f64,
    /// Fences: segments `[a, b]` [m] in the world frame.
    pub walls: Vec<[[f64; 2]; 2]>,
    /// Whether the walls are fixed to the plate (they move with it) rather than to the frame.
    pub walls_move_with_plate: bool,
    /// Mass of every part (only ratios matter; points ignore theirs); `None`: proportional to the
    /// disk's area.
    pub mass: Option<Vec<f64>>,
    /// rapier solver iterations per step (`>= 1`).
    pub iterations: usize,
}

impl Default for Contacts {
    fn default() -> Self {
        Contacts {
            restitution: 0.5,
            part_friction: 0.3,
            walls: Vec::new(),
            walls_move_with_plate: false,
            mass: None,
            iterations: 4,
        }
    }
}

/// Steps after a failed [`ContactWorld::free_steps`] before the next try.
const RECHECK: usize = 16;

/// One world's rapier bodies for its disks.
pub(super) struct ContactWorld {
    world: PhysicsWorld,
    /// The body of each disk (in the order of the world's disks); `None` once it left the plate.
    bodies: Vec<Option<RigidBodyHandle>>,
    /// The body of each polygon part, likewise.
    shapes: Vec<Option<RigidBodyHandle>>,
    /// The walls' body when they move with the plate.
    plate: Option<RigidBodyHandle>,
    /// Lengths in rapier = metres x `scale`.
    scale: f64,
    /// The walls (checked by [`Self::free_steps`]).
    walls: Vec<[[f64; 2]; 2]>,
    /// Steps before `free_until` need no contact solve; none is tried before `recheck_at`.
    free_until: usize,
    recheck_at: usize,
}

/// The relative tolerance under which a velocity returned by rapier counts as untouched.
const UNTOUCHED: f64 = 1e-12;

impl ContactWorld {
    /// Bodies for `disks` and `polygons` (`mass[j]`: the j-th disk's mass, then the polygons',
    /// any unit) and colliders for the walls.
    pub(super) fn new(
        disks: &[DiskState],
        polygons: &[PolygonState],
        mass: &[f64],
        contacts: &Contacts,
        cfg: &Config,
    ) -> Self {
        let radii = disks
            .iter()
            .map(|d| d.radius)
            .chain(polygons.iter().map(|p| p.stepper.shape.radius));
        let mean_r = radii.sum::<f64>() / (disks.len() + polygons.len()).max(1) as f64;
        let scale = if mean_r > 0.0 { 1.0 / mean_r } else { 1.0 };
        let mut world = PhysicsWorld::new();
        world.gravity = Vector::ZERO;
        let p = &mut world.integration_parameters;
        p.dt = cfg.dt;
        p.length_unit = 1.0;
        p.num_solver_iterations = contacts.iterations;
        p.contact_softness = SpringCoefficients::new(0.5 / cfg.dt, 10.0);
        p.static_contact_softness = SpringCoefficients::new(1.0 / cfg.dt, 10.0);
        p.normalized_allowed_linear_error = 0.001;
        p.normalized_prediction_distance = 0.02;
        p.normalized_max_linear_velocity = 1e6;
        p.contact_recycling = false;
        let mean_m = mass.iter().sum::<f64>() / mass.len().max(1) as f64;
        let material = |c: ColliderBuilder| {
            c.restitution(contacts.restitution)
                .friction(contacts.part_friction)
                .restitution_combine_rule(CoefficientCombineRule::Max)
                .friction_combine_rule(CoefficientCombineRule::Max)
        };
        let bodies = disks
            .iter()
            .zip(mass)
            .map(|(d, &m)| {
                d.active.then(|| {
                    let body = RigidBodyBuilder::dynamic()
                        .translation(Vector::new(d.p[0] * scale, d.p[1] * scale))
                        .linvel(Vector::new(d.v[0] * scale, d.v[1] * scale))
                        .angvel(d.spin)
                        .can_sleep(false);
                    let collider =
                        material(ColliderBuilder::ball(d.radius * scale)).mass(m / mean_m);
                    world.insert(body, collider).0
                })
            })
            .collect();
        let shapes = polygons
            .iter()
            .zip(&mass[disks.len()..])
            .map(|(p, &m)| {
                let shape = convex(&p.stepper.shape, scale)?;
                p.active.then(|| {
                    let body = RigidBodyBuilder::dynamic()
                        .translation(Vector::new(p.c[0] * scale, p.c[1] * scale))
                        .rotation(p.angle)
                        .linvel(Vector::new(p.v[0] * scale, p.v[1] * scale))
                        .angvel(p.spin)
                        .can_sleep(false);
                    let collider =
                        material(ColliderBuilder::new(SharedShape::new(shape))).mass(m / mean_m);
                    world.insert(body, collider).0
                })
            })
            .collect();
        let plate = if contacts.walls.is_empty() {
            None
        } else {
            let body = if contacts.walls_move_with_plate {
                RigidBodyBuilder::kinematic_velocity_based().can_sleep(false)
            } else {
                RigidBodyBuilder::fixed()
            };
            let handle = world.insert_body(body);
            for &[a, b] in &contacts.walls {
                let seg = ColliderBuilder::segment(
                    Vector::new(a[0] * scale, a[1] * scale),
                    Vector::new(b[0] * scale, b[1] * scale),
                );
                world.insert_collider(material(seg), Some(handle));
            }
            contacts.walls_move_with_plate.then_some(handle)
        };
        ContactWorld {
            world,
            bodies,
            shapes,
            plate,
            scale,
            walls: contacts.walls.clone(),
            free_until: 0,
            recheck_at: 0,
        }
    }

    /// The parts' friction changed (a [`super::FrictionMap`] looked up anew): the contact-free
    /// stretch reckoned from the old thresholds is reckoned again.
    pub(super) fn resurfaced(&mut self) {
        (self.free_until, self.recheck_at) = (0, 0);
    }

    /// How many steps from now no contact can happen, so rapier's step can be left out (it would
    /// change nothing: untouched disks keep the contact-free update anyway). A disk's speed
    /// changes by at most `mu_s g dt` a step (friction never exceeds `mu_s m g`), so in time `T`
    /// it moves at most `|v| T + mu_s g T^2 / 2`; no two disks (nor a disk and a fixed wall) can
    /// come within rapier's prediction distance while twice that reach stays below their gap.
    fn free_steps(&self, disks: &[DiskState], polygons: &[PolygonState], dt: f64) -> usize {
        if self.plate.is_some() {
            return 0; // walls moving with the plate
        }
        // (centre, bounding radius, speed, largest friction deceleration) of every part on the
        // plate: a polygon within the circle round its centroid through its farthest vertex
        let on: Vec<([f64; 2], f64, f64, f64)> = disks
            .iter()
            .filter(|d| d.active)
            .map(|d| (d.p, d.radius, d.v[0].hypot(d.v[1]), d.hold / dt))
            .chain(polygons.iter().filter(|p| p.active).map(|p| {
                (
                    p.c,
                    p.stepper.shape.radius,
                    p.v[0].hypot(p.v[1]),
                    p.hold / dt,
                )
            }))
            .collect();
        let centres: Vec<([f64; 2], f64)> = on.iter().map(|d| (d.0, d.1)).collect();
        let mut gap = closest_pair(&centres).map_or(f64::INFINITY, |(g, _, _)| g);
        for d in &on {
            // A wall does not move: only one reach is needed, but twice is as safe.
            if let Some((g, _)) = wall_gap(d.0, d.1, &self.walls) {
                gap = gap.min(g);
            }
        }
        let margin = 0.05 / self.scale;
        if !gap.is_finite() {
            return usize::MAX / 2;
        }
        let slack = 0.5 * (gap - margin);
        if slack <= 0.0 {
            return 0;
        }
        let v = on.iter().map(|d| d.2).fold(0.0, f64::max);
        let a = on.iter().map(|d| d.3).fold(0.0, f64::max);
        // Largest T with v T + a T^2 / 2 <= slack.
        let t = if a > 0.0 {
            2.0 * slack / (v + (v * v + 2.0 * a * slack).sqrt())
        } else if v > 0.0 {
            slack / v
        } else {
            f64::INFINITY
        };
        (t / dt).floor().min(1e9) as usize
    }

    /// Advances `disks` and `polygons` through one block: `table[k] = (u1, u2, u3)` at the end
    /// of step `first + k` (as [`DiskState::run`]); an error from a polygon's friction step
    /// stops the run.
    pub(super) fn run(
        &mut self,
        disks: &mut [DiskState],
        polygons: &mut [PolygonState],
        table: &[[f64; 3]],
        first: usize,
        cfg: &Config,
        rec: &Rec,
    ) -> Result<()> {
        let s = self.scale;
        let dt = cfg.dt;
        let mut wanted = vec![([0.0; 2], 0.0, false); disks.len()];
        let mut next = Vec::with_capacity(polygons.len());
        for (k, &u) in table.iter().enumerate() {
            let step = first + k;
            if step >= self.free_until && step >= self.recheck_at {
                match self.free_steps(disks, polygons, dt) {
                    0 => self.recheck_at = step + RECHECK,
                    n => self.free_until = step.saturating_add(n),
                }
            }
            if step < self.free_until {
                for (d, body) in disks.iter_mut().zip(&mut self.bodies) {
                    if let (true, Some(h)) = (d.step(u, step, cfg), *body) {
                        self.world.remove_body(h);
                        *body = None;
                    }
                    d.record_step(Some(step), rec);
                }
                for (p, body) in polygons.iter_mut().zip(&mut self.shapes) {
                    let was = p.active;
                    p.step(u, step, cfg)?;
                    if let (true, false, Some(h)) = (was, p.active, *body) {
                        self.world.remove_body(h);
                        *body = None;
                    }
                    p.record(step + 1, rec);
                }
                continue;
            }
            for ((d, body), want) in disks.iter().zip(&self.bodies).zip(wanted.iter_mut()) {
                let Some(h) = body else { continue };
                *want = d.friction(u);
                let (v, spin, _) = *want;
                let b = &mut self.world.bodies[*h];
                b.set_translation(Vector::new(d.p[0] * s, d.p[1] * s), false);
                b.set_linvel(Vector::new(v[0] * s, v[1] * s), true);
                b.set_angvel(spin, true);
            }
            next.clear();
            for (p, body) in polygons.iter().zip(&self.shapes) {
                let Some(h) = body else {
                    next.push(None);
                    continue;
                };
                let n = p.friction(u, 1.0)?;
                let b = &mut self.world.bodies[*h];
                b.set_translation(Vector::new(p.c[0] * s, p.c[1] * s), false);
                b.set_rotation(Rotation::new(p.angle), false);
                b.set_linvel(Vector::new(n.v[0] * s, n.v[1] * s), true);
                b.set_angvel(n.spin, true);
                next.push(Some(n));
            }
            if let Some(h) = self.plate {
                // The walls' body moves like the plate surface under its own origin.
                let b = &mut self.world.bodies[h];
                let o = b.translation() / s;
                let [u1, u2, u3] = u;
                b.set_linvel(Vector::new((u1 - u3 * o.y) * s, (u2 + u3 * o.x) * s), true);
                b.set_angvel(u3, true);
            }
            self.world.step();
            for ((d, body), &(v, spin, stuck)) in
                disks.iter_mut().zip(&mut self.bodies).zip(&wanted)
            {
                let Some(h) = *body else { continue };
                let b = &self.world.bodies[h];
                let (lv, w) = (b.linvel() / s, b.angvel());
                if touched([lv.x, lv.y], w, v, spin, d.radius, dt) {
                    let t = b.translation() / s;
                    d.angle += 0.5 * (d.spin + w) * dt;
                    (d.p, d.v, d.spin, d.stuck) = ([t.x, t.y], [lv.x, lv.y], w, false);
                } else {
                    d.advance(v, spin, stuck, dt);
                }
                if d.leaves(first + k, cfg) {
                    self.world.remove_body(h);
                    *body = None;
                }
            }
            for ((p, body), n) in polygons.iter_mut().zip(&mut self.shapes).zip(&next) {
                let (Some(h), Some(n)) = (*body, *n) else {
                    continue;
                };
                let b = &self.world.bodies[h];
                let (lv, w) = (b.linvel() / s, b.angvel());
                if touched([lv.x, lv.y], w, n.v, n.spin, p.stepper.shape.radius, dt) {
                    let t = b.translation() / s;
                    // rapier's angle is wrapped to (-pi, pi]; ours keeps counting turns
                    let turn = b.rotation().angle() - p.angle;
                    let angle = p.angle + turn.sin().atan2(turn.cos());
                    p.collided([t.x, t.y], angle, [lv.x, lv.y], w);
                } else {
                    p.advance(n, dt);
                }
                if p.leaves(first + k, cfg) {
                    self.world.remove_body(h);
                    *body = None;
                }
            }
            for d in disks.iter_mut() {
                d.record_step(Some(first + k), rec);
            }
            for p in polygons.iter() {
                p.record(first + k + 1, rec);
            }
        }
        Ok(())
    }
}

/// Whether rapier changed a part's velocity `lv` or spin `w` from the friction step's `v` and
/// `spin` (a part of size `radius`): a contact touched it.
fn touched(lv: [f64; 2], w: f64, v: [f64; 2], spin: f64, radius: f64, dt: f64) -> bool {
    let tol = UNTOUCHED * (v[0].hypot(v[1]) + (spin * radius).abs() + radius / dt);
    (lv[0] - v[0]).abs() > tol || (lv[1] - v[1]).abs() > tol || ((w - spin) * radius).abs() > tol
}
