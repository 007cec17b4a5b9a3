//! Velocity fields of a plate that moves out of its plane (docs/spec.md §10; the PPOD line of
//! Vose, Umbanhowar and Lynch).
//!
//! Two fields at points `P` of the plate, for a periodic motion (one item that repeats forever):
//!
//! * the **drift** [`drift`]: the mean velocity of a part held at `P` in the periodic steady
//!   state of the exact stick–slip dynamics (the integrator's own step, [`crate::sim::lift::step`],
//!   with the part's position frozen), found by running whole periods until the mean velocity of
//!   a period changes by less than a tolerance;
//! * the **asymptotic** field [`asymptotic`]: `v* = argmin_v < (g + a_z)^+ |v - v_h(t)| >`, the
//!   weighted geometric median of the surface velocity's hodograph at `P`, the drift's limit when
//!   the plate's acceleration is large against `mu g`; independent of `mu` and of mass. The
//!   cycle average is the midpoint rule on `samples` times (exact for the trigonometric
//!   polynomials of the weights to high order; the kink of `|v - v_h|` limits it to about
//!   `samples^-2`), and the median is found by Weiszfeld's iteration with Vardi and Zhang's
//!   treatment of sample points.
//!
//! Both report the largest horizontal acceleration of the surface at `P` (the validity index is
//! `mu g` over it) and the fraction of the cycle the normal force is negative (lift-off).

use rayon::prelude::*;

use crate::error::{finite, positive, Error, Result};
use crate::motion::spatial::normal_at;
use crate::motion::PlateMotion;
use crate::sim::lift::{step, State};

/// Settings of the drift field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriftConfig {
    /// Sliding friction coefficient.
    pub mu: f64,
    /// Static friction coefficient (`>= mu`).
    pub mu_s: f64,
    /// Gravity [m/s²].
    pub g: f64,
    /// Steps per period.
    pub steps: usize,
    /// Stop when a period's mean velocity differs from the previous one's by at most this [m/s].
    pub tol: f64,
    /// Give up after this many periods.
    pub max_periods: usize,
}

/// The field at one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldPoint {
    /// Field velocity [m/s].
    pub v: [f64; 2],
    /// Largest horizontal acceleration of the plate surface at the point over a cycle [m/s²].
    pub max_accel: f64,
    /// Fraction of the cycle in which `g + a_z < 0` (the part cannot stay on the plate).
    pub lift: f64,
    /// Periods run (drift) or iterations (asymptotic) until converged.
    pub work: usize,
    /// Whether the tolerance was met.
    pub converged: bool,
}

/// The period of a motion that repeats: one item without a duration.
fn period(motion: &PlateMotion) -> Result<f64> {
    if motion.items().len() != 1 || motion.duration().is_some() {
        return Err(Error::parameter(
            "motion",
            "a velocity field needs a periodic motion: one motion that repeats forever (no \
             duration, no sequence)",
        ));
    }
    motion.span()
}

/// One cycle of the plate at the midpoints of `n` equal steps: in-plane velocity at each step's
/// sample time (as the integrator takes it) and out-of-plane acceleration.
struct Cycle {
    u: Vec<[f64; 3]>,
    nz: Vec<[f64; 3]>,
    a: Vec<[f64; 3]>,
    dt: f64,
}

impl Cycle {
    fn new(motion: &PlateMotion, n: usize) -> Result<Self> {
        let t = period(motion)?;
        let dt = t / n as f64;
        let mut u = Vec::with_capacity(n);
        motion.velocities_into(0..n, dt, &mut u);
        let mut nz = Vec::with_capacity(n);
        motion.normals_into(0..n, dt, &mut nz);
        let a = (0..n)
            .map(|s| motion.at((s as f64 + 1.0 - 1e-6) * dt).1)
            .collect();
        Ok(Cycle { u, nz, a, dt })
    }

    /// Largest `|d v_h / dt|` at `p` over the samples, and the fraction with `g + a_z < 0`.
    fn extremes(&self, p: [f64; 2], g: f64) -> (f64, f64) {
        let [x, y] = p;
        let top = self
            .a
            .iter()
            .map(|a| (a[0] - a[2] * y).hypot(a[1] + a[2] * x))
            .fold(0.0, f64::max);
        let below = self
            .nz
            .iter()
            .filter(|nz| g + normal_at(nz, p) < 0.0)
            .count();
        (top, below as f64 / self.nz.len() as f64)
    }
}

fn check_points(points: &[[f64; 2]]) -> Result<()> {
    for (i, p) in points.iter().enumerate() {
        for &c in p {
            finite("points", c).map_err(|e| e.with_context(&format!("point {i}")))?;
        }
    }
    Ok(())
}

/// The drift field of `motion` at `points` (see the module).
pub fn drift(
    motion: &PlateMotion,
    points: &[[f64; 2]],
    cfg: &DriftConfig,
) -> Result<Vec<FieldPoint>> {
    positive("mu", cfg.mu)?;
    positive("g", cfg.g)?;
    positive("tol", cfg.tol)?;
    if !(cfg.mu_s >= cfg.mu && cfg.mu_s.is_finite()) {
        return Err(Error::parameter(
            "mu_s",
            format!("must be finite and >= mu = {}; got {}", cfg.mu, cfg.mu_s),
        ));
    }
    if !(16..=1_000_000).contains(&cfg.steps) {
        return Err(Error::parameter(
            "steps",
            format!("must be 16..=1000000 steps per period; got {}", cfg.steps),
        ));
    }
    if cfg.max_periods == 0 {
        return Err(Error::parameter("max_periods", "must be at least 1"));
    }
    check_points(points)?;
    let cycle = Cycle::new(motion, cfg.steps)?;
    let span = cycle.dt * cfg.steps as f64;
    let (slide, hold) = (cfg.mu * cfg.g * cycle.dt, cfg.mu_s * cfg.g * cycle.dt);
    let inv_g = 1.0 / cfg.g;
    Ok(points
        .par_iter()
        .with_min_len(crate::parallel::min_len())
        .map(|&p| {
            let normal: Vec<f64> = cycle.nz.iter().map(|nz| cfg.g + normal_at(nz, p)).collect();
            let mut s = State {
                p,
                ..State::default()
            };
            let mut last = [f64::NAN; 2];
            let mut calm = 0;
            let mut periods = 0;
            let mut mean = [0.0; 2];
            while periods < cfg.max_periods && calm < 2 {
                let mut moved = [0.0; 2];
                for (&u, &n) in cycle.u.iter().zip(&normal) {
                    step(&mut s, u, n, inv_g, slide, hold, cycle.dt);
                    moved[0] += s.p[0] - p[0];
                    moved[1] += s.p[1] - p[1];
                    s.p = p;
                }
                mean = [moved[0] / span, moved[1] / span];
                let change = (mean[0] - last[0]).hypot(mean[1] - last[1]);
                calm = if change <= cfg.tol { calm + 1 } else { 0 };
                last = mean;
                periods += 1;
            }
            let (max_accel, lift) = cycle.extremes(p, cfg.g);
            FieldPoint {
                v: mean,
                max_accel,
                lift,
                work: periods,
                converged: calm >= 2,
            }
        })
        .collect())
}

/// The asymptotic field of `motion` at `points` from `samples` times per cycle (see the module);
/// `g` is gravity [m/s²].
pub fn asymptotic(
    motion: &PlateMotion,
    points: &[[f64; 2]],
    g: f64,
    samples: usize,
) -> Result<Vec<FieldPoint>> {
    positive("g", g)?;
    if !(16..=1_000_000).contains(&samples) {
        return Err(Error::parameter(
            "samples",
            format!("must be 16..=1000000 per period; got {samples}"),
        ));
    }
    check_points(points)?;
    let cycle = Cycle::new(motion, samples)?;
    Ok(points
        .par_iter()
        .with_min_len(crate::parallel::min_len())
        .map(|&p| {
            let [x, y] = p;
            let hodo: Vec<[f64; 2]> = cycle
                .u
                .iter()
                .map(|u| [u[0] - u[2] * y, u[1] + u[2] * x])
                .collect();
            let w: Vec<f64> = cycle
                .nz
                .iter()
                .map(|nz| (g + normal_at(nz, p)).max(0.0))
                .collect();
            let (v, iterations, converged) = median(&hodo, &w);
            let (max_accel, lift) = cycle.extremes(p, g);
            FieldPoint {
                v,
                max_accel,
                lift,
                work: iterations,
                converged,
            }
        })
        .collect())
}

/// The weighted geometric median of the closed curve sampled at equal times `h` with weights
/// `w >= 0` (Weiszfeld's iteration, Vardi and Zhang's step at a sample point), with its iteration
/// count and whether it converged. A curve on a line (a translation's hodograph) has its median
/// on the line, where the sum of `|v - h|` is piecewise linear: there the curve and the weights
/// are taken as piecewise linear in time and the weighted median of the continuous curve is found
/// by bisection, not at a sample.
pub fn median(h: &[[f64; 2]], w: &[f64]) -> ([f64; 2], usize, bool) {
    let total: f64 = w.iter().sum();
    if total <= 0.0 {
        return ([0.0; 2], 0, true); // the part never touches the plate: no friction, no field
    }
    let scale = h.iter().map(|q| q[0].hypot(q[1])).fold(0.0, f64::max);
    let mut v = [0.0; 2];
    for (q, &wi) in h.iter().zip(w) {
        v[0] += wi * q[0] / total;
        v[1] += wi * q[1] / total;
    }
    if scale == 0.0 {
        return (v, 0, true);
    }
    if let Some(dir) = line(h, scale) {
        return line_median(h, w, dir);
    }
    let tol = 1e-13 * scale;
    for it in 1..=20_000 {
        let (mut num, mut den, mut at) = ([0.0; 2], 0.0, 0.0);
        let mut pull = [0.0; 2];
        for (q, &wi) in h.iter().zip(w) {
            let (dx, dy) = (q[0] - v[0], q[1] - v[1]);
            let d = dx.hypot(dy);
            if d <= 1e-300 {
                at += wi;
                continue;
            }
            num[0] += wi * q[0] / d;
            num[1] += wi * q[1] / d;
            den += wi / d;
            pull[0] += wi * dx / d;
            pull[1] += wi * dy / d;
        }
        if den == 0.0 {
            return (v, it, true);
        }
        let t = [num[0] / den, num[1] / den];
        let next = if at > 0.0 {
            // Vardi–Zhang: stay at the sample point when its weight outweighs the others' pull.
            let r = pull[0].hypot(pull[1]);
            if r <= at {
                return (v, it, true);
            }
            let k = (at / r).min(1.0);
            [(1.0 - k) * t[0] + k * v[0], (1.0 - k) * t[1] + k * v[1]]
        } else {
            t
        };
        let change = (next[0] - v[0]).hypot(next[1] - v[1]);
        v = next;
        if change <= tol {
            return (v, it, true);
        }
    }
    (v, 20_000, false)
}

/// The unit direction of the line every sample lies on (within `1e-12 scale`), if there is one.
fn line(h: &[[f64; 2]], scale: f64) -> Option<[f64; 2]> {
    let far = h
        .iter()
        .max_by(|a, b| {
            let da = (a[0] - h[0][0]).hypot(a[1] - h[0][1]);
            let db = (b[0] - h[0][0]).hypot(b[1] - h[0][1]);
            da.total_cmp(&db)
        })
        .copied()?;
    let (dx, dy) = (far[0] - h[0][0], far[1] - h[0][1]);
    let len = dx.hypot(dy);
    if len == 0.0 {
        return Some([1.0, 0.0]);
    }
    let d = [dx / len, dy / len];
    let off = |q: &[f64; 2]| ((q[0] - h[0][0]) * d[1] - (q[1] - h[0][1]) * d[0]).abs();
    h.iter().all(|q| off(q) <= 1e-12 * scale).then_some(d)
}

/// The weighted median of a closed curve on the line through `h[0]` along `dir`, the curve and
/// the weights linear in time between samples: the point that has half the weighted time on
/// each side.
fn line_median(h: &[[f64; 2]], w: &[f64], dir: [f64; 2]) -> ([f64; 2], usize, bool) {
    let s: Vec<f64> = h
        .iter()
        .map(|q| (q[0] - h[0][0]) * dir[0] + (q[1] - h[0][1]) * dir[1])
        .collect();
    let n = s.len();
    // Weighted time with s(t) < x over the cycle, each interval [i, i + 1] exactly.
    let below = |x: f64| -> f64 {
        let mut acc = 0.0;
        for i in 0..n {
            let j = (i + 1) % n;
            let (s0, s1, w0, w1) = (s[i], s[j], w[i], w[j]);
            // Fraction of the interval where s < x, and the weight over it (linear in time).
            let (lo, hi) = if s0 == s1 {
                if s0 < x {
                    (0.0, 1.0)
                } else {
                    (0.0, 0.0)
                }
            } else {
                let c = ((x - s0) / (s1 - s0)).clamp(0.0, 1.0);
                if s1 > s0 {
                    (0.0, c)
                } else {
                    (c, 1.0)
                }
            };
            // integral of w0 + (w1 - w0) u over [lo, hi]
            acc += (hi - lo) * (w0 + 0.5 * (w1 - w0) * (lo + hi));
        }
        acc
    };
    let half = 0.5 * below(f64::INFINITY);
    let (mut a, mut b) = (
        s.iter().copied().fold(f64::INFINITY, f64::min),
        s.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    );
    let mut it = 0;
    while it < 200 && b - a > 1e-15 * (a.abs() + b.abs()).max(1e-300) {
        let mid = 0.5 * (a + b);
        if below(mid) < half {
            a = mid;
        } else {
            b = mid;
        }
        it += 1;
    }
    let x = 0.5 * (a + b);
    ([h[0][0] + x * dir[0], h[0][1] + x * dir[1]], it, true)
}
