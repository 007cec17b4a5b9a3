//! Three-point support (Vose, Umbanhowar and Lynch, IJRR 2012): a part that rests on three feet
//! instead of its whole footprint (docs/polygons.md).
//!
//! The normal force splits over the feet `s_i` (from the centroid) so that they carry the part's
//! weight and its moment: the shares `lambda_i` are the barycentric coordinates of the centre of
//! pressure `q` in the feet's triangle (the centroid for a part on a level plate; `S k` on a
//! rocking plate, `S` the footprint's second moments over its area and `k` the pressure gradient
//! of [`Polygon::set_load`], the same split a continuous footprint takes). Per `mu N`, a relative
//! twist `(v, omega)` slides foot `i` at `u_i = v + omega J s_i` (`J` the quarter turn) and
//!
//! ```text
//! D = sum lambda_i |u_i|,   F = -sum lambda_i u_i/|u_i|,   M = -sum lambda_i s_i x u_i/|u_i|.
//! ```
//!
//! `D` has kinks where a foot is still: at no relative motion (sticking) and on the three lines
//! of twists that turn the part about one foot (pivoting). Both have exact answers here.
//!
//! - **The gauge** of a wrench `(F, M)` is `max(rho(F, M), rho(-F, -M))`, `rho` the largest
//!   `(F . v + M) / sum lambda_i |v + q_i|` over `v` (`q_i = J s_i`; the twists with `omega = 1`;
//!   those with `omega = 0` are its limit `|F|` far away). Dinkelbach's iteration finds it: each
//!   step is a weighted Fermat–Weber problem with a linear term, `min_x sum lambda_i |q_i - x| +
//!   b . x`, whose minimum is at a foot (a closed-form test) or where its gradient vanishes
//!   (Newton's method: it is smooth and strictly convex there).
//! - **Pivoting** about foot `i`: on the line `y = t p_i` the step's objective is a parabola
//!   plus `c |t| sum_{j != i} lambda_j |s_i - s_j|`, least at a soft threshold in closed form; it
//!   is the step exactly when the force foot `i` must then give is within its share `lambda_i`.

use super::{cross, sub, Friction, Gauge};
use crate::error::{Error, Result};

/// Three feet under a part and their shares of its normal force.
#[derive(Debug, Clone, PartialEq)]
pub struct Tripod {
    /// The feet relative to the centroid, in the part's frame [m].
    pub feet: [[f64; 2]; 3],
    /// Each foot's share of the normal force (summing to 1).
    pub shares: [f64; 3],
    /// `shares = level + slope . q` for the centre of pressure `q`.
    level: [f64; 3],
    slope: [[f64; 2]; 3],
}

/// Relative size of the last Newton step of a Fermat–Weber solve.
const TOLERANCE: f64 = 1e-14;

impl Tripod {
    /// Feet `feet` in the frame the polygon's vertices were given in, whose centroid is
    /// `centroid` there and whose outline about the centroid is `outline`. Refused, naming
    /// `name`: non-finite, on one line, outside the outline, or not around the centroid (the
    /// part would tip).
    pub fn new(
        name: &str,
        feet: [[f64; 2]; 3],
        centroid: [f64; 2],
        outline: &[[f64; 2]],
    ) -> Result<Self> {
        let bad = |why: String| Err(Error::parameter(name, why));
        if feet.iter().flatten().any(|x| !x.is_finite()) {
            return bad(format!("must be finite; got {feet:?}"));
        }
        let feet = feet.map(|f| sub(f, centroid));
        let scale = outline.iter().map(|v| v[0].hypot(v[1])).fold(0.0, f64::max);
        let twice = cross(sub(feet[1], feet[0]), sub(feet[2], feet[0]));
        if twice.abs() <= 1e-9 * scale * scale {
            return bad("lie on one line: three feet must span a triangle".into());
        }
        let k = outline.len();
        for (i, f) in feet.iter().enumerate() {
            let outside = (0..k).any(|e| {
                let (a, b) = (outline[e], outline[(e + 1) % k]);
                cross(sub(b, a), sub(*f, a)) < -1e-12 * scale * scale
            });
            if outside {
                return bad(format!("foot {i} lies outside the part's outline"));
            }
        }
        // barycentric coordinates: cross(b - q, c - q) / twice = cross(b, c)/twice + n . q
        let mut level = [0.0; 3];
        let mut slope = [[0.0; 2]; 3];
        for i in 0..3 {
            let (b, c) = (feet[(i + 1) % 3], feet[(i + 2) % 3]);
            let e = sub(c, b);
            level[i] = cross(b, c) / twice;
            slope[i] = [-e[1] / twice, e[0] / twice];
        }
        if level.iter().any(|&l| l <= 0.0) {
            return bad(
                "must surround the centroid: a part whose centroid lies outside its feet's \
                 triangle tips over"
                    .into(),
            );
        }
        Ok(Tripod {
            feet,
            shares: level,
            level,
            slope,
        })
    }

    /// The shares of the normal force with the centre of pressure at `q` (from the centroid).
    pub fn shares_at(&self, q: [f64; 2]) -> [f64; 3] {
        std::array::from_fn(|i| self.level[i] + self.slope[i][0] * q[0] + self.slope[i][1] * q[1])
    }

    /// Moves the centre of pressure to `q`; refused if a foot would pull (a negative share).
    pub fn set_centre(&mut self, q: [f64; 2]) -> Result<()> {
        let s = self.shares_at(q);
        if !(s.iter().all(|x| x.is_finite() && *x >= 0.0)) {
            return Err(Error::parameter(
                "load",
                format!(
                    "must leave every foot pressed; the centre of pressure {q:?} gives the \
                     shares {s:?}"
                ),
            ));
        }
        self.shares = s;
        Ok(())
    }

    /// The largest `f` in `[0, 1]` for which the centre of pressure `f q` leaves no foot pulling.
    pub fn steady(&self, q: [f64; 2]) -> f64 {
        let mut f: f64 = 1.0;
        for i in 0..3 {
            let d = self.slope[i][0] * q[0] + self.slope[i][1] * q[1];
            if self.level[i] + d < 0.0 {
                f = f.min(self.level[i] / -d);
            }
        }
        f
    }

    /// `q_i = J s_i`: the feet turned a quarter, where `r x f = (J r) . f`.
    fn turned(&self) -> [[f64; 2]; 3] {
        self.feet.map(|s| [-s[1], s[0]])
    }

    /// The friction of the relative twist `(v, omega)` per `mu N` and, if `HESSIAN`, the
    /// Hessian of its rate of work (module docs); a still foot adds nothing (a kink of `D`).
    pub fn friction<const HESSIAN: bool>(&self, v: [f64; 2], omega: f64) -> Friction {
        let mut out = Friction::default();
        for (s, &l) in self.feet.iter().zip(&self.shares) {
            let u = [v[0] - omega * s[1], v[1] + omega * s[0]];
            let n = u[0].hypot(u[1]);
            if n == 0.0 || l == 0.0 {
                continue;
            }
            let h = [u[0] / n, u[1] / n];
            out.work += l * n;
            out.wrench[0] -= l * h[0];
            out.wrench[1] -= l * h[1];
            out.wrench[2] -= l * cross(*s, h);
            if HESSIAN {
                // J^T (I - h h^T) J l / |u|, J = [I, J s]: (I - h h^T) = g g^T with g = J h,
                // and (J s) . (J h) = s . h
                let g = [-h[1], h[0]];
                let row = [g[0], g[1], s[0] * h[0] + s[1] * h[1]];
                let a = l / n;
                for (r, hr) in out.hessian.iter_mut().enumerate() {
                    for (c, hc) in hr.iter_mut().enumerate() {
                        *hc += a * row[r] * row[c];
                    }
                }
            }
        }
        out
    }

    /// The largest moment per `mu N`: spinning about the centroid, `sum lambda_i |s_i|`.
    pub fn largest_moment(&self) -> f64 {
        (0..3)
            .map(|i| self.shares[i] * self.feet[i][0].hypot(self.feet[i][1]))
            .sum()
    }

    /// `min_x sum lambda_i |q_i - x| + b . x` (`|b| < 1`) and where it is: at a foot `q_i` when
    /// the other terms' pull there is within `lambda_i`, else by Newton's method.
    fn weber(&self, b: [f64; 2]) -> Result<(f64, [f64; 2])> {
        let q = self.turned();
        let l = self.shares;
        let value = |x: [f64; 2]| -> f64 {
            (0..3)
                .map(|i| l[i] * (q[i][0] - x[0]).hypot(q[i][1] - x[1]))
                .sum::<f64>()
                + b[0] * x[0]
                + b[1] * x[1]
        };
        // gradient and Hessian away from the feet (a foot the iterate sits on adds nothing)
        let slope = |x: [f64; 2]| {
            let mut g = b;
            let mut h = [0.0; 3];
            for i in 0..3 {
                let d = sub(x, q[i]);
                let n = d[0].hypot(d[1]);
                if n == 0.0 || l[i] == 0.0 {
                    continue;
                }
                g[0] += l[i] * d[0] / n;
                g[1] += l[i] * d[1] / n;
                let a = l[i] / (n * n * n);
                h[0] += a * d[1] * d[1];
                h[1] -= a * d[0] * d[1];
                h[2] += a * d[0] * d[0];
            }
            (g, h)
        };
        let scale = q.iter().map(|p| p[0].hypot(p[1])).fold(0.0, f64::max);
        // the start: the lowest of the centre of pressure's turn and each foot moved down its
        // steepest descent (the vertex test failed there: the pull beats the foot's share)
        let mut x = [0.0; 2];
        for i in 0..3 {
            x[0] += l[i] * q[i][0];
            x[1] += l[i] * q[i][1];
        }
        let mut at = value(x);
        for i in 0..3 {
            let mut g = b;
            let mut near = f64::INFINITY;
            for j in (0..3).filter(|&j| j != i) {
                let d = sub(q[i], q[j]);
                let n = d[0].hypot(d[1]);
                near = near.min(n);
                g[0] += l[j] * d[0] / n;
                g[1] += l[j] * d[1] / n;
            }
            let n = g[0].hypot(g[1]);
            if n <= l[i] {
                return Ok((value(q[i]), q[i]));
            }
            let t = 0.25 * near / n;
            let y = [q[i][0] - t * g[0], q[i][1] - t * g[1]];
            let v = value(y);
            if v < at {
                (x, at) = (y, v);
            }
        }
        // Newton's method, halving; where it cannot fall (near a foot, where the curvature is
        // huge across), steepest descent
        for _ in 0..200 {
            let (g, h) = slope(x);
            let det = h[0] * h[2] - h[1] * h[1];
            let newton = (det > 0.0 && det.is_finite()).then(|| {
                [
                    -(h[2] * g[0] - h[1] * g[1]) / det,
                    -(h[0] * g[1] - h[1] * g[0]) / det,
                ]
            });
            if let Some(step) = newton {
                if step[0].hypot(step[1]) <= TOLERANCE * (x[0].hypot(x[1]) + scale) {
                    return Ok((at, x));
                }
            }
            let steepest = [-g[0] * scale, -g[1] * scale];
            let mut moved = false;
            for (mut step, tries) in newton.into_iter().map(|s| (s, 12)).chain([(steepest, 60)]) {
                let fall = g[0] * step[0] + g[1] * step[1];
                for _ in 0..tries {
                    let next = [x[0] + step[0], x[1] + step[1]];
                    let v = value(next);
                    if v < at && v <= at + 1e-4 * fall {
                        (x, at, moved) = (next, v, true);
                        break;
                    }
                    step = [0.5 * step[0], 0.5 * step[1]];
                }
                if moved {
                    break;
                }
            }
            if !moved {
                return Ok((at, x)); // no step lowers W within rounding: its minimum
            }
        }
        Err(Error::Convergence(format!(
            "the Fermat-Weber problem of a three-point support with pull {b:?} did not converge"
        )))
    }

    /// `rho(F, M)` of the module docs and the `v` that attains it (None: `|F|`, far away).
    ///
    /// `D(v) >= |v + qbar|` (`qbar = sum lambda_i q_i`, the centre of pressure turned), so the
    /// ratio is at most `|F| + (M - F . qbar) / |v + qbar|`: when `M <= F . qbar` the supremum is
    /// `|F|`, approached as `|v|` grows. Otherwise along `v = R F/|F| - qbar` the ratio is `|F| +
    /// (M - F . qbar) / R + O(1/R²)`, above `|F|` for `R` large enough; from the best such point
    /// Dinkelbach's iteration climbs, each Fermat–Weber problem bounded (`|F| / rho < 1`).
    fn ratio(&self, force: [f64; 2], moment: f64) -> Result<(f64, Option<[f64; 2]>)> {
        let q = self.turned();
        let l = self.shares;
        let d = |v: [f64; 2]| -> f64 {
            (0..3)
                .map(|i| l[i] * (v[0] + q[i][0]).hypot(v[1] + q[i][1]))
                .sum()
        };
        let bar = [
            (0..3).map(|i| l[i] * q[i][0]).sum::<f64>(),
            (0..3).map(|i| l[i] * q[i][1]).sum::<f64>(),
        ];
        let pull = force[0].hypot(force[1]);
        let excess = moment - (force[0] * bar[0] + force[1] * bar[1]);
        if excess <= 0.0 {
            return Ok((pull, None));
        }
        let n = |v: [f64; 2]| force[0] * v[0] + force[1] * v[1] + moment;
        // a start above |F|: the centroid's turn, then out along F
        let mut best = ([0.0; 2], n([0.0; 2]) / d([0.0; 2]));
        if pull > 0.0 {
            let scale = q.iter().map(|p| p[0].hypot(p[1])).fold(0.0, f64::max);
            let mut r = scale;
            for _ in 0..48 {
                let v = [r * force[0] / pull - bar[0], r * force[1] / pull - bar[1]];
                let x = n(v) / d(v);
                if x > best.1 {
                    best = (v, x);
                }
                r *= 2.0;
            }
        }
        let (mut v, mut g) = best;
        if g <= pull {
            // (the excess is lost to rounding: the supremum is |F| to that rounding)
            return Ok((pull, None));
        }
        for _ in 0..100 {
            // min_v g D(v) - F.v - M = g min_x [sum lambda_i |q_i - x| + F.x / g] - M, x = -v
            let (w, x) = self.weber([force[0] / g, force[1] / g])?;
            let next_v = [-x[0], -x[1]];
            let next = n(next_v) / d(next_v);
            if g * w - moment >= -1e-15 * (g * w).abs().max(moment.abs()) || next <= g {
                // (the last minimiser is the argmax to the solve's accuracy; v only to its root)
                return Ok(if next >= g {
                    (next, Some(next_v))
                } else {
                    (g, Some(v))
                });
            }
            (v, g) = (next_v, next);
        }
        Err(Error::Convergence(format!(
            "the gauge of ({force:?}, {moment}) on a three-point support did not converge"
        )))
    }

    /// The gauge of the wrench `(fx, fy, m)` per `mu N` in the limit set and the twist the part
    /// starts to slide with ([`Gauge`]).
    pub fn gauge(&self, fx: f64, fy: f64, m: f64) -> Result<Gauge> {
        let (up, at_up) = self.ratio([fx, fy], m)?;
        let (down, at_down) = self.ratio([-fx, -fy], -m)?;
        // the maximum is at e = (v, 1), or (-v, -1) for the other sign; the twist is -e
        let (value, e) = if up >= down {
            (up, at_up.map(|v| [v[0], v[1], 1.0]))
        } else {
            (down, at_down.map(|v| [-v[0], -v[1], -1.0]))
        };
        let n = fx.hypot(fy);
        let e = e.unwrap_or(if n > 0.0 {
            [fx / n, fy / n, 0.0]
        } else {
            [0.0; 3]
        });
        Ok(Gauge {
            value,
            twist: [-e[0], -e[1], -e[2]],
            iterations: 0,
        })
    }

    /// The step's minimiser when it pivots about a foot (`Ok`), or else a start for the sliding
    /// solve near the pivot that came closest (`Err`, None when no pivot moves): the scaled twist
    /// `y = (vx, vy, k omega)` minimising `|y - target|² / 2 + c D` (module docs; `k` the radius
    /// of gyration). A part that nearly pivots slides with that foot slipping a little, against
    /// the force the foot could not give; Newton's method started on the pivot's line would
    /// have to leave a kink.
    pub fn pivot(
        &self,
        target: [f64; 3],
        c: f64,
        k: f64,
    ) -> std::result::Result<[f64; 3], Option<[f64; 3]>> {
        let s = self.feet;
        let l = self.shares;
        let mut near: Option<(f64, [f64; 3])> = None;
        for i in 0..3 {
            if l[i] == 0.0 {
                continue;
            }
            let p = [s[i][1], -s[i][0], k];
            let others: f64 = (0..3)
                .filter(|&j| j != i)
                .map(|j| l[j] * (s[i][0] - s[j][0]).hypot(s[i][1] - s[j][1]))
                .sum();
            let a = p[0] * target[0] + p[1] * target[1] + p[2] * target[2];
            let room = a.abs() - c * others;
            if room <= 0.0 {
                continue;
            }
            let t = a.signum() * room / (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
            let y = [t * p[0], t * p[1], t * p[2]];
            // the gradient of the smooth part; foot i must cancel its force components
            let mut g = [y[0] - target[0], y[1] - target[1]];
            for j in (0..3).filter(|&j| j != i) {
                let u = [t * (s[i][1] - s[j][1]), t * (s[j][0] - s[i][0])];
                let n = u[0].hypot(u[1]);
                g[0] += c * l[j] * u[0] / n;
                g[1] += c * l[j] * u[1] / n;
            }
            let pull = g[0].hypot(g[1]);
            let excess = pull - c * l[i];
            if excess <= 0.0 {
                return Ok(y);
            }
            // slipping: foot i moves by about the excess against the pull (a translation)
            let ratio = excess / (c * l[i]);
            if near.is_none_or(|(r, _)| ratio < r) {
                let f = excess / pull;
                near = Some((ratio, [y[0] - f * g[0], y[1] - f * g[1], y[2]]));
            }
        }
        Err(near.map(|n| n.1))
    }
}
