//! A polygon part's step taken in parts, so that many parts' sliding solves can take their
//! friction together (`sim::polygons`, eight parts in lanes, [`super::Quad`]): [`Stepper::begin`]
//! decides the step as [`Stepper::step`] does, up to a sliding solve that goes on from a guess,
//! and that solve ([`Solve`]) asks for `Phi` at one twist after another.

use super::four::{Asked, Quad};
use super::newton::{dot, Ask, Eval, Evals, Newton};
use super::step::{Plan, Step, Stepper};
use crate::error::Result;

/// One part's arguments of its step ([`Stepper::step_request`]; [`Stepper::step`] takes all but
/// the last).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Request {
    /// The free relative twist, in the part's frame.
    pub free: [f64; 3],
    /// `mu g dt`.
    pub slide: f64,
    /// `mu_s g dt`.
    pub hold: f64,
    /// Whether the part moved with the plate after the last step.
    pub was_stuck: bool,
    /// A relative twist near the answer, if one is known.
    pub guess: Option<[f64; 3]>,
    /// The contraction the part's last sliding solve measured ([`Step::contraction`]), if the
    /// solve from `guess` is to trust it.
    pub contraction: Option<f64>,
}

/// A sliding solve from a guess ([`Stepper::begin`]): Newton's method in the scaled twist `y`
/// ([`Newton`]), asking for the friction at one twist after another.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Solve {
    newton: Newton,
    target: [f64; 3],
    free: [f64; 3],
    c: f64,
    toward: Option<[f64; 3]>,
    /// The scaled twist it asks about.
    at: [f64; 3],
}

impl Solve {
    /// What it asks about, of `stepper` (the one that began it): the relative twist whose
    /// friction it needs and what `Phi` there takes ([`Eval::of`]).
    pub(crate) fn asked(&self, stepper: &Stepper) -> Asked {
        let (y, k) = (self.at, stepper.gyration);
        Asked {
            twist: [y[0], y[1], y[2] / k],
            y,
            target: self.target,
            c: self.c,
            kinv: stepper.kinv,
        }
    }

    /// Takes `Phi` at what it asked about ([`Solve::asked`]): the step when the solve is done,
    /// else None and it asks about another twist. A solve that ends off the minimiser goes on
    /// as [`Stepper::step`] would, whole.
    #[inline(always)]
    pub(crate) fn feed(&mut self, stepper: &Stepper, at: &Eval) -> Result<Option<Step>> {
        match self.newton.feed(at)? {
            Ask::Eval(y) => {
                self.at = y;
                Ok(None)
            }
            Ask::Done(Some(step)) => Ok(Some(step)),
            Ask::Done(None) => stepper.slide_from(self.free, self.c, self.toward).map(Some),
        }
    }
}

impl Stepper {
    /// [`Stepper::step`] with `r`'s arguments, up to a sliding solve that goes on from a guess:
    /// then that solve is begun in `solve` (and None returned), which asks for the friction at
    /// one twist after another ([`Solve::feed`]), so that many parts' solves can take their
    /// friction together (in lanes, [`super::Quad::evaluate`]). Every other step is taken
    /// whole. (The solve is begun in place: moved, its few hundred bytes cost more than the
    /// step's bookkeeping.)
    #[inline(always)]
    pub(crate) fn begin(&self, r: &Request, solve: &mut Solve) -> Result<Option<Step>> {
        if self.sliding_on(r, solve) {
            return Ok(None);
        }
        self.begin_planned(r, solve)
    }

    /// The most common step, decided as [`Stepper::plan`] decides it, inline: a part that slid
    /// on (its twist a guess) under uniform pressure on its footprint, with a free spin and a
    /// wrench outside the cylinder that holds the limit set, slides on from its guess.
    /// Begins it in `solve` if so.
    #[inline(always)]
    fn sliding_on(&self, r: &Request, solve: &mut Solve) -> bool {
        let Some(g) = r.guess.filter(|g| g.iter().any(|&x| x != 0.0)) else {
            return false;
        };
        let free = r.free;
        if r.was_stuck
            || free[2] == 0.0
            || self.shape.load() != [0.0; 2]
            || self.shape.tripod().is_some()
        {
            return false;
        }
        let (k, c) = (self.gyration, r.slide);
        let force = (free[0] * free[0] + free[1] * free[1]).sqrt() / c;
        let moment = (k * k * free[2]).abs() / c;
        if force + moment / self.pure_moment <= 1.0 || !(force > 1.0 || moment > 1.0) {
            return false;
        }
        self.solve_from(r, g, None, solve);
        true
    }

    /// The sliding solve of `r` from the guess `g` (nonzero), begun in `solve`.
    #[inline(always)]
    fn solve_from(&self, r: &Request, g: [f64; 3], toward: Option<[f64; 3]>, solve: &mut Solve) {
        let k = self.gyration;
        let target = [r.free[0], r.free[1], k * r.free[2]];
        let y = [g[0], g[1], k * g[2]];
        let scale = dot(target, target).sqrt() + r.slide;
        let (newton, _) = Newton::new(y, scale, k, r.contraction);
        *solve = Solve {
            newton,
            target,
            free: r.free,
            c: r.slide,
            toward,
            at: y,
        };
    }

    /// [`Stepper::begin`] through [`Stepper::plan`].
    #[inline(never)]
    fn begin_planned(&self, r: &Request, solve: &mut Solve) -> Result<Option<Step>> {
        match self.plan(r)? {
            Plan::Done(step) => Ok(Some(step)),
            Plan::Slide { toward, guess } => match guess.filter(|g| g.iter().any(|&x| x != 0.0)) {
                Some(g) if self.shape.tripod().is_none() => {
                    self.solve_from(r, g, toward, solve);
                    Ok(None)
                }
                _ => self
                    .slide(r.free, r.slide, toward, guess, r.contraction)
                    .map(Some),
            },
        }
    }

    /// [`Stepper::step`]'s solve from the guess `g` (nonzero; `toward` the way the part starts
    /// to slide, if known), in a lane of its own of `quad` (the stepper's shape in lane 0),
    /// trusting the contraction the part's last solve measured, if given: the same bits as in
    /// lanes beside other parts.
    pub(super) fn solve_alone(
        &self,
        quad: &Quad,
        free: [f64; 3],
        c: f64,
        g: [f64; 3],
        toward: Option<[f64; 3]>,
        contraction: Option<f64>,
    ) -> Result<Step> {
        let r = Request {
            free,
            slide: c,
            hold: c,
            was_stuck: false,
            guess: Some(g),
            contraction,
        };
        let mut solve = Solve::default();
        self.solve_from(&r, g, toward, &mut solve);
        let mut evals = Evals::default();
        let shapes = [Some(&self.shape), None, None, None];
        loop {
            let asks = [Some(solve.asked(self)), None, None, None];
            quad.evaluate(shapes, &asks, &mut evals);
            if let Some(st) = solve.feed(self, &evals.get(0))? {
                return Ok(st);
            }
        }
    }
}
