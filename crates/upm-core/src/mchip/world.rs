//! The M-Chip's run: the rapier3d world of the array and the part, stepped with the spring, damper and
//! drive torques applied at each joint, the collisions and the energy book kept (the model and its
//! units: the parent module).

use rapier3d_f64::prelude::*;

use super::{
    peak_per_torque, spring_lead, validate, Collision, Design, Drive, Energy, Output, Settings, UL,
    UM, UT,
};
use crate::error::{Error, Result};

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
    let (_, _, inertia) = design.inertia();
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
    let force_unit = UM * UL / (UT * UT);
    let torque_unit = force_unit * UL;
    let dt = settings.dt / UT;
    let Scene {
        mut world,
        resonators,
        part,
        part_collider,
    } = scene(design, settings, dt);
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
    record(&world, part, &resonators, &mut out, 0.0);
    let m_part = design.part_mass / UM;
    let fx_ext = settings.external_force[0] / force_unit;
    let fy_ext = settings.external_force[1] / force_unit;
    let mut contacts = Contacts::new(resonators.len(), settings.dt);
    let mut energy = Energy::default();
    let lead = spring_lead(settings.iterations) * dt;
    let energy_unit = UM * UL * UL / (UT * UT);
    // Every resonator's (angle, angular speed) at the current step's start: read once after each
    // step, for the collision log, the energies and the next step's torques.
    let mut joint_state: Vec<(f64, f64)> = resonators.iter().map(|&h| joint(&world, h)).collect();
    // The state at the step's start, kept for the collision log: a collision's angle and angular
    // speed are the resonator's as it came in, before the impact reversed it.
    let mut before = joint_state.clone();
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
            *state = joint(&world, h);
        }
        let t_end = (s + 1) as f64 * settings.dt;
        let b = &world.bodies[part];
        let dpx = m_part * (b.linvel().x - v_before.x) - fx_ext * dt;
        contacts.log(&world, part_collider, s, t_end, &before, dpx, &mut out);
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
            record(&world, part, &resonators, &mut out, t_end);
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

/// The rapier world in scaled units, and the handles the run reads.
struct Scene {
    world: PhysicsWorld,
    resonators: Vec<RigidBodyHandle>,
    part: RigidBodyHandle,
    part_collider: ColliderHandle,
}

/// Builds the world (step `dt` in scaled time): the ground, every resonator (a slab and its ridge
/// on a revolute joint about y, colliders carrying the resonator's index) and the part dropped
/// onto the ridges (disabled when `settings.part` is false). Resonators collide with the part only.
fn scene(design: &Design, settings: &Settings, dt: f64) -> Scene {
    let (ms, mr, _) = design.inertia();
    let l = |x: f64| x / UL;
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
    let mut resonators = Vec::with_capacity(design.rows * design.cols);
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
    Scene {
        world,
        resonators,
        part,
        part_collider,
    }
}

/// A resonator's angle about its joint [rad].
fn angle_of(b: &RigidBody) -> f64 {
    let q = b.rotation();
    2.0 * q.y.atan2(q.w)
}

/// A resonator's (angle, angular speed in scaled time).
fn joint(world: &PhysicsWorld, h: RigidBodyHandle) -> (f64, f64) {
    let b = &world.bodies[h];
    (angle_of(b), b.angvel().y)
}

/// Appends the part's state at `t` [s] and every resonator's angle, in SI units.
fn record(
    world: &PhysicsWorld,
    part: RigidBodyHandle,
    resonators: &[RigidBodyHandle],
    out: &mut Output,
    t: f64,
) {
    let b = &world.bodies[part];
    let (tr, v) = (b.translation(), b.linvel());
    out.t.push(t);
    out.position.push([tr.x * UL, tr.y * UL, tr.z * UL]);
    out.velocity
        .push([v.x * UL / UT, v.y * UL / UT, v.z * UL / UT]);
    let (q, w) = (b.rotation(), b.angvel());
    out.orientation.push([q.x, q.y, q.z, q.w]);
    out.angular_velocity.push([w.x / UT, w.y / UT, w.z / UT]);
    for &h in resonators {
        out.angles.push(angle_of(&world.bodies[h]));
    }
}

/// The collision log's bookkeeping: each resonator's open contact episode and the step it last
/// touched the part.
struct Contacts {
    /// Open contact episodes per resonator: index into `Output::collisions`.
    open: Vec<Option<usize>>,
    /// This step's contact impulse on the part per resonator (scaled units).
    touching: Vec<f64>,
    last_touch: Vec<usize>,
    /// Steps within which a contact that breaks off and resumes is the same impact (the soft
    /// contact resolving it over a few steps), not a new collision: [`REJOIN`].
    rejoin: usize,
}

impl Contacts {
    fn new(resonators: usize, dt: f64) -> Self {
        Self {
            open: vec![None; resonators],
            touching: vec![0.0; resonators],
            last_touch: vec![0; resonators],
            rejoin: (REJOIN / dt).ceil() as usize,
        }
    }

    /// Logs step `s` (ending at `t_end` [s]): a resonator touching the part opens a collision
    /// (its angle and speed as it came in, `before`) or adds to its open one: the normal impulse,
    /// and its share by impulse of `dpx`, the part's x momentum change less the external force's
    /// (scaled units; the log is in SI units). Episodes not touched for [`REJOIN`] close.
    fn log(
        &mut self,
        world: &PhysicsWorld,
        part_collider: ColliderHandle,
        s: usize,
        t_end: f64,
        before: &[(f64, f64)],
        dpx: f64,
        out: &mut Output,
    ) {
        let force_unit = UM * UL / (UT * UT);
        self.touching.iter_mut().for_each(|v| *v = 0.0);
        for pair in world.narrow_phase.contact_pairs_with(part_collider) {
            let other = if pair.collider1 == part_collider {
                pair.collider2
            } else {
                pair.collider1
            };
            self.touching[world.colliders[other].user_data as usize] +=
                pair.total_impulse_magnitude();
        }
        let total: f64 = self.touching.iter().sum();
        for i in 0..self.open.len() {
            if self.open[i].is_some() && s - self.last_touch[i] > self.rejoin {
                self.open[i] = None;
            }
            if self.touching[i] > 0.0 {
                self.last_touch[i] = s;
                let k = *self.open[i].get_or_insert_with(|| {
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
                c.impulse_normal += self.touching[i] * force_unit * UT;
                c.impulse_x += dpx * self.touching[i] / total * force_unit * UT;
            }
        }
    }
}
