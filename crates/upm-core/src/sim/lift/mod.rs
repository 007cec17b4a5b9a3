//! Point parts on a plate that moves out of its plane (docs/spec.md §10): the normal force
//! `N = m (g + a_z)` varies over the plate and the cycle, and a part flies while `g + a_z < 0`.
//!
//! The step is the exact implicit Coulomb step of [`super`] with `mu g dt` replaced by
//! `mu (g + a_z) dt` (and `mu_s` alike), `a_z` taken at the part's position at the start of the
//! step and the sample time of the plate's velocity. A part whose normal force would be negative
//! leaves the plate: its horizontal velocity is kept, and its height above the plate surface
//! `h` follows `h'' = -(g + a_z)` (the part falls at `g`, the surface under it accelerates at
//! `a_z`), integrated by semi-implicit Euler; when `h` returns to zero it lands without bounce
//! and friction acts again from the next step. With `a_z = 0` the step is the planar one.
//!
//! [`step`] is the one home of this update: the portable chunk runner below calls it for every
//! part (in tiles the compiler vectorises: it is branch-free, correctly rounded square root and
//! division), the disks take its flight half ([`fly`]) and [`crate::ppod`] takes it for the drift
//! field. The AVX-512 ([`avx512`]) and AVX2 ([`avx2`]) builds are the same update with the
//! planar kernels' refined reciprocal square roots and fused operations: they agree with the
//! portable one to a few ulp (tested below), and one machine always takes the same build, so
//! results are bitwise identical for any thread count.

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;

use super::kernel::Lanes;
use crate::motion::spatial::normal_at;
use crate::simd::Simd;

/// One part's state in the step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct State {
    /// Position [m].
    pub p: [f64; 2],
    /// Velocity [m/s].
    pub v: [f64; 2],
    /// Moving with the plate surface (static friction holds it).
    pub stuck: bool,
    /// Height of the part above the plate surface [m] (0: on it).
    pub h: f64,
    /// Rate of `h` [m/s].
    pub hv: f64,
}

/// The flight half of a step under the normal acceleration `n = g + a_z` [m/s²]: when the part
/// is in the air (`h > 0`) or leaves now (`n < 0`), `(h, hv)` advance and the part is airborne
/// for this step (it lands, `h = hv = 0`, when `h` reaches 0). Returns whether it flew.
#[inline(always)]
pub fn fly(n: f64, dt: f64, h: &mut f64, hv: &mut f64) -> bool {
    let flying = (*h > 0.0) | (n < 0.0);
    let rate = *hv - n * dt;
    let height = *h + rate * dt;
    let landed = height <= 0.0;
    *hv = if flying && !landed { rate } else { 0.0 };
    *h = if flying && !landed { height } else { 0.0 };
    flying
}

/// One step of a point part: `u` the plate's in-plane velocity `(u1, u2, u3)` at the step's
/// end, `n = g + a_z` at the part, `slide = mu g dt`, `hold = mu_s g dt`, `inv_g = 1 / g`.
/// Branch-free, so tiles of parts vectorise. Returns whether the part flew.
#[inline(always)]
pub fn step(
    s: &mut State,
    u: [f64; 3],
    n: f64,
    inv_g: f64,
    slide: f64,
    hold: f64,
    dt: f64,
) -> bool {
    let [x, y] = s.p;
    let [vx, vy] = s.v;
    let flew = fly(n, dt, &mut s.h, &mut s.hv);
    let (sx, sy) = (u[0] - u[2] * y, u[1] + u[2] * x);
    let (wx, wy) = (vx - sx, vy - sy);
    let wn = (wx * wx + wy * wy).sqrt();
    let r = n * inv_g;
    let (sl, ho) = (slide * r, hold * r);
    let stick = (wn <= sl) | (s.stuck & (wn <= ho));
    let keep = if stick { 0.0 } else { 1.0 - sl / wn };
    let (cx, cy) = (sx + wx * keep, sy + wy * keep);
    let (nvx, nvy) = if flew { (vx, vy) } else { (cx, cy) };
    s.p = [x + 0.5 * (vx + nvx) * dt, y + 0.5 * (vy + nvy) * dt];
    s.v = [nvx, nvy];
    s.stuck = stick & !flew;
    flew
}

/// The air state of a chunk's parts: height, its rate, and steps spent in flight.
pub(super) struct Air<'a> {
    pub h: &'a mut [f64],
    pub hv: &'a mut [f64],
    pub flight: &'a mut [f64],
}

/// Parts per tile (the state of a tile stays in registers through the steps).
const TILE: usize = 16;

/// A segment of steps: the plate's in-plane velocities `u` and out-of-plane accelerations
/// `(z'', alpha'', beta'')` at each step, the steps already done, the step, half the plate's
/// side (a part whose centre passes it is frozen) and gravity.
pub(super) struct Steps<'t> {
    pub u: &'t [[f64; 3]],
    pub normals: &'t [[f64; 3]],
    pub first: usize,
    pub dt: f64,
    pub half: f64,
    pub g: f64,
}

/// A bound on where a tile's active parts are, carried step by step, so that a vector build can
/// skip the flight test for a step in which no part of the tile can leave the plate (the normal
/// force is positive wherever they may be; the step is then the same, bit for bit).
///
/// `r` bounds `|x|` and `|y|`, `v` bounds `|vx| + |vy|`. A step moves a part by at most
/// `v dt` in each coordinate, and its new velocity is a convex combination of its old one and
/// the plate surface's under it (or one of them), whose `|.|_1` is at most
/// `|u1| + |u2| + 2 |u3| r`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Reach {
    r: f64,
    v: f64,
    /// Steps since `r` and `v` were measured.
    pub age: usize,
}

impl Reach {
    /// From measured bounds.
    pub fn new(r: f64, v: f64) -> Self {
        Self { r, v, age: 0 }
    }

    /// Whether `g + a_z > 0` under every part within the bound, with a margin far above the
    /// rounding of the normal force.
    #[inline(always)]
    pub fn grounded(&self, nz: &[f64; 3], g: f64) -> bool {
        let tilt = self.r * (nz[1].abs() + nz[2].abs());
        let base = g + nz[0];
        base - tilt > 1e-9 * (base.abs() + tilt)
    }

    /// Whether the flight test can be skipped in the step of `u` and `nz`: no part of the tile
    /// in the air and [`Reach::grounded`], the bound measured again (`measure`) when it failed
    /// and has grown for a few steps. Advances the bound by the step.
    #[inline(always)]
    pub fn step(
        &mut self,
        in_air: bool,
        u: &[f64; 3],
        nz: &[f64; 3],
        steps: &Steps,
        measure: impl FnOnce() -> Self,
    ) -> bool {
        let mut grounded = !in_air && self.grounded(nz, steps.g);
        if !in_air && !grounded && self.age >= 4 {
            *self = measure();
            grounded = self.grounded(nz, steps.g);
        }
        self.advance(u, steps.dt, steps.half);
        grounded
    }

    /// The bound after a step of the plate's velocity `u` (in a plate of half side `half`, an
    /// active part is within it after the step).
    #[inline(always)]
    pub fn advance(&mut self, u: &[f64; 3], dt: f64, half: f64) {
        self.v = self
            .v
            .max(u[0].abs() + u[1].abs() + 2.0 * u[2].abs() * self.r);
        self.r = ((self.r + self.v * dt) * (1.0 + 1e-12)).min(half);
        self.age += 1;
    }
}

/// Advances every part of `l` through `steps`, as [`super::kernel::run`] does in the plane.
pub(super) fn run(steps: &Steps, l: &mut Lanes, air: &mut Air) {
    assert_eq!(steps.u.len(), steps.normals.len(), "one normal per step");
    match super::kernel::simd() {
        // SAFETY: simd() only reports builds the CPU has.
        #[cfg(target_arch = "x86_64")]
        Simd::Avx512 => unsafe { avx512::run(steps, l, air) },
        #[cfg(target_arch = "x86_64")]
        Simd::Avx2 => unsafe { avx2::run(steps, l, air) },
        _ => run_tiles(steps, l, air),
    }
}

#[inline(always)]
fn run_tiles(steps: &Steps, l: &mut Lanes, air: &mut Air) {
    let n = l.x.len();
    let mut at = 0;
    while at < n {
        let w = TILE.min(n - at);
        let mut t = Tile::default();
        for j in 0..w {
            let i = at + j;
            (t.x[j], t.y[j], t.vx[j], t.vy[j]) = (l.x[i], l.y[i], l.vx[i], l.vy[i]);
            (t.stuck[j], t.h[j], t.hv[j]) = (l.stuck[i], air.h[i], air.hv[i]);
            (t.slide[j], t.hold[j]) = (l.slide[i], l.hold[i]);
            (t.active[j], t.left[j]) = (l.active[i], l.left[i]);
        }
        t.run(steps);
        for j in 0..w {
            let i = at + j;
            (l.x[i], l.y[i], l.vx[i], l.vy[i]) = (t.x[j], t.y[j], t.vx[j], t.vy[j]);
            (l.stuck[i], air.h[i], air.hv[i]) = (t.stuck[j], t.h[j], t.hv[j]);
            air.flight[i] += t.flown[j];
            (l.active[i], l.left[i]) = (t.active[j], t.left[j]);
        }
        at += w;
    }
}

/// A tile of parts in registers, structure of arrays (flags 0 or 1); the lanes past a chunk's
/// end are inactive.
#[derive(Default)]
struct Tile {
    x: [f64; TILE],
    y: [f64; TILE],
    vx: [f64; TILE],
    vy: [f64; TILE],
    stuck: [f64; TILE],
    h: [f64; TILE],
    hv: [f64; TILE],
    slide: [f64; TILE],
    hold: [f64; TILE],
    active: [f64; TILE],
    left: [f64; TILE],
    flown: [f64; TILE],
}

impl Tile {
    /// Every step of `steps`, every lane, branch-free (the compiler vectorises across lanes):
    /// a part off the plate keeps its state.
    #[inline(always)]
    fn run(&mut self, steps: &Steps) {
        let inv_g = 1.0 / steps.g;
        for (k, (&u, nz)) in steps.u.iter().zip(steps.normals).enumerate() {
            let now = (steps.first + k + 1) as f64;
            for j in 0..TILE {
                let mut s = State {
                    p: [self.x[j], self.y[j]],
                    v: [self.vx[j], self.vy[j]],
                    stuck: self.stuck[j] > 0.0,
                    h: self.h[j],
                    hv: self.hv[j],
                };
                let n = steps.g + normal_at(nz, s.p);
                let flew = step(&mut s, u, n, inv_g, self.slide[j], self.hold[j], steps.dt);
                let on = self.active[j] > 0.0;
                let out = on & ((s.p[0].abs() > steps.half) | (s.p[1].abs() > steps.half));
                let keep = |new: f64, old: f64| if on { new } else { old };
                self.x[j] = keep(s.p[0], self.x[j]);
                self.y[j] = keep(s.p[1], self.y[j]);
                self.vx[j] = keep(s.v[0], self.vx[j]);
                self.vy[j] = keep(s.v[1], self.vy[j]);
                self.stuck[j] = keep(if s.stuck { 1.0 } else { 0.0 }, self.stuck[j]);
                self.h[j] = keep(s.h, self.h[j]);
                self.hv[j] = keep(s.hv, self.hv[j]);
                self.flown[j] += if on & flew { 1.0 } else { 0.0 };
                self.left[j] = if out { now } else { self.left[j] };
                self.active[j] = if out { 0.0 } else { self.active[j] };
            }
        }
    }
}

impl super::DiskState {
    /// Step `s` (0-based) on a plate that moves out of its plane, `nz` its `(z'', alpha'',
    /// beta'')`: the normal force at the centroid scales the friction force and torque limits,
    /// and the disk flies (keeping its velocity and spin) while it is negative ([`fly`]).
    fn step_spatial(&mut self, u: [f64; 3], nz: &[f64; 3], s: usize, cfg: &super::Config) -> bool {
        if !self.active {
            return false;
        }
        let n = cfg.g + normal_at(nz, self.p);
        let [h, hv] = &mut self.air;
        if fly(n, cfg.dt, h, hv) {
            self.flight += 1;
            return self.take((self.v, self.spin, false), s, cfg);
        }
        let (surface, free, spin) = self.relative(u);
        let r = n / cfg.g;
        let st = crate::disk::implicit_step(free, spin, self.slide * r, self.hold * r, self.stuck);
        self.take(self.absolute(surface, u[2], st), s, cfg)
    }
}

/// The disks of a world on a plate that moves out of its plane through one block (each disk on
/// its own: the out-of-plane step has no grouped solve), recording as they go.
pub(super) fn run_disks(
    disks: &mut [super::DiskState],
    table: &[[f64; 3]],
    normals: &[[f64; 3]],
    first: usize,
    cfg: &super::Config,
    rec: &super::Rec,
) {
    use rayon::prelude::*;
    disks
        .par_iter_mut()
        .with_min_len(crate::parallel::min_len())
        .for_each(|d| {
            for (k, (&u, nz)) in table.iter().zip(normals).enumerate() {
                d.step_spatial(u, nz, first + k, cfg);
                d.record_step(Some(first + k), rec);
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::kernel::noise;

    /// `n` parts: positions, velocities around the stick threshold, a third stuck, a fifth in
    /// the air, every seventh off the plate; and a plate whose normal force crosses zero within
    /// `spread` of the centre (0.1), or not (0.01: the vector builds skip the flight test once
    /// the parts have landed).
    fn run(simd: Simd, n: usize, seed: u64, steps: usize, half: f64, spread: f64) -> Vec<Vec<f64>> {
        let r = noise(seed, 8 * n);
        let dt = 1e-4;
        let slide = 0.3 * 9.81 * dt;
        let mut v: Vec<Vec<f64>> = vec![
            r[..n].iter().map(|a| spread * a).collect(),
            r[n..2 * n].iter().map(|a| spread * a).collect(),
            r[2 * n..3 * n].iter().map(|a| 3.0 * slide * a).collect(),
            r[3 * n..4 * n].iter().map(|a| 3.0 * slide * a).collect(),
            (0..n).map(|k| f64::from(u8::from(k % 3 == 0))).collect(),
            (0..n)
                .map(|k| f64::from(u8::from(half.is_infinite() || k % 7 != 5)))
                .collect(),
            vec![f64::INFINITY; n],
            (0..n)
                .map(|k| slide * (1.0 + 0.1 * (k % 5) as f64))
                .collect(),
            (0..n)
                .map(|k| slide * (1.3 + 0.1 * (k % 5) as f64))
                .collect(),
            (0..n)
                .map(|k| {
                    if k % 5 == 1 {
                        1e-6 * (1.0 + r[4 * n + k])
                    } else {
                        0.0
                    }
                })
                .collect(),
            (0..n)
                .map(|k| if k % 5 == 1 { 1e-3 * r[5 * n + k] } else { 0.0 })
                .collect(),
            vec![0.0; n],
        ];
        let u: Vec<[f64; 3]> = (0..steps)
            .map(|k| {
                let t = (k + 1) as f64 * dt;
                [
                    0.05 * (125.0 * t).cos(),
                    0.05 * (125.0 * t).sin(),
                    0.5 * (250.0 * t).sin(),
                ]
            })
            .collect();
        let normals: Vec<[f64; 3]> = (0..steps)
            .map(|k| {
                let t = (k + 1) as f64 * dt;
                [
                    6.0 * (125.0 * t).sin(),
                    80.0 * (125.0 * t + 1.0).sin(),
                    80.0 * (125.0 * t + 2.0).sin(),
                ]
            })
            .collect();
        let s = Steps {
            u: &u,
            normals: &normals,
            first: 0,
            dt,
            half,
            g: 9.81,
        };
        {
            let [x, y, vx, vy, stuck, active, left, sl, ho, h, hv, flight] = &mut v[..] else {
                unreachable!()
            };
            let mut l = Lanes {
                x,
                y,
                vx,
                vy,
                stuck,
                active,
                left,
                slide: sl,
                hold: ho,
                kick: [0.0; 2],
            };
            let mut air = Air { h, hv, flight };
            match simd {
                #[cfg(target_arch = "x86_64")]
                Simd::Avx512 => unsafe { avx512::run(&s, &mut l, &mut air) },
                #[cfg(target_arch = "x86_64")]
                Simd::Avx2 => unsafe { avx2::run(&s, &mut l, &mut air) },
                Simd::Portable => run_tiles(&s, &mut l, &mut air),
            }
        }
        v
    }

    #[test]
    fn the_vector_builds_agree_with_the_portable_one() {
        for build in Simd::available().into_iter().skip(1) {
            agrees(build);
        }
    }

    fn agrees(build: Simd) {
        let cases = [(1, 50), (7, 50), (9, 50), (33, 50), (67, 400), (4096, 1)];
        for ((n, steps), half) in cases
            .into_iter()
            .flat_map(|c| [(c, 0.098), (c, f64::INFINITY)])
        {
            for (seed, spread) in (0..4).flat_map(|s| [(s, 0.1), (s, 0.01)]) {
                let p = run(Simd::Portable, n, seed, steps, half, spread);
                let b = run(build, n, seed, steps, half, spread);
                // stuck, active, left and flight exactly; the state to rounding
                for k in [4, 5, 6, 11] {
                    assert_eq!(p[k], b[k], "n {n} seed {seed} array {k}");
                }
                for k in [0, 1, 2, 3, 9, 10] {
                    for i in 0..n {
                        let (e, g) = (p[k][i], b[k][i]);
                        assert!(
                            (e - g).abs() <= 1e-12 * (1.0 + e.abs()),
                            "array {k} part {i}: {g} vs {e}"
                        );
                    }
                }
                assert!(p[11].iter().any(|&f| f > 0.0) || n < 9, "some part flew");
            }
        }
    }
}
