//! Convex polygon parts in the integrator: each step is the polygon's exact implicit stick–slip
//! step ([`crate::polygon::Stepper`]) on its twist relative to the plate surface under its
//! centroid, taken in the part's frame, then the trapezoid for its centroid and angle.
//!
//! A polygon part's recorded position is its frame's origin (with its angle, the pose that
//! redraws it from its vertices), its recorded velocity that of its centroid.
//!
//! On a plate that moves out of its plane the normal force at the centroid, `m (g + a_z)`,
//! scales the friction limits, the pressure varies across the footprint as `g + a_z` does
//! (the plate's rocking: [`crate::polygon::Polygon::set_load`]), and the part flies (keeping its
//! velocity and spin) while the force is negative ([`super::lift::fly`]).

use rayon::prelude::*;

use crate::error::Result;
use crate::polygon::{
    evaluate_pair, Evals, Polygon, Quad, Request, Solve, Step, Stepper, EIGHT, FOUR,
};

use super::lift::fly;
use super::record::Rec;
use super::{half_side, moves_with_plate, off_plate, Config, FrictionMap, PartsView};
use crate::motion::spatial::normal_at;

/// A polygon part's state after a friction step ([`PolygonState::friction`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct Next {
    /// The centroid's velocity [m/s] and the spin [rad/s].
    pub(super) v: [f64; 2],
    pub(super) spin: f64,
    pub(super) stuck: bool,
    /// The twist relative to the plate in the part's frame (the next solve's guess).
    relative: [f64; 3],
    /// Newton iterations of the sliding solve (0: none) and the contraction it measured.
    iterations: usize,
    contraction: Option<f64>,
}

/// One polygon part: its state and friction thresholds.
pub(super) struct PolygonState {
    pub(super) stepper: Stepper,
    /// Centroid [m], its velocity [m/s], the frame's angle [rad] and the spin [rad/s].
    pub(super) c: [f64; 2],
    pub(super) v: [f64; 2],
    pub(super) angle: f64,
    pub(super) spin: f64,
    stuck: bool,
    /// The relative twists in the part's frame after the last steps, the latest first, and how
    /// many of them slid on one after another (at most [`HISTORY`]): the next solve starts from
    /// their extrapolation ([`PolygonState::guess`]).
    history: [[f64; 3]; HISTORY],
    slid: usize,
    /// The contraction of the Newton steps the part's last solve measured ([`Step::contraction`])
    /// and the solves since then that trusted it: the next solve trusts it up to [`TRUSTED`]
    /// solves in a row.
    contraction: Option<f64>,
    trusted: usize,
    pub(super) active: bool,
    pub(super) left: Option<f64>,
    /// Height above the plate surface and its rate, on a plate that moves out of its plane.
    air: [f64; 2],
    /// Steps spent in flight.
    pub(super) flight: usize,
    slide: f64,
    pub(super) hold: f64,
    /// Its own `slide` and `hold` (`mu g dt`, `mu_s g dt`), before a [`FrictionMap`]'s factor.
    own: [f64; 2],
    /// Gravity's in-plane velocity a step [m/s] ([`Config::tilt`] `dt`).
    pub(super) kick: [f64; 2],
    /// Its place among all parts.
    pub(super) index: usize,
    /// The cosine and sine of the angle, kept as the angle changes ([`PolygonState::turn_to`]),
    /// and the turns since they were last the library's.
    cs: [f64; 2],
    turns: usize,
}

/// Relative twists of the steps before a sliding solve that its guess extrapolates, at most.
const HISTORY: usize = 7;

/// The weights of the polynomial extrapolations to the next step from the last `n` relative
/// twists (row `n - 1`, the latest first: `(-1)^j C(n, j + 1)`).
const EXTRAPOLATION: [[f64; HISTORY]; HISTORY] = [
    [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [2.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0, -3.0, 1.0, 0.0, 0.0, 0.0, 0.0],
    [4.0, -6.0, 4.0, -1.0, 0.0, 0.0, 0.0],
    [5.0, -10.0, 10.0, -5.0, 1.0, 0.0, 0.0],
    [6.0, -15.0, 20.0, -15.0, 6.0, -1.0, 0.0],
    [7.0, -21.0, 35.0, -35.0, 21.0, -7.0, 1.0],
];

/// The largest turn in one step [rad] by which a part's cosine and sine are rotated rather than
/// computed ([`PolygonState::turn_to`]).
const SMALL_TURN: f64 = 1e-3;
/// Turns after which a part's cosine and sine are computed again.
const EXACT_TURNS: usize = 16;

/// Sliding solves in a row that trust the contraction measured before them: then one measures
/// it again.
const TRUSTED: usize = 32;

/// The steppers of `polygons` (`(part, shape)`), in order: one built per distinct shape (its
/// outline, its frame and its feet, to the bit) and cloned for the others, so that many parts of
/// one shape, or one shape in many worlds, do not each pay for the sampled planes and the gauge
/// a [`Stepper`] computes (about 10 us).
pub(super) fn steppers(polygons: &[(usize, Polygon)]) -> Vec<Stepper> {
    let mut built: std::collections::HashMap<Vec<u64>, usize> = std::collections::HashMap::new();
    let mut out: Vec<Stepper> = Vec::with_capacity(polygons.len());
    for (_, shape) in polygons {
        let feet = shape.tripod().map(|t| t.feet).unwrap_or_default();
        let key: Vec<u64> = shape
            .vertices
            .iter()
            .chain([&shape.centroid])
            .chain(feet.iter())
            .chain([&shape.load()])
            .flat_map(|v| [v[0].to_bits(), v[1].to_bits()])
            .collect();
        let stepper = match built.get(&key) {
            Some(&j) => out[j].clone(),
            None => {
                built.insert(key, out.len());
                Stepper::new(shape.clone())
            }
        };
        out.push(stepper);
    }
    out
}

/// The cosine and sine `[c, s]` of an angle, of the angle `d` more (`|d| <` [`SMALL_TURN`]):
/// `sin d = d (1 - d²/6 (1 - d²/20))`, `cos d = 1 - d²/2 (1 - d²/12)`, the next terms below
/// 1e-21 of them there.
fn rotate([c0, s0]: [f64; 2], d: f64) -> [f64; 2] {
    let d2 = d * d;
    let (c, s) = (
        1.0 - 0.5 * d2 * (1.0 - d2 / 12.0),
        d * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0)),
    );
    [c0 * c - s0 * s, s0 * c + c0 * s]
}

/// `p` turned by the angle whose cosine and sine are `cs`.
fn turn([c, s]: [f64; 2], p: [f64; 2]) -> [f64; 2] {
    [c * p[0] - s * p[1], s * p[0] + c * p[1]]
}

impl PolygonState {
    /// Part `i` of `parts`, stepped by `stepper` (its shape's, [`steppers`]), under the plate
    /// velocity `u0` at the start.
    pub(super) fn new(
        parts: &PartsView,
        i: usize,
        stepper: &Stepper,
        cfg: &Config,
        u0: [f64; 3],
    ) -> Self {
        let shape = &stepper.shape;
        let (p, v, angle, spin) = (
            parts.position[i],
            parts.velocity(i),
            parts.angle(i),
            parts.spin(i),
        );
        let off = turn([angle.cos(), angle.sin()], shape.centroid);
        let c = [p[0] + off[0], p[1] + off[1]];
        let outside = off_plate(c[0], c[1], half_side(cfg));
        PolygonState {
            stepper: stepper.clone(),
            c,
            v,
            angle,
            spin,
            // A part that starts moving with the plate surface starts stuck.
            stuck: moves_with_plate(c, v, u0) && spin == u0[2],
            history: [[0.0; 3]; HISTORY],
            slid: 0,
            contraction: None,
            trusted: 0,
            active: !outside,
            left: outside.then_some(0.0),
            air: [0.0; 2],
            flight: 0,
            slide: parts.mu(i) * cfg.g * cfg.dt,
            hold: parts.mu_s(i) * cfg.g * cfg.dt,
            own: [parts.mu(i) * cfg.g * cfg.dt, parts.mu_s(i) * cfg.g * cfg.dt],
            kick: cfg.kick(),
            index: i,
            cs: [angle.cos(), angle.sin()],
            turns: 0,
        }
    }

    /// Its friction thresholds on a plate of friction `map` where its centroid will be `ahead`
    /// [s] from now at its present velocity (the middle of the block it starts).
    pub(super) fn resurface(&mut self, map: &FrictionMap, ahead: f64) {
        let f = map.factor(self.c[0] + self.v[0] * ahead, self.c[1] + self.v[1] * ahead);
        (self.slide, self.hold) = (self.own[0] * f, self.own[1] * f);
    }

    /// `[cos, sin]` of the angle ([`PolygonState::turn_to`]).
    fn turned(&self) -> [f64; 2] {
        self.cs
    }

    /// Sets the angle, and its cosine and sine if it changed: a turn by `d` below [`SMALL_TURN`]
    /// rotates them by `d` (its cosine and sine by their series, exact to rounding there), and
    /// every [`EXACT_TURNS`]-th turn, or a larger one, takes them from the library, so that the
    /// rounding of the rotations never adds up past a few ulps. (A spinning part turns every
    /// step, and the next step waits on the library's `sincos`: 11-12 ns here, 15 % of a
    /// hexagon's step.) The turns are the part's own: its bits do not depend on the lanes.
    fn turn_to(&mut self, angle: f64) {
        if angle.to_bits() == self.angle.to_bits() {
            return;
        }
        let d = angle - self.angle;
        let small = d.abs() < SMALL_TURN;
        self.turns += 1;
        if self.turns >= EXACT_TURNS || !small {
            (self.cs, self.turns) = ([angle.cos(), angle.sin()], 0);
        } else {
            self.cs = rotate(self.cs, d);
        }
        self.angle = angle;
    }

    /// One step (0-based `s`) under the plate velocity `u`, if the part is still on the plate.
    pub(super) fn step(&mut self, u: [f64; 3], s: usize, cfg: &Config) -> Result<()> {
        if !self.active {
            return Ok(());
        }
        let next = self.friction(u, 1.0)?;
        self.advance(next, cfg.dt);
        self.leaves(s, cfg);
        Ok(())
    }

    /// Step `s` (0-based) on a plate that moves out of its plane, `nz` its `(z'', alpha'',
    /// beta'')`: the normal force at the centroid scales the friction limits, and the part flies
    /// while it is negative, its velocity and spin kept.
    fn step_spatial(&mut self, u: [f64; 3], nz: &[f64; 3], s: usize, cfg: &Config) -> Result<()> {
        if !self.active {
            return Ok(());
        }
        let n = cfg.g + normal_at(nz, self.c);
        let [h, hv] = &mut self.air;
        let flew = fly(n, cfg.dt, h, hv);
        // (with no normal force at all, n = 0 on the plate, friction vanishes too)
        let next = if flew || n <= 0.0 {
            self.flight += usize::from(flew);
            // (no guess after landing: the twist changed freely in the air)
            Next {
                v: self.v,
                spin: self.spin,
                stuck: false,
                relative: [0.0; 3],
                iterations: 0,
                contraction: None,
            }
        } else {
            self.press(nz, n)?;
            self.friction(u, n / cfg.g)?
        };
        self.advance(next, cfg.dt);
        self.leaves(s, cfg);
        Ok(())
    }

    /// Sets the pressure across the footprint for a step under the plate's out-of-plane
    /// accelerations `nz` with the normal acceleration `n = g + a_z > 0` at the centroid: each
    /// element is pressed by `g + a_z` where it lies, `1 + k . r` times the mean with `k` the
    /// gradient of `a_z` over `n`, in the part's frame (on three feet, the same moment: their
    /// shares put the centre of pressure where the footprint's is). Where that would lift an
    /// edge or a foot off the plate (a part tipping), `k` is shortened until it just does not
    /// ([`Polygon::steady_load`]): the part stays flat.
    fn press(&mut self, nz: &[f64; 3], n: f64) -> Result<()> {
        // a_z = z'' + y alpha'' - x beta'': its gradient is (-beta'', alpha'')
        let world = [-nz[2] / n, nz[1] / n];
        let [c, s] = self.turned();
        let shape = &mut self.stepper.shape;
        let k = shape.steady_load(turn([c, -s], world));
        shape
            .set_load(k)
            .map_err(|e| e.with_context(&format!("part {}", self.index)))
    }

    /// The centroid's velocity, the spin, the stuck flag and the relative twist in the part's
    /// frame after the friction step under the plate velocity `u`, the friction limits scaled by
    /// `load` (the normal force over `m g`); the state is not changed.
    pub(super) fn friction(&self, u: [f64; 3], load: f64) -> Result<Next> {
        let (r, turned) = self.request(u, load);
        let st = self.stepper.step_request(&r).map_err(|e| self.failed(e))?;
        Ok(self.finish(u, turned, st))
    }

    /// The error `e` of this part's step, naming the part.
    #[cold]
    #[inline(never)]
    fn failed(&self, e: crate::error::Error) -> crate::error::Error {
        e.with_context(&format!("part {}", self.index))
    }

    /// The arguments of [`PolygonState::friction`]'s step ([`Stepper::step`]), and the cosine
    /// and sine of the part's angle.
    #[inline(always)]
    fn request(&self, [u1, u2, u3]: [f64; 3], load: f64) -> (Request, [f64; 2]) {
        let [x, y] = self.c;
        let surface = [u1 - u3 * y, u2 + u3 * x];
        let free = [
            (self.v[0] + self.kick[0]) - surface[0],
            (self.v[1] + self.kick[1]) - surface[1],
        ];
        let cs = self.turned();
        let local = turn([cs[0], -cs[1]], free);
        let r = Request {
            free: [local[0], local[1], self.spin - u3],
            slide: self.slide * load,
            hold: self.hold * load,
            was_stuck: self.stuck,
            guess: (!self.stuck).then(|| self.guess()),
            contraction: self.contraction.filter(|_| self.trusted < TRUSTED),
        };
        (r, cs)
    }

    /// The state after the step `st` taken for [`PolygonState::request`] under the plate
    /// velocity `u` (`cs` the angle's cosine and sine).
    #[inline(always)]
    fn finish(&self, [u1, u2, u3]: [f64; 3], cs: [f64; 2], st: Step) -> Next {
        let [x, y] = self.c;
        let surface = [u1 - u3 * y, u2 + u3 * x];
        let w = turn(cs, [st.w[0], st.w[1]]);
        Next {
            v: [surface[0] + w[0], surface[1] + w[1]],
            spin: u3 + st.w[2],
            stuck: st.stuck,
            relative: st.w,
            iterations: st.iterations,
            contraction: st.contraction,
        }
    }

    /// Moves on by the step `st` taken for [`PolygonState::request`] under the plate velocity
    /// `u` in step `s` (0-based; `cs` the angle's cosine and sine).
    #[inline(always)]
    fn take(&mut self, u: [f64; 3], cs: [f64; 2], st: Step, s: usize, cfg: &Config) {
        let next = self.finish(u, cs, st);
        self.advance(next, cfg.dt);
        self.leaves(s, cfg);
    }

    /// The next sliding solve's start: the relative twists of the last steps that slid on one
    /// after another, extrapolated ([`EXTRAPOLATION`]); zero when the last step did not slide.
    fn guess(&self) -> [f64; 3] {
        let Some(weights) = self.slid.checked_sub(1).map(|n| EXTRAPOLATION[n]) else {
            return [0.0; 3];
        };
        std::array::from_fn(|i| {
            let terms = weights.iter().zip(&self.history).map(|(w, h)| w * h[i]);
            terms.fold(0.0, |sum, t| sum + t)
        })
    }

    /// Moves to the state `next` over one step of `dt`: the centroid and angle by the trapezoid.
    pub(super) fn advance(&mut self, next: Next, dt: f64) {
        let [x, y] = self.c;
        self.c = [
            x + 0.5 * (self.v[0] + next.v[0]) * dt,
            y + 0.5 * (self.v[1] + next.v[1]) * dt,
        ];
        self.turn_to(self.angle + 0.5 * (self.spin + next.spin) * dt);
        (self.v, self.spin, self.stuck) = (next.v, next.spin, next.stuck);
        if next.relative == [0.0; 3] {
            self.slid = 0;
        } else {
            self.history.copy_within(..HISTORY - 1, 1);
            self.history[0] = next.relative;
            self.slid = (self.slid + 1).min(HISTORY);
        }
        // the contraction a solve measured, trusted by the next ones
        match (next.iterations, next.contraction) {
            (0, _) => (self.contraction, self.trusted) = (None, 0),
            (_, Some(k)) => (self.contraction, self.trusted) = (Some(k), 0),
            (_, None) => self.trusted += 1,
        }
    }

    /// Takes the state a contact solve gave (centroid, angle, velocity, spin); the part slides
    /// into the next friction step.
    pub(super) fn collided(&mut self, c: [f64; 2], angle: f64, v: [f64; 2], spin: f64) {
        (self.c, self.v, self.spin, self.stuck) = (c, v, spin, false);
        self.turn_to(angle);
        // no guess: the contact changed the twist
        (self.slid, self.contraction) = (0, None);
    }

    /// Whether the centroid left the plate in step `s` (0-based); the part is then frozen.
    pub(super) fn leaves(&mut self, s: usize, cfg: &Config) -> bool {
        super::leaves(&mut self.active, &mut self.left, self.c, s, cfg)
    }

    /// Records the state after step `s` (1-based; 0: the initial state) if that step is recorded.
    pub(super) fn record(&self, s: usize, rec: &Rec) {
        if let Some(row) = rec.row(s) {
            let off = turn(self.turned(), self.stepper.shape.centroid);
            let origin = [self.c[0] - off[0], self.c[1] - off[1]];
            let state = (origin, self.v, self.angle, self.spin, self.stuck);
            // SAFETY: row < rows (from Rec::row), index < m, one polygon is one cell of a row.
            unsafe { rec.disk(row, self.index, state) };
        }
    }
}

/// Advances `polygons` through one block (`table[k]`: the plate velocity at the end of step
/// `first + k`; `normals[k]` its out-of-plane accelerations, empty for a planar plate),
/// recording as it goes; the first error (a sliding solve that did not converge) stops the run.
/// On a planar plate slices of parts run eight at a time in lanes ([`run_lanes`]), a rayon task
/// each; on a plate that moves out of its plane (each part's pressure its own), one part per
/// task.
pub(super) fn run(
    polygons: &mut [PolygonState],
    table: &[[f64; 3]],
    normals: &[[f64; 3]],
    first: usize,
    cfg: &Config,
    rec: &Rec,
) -> Result<()> {
    if normals.is_empty() {
        // a slice of parts a task (the results do not depend on it): one on one thread, two for
        // each of more. (A slice ends with lanes idle while its last parts finish the block: four
        // slices on one thread cost 174-176 ns per part-step for the kernel bench's hexagons,
        // one 159-162.)
        let threads = crate::parallel::threads();
        let slices = if threads == 1 { 1 } else { 2 * threads };
        let slice = polygons.len().div_ceil(slices).max(EIGHT);
        return polygons
            .par_chunks_mut(slice)
            .with_min_len(crate::parallel::min_len())
            .try_for_each(|parts| run_lanes(parts, table, first, cfg, rec));
    }
    polygons
        .par_iter_mut()
        .with_min_len(crate::parallel::min_len())
        .try_for_each(|p| {
            for (k, (&u, nz)) in table.iter().zip(normals).enumerate() {
                p.step_spatial(u, nz, first + k, cfg)?;
                p.record(first + k + 1, rec);
            }
            Ok(())
        })
}

/// [`run`] for `parts` on a planar plate, eight at a time in lanes: each lane takes a part
/// through the block's steps on its own until the part's sliding solve asks for the friction
/// at a twist ([`Stepper::begin`]); then the lanes' friction is taken together
/// ([`evaluate_pair`]: a vector of eight on AVX-512, two of four elsewhere), and each goes on.
/// A lane whose part is done with the block takes the next part, so that lanes wait for each
/// other only at the end of the slice. (Parts taken for stints of 64 steps in turn, so that the
/// lanes would run out of work together, cost more than the idle lanes at the end: about 10 ns
/// per part-step for the kernel bench's hexagons.)
fn run_lanes(
    parts: &mut [PolygonState],
    table: &[[f64; 3]],
    first: usize,
    cfg: &Config,
    rec: &Rec,
) -> Result<()> {
    // two quads of as many edges: the lanes of one vector of eight on AVX-512, two of four
    // elsewhere
    let edges = parts.iter().map(|p| p.stepper.shape.vertices.len());
    let edges = edges.max().unwrap_or(0);
    let mut quads = [Quad::new(edges), Quad::new(edges)];
    // each lane's part, that part's next step in the block, and its solve (begun in place, with
    // its angle's cosine and sine) while it waits for friction
    let mut part: [Option<usize>; EIGHT] = [None; EIGHT];
    let mut next = [0; EIGHT];
    let mut solves = [Solve::default(); EIGHT];
    let mut turned = [[1.0, 0.0]; EIGHT];
    let mut solving = [false; EIGHT];
    let mut evals = [Evals::default(); 2];
    let mut waiting = 0;
    loop {
        for l in 0..EIGHT {
            while !solving[l] {
                let i = match part[l] {
                    Some(i) if next[l] < table.len() => i,
                    _ if waiting < parts.len() => {
                        // done with its part (or none yet): the next one
                        (part[l], next[l]) = (Some(waiting), 0);
                        quads[l / FOUR].set(l % FOUR, Some(&parts[waiting].stepper.shape));
                        waiting += 1;
                        continue;
                    }
                    _ => {
                        part[l] = None;
                        break;
                    }
                };
                let p = &mut parts[i];
                let (k, u) = (next[l], table[next[l]]);
                if p.active {
                    let (r, cs) = p.request(u, 1.0);
                    match p.stepper.begin(&r, &mut solves[l]) {
                        Ok(None) => {
                            (solving[l], turned[l]) = (true, cs);
                            break;
                        }
                        Ok(Some(st)) => p.take(u, cs, st, first + k, cfg),
                        Err(e) => return Err(p.failed(e)),
                    }
                }
                p.record(first + k + 1, rec);
                next[l] += 1;
            }
        }
        if !solving.contains(&true) {
            return Ok(());
        }
        let asks = std::array::from_fn(|l| match part[l] {
            Some(i) if solving[l] => Some(solves[l].asked(&parts[i].stepper)),
            _ => None,
        });
        let shapes = part.map(|i| i.map(|i| &parts[i].stepper.shape));
        evaluate_pair([&quads[0], &quads[1]], shapes, &asks, &mut evals);
        for l in 0..EIGHT {
            let Some(i) = part[l].filter(|_| solving[l]) else {
                continue;
            };
            let p = &mut parts[i];
            let st = match solves[l].feed(&p.stepper, &evals[l / FOUR].get(l % FOUR)) {
                Ok(None) => continue,
                Ok(Some(st)) => st,
                Err(e) => return Err(p.failed(e)),
            };
            let k = next[l];
            solving[l] = false;
            p.take(table[k], turned[l], st, first + k, cfg);
            p.record(first + k + 1, rec);
            next[l] += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cosine_and_sine_rotated_by_small_turns_stay_within_ulps_of_the_library_s() {
        // turns of up to SMALL_TURN either way, EXACT_TURNS - 1 of them from an exact start
        // (then the integrator computes them again): within 2e-15 of cos and sin of the
        // summed angle, and still of unit length
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut uniform = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut worst: f64 = 0.0;
        for _ in 0..2000 {
            let mut angle = 200.0 * (uniform() - 0.5);
            let mut cs = [angle.cos(), angle.sin()];
            for _ in 1..EXACT_TURNS {
                let next = angle + SMALL_TURN * (2.0 * uniform() - 1.0);
                cs = rotate(cs, next - angle);
                angle = next;
                let err = (cs[0] - angle.cos()).abs().max((cs[1] - angle.sin()).abs());
                worst = worst.max(err);
            }
            let norm = (cs[0].hypot(cs[1]) - 1.0).abs();
            assert!(norm < 2e-15, "norm off by {norm:e}, worst {worst:e}");
        }
        assert!(worst < 2e-15, "{worst:e}");
        // (and not exact: the test would not see a rotation that did nothing)
        assert!(rotate([1.0, 0.0], 1e-4)[1] > 0.99e-4);
    }
}
