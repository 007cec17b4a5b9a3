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
//! [gauge]: Polygon::gauge

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
}

/// `Phi` at a point of the sliding solve, with its gradient and Hessian.
struct Point {
    value: f64,
    grad: [f64; 3],
    hess: [[f64; 3]; 3],
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
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Relative size of a Newton step under which the solve has converged.
const TOLERANCE: f64 = 1e-14;
/// Sampled twist directions of [`Stepper`].
const SAMPLES: usize = 48;
/// Whole Newton steps taken once `Phi` no longer resolves its fall, at most (the gradient then
/// sits at its rounding floor).
const FINE_STEPS: usize = 4;
/// Newton iterations allowed before the solve reports that it did not converge.
const MAX_ITERATIONS: usize = 100;

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
        let k = self.gyration;
        let c = if was_stuck { hold } else { slide };
        // the wrench per mu N that keeps the part with the plate, force and moment / mean distance
        let speed = (free[0] * free[0] + free[1] * free[1]).sqrt();
        let force = speed / c;
        let stuck = Step {
            w: [0.0; 3],
            stuck: true,
            iterations: 0,
        };
        let load = self.shape.load();
        if load != [0.0; 2] {
            return self.step_loaded(free, [slide, c, force], guess, load);
        }
        if free[2] == 0.0 {
            // no spin: a point's stick or slide (a translating part feels no moment)
            if force <= 1.0 {
                return Ok(stuck);
            }
            // |free| > hold >= slide: it slides on
            let f = 1.0 - slide / speed;
            return Ok(Step {
                w: [free[0] * f, free[1] * f, 0.0],
                stuck: false,
                iterations: 0,
            });
        }
        // the moment that keeps it, per mu N [m], over the largest pure moment
        let moment = (k * k * free[2]).abs() / c;
        if force + moment / self.pure_moment <= 1.0 {
            return Ok(stuck); // inside the double cone, inside the limit set
        }
        // outside the cylinder that holds the limit set a part sliding on needs no direction to
        // start from: it slides, from its last twist
        let guess = guess.filter(|g| g.iter().any(|&x| x != 0.0));
        if (force > 1.0 || moment > 1.0) && guess.is_some() {
            return self.slide(free, slide, None, guess);
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
                return Ok(stuck);
            }
            toward = [g.twist[0], g.twist[1], k * g.twist[2]];
        }
        // Static friction let go (or the part was sliding): it slides under sliding friction. A
        // wrench outside the static limit set (scaled by mu / mu_s <= 1) lies outside the sliding
        // one too, which contains 0 and is convex, so the minimiser is not 0.
        self.slide(free, slide, Some(toward), guess)
    }

    /// [`Stepper::step`] under a pressure that varies across the footprint (`load`, `k` of
    /// [`Polygon::load`]): the quick tests above are for uniform pressure (the sampled planes
    /// and the double cone; a translating part now feels a moment), so the exact gauge decides,
    /// unless the force alone is outside the cylinder `|F| <= 1` (still the limit set's bound:
    /// the pressure is nowhere negative) and the part slides on from a guess.
    /// `[slide, c, force]`: the sliding threshold, the threshold in force now (static while
    /// stuck) and the free twist's force over it.
    fn step_loaded(
        &self,
        free: [f64; 3],
        [slide, c, force]: [f64; 3],
        guess: Option<[f64; 3]>,
        load: [f64; 2],
    ) -> Result<Step> {
        let k = self.gyration;
        let guess = guess.filter(|g| g.iter().any(|&x| x != 0.0));
        if force > 1.0 && guess.is_some() {
            return self.slide(free, slide, None, guess);
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
            return self.slide(free, slide, None, guess);
        }
        let g = self
            .shape
            .gauge(free[0] / c, free[1] / c, k * k * free[2] / c)?;
        if g.value <= 1.0 {
            return Ok(Step {
                w: [0.0; 3],
                stuck: true,
                iterations: 0,
            });
        }
        let toward = [g.twist[0], g.twist[1], k * g.twist[2]];
        self.slide(free, slide, Some(toward), guess)
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
    /// kink at 0.
    fn slide(
        &self,
        free: [f64; 3],
        c: f64,
        toward: Option<[f64; 3]>,
        guess: Option<[f64; 3]>,
    ) -> Result<Step> {
        let k = self.gyration;
        // scaled coordinates y = (vx, vy, k omega): Phi = |y - y*|²/2 + c D
        let target = [free[0], free[1], k * free[2]];
        let scale = [1.0, 1.0, 1.0 / k];
        // Phi, its gradient and its Hessian I + c S H S (H the Hessian of D, S = diag(1, 1, 1/k))
        let phi = |y: [f64; 3]| -> Point {
            let f = self.shape.friction_hessian([y[0], y[1]], y[2] / k);
            let r = [y[0] - target[0], y[1] - target[1], y[2] - target[2]];
            let grad = std::array::from_fn(|i| r[i] - c * f.wrench[i] * scale[i]);
            let hess = std::array::from_fn(|i| {
                std::array::from_fn(|j| {
                    let eye = if i == j { 1.0 } else { 0.0 };
                    eye + c * f.hessian[i][j] * scale[i] * scale[j]
                })
            });
            Point {
                value: 0.5 * dot(r, r) + c * f.work,
                grad,
                hess,
            }
        };
        let size = dot(target, target).sqrt();
        if let Some(t) = self.shape.tripod() {
            // on three feet it may turn about one of them: a kink of Phi, in closed form; if
            // it nearly does, Newton starts beside that pivot, off its kink
            match t.pivot(target, c, k) {
                Ok(y) => return Ok(self.done(y, 0)),
                Err(Some(y)) => {
                    if let Some(st) = self.newton(y, phi(y), size + c, &phi)? {
                        return Ok(st);
                    }
                }
                Err(None) => {}
            }
        }
        if let Some(g) = guess.filter(|g| g.iter().any(|&x| x != 0.0)) {
            let y = [g[0], g[1], k * g[2]];
            if let Some(st) = self.newton(y, phi(y), size + c, &phi)? {
                return Ok(st);
            }
        }
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
        if let Some(st) = self.newton(y, at, size + c, &phi)? {
            return Ok(st);
        }
        // the last resort: from the exact gauge's direction (the start above may have come
        // from a sampled one, or from the free twist, and ended at the kink)
        let z = [free[0] / c, free[1] / c, k * k * free[2] / c];
        let g = self.shape.gauge(z[0], z[1], z[2])?;
        let (y, at) = self.start(target, [g.twist[0], g.twist[1], k * g.twist[2]], c, &phi);
        match self.newton(y, at, size + c, &phi)? {
            Some(st) => Ok(st),
            None => Err(Error::Convergence(format!(
                "the sliding step of a polygon part from the relative twist {free:?} ended off \
                 the minimiser"
            ))),
        }
    }

    /// Newton's method from `y` (where `Phi` is `at`): the step, or None when it ends where the
    /// gradient is not zero to `1e-9` of `scale` (`|y*| + c`, the gradient's terms).
    fn newton(
        &self,
        mut y: [f64; 3],
        mut at: Point,
        scale: f64,
        phi: &impl Fn([f64; 3]) -> Point,
    ) -> Result<Option<Step>> {
        let settled = |y: [f64; 3], at: &Point, it: usize| {
            (dot(at.grad, at.grad).sqrt() <= 1e-9 * scale).then(|| self.done(y, it))
        };
        let mut fine = 0;
        let mut last = f64::INFINITY;
        // the last whole Newton step's length (infinite when none)
        let mut previous = f64::INFINITY;
        for it in 0..MAX_ITERATIONS {
            let norm = dot(y, y).sqrt();
            let grad = at.grad;
            let mut step = solve3(at.hess, [-grad[0], -grad[1], -grad[2]])
                .filter(|s| dot(*s, grad) < 0.0)
                .unwrap_or([-grad[0], -grad[1], -grad[2]]);
            let length = dot(step, step).sqrt();
            if length <= TOLERANCE * norm + 1e-15 * scale {
                return Ok(settled(y, &at, it));
            }
            // converging quadratically, |next| ~ |step|² |step| / |previous|²: when that is
            // below the tolerance this step is the last, taken without evaluating Phi after it
            if previous.is_finite()
                && length <= 1e-7 * norm
                && length * length * length <= TOLERANCE * norm * previous * previous
            {
                let y = [y[0] + step[0], y[1] + step[1], y[2] + step[2]];
                return Ok(Some(self.done(y, it + 1)));
            }
            if -dot(step, grad) <= 1e-14 * at.value {
                // Phi's fall is below its rounding: Newton's region, where its steps are taken
                // whole while they shrink, the gradient (exact to rounding) falling to its floor
                fine += 1;
                if fine > FINE_STEPS || length >= 0.5 * last {
                    return Ok(settled(y, &at, it));
                }
                last = length;
                y = [y[0] + step[0], y[1] + step[1], y[2] + step[2]];
                at = phi(y);
                continue;
            }
            // halve the step until Phi falls (Armijo); a convex Phi always falls for a small one
            let (mut moved, mut full) = (false, true);
            for _ in 0..60 {
                let cand = [y[0] + step[0], y[1] + step[1], y[2] + step[2]];
                let next = phi(cand);
                if next.value < at.value && next.value <= at.value + 1e-4 * dot(step, grad) {
                    (y, at, moved) = (cand, next, true);
                    break;
                }
                full = false;
                step = [0.5 * step[0], 0.5 * step[1], 0.5 * step[2]];
            }
            if !moved {
                // no step within rounding lowers Phi: the minimum to rounding
                return Ok(settled(y, &at, it + 1));
            }
            previous = if full { length } else { f64::INFINITY };
        }
        Err(Error::Convergence(format!(
            "the sliding step of a polygon part did not converge in {MAX_ITERATIONS} Newton \
             iterations (last iterate {y:?})"
        )))
    }

    /// A start for the sliding solve of a part with no twist to go on: the lowest of the free
    /// twist and the best points on the rays through it and through `toward` (either sign).
    fn start(
        &self,
        target: [f64; 3],
        toward: [f64; 3],
        c: f64,
        phi: &impl Fn([f64; 3]) -> Point,
    ) -> ([f64; 3], Point) {
        let k = self.gyration;
        let mut best = (target, phi(target));
        let rays = [target, toward, [-toward[0], -toward[1], -toward[2]]];
        for d in rays.into_iter().filter(|d| dot(*d, *d) > 0.0) {
            let (_, dd) = self.shape.friction([d[0], d[1]], d[2] / k);
            let t = (dot(d, target) - c * dd) / dot(d, d);
            if t > 0.0 {
                let cand = [t * d[0], t * d[1], t * d[2]];
                let at = phi(cand);
                if at.value < best.1.value {
                    best = (cand, at);
                }
            }
        }
        best
    }

    fn done(&self, y: [f64; 3], iterations: usize) -> Step {
        Step {
            w: [y[0], y[1], y[2] / self.gyration],
            stuck: false,
            iterations,
        }
    }
}

/// `a x = b` for a symmetric 3x3 `a` by its adjugate (six cofactors, one division), None when
/// `a` is singular.
fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let [[a00, a01, a02], [_, a11, a12], [_, _, a22]] = a;
    let c00 = a11 * a22 - a12 * a12;
    let c01 = a02 * a12 - a01 * a22;
    let c02 = a01 * a12 - a02 * a11;
    let c11 = a00 * a22 - a02 * a02;
    let c12 = a01 * a02 - a00 * a12;
    let c22 = a00 * a11 - a01 * a01;
    let d = a00 * c00 + a01 * c01 + a02 * c02;
    if !(d.is_finite() && d.abs() > 0.0) {
        return None;
    }
    let inv = 1.0 / d;
    let x = [
        (c00 * b[0] + c01 * b[1] + c02 * b[2]) * inv,
        (c01 * b[0] + c11 * b[1] + c12 * b[2]) * inv,
        (c02 * b[0] + c12 * b[1] + c22 * b[2]) * inv,
    ];
    x.iter().all(|v| v.is_finite()).then_some(x)
}
