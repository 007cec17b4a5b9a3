//! The implicit stick–slip step of a polygon part (docs/spec.md §11, docs/polygons.md).
//!
//! Per unit mass, with the relative twist `w = (vx, vy, omega)` at the centroid (the part's less
//! the plate surface's), the part's state after a step of `dt` minimises
//!
//! ```text
//! Phi(w) = |v - v*|² / 2 + k² (omega - omega*)² / 2 + c D(w),     c = mu g dt,
//! ```
//!
//! `w* = (v*, omega*)` the relative twist the part would have without friction, `k` its radius of
//! gyration and `D` the rate of work of friction per `mu N` ([`Polygon::friction`]): convex,
//! positively homogeneous, smooth away from 0. The minimum is at `w = 0` (the part sticks to the
//! plate) exactly when the wrench `(v*, k² omega*) / c` lies in the limit set, its [gauge] at most
//! 1 (with `c = mu_s g dt` while the part is stuck); otherwise it is where `Phi` is smooth and
//! found by Newton's method, with the step length halved until `Phi` falls. Sticking is exact:
//! no velocity below a threshold is rounded to zero (no creep), and the minimiser is unique (no
//! chatter between stick and slip that the motion does not make).
//!
//! Most steps are cheap: the limit set contains the double cone over the unit force disk and the
//! largest pure moments `±M0` (a wrench inside it sticks), and lies inside the cylinder `|F| <=
//! 1`, `|M| <=` the mean distance (a wrench outside it slides). The mean distance is the largest
//! moment, spinning about the centroid; `M0` equals it only for a part that spinning there
//! pushes nowhere (a symmetric one): a right triangle's is 0.27 % less
//! (`Stepper::pure_moment`). A twist with no relative spin and no free spin slides as a point
//! does (uniform pressure gives a translating part no moment about its centroid), in closed
//! form.
//!
//! Newton's method is a machine that asks for `Phi` at one point at a time (`newton`): a part
//! sliding on from its last twist takes its solve's friction in lanes ([`super::Quad`]), four
//! parts side by side in the integrator ([`Stepper::begin`], [`Solve`]), one in a lane of its
//! own here; the bits are the same either way.
//!
//! [gauge]: Polygon::gauge

use super::begin::Request;
use super::four::Quad;
use super::newton::{dot, Ask, Eval, Newton};
use super::Polygon;
use crate::error::{Error, Result};

/// The result of one step: the relative twist after it and whether the part sticks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// Relative twist `(vx, vy, omega)` after the step [m/s, rad/s] (zero when stuck).
    pub w: [f64; 3],
    /// Whether the part moves with the plate after the step.
    pub stuck: bool,
    /// Newton iterations of the sliding solve (0 when it took no solve).
    pub iterations: usize,
    /// The contraction of its Newton steps the sliding solve measured (`|next| / |y| ~ kappa
    /// (|step| / |y|)²`), if it took two in a row; the part's next solve may trust it.
    pub contraction: Option<f64>,
}

/// Where [`Stepper::step`] goes: done, or on to its sliding solve, started from the last twist
/// (`guess`) if there is one, else toward `toward` (the way the part starts to slide, if known).
#[derive(Debug, Clone, Copy)]
pub(super) enum Plan {
    Done(Step),
    Slide {
        toward: Option<[f64; 3]>,
        guess: Option<[f64; 3]>,
    },
}

/// A polygon's constants for stepping it: the shape and its gyration and mean distance.
#[derive(Debug, Clone)]
pub struct Stepper {
    /// The shape, vertices about the centroid.
    pub shape: Polygon,
    /// Radius of gyration about the centroid, `sqrt(polar / area)` [m].
    pub gyration: f64,
    /// Mean distance of the footprint from the centroid [m]: the largest friction moment per
    /// `mu N`.
    pub mean_distance: f64,
    /// The largest pure moment (no force) in the limit set per `mu N`, `1 / gauge(0, 0, 1)` [m]:
    /// the mean distance for a part that spinning about its centroid pushes nowhere, less for
    /// one it pushes (0 if the gauge failed: then no wrench with a moment sticks unchecked).
    pub pure_moment: f64,
    /// Twist directions `e = (vx, vy, radius * omega)` over a half sphere, each divided by its
    /// rate of work `D(e)`: each an exact supporting plane of the limit set, for a quick lower
    /// bound of a wrench's gauge and a start for the exact one (`samples[j][i]`: component `j`
    /// of direction `i`).
    samples: Box<[[f64; SAMPLES]; 3]>,
    /// The shape's outline in the first lane of four, for its sliding solves from a guess
    /// ([`Quad::evaluate`]).
    quad: Quad,
    /// `1 / gyration`.
    pub(super) kinv: f64,
}

/// Sampled twist directions of [`Stepper`].
const SAMPLES: usize = 48;

/// A free twist whose gauge is at most `1 +` this slides by its closed-form bound when Newton
/// stalls at the kink ([`Stepper::slide_from`]): the twist is then off by under `2e-6` of it.
const NEAR_LIMIT: f64 = 1e-6;

impl Stepper {
    /// The constants of `shape`.
    pub fn new(shape: Polygon) -> Self {
        let gyration = (shape.polar / shape.area).sqrt();
        let mean_distance = shape.mean_distance();
        // (L is symmetric, D being even: the same both ways)
        let pure_moment = shape
            .gauge(0.0, 0.0, 1.0)
            .map_or(0.0, |g| 1.0 / g.value)
            .min(mean_distance);
        // directions over a half sphere (D is even), golden-angle spiral
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let mut samples = Box::new([[0.0; SAMPLES]; 3]);
        for i in 0..SAMPLES {
            let z = (i as f64 + 0.5) / SAMPLES as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * i as f64;
            let e = [r * a.cos(), r * a.sin(), z];
            let d = shape.friction([e[0], e[1]], e[2] / shape.radius).1;
            for j in 0..3 {
                samples[j][i] = e[j] / d;
            }
        }
        Stepper {
            quad: Quad::of([Some(&shape), None, None, None]),
            kinv: 1.0 / gyration,
            shape,
            gyration,
            mean_distance,
            pure_moment,
            samples,
        }
    }

    /// One implicit step from the free relative twist `free` (in the part's frame), with `slide
    /// = mu g dt` and `hold = mu_s g dt` (the latter while the part `was_stuck`); `guess` is a
    /// relative twist near the answer, if one is known (the last step's, for a part sliding on).
    pub fn step(
        &self,
        free: [f64; 3],
        slide: f64,
        hold: f64,
        was_stuck: bool,
        guess: Option<[f64; 3]>,
    ) -> Result<Step> {
        self.step_request(&Request {
            free,
            slide,
            hold,
            was_stuck,
            guess,
            contraction: None,
        })
    }

    /// [`Stepper::step`] with `r`'s arguments; a solve from a guess trusts the contraction the
    /// part's last solve measured, if given ([`Step::contraction`]): it may then end after one
    /// Newton step, as the integrator's solves do.
    pub fn step_request(&self, r: &Request) -> Result<Step> {
        match self.plan(r)? {
            Plan::Done(st) => Ok(st),
            Plan::Slide { toward, guess } => {
                self.slide(r.free, r.slide, toward, guess, r.contraction)
            }
        }
    }

    /// [`Stepper::step`] up to its sliding solve: the step if it takes none, else where the
    /// solve starts.
    pub(super) fn plan(&self, r: &Request) -> Result<Plan> {
        let (free, slide, hold, guess) = (r.free, r.slide, r.hold, r.guess);
        let k = self.gyration;
        let c = if r.was_stuck { hold } else { slide };
        // the wrench per mu N that keeps the part with the plate, force and moment / mean distance
        let speed = (free[0] * free[0] + free[1] * free[1]).sqrt();
        let force = speed / c;
        let stuck = Step {
            w: [0.0; 3],
            stuck: true,
            iterations: 0,
            contraction: None,
        };
        let load = self.shape.load();
        if load != [0.0; 2] {
            return self
                .step_loaded(free, [slide, c, force], guess, load, r.contraction)
                .map(Plan::Done);
        }
        if free[2] == 0.0 {
            // no spin: a point's stick or slide (a translating part feels no moment)
            if force <= 1.0 {
                return Ok(Plan::Done(stuck));
            }
            // |free| > hold >= slide: it slides on
            let f = 1.0 - slide / speed;
            return Ok(Plan::Done(Step {
                w: [free[0] * f, free[1] * f, 0.0],
                stuck: false,
                iterations: 0,
                contraction: None,
            }));
        }
        // the moment that keeps it, per mu N [m], over the largest pure moment
        let moment = (k * k * free[2]).abs() / c;
        if force + moment / self.pure_moment <= 1.0 {
            return Ok(Plan::Done(stuck)); // inside the double cone, inside the limit set
        }
        // outside the cylinder that holds the limit set a part sliding on needs no direction to
        // start from: it slides, from its last twist
        let guess = guess.filter(|g| g.iter().any(|&x| x != 0.0));
        if (force > 1.0 || moment > 1.0) && guess.is_some() {
            return Ok(Plan::Slide {
                toward: None,
                guess,
            });
        }
        // The gauge's lower bound over the sampled directions (exact supporting planes of the
        // limit set): over 1, the part slides; else the exact gauge, started at the best one.
        let l = self.shape.radius;
        let z = [free[0] / c, free[1] / c, k * k * free[2] / c];
        let zs = [z[0], z[1], z[2] / l];
        let (lower, best) = self.lower_bound(zs);
        // the way it starts to slide, in the solve's coordinates (v, k omega): minus the gauge's
        // direction (either sign is tried)
        // (outside the cylinder but not past a sampled plane, the part slides but the sampled
        // direction does not point out of the limit set: the gauge's does, for the start)
        let mut toward = [best[0], best[1], k * best[2] / l];
        if lower <= 1.0 {
            let g = self.shape.gauge_from(z[0], z[1], z[2], Some(best))?;
            if g.value <= 1.0 && force <= 1.0 && moment <= 1.0 {
                return Ok(Plan::Done(stuck));
            }
            toward = [g.twist[0], g.twist[1], k * g.twist[2]];
        }
        // Static friction let go (or the part was sliding): it slides under sliding friction. A
        // wrench outside the static limit set (scaled by mu / mu_s <= 1) lies outside the sliding
        // one too, which contains 0 and is convex, so the minimiser is not 0.
        Ok(Plan::Slide {
            toward: Some(toward),
            guess,
        })
    }

    /// [`Stepper::step`] under a pressure that varies across the footprint (`load`, `k` of
    /// [`Polygon::load`]): the quick tests above are for uniform pressure (the sampled planes
    /// and the double cone; a translating part now feels a moment), so the exact gauge decides,
    /// unless the force alone is outside the cylinder `|F| <= 1` (still the limit set's bound:
    /// the pressure is nowhere negative) and the part slides on from a guess.
    /// `[slide, c, force]`: the sliding threshold, the threshold in force now (static while
    /// stuck) and the free twist's force over it; `prior` the contraction the part's last solve
    /// measured, which its solve from a guess may trust.
    fn step_loaded(
        &self,
        free: [f64; 3],
        [slide, c, force]: [f64; 3],
        guess: Option<[f64; 3]>,
        load: [f64; 2],
        prior: Option<f64>,
    ) -> Result<Step> {
        let k = self.gyration;
        let guess = guess.filter(|g| g.iter().any(|&x| x != 0.0));
        if force > 1.0 && guess.is_some() {
            return self.slide(free, slide, None, guess, prior);
        }
        // a moment beyond the loaded mean distance's bound, max(1 + k.r) times the uniform one
        // (on three feet, the farthest foot's distance)
        let bound = match self.shape.tripod() {
            Some(t) => t.feet.iter().map(|s| s[0].hypot(s[1])).fold(0.0, f64::max),
            None => {
                let heavy =
                    1.0 + (load[0] * load[0] + load[1] * load[1]).sqrt() * self.shape.radius;
                self.mean_distance * heavy
            }
        };
        let moment = (k * k * free[2]).abs() / (c * bound);
        if moment > 1.0 && guess.is_some() {
            return self.slide(free, slide, None, guess, prior);
        }
        let g = self
            .shape
            .gauge(free[0] / c, free[1] / c, k * k * free[2] / c)?;
        if g.value <= 1.0 {
            return Ok(Step {
                w: [0.0; 3],
                stuck: true,
                iterations: 0,
                contraction: None,
            });
        }
        let toward = [g.twist[0], g.twist[1], k * g.twist[2]];
        self.slide(free, slide, Some(toward), guess, prior)
    }

    /// The largest ratio `<zs, e> / D(e)` over the sampled directions (a lower bound of the
    /// gauge of `zs`, spin scaled by the radius) and the direction, signed, that gives it.
    fn lower_bound(&self, zs: [f64; 3]) -> (f64, [f64; 3]) {
        let [px, py, pz] = &*self.samples;
        let mut r = [0.0; SAMPLES];
        for i in 0..SAMPLES {
            r[i] = zs[0] * px[i] + zs[1] * py[i] + zs[2] * pz[i];
        }
        let (mut lower, mut at) = (f64::NEG_INFINITY, 0);
        for (i, x) in r.iter().enumerate() {
            if x.abs() > lower {
                (lower, at) = (x.abs(), i);
            }
        }
        let sign = if r[at] < 0.0 { -1.0 } else { 1.0 };
        let best = [sign * px[at], sign * py[at], sign * pz[at]];
        (lower, best)
    }

    /// The sliding solve: the minimiser of `Phi` (module docs), not at 0, by Newton's method with
    /// the exact Hessian ([`Polygon::friction_hessian`]). A part sliding on starts from `guess`
    /// (its last relative twist, extrapolated). If there is none, or if the iterates end where
    /// the gradient is not zero (at the kink at 0, when the answer is small and the guess far
    /// from it: a test caught it), the solve starts from the lowest of the free twist and the
    /// best points on the rays through the free twist and through `toward` (either sign; the way
    /// the part starts to slide; the best sampled direction when not given): along a ray `t d`,
    /// `Phi` is a parabola in `t` (`D` is homogeneous), least at `t = (<d, y*> - c D(d)) / |d|²`.
    /// Near the limit surface the minimiser is small and lies close to `toward`'s ray, where
    /// `Phi` is smooth; started from the free twist instead, Newton's iterates could end at the
    /// kink at 0. `prior`: the contraction the part's last solve measured, for a solve from a
    /// guess ([`Newton`]).
    pub(super) fn slide(
        &self,
        free: [f64; 3],
        c: f64,
        toward: Option<[f64; 3]>,
        guess: Option<[f64; 3]>,
        prior: Option<f64>,
    ) -> Result<Step> {
        let k = self.gyration;
        // scaled coordinates y = (vx, vy, k omega): Phi = |y - y*|²/2 + c D
        let target = [free[0], free[1], k * free[2]];
        let phi = self.phi(target, c);
        let size = dot(target, target).sqrt();
        if let Some(t) = self.shape.tripod() {
            // on three feet it may turn about one of them: a kink of Phi, in closed form; if
            // it nearly does, Newton starts beside that pivot, off its kink
            match t.pivot(target, c, k) {
                Ok(y) => {
                    return Ok(Step {
                        w: [y[0], y[1], y[2] / k],
                        stuck: false,
                        iterations: 0,
                        contraction: None,
                    })
                }
                Err(Some(y)) => {
                    if let Some(st) = self.newton(y, phi(y), size + c, &phi, None)? {
                        return Ok(st);
                    }
                }
                Err(None) => {}
            }
        }
        if let Some(g) = guess.filter(|g| g.iter().any(|&x| x != 0.0)) {
            if self.shape.tripod().is_none() && self.shape.load() == [0.0; 2] {
                // the solve parts in lanes take (Stepper::begin; a planar plate's, uniform
                // pressure), in a lane of its own: the same bits whichever way the part is
                // stepped
                return self.solve_alone(&self.quad, free, c, g, toward, prior);
            }
            let y = [g[0], g[1], k * g[2]];
            if let Some(st) = self.newton(y, phi(y), size + c, &phi, prior)? {
                return Ok(st);
            }
        }
        self.slide_from(free, c, toward)
    }

    /// `Phi` of the sliding solve toward the free twist `target` (scaled, module docs) with
    /// `c = mu g dt` ([`Eval::of`]).
    fn phi(&self, target: [f64; 3], c: f64) -> impl Fn([f64; 3]) -> Eval + '_ {
        let k = self.gyration;
        move |y: [f64; 3]| {
            let f = self.shape.friction_hessian([y[0], y[1]], y[2] / k);
            Eval::of(&f, y, target, c, self.kinv)
        }
    }

    /// The sliding solve with no twist to go on (or the one gone on from ended off the
    /// minimiser): from the best start on the rays ([`Stepper::start`]), and at last from the
    /// exact gauge's direction.
    pub(super) fn slide_from(
        &self,
        free: [f64; 3],
        c: f64,
        toward: Option<[f64; 3]>,
    ) -> Result<Step> {
        let k = self.gyration;
        let target = [free[0], free[1], k * free[2]];
        let phi = self.phi(target, c);
        let size = dot(target, target).sqrt();
        let toward = match toward {
            Some(t) => t,
            None => {
                let z = [free[0] / c, free[1] / c, k * k * free[2] / c];
                if self.shape.load() == [0.0; 2] {
                    let best = self.lower_bound([z[0], z[1], z[2] / self.shape.radius]).1;
                    [best[0], best[1], k * best[2] / self.shape.radius]
                } else {
                    // (the sampled planes are uniform pressure's)
                    let g = self.shape.gauge(z[0], z[1], z[2])?;
                    [g.twist[0], g.twist[1], k * g.twist[2]]
                }
            }
        };
        let (y, at) = self.start(target, toward, c, &phi);
        if let Some(st) = self.newton(y, at, size + c, &phi, None)? {
            return Ok(st);
        }
        // the last resort: from the exact gauge's direction (the start above may have come
        // from a sampled one, or from the free twist, and ended at the kink)
        let z = [free[0] / c, free[1] / c, k * k * free[2] / c];
        let g = self.shape.gauge(z[0], z[1], z[2])?;
        let (y, at) = self.start(target, [g.twist[0], g.twist[1], k * g.twist[2]], c, &phi);
        if let Some(st) = self.newton(y, at, size + c, &phi, None)? {
            return Ok(st);
        }
        // Just outside the limit set (gauge 1 + 1e-6 or less), the minimiser is at the kink's
        // doorstep: by Moreau's decomposition it is the free twist less its projection onto the
        // limit set, no longer than |y*| (1 - 1/gauge), and this twist along the free one is
        // within twice that of it (a test caught Newton stalling here, a spin at the edge of
        // sticking).
        if g.value <= 1.0 + NEAR_LIMIT {
            let f = (1.0 - 1.0 / g.value).max(0.0);
            return Ok(Step {
                w: [f * free[0], f * free[1], f * free[2]],
                stuck: false,
                iterations: 0,
                contraction: None,
            });
        }
        Err(Error::Convergence(format!(
            "the sliding step of a polygon part from the relative twist {free:?} ended off the \
             minimiser"
        )))
    }

    /// Newton's method ([`Newton`]) from `y` (where `Phi` is `at`), trusting the contraction
    /// `prior` for a start from a guess: the step, or None when it ends where the gradient is
    /// not zero to `1e-9` of `scale` (`|y*| + c`, the gradient's terms).
    fn newton(
        &self,
        y: [f64; 3],
        at: Eval,
        scale: f64,
        phi: &impl Fn([f64; 3]) -> Eval,
        prior: Option<f64>,
    ) -> Result<Option<Step>> {
        let (mut solve, _) = Newton::new(y, scale, self.gyration, prior);
        let mut ask = solve.feed(&at)?;
        loop {
            match ask {
                Ask::Eval(y) => ask = solve.feed(&phi(y))?,
                Ask::Done(step) => return Ok(step),
            }
        }
    }

    /// A start for the sliding solve of a part with no twist to go on: the lowest of the free
    /// twist and the best points on the rays through it and through `toward` (either sign).
    fn start(
        &self,
        target: [f64; 3],
        toward: [f64; 3],
        c: f64,
        phi: &impl Fn([f64; 3]) -> Eval,
    ) -> ([f64; 3], Eval) {
        let k = self.gyration;
        // (the candidates compared by Phi alone, Eval::of's value, without the Hessian; the
        // start taken evaluated whole)
        let value = |y: [f64; 3]| {
            let work = self.shape.friction([y[0], y[1]], y[2] / k).1;
            let r = [y[0] - target[0], y[1] - target[1], y[2] - target[2]];
            0.5 * dot(r, r) + c * work
        };
        let mut best = (target, value(target));
        let rays = [target, toward, [-toward[0], -toward[1], -toward[2]]];
        for d in rays.into_iter().filter(|d| dot(*d, *d) > 0.0) {
            let (_, dd) = self.shape.friction([d[0], d[1]], d[2] / k);
            let t = (dot(d, target) - c * dd) / dot(d, d);
            if t > 0.0 {
                let cand = [t * d[0], t * d[1], t * d[2]];
                let at = value(cand);
                if at < best.1 {
                    best = (cand, at);
                }
            }
        }
        (best.0, phi(best.0))
    }
}
