//! Disk parts in the integrator: each step is the disk's implicit stick–slip step
//! ([`crate::disk`]) on its velocity and spin relative to the plate surface under its centre, in
//! groups of disks (the steps outside, so independent disks overlap in the out-of-order core).

use rayon::prelude::*;

use super::lift;
use super::record::Rec;
use super::{half_side, moves_with_plate, off_plate, Config, FrictionMap, PartsView};

/// A recorded disk state: position, velocity, angle, spin, stuck.
pub(super) type DiskRow = ([f64; 2], [f64; 2], f64, f64, bool);

/// One disk part: its state and friction thresholds.
pub(super) struct DiskState {
    pub(super) p: [f64; 2],
    pub(super) v: [f64; 2],
    pub(super) angle: f64,
    pub(super) spin: f64,
    pub(super) radius: f64,
    pub(super) stuck: bool,
    pub(super) active: bool,
    pub(super) left: Option<f64>,
    pub(super) slide: f64,
    pub(super) hold: f64,
    /// Its own `slide` and `hold` (`mu g dt`, `mu_s g dt`), before a [`FrictionMap`]'s factor.
    own: [f64; 2],
    /// Gravity's in-plane velocity a step [m/s] ([`Config::tilt`] `dt`).
    pub(super) kick: [f64; 2],
    /// Its place among all parts.
    pub(super) index: usize,
    /// Height above the plate and its rate, on a plate that moves out of its plane ([`lift`]).
    pub(super) air: [f64; 2],
    /// Steps spent in flight.
    pub(super) flight: usize,
}

impl DiskState {
    pub(super) fn new(parts: &PartsView, i: usize, cfg: &Config, u0: [f64; 3]) -> Self {
        let (p, v, spin) = (parts.position[i], parts.velocity(i), parts.spin(i));
        let outside = off_plate(p[0], p[1], half_side(cfg));
        DiskState {
            p,
            v,
            angle: parts.angle(i),
            spin,
            radius: parts.radius(i),
            // A disk that starts moving with the plate surface starts stuck.
            stuck: moves_with_plate(p, v, u0) && spin == u0[2],
            active: !outside,
            left: outside.then_some(0.0),
            slide: parts.mu(i) * cfg.g * cfg.dt,
            hold: parts.mu_s(i) * cfg.g * cfg.dt,
            own: [parts.mu(i) * cfg.g * cfg.dt, parts.mu_s(i) * cfg.g * cfg.dt],
            kick: cfg.kick(),
            index: i,
            air: [0.0; 2],
            flight: 0,
        }
    }

    /// Its friction thresholds on a plate of friction `map` where it will be `ahead` [s] from
    /// now at its present velocity (the middle of the block it starts).
    pub(super) fn resurface(&mut self, map: &FrictionMap, ahead: f64) {
        let f = map.factor(self.p[0] + self.v[0] * ahead, self.p[1] + self.v[1] * ahead);
        (self.slide, self.hold) = (self.own[0] * f, self.own[1] * f);
    }

    pub(super) fn row(&self) -> DiskRow {
        (self.p, self.v, self.angle, self.spin, self.stuck)
    }

    /// The plate surface's velocity under the disk's centre, the disk's velocity relative to it
    /// and `R` times its spin relative to the plate's, under the plate velocity `u`.
    pub(super) fn relative(&self, [u1, u2, u3]: [f64; 3]) -> ([f64; 2], [f64; 2], f64) {
        let [x, y] = self.p;
        let (sx, sy) = (u1 - u3 * y, u2 + u3 * x);
        (
            [sx, sy],
            [
                (self.v[0] + self.kick[0]) - sx,
                (self.v[1] + self.kick[1]) - sy,
            ],
            self.radius * (self.spin - u3),
        )
    }

    /// The disk's velocity, spin and stuck flag after the implicit friction step
    /// ([`crate::disk::implicit_step`]) under the plate velocity `u`; the state is not changed.
    pub(super) fn friction(&self, u: [f64; 3]) -> ([f64; 2], f64, bool) {
        let (surface, free, s) = self.relative(u);
        let st = crate::disk::implicit_step(free, s, self.slide, self.hold, self.stuck);
        self.absolute(surface, u[2], st)
    }

    /// The velocity, spin and stuck flag of the relative step `st` over the surface velocity
    /// `surface` and the plate's spin `u3`.
    pub(super) fn absolute(
        &self,
        surface: [f64; 2],
        u3: f64,
        st: crate::disk::Step,
    ) -> ([f64; 2], f64, bool) {
        (
            [surface[0] + st.w[0], surface[1] + st.w[1]],
            u3 + st.s / self.radius,
            st.stuck,
        )
    }

    /// Moves to velocity `v` and spin `spin` over one step, positions by the trapezoid.
    pub(super) fn advance(&mut self, v: [f64; 2], spin: f64, stuck: bool, dt: f64) {
        let [x, y] = self.p;
        self.p = [
            x + 0.5 * (self.v[0] + v[0]) * dt,
            y + 0.5 * (self.v[1] + v[1]) * dt,
        ];
        self.angle += 0.5 * (self.spin + spin) * dt;
        (self.v, self.spin, self.stuck) = (v, spin, stuck);
    }

    /// Whether the disk's centre left the plate in step `s` (0-based); it is then frozen.
    pub(super) fn leaves(&mut self, s: usize, cfg: &Config) -> bool {
        super::leaves(&mut self.active, &mut self.left, self.p, s, cfg)
    }

    /// Records the state after step `s` (0-based; the initial state: `None`) if that step is
    /// recorded.
    pub(super) fn record_step(&self, s: Option<usize>, rec: &Rec) {
        if let Some(row) = rec.row(s.map_or(0, |s| s + 1)) {
            // SAFETY: row < rows (from Rec::row), index < m, one disk is one cell of a row.
            unsafe { rec.disk(row, self.index, self.row()) };
        }
    }

    /// Step `s` (0-based) under the plate velocity `u` without contacts, if the disk is still on
    /// the plate; whether it left it in this step.
    pub(super) fn step(&mut self, u: [f64; 3], s: usize, cfg: &Config) -> bool {
        if !self.active {
            return false;
        }
        self.take(self.friction(u), s, cfg)
    }

    /// Takes step `s` (0-based) to the velocity, spin and stuck flag `next`; whether the disk
    /// left the plate in it.
    pub(super) fn take(
        &mut self,
        (v, spin, stuck): ([f64; 2], f64, bool),
        s: usize,
        cfg: &Config,
    ) -> bool {
        self.advance(v, spin, stuck, cfg.dt);
        self.leaves(s, cfg)
    }
}

/// A disk's plate surface velocity, relative velocity and `R` times relative spin
/// ([`DiskState::relative`]).
type Relative = ([f64; 2], [f64; 2], f64);

/// Disks per group of [`run_disks`].
pub(super) const DISK_GROUP: usize = 32;

/// Advances `disks` (no contacts) through one block with the disk's implicit step
/// ([`crate::disk::implicit_step`]), in groups on rayon threads. Within a group the steps are the
/// outer loop: consecutive disks are independent, so their long dependency chains overlap in the
/// out-of-order core (one disk's steps are a single chain), and the sliding solves of a step run
/// side by side ([`crate::disk::lanes::slide_many`]).
pub(super) fn run_disks(
    disks: &mut [DiskState],
    table: &[[f64; 3]],
    normals: &[[f64; 3]],
    first: usize,
    cfg: &Config,
    rec: &Rec,
) {
    if !normals.is_empty() {
        return lift::run_disks(disks, table, normals, first, cfg, rec);
    }
    disks
        .par_chunks_mut(DISK_GROUP)
        .with_min_len(crate::parallel::min_len())
        .for_each(|group| {
            for (k, &u) in table.iter().enumerate() {
                step_group(group, u, first + k, cfg);
                for d in group.iter() {
                    d.record_step(Some(first + k), rec);
                }
            }
        });
}

/// Step `s` (0-based) of the group's disks still on the plate under the plate velocity `u`, as
/// [`DiskState::step`] takes it one disk at a time (bitwise the same): the stick tests and
/// closed forms first, then the sliding solves of all sliding disks at once.
fn step_group(group: &mut [DiskState], u: [f64; 3], s: usize, cfg: &Config) {
    use crate::disk::{decide, finish, lanes::slide_many, magnitudes, slide_safe, Magnitudes, Pre};
    // First every disk's relative motion and magnitudes, in one branch-free pass (the square
    // roots and divisions of independent disks overlap), then the decisions.
    let mut rel: [Relative; DISK_GROUP] = [([0.0; 2], [0.0; 2], 0.0); DISK_GROUP];
    let mut mag = [Magnitudes::default(); DISK_GROUP];
    for ((d, r), m) in group.iter().zip(&mut rel).zip(&mut mag) {
        *r = d.relative(u);
        *m = magnitudes(r.1, r.2, d.slide, d.hold, d.stuck);
    }
    let mut a0 = [0.0; DISK_GROUP];
    let mut b0 = [0.0; DISK_GROUP];
    let mut c = [0.0; DISK_GROUP];
    let mut which = [0usize; DISK_GROUP];
    let mut out = [None; DISK_GROUP];
    let mut k = 0;
    for (i, d) in group.iter_mut().enumerate() {
        if !d.active {
            continue;
        }
        let (surface, free, spin) = rel[i];
        match decide(free, spin, d.slide, mag[i]) {
            Pre::Done(st) => {
                d.take(d.absolute(surface, u[2], st), s, cfg);
            }
            Pre::Slide { a0: a, b0: b } => {
                (a0[k], b0[k], c[k], which[k]) = (a, b, d.slide, i);
                k += 1;
            }
        }
    }
    slide_many(&a0[..k], &b0[..k], &c[..k], &mut out[..k]);
    for j in 0..k {
        let d = &mut group[which[j]];
        let (surface, free, spin) = rel[which[j]];
        let (a, b) = out[j].unwrap_or_else(|| slide_safe(a0[j], b0[j], c[j]));
        let st = finish(free, spin, a0[j], a, b);
        d.take(d.absolute(surface, u[2], st), s, cfg);
    }
}
