//! Newton's method for the sliding solve of [`super::Stepper`], as a machine that asks for `Phi`
//! at one point at a time ([`Newton::feed`]): one solve drives it with one evaluation after
//! another, parts in lanes (`sim::polygons`) drive eight with one evaluation of the eight
//! points, and both take the same steps.

use super::step::Step;
use super::Friction;
use crate::error::{Error, Result};

/// `Phi` at a point of the sliding solve, its gradient's size, and the Newton step there: all
/// the solve needs of the point.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Eval {
    pub(super) value: f64,
    /// `|grad|`.
    pub(super) gnorm: f64,
    /// The Newton step (minus the gradient where the Hessian gives no descent).
    pub(super) step: [f64; 3],
    /// `|step|`, `<step, grad>` and `|y|`.
    pub(super) length: f64,
    pub(super) slope: f64,
    pub(super) norm: f64,
}

/// Four lanes' [`Eval`]s, by field (as the AVX2 build stores them): value, gnorm, step (3),
/// length, slope, norm.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Evals(pub(super) [[f64; 4]; 8]);

impl Evals {
    /// Lane `l`'s.
    #[inline(always)]
    pub(crate) fn get(&self, l: usize) -> Eval {
        let o = &self.0;
        Eval {
            value: o[0][l],
            gnorm: o[1][l],
            step: [o[2][l], o[3][l], o[4][l]],
            length: o[5][l],
            slope: o[6][l],
            norm: o[7][l],
        }
    }

    /// Sets lane `l`'s.
    #[inline(always)]
    pub(crate) fn set(&mut self, l: usize, e: &Eval) {
        let o = &mut self.0;
        o[0][l] = e.value;
        o[1][l] = e.gnorm;
        (o[2][l], o[3][l], o[4][l]) = (e.step[0], e.step[1], e.step[2]);
        (o[5][l], o[6][l], o[7][l]) = (e.length, e.slope, e.norm);
    }
}

impl Eval {
    /// `Phi = |y - target|² / 2 + c D` at `y = (vx, vy, k omega)` from the friction `f` of the
    /// twist there (`kinv` the reciprocal of the radius of gyration `k`), with its gradient
    /// and the Newton step of its Hessian `I + c S H S` (`H` the Hessian of `D`, `S = diag(1,
    /// 1, 1/k)`). (The AVX2 build in lanes, `avx2::evals_four`, takes the same operations.)
    pub(super) fn of(f: &Friction, y: [f64; 3], target: [f64; 3], c: f64, kinv: f64) -> Eval {
        let scale = [1.0, 1.0, kinv];
        let r = [y[0] - target[0], y[1] - target[1], y[2] - target[2]];
        let grad: [f64; 3] = std::array::from_fn(|i| r[i] - c * f.wrench[i] * scale[i]);
        let hess = std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                let eye = if i == j { 1.0 } else { 0.0 };
                eye + c * f.hessian[i][j] * scale[i] * scale[j]
            })
        });
        let step = solve3(hess, [-grad[0], -grad[1], -grad[2]])
            .filter(|s| dot(*s, grad) < 0.0)
            .unwrap_or([-grad[0], -grad[1], -grad[2]]);
        Eval {
            value: 0.5 * dot(r, r) + c * f.work,
            gnorm: dot(grad, grad).sqrt(),
            step,
            length: dot(step, step).sqrt(),
            slope: dot(step, grad),
            norm: dot(y, y).sqrt(),
        }
    }
}

/// What a solve asks for next.
#[derive(Debug, Clone, Copy)]
pub(super) enum Ask {
    /// `Phi` at this point.
    Eval([f64; 3]),
    /// The step, or None when the iterates ended where the gradient is not zero.
    Done(Option<Step>),
}

/// Where a solve is.
#[derive(Debug, Clone, Copy, Default)]
enum Phase {
    /// Waiting for `Phi` at the start.
    #[default]
    Start,
    /// A whole Newton step taken in Newton's region, waiting for `Phi` after it.
    Fine,
    /// Waiting for `Phi` at `y + step` (halved `tries` times from the Newton step of `length`;
    /// `slope` its product with the gradient at `y`).
    Search {
        step: [f64; 3],
        slope: f64,
        length: f64,
        tries: usize,
    },
}

/// Relative size of a Newton step under which the solve has converged.
const TOLERANCE: f64 = 1e-14;
/// Whole Newton steps taken once `Phi` no longer resolves its fall, at most (the gradient then
/// sits at its rounding floor).
const FINE_STEPS: usize = 4;
/// How far the contraction a part's last solve measured is trusted for its next solve's first
/// step: that step ends the solve if this many times the contraction predicts a next step below
/// [`TOLERANCE`].
const SAFETY: f64 = 10.0;
/// Newton iterations allowed before the solve reports that it did not converge.
const MAX_ITERATIONS: usize = 100;
/// Halvings of a step before the line search gives up (no step within rounding lowers `Phi`).
const HALVINGS: usize = 60;

/// One sliding solve: Newton's method with the exact Hessian, the step halved until `Phi`
/// falls (Armijo); done when the step is below [`TOLERANCE`] of the iterate (or, converging
/// quadratically, the next one would be), and then settled only if the gradient is zero to
/// `1e-9` of `scale` (`|y*| + c`, the gradient's terms).
///
/// Converging quadratically, `|next| / |y| ~ kappa (|step| / |y|)²`: the solve measures the
/// contraction `kappa` from its steps ([`Step::contraction`]), and a solve given the one its
/// part's last solve measured (`prior`) may end at its first step, from a guess close enough
/// that [`SAFETY`] times that contraction predicts a next step below the tolerance: a part
/// sliding on smoothly from an extrapolated guess then asks for `Phi` once a step.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Newton {
    y: [f64; 3],
    /// `Phi` and the gradient's size at `y` (once evaluated).
    value: f64,
    gnorm: f64,
    scale: f64,
    /// The radius of gyration (the twist is `(y0, y1, y2 / k)`).
    k: f64,
    fine: usize,
    /// The last fine step's length, and the last whole Newton step's (infinite when none).
    last: f64,
    previous: f64,
    it: usize,
    phase: Phase,
    /// The contraction the part's last solve measured, and the one this solve measures.
    prior: Option<f64>,
    measured: Option<f64>,
}

impl Newton {
    /// A solve from `y`, which asks for `Phi` there first; `prior` the contraction the part's
    /// last solve measured, if it is to be trusted.
    pub(super) fn new(y: [f64; 3], scale: f64, k: f64, prior: Option<f64>) -> (Self, Ask) {
        let n = Newton {
            y,
            value: f64::NAN,
            gnorm: f64::NAN,
            scale,
            k,
            fine: 0,
            last: f64::INFINITY,
            previous: f64::INFINITY,
            it: 0,
            phase: Phase::Start,
            prior,
            measured: None,
        };
        (n, Ask::Eval(y))
    }

    /// `Phi` at the point last asked for; the next request.
    #[inline(always)]
    pub(super) fn feed(&mut self, p: &Eval) -> Result<Ask> {
        match self.phase {
            Phase::Start => self.decide(p),
            Phase::Fine => {
                self.it += 1;
                self.decide(p)
            }
            Phase::Search {
                step,
                slope,
                length,
                tries,
            } => {
                if p.value < self.value && p.value <= self.value + 1e-4 * slope {
                    self.y = add(self.y, step);
                    self.previous = if tries == 0 { length } else { f64::INFINITY };
                    self.it += 1;
                    return self.decide(p);
                }
                if tries + 1 == HALVINGS {
                    // no step within rounding lowers Phi: the minimum to rounding
                    return Ok(Ask::Done(self.settled(self.it + 1)));
                }
                // (halving is exact: the halved step's product with the gradient is half its)
                let step = step.map(|s| 0.5 * s);
                self.phase = Phase::Search {
                    step,
                    slope: 0.5 * slope,
                    length,
                    tries: tries + 1,
                };
                Ok(Ask::Eval(add(self.y, step)))
            }
        }
    }

    /// The Newton step from the current iterate, where `Phi` is `at`, or the end.
    #[inline(always)]
    fn decide(&mut self, at: &Eval) -> Result<Ask> {
        (self.value, self.gnorm) = (at.value, at.gnorm);
        let y = self.y;
        if self.it >= MAX_ITERATIONS {
            return Err(unconverged(y));
        }
        let (norm, step, length) = (at.norm, at.step, at.length);
        if self.previous.is_finite() && self.previous > 0.0 {
            // the contraction after a whole Newton step (a step below rounding counted as at
            // it: the iterate is then as close as rounding tells, not closer)
            let next = length.max(f64::EPSILON * norm);
            self.measured = Some(next * norm / (self.previous * self.previous));
        }
        if length <= TOLERANCE * norm + 1e-15 * self.scale {
            return Ok(Ask::Done(self.settled(self.it)));
        }
        // converging quadratically, |next| ~ |step|² |step| / |previous|²: when that is below
        // the tolerance this step is the last, taken without evaluating Phi after it
        let previous = self.previous;
        let last = if previous.is_finite() {
            length * length * length <= TOLERANCE * norm * previous * previous
        } else {
            // the first step: by the contraction the part's last solve measured
            self.prior
                .is_some_and(|k| SAFETY * k * length * length <= TOLERANCE * norm * norm)
        };
        if last && length <= 1e-7 * norm {
            return Ok(Ask::Done(Some(self.done(add(y, step), self.it + 1))));
        }
        if -at.slope <= 1e-14 * at.value {
            // Phi's fall is below its rounding: Newton's region, where its steps are taken
            // whole while they shrink, the gradient (exact to rounding) falling to its floor
            self.fine += 1;
            if self.fine > FINE_STEPS || length >= 0.5 * self.last {
                return Ok(Ask::Done(self.settled(self.it)));
            }
            (self.last, self.previous) = (length, length);
            self.y = add(y, step);
            self.phase = Phase::Fine;
            return Ok(Ask::Eval(self.y));
        }
        // halve the step until Phi falls (Armijo); a convex Phi always falls for a small one
        self.phase = Phase::Search {
            step,
            slope: at.slope,
            length,
            tries: 0,
        };
        Ok(Ask::Eval(add(y, step)))
    }

    /// The current iterate as the answer if the gradient is zero to `1e-9` of the scale.
    fn settled(&self, iterations: usize) -> Option<Step> {
        (self.gnorm <= 1e-9 * self.scale).then(|| self.done(self.y, iterations))
    }

    fn done(&self, y: [f64; 3], iterations: usize) -> Step {
        Step {
            w: [y[0], y[1], y[2] / self.k],
            stuck: false,
            iterations,
            contraction: self.measured,
        }
    }
}

/// The error of a solve that took [`MAX_ITERATIONS`] (out of line: the solve's own code is
/// inlined where it is driven).
#[cold]
#[inline(never)]
fn unconverged(y: [f64; 3]) -> Error {
    Error::Convergence(format!(
        "the sliding step of a polygon part did not converge in {MAX_ITERATIONS} Newton \
         iterations (last iterate {y:?})"
    ))
}

pub(super) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
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
