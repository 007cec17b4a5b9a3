//! The limit set of a polygon part: every friction wrench (per `mu N`) uniform pressure can give.
//!
//! Its support function is the rate of work `D(e) = ∫ |u| dA / A` of the relative twist `e`
//! ([`Polygon::friction`]), and the wrench of a sliding twist is minus the gradient of `D` there.
//! A wrench `z` can be supplied by static friction, and so holds the part, exactly when `z` lies
//! in the set, that is when its gauge `max_e <z, e> / D(e)` is at most 1 (docs/spec.md §11).
//!
//! For `z != 0` the ratio is quasi-concave where it is positive: its superlevel sets for `t > 0`
//! are the convex cones `<z, e> - t D(e) >= 0`. So a Newton ascent over the directions `e`,
//! started at `z` (where the ratio is positive) and increasing the ratio at every step, finds the
//! global maximum. The twist's spin is scaled by the part's radius so that the three components
//! weigh alike.

use super::Polygon;
use crate::error::{Error, Result};

/// The gauge of a wrench and where it is attained.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gauge {
    /// `max_e <z, e> / D(e)`: the wrench holds the part when this is at most 1; the wrench
    /// divided by it lies on the limit surface.
    pub value: f64,
    /// The relative twist `(vx, vy, omega)` [m/s, rad/s] (up to scale) whose friction is the
    /// wrench divided by the gauge: the way the part starts to slide when the wrench it needs
    /// from friction grows past the limit (the maximum is attained at minus this twist).
    pub twist: [f64; 3],
    /// Newton iterations taken.
    pub iterations: usize,
}

/// [`Polygon::ratio`] at one direction.
struct Ratio {
    value: f64,
    grad: [f64; 3],
    hess: [[f64; 3]; 3],
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let n = dot(a, a).sqrt();
    [a[0] / n, a[1] / n, a[2] / n]
}

impl Polygon {
    /// The ratio `<z, e> / D(e)` with its gradient and Hessian in the scaled coordinates (`e =
    /// (vx, vy, radius * omega)`, `z = (Fx, Fy, M / radius)`), from the exact friction and its
    /// Hessian at `e`.
    fn ratio(&self, z: [f64; 3], e: [f64; 3]) -> Ratio {
        let l = self.radius;
        let f = self.friction_hessian([e[0], e[1]], e[2] / l);
        let d = f.work;
        // D's gradient and Hessian in the scaled coordinates
        let s = [1.0, 1.0, 1.0 / l];
        let gd: [f64; 3] = std::array::from_fn(|k| -f.wrench[k] * s[k]);
        let inv = 1.0 / d;
        let value = dot(z, e) * inv;
        let grad = std::array::from_fn(|k| (z[k] - value * gd[k]) * inv);
        // d²(R = <z, e> / D) = (2 R gd gd^T - z gd^T - gd z^T) / D² - R d²D / D
        let hess = std::array::from_fn(|j| {
            std::array::from_fn(|k| {
                let hd = f.hessian[j][k] * s[j] * s[k];
                (2.0 * value * gd[j] * gd[k] - z[j] * gd[k] - gd[j] * z[k]) * inv * inv
                    - value * hd * inv
            })
        });
        Ratio { value, grad, hess }
    }

    /// The gauge of the wrench `(fx, fy, m) / (mu N)` (`m` in metres) in the limit set
    /// (module docs).
    pub fn gauge(&self, fx: f64, fy: f64, m: f64) -> Result<Gauge> {
        self.gauge_from(fx, fy, m, None)
    }

    /// [`Polygon::gauge`], the ascent started from the twist direction `start` (`(vx, vy,
    /// radius * omega)`, where the ratio is positive; a good one saves iterations) instead of
    /// from the wrench itself.
    pub fn gauge_from(&self, fx: f64, fy: f64, m: f64, start: Option<[f64; 3]>) -> Result<Gauge> {
        for (name, x) in [("force", fx), ("force", fy), ("moment", m)] {
            crate::error::finite(name, x)?;
        }
        if let Some(t) = self.tripod() {
            return t.gauge(fx, fy, m);
        }
        let l = self.radius;
        let z = [fx, fy, m / l];
        let size = dot(z, z).sqrt();
        if size == 0.0 {
            return Ok(Gauge {
                value: 0.0,
                twist: [0.0; 3],
                iterations: 0,
            });
        }
        let mut e = unit(z);
        let mut at = self.ratio(z, e);
        if let Some(s) = start.filter(|s| dot(*s, *s) > 0.0) {
            let there = self.ratio(z, unit(s));
            if there.value > at.value {
                (e, at) = (unit(s), there);
            }
        }
        for it in 0..60 {
            let (f, g) = (at.value, at.grad);
            // an orthonormal basis of the directions' tangent plane at e
            let pick = if e[0].abs() < 0.6 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            };
            let p = dot(pick, e);
            let t1 = unit([pick[0] - p * e[0], pick[1] - p * e[1], pick[2] - p * e[2]]);
            let t2 = [
                e[1] * t1[2] - e[2] * t1[1],
                e[2] * t1[0] - e[0] * t1[2],
                e[0] * t1[1] - e[1] * t1[0],
            ];
            let grad = [dot(g, t1), dot(g, t2)];
            let gnorm = grad[0].hypot(grad[1]);
            if gnorm <= 1e-13 * f.abs().max(size) {
                return Ok(self.done(f, e, it));
            }
            // the tangent Hessian: the ratio is constant along e (degree 0), so over the plane
            // e + s1 t1 + s2 t2 (each point's direction) its Hessian is T^T (d² ratio) T
            let h = at.hess;
            let ht = |t: [f64; 3]| -> [f64; 3] { std::array::from_fn(|j| dot(h[j], t)) };
            let (h1, h2) = (ht(t1), ht(t2));
            let (a, b, c) = (dot(t1, h1), 0.5 * (dot(t1, h2) + dot(t2, h1)), dot(t2, h2));
            let det = a * c - b * b;
            let mut step = if a < 0.0 && det > 0.0 {
                let step = [
                    -(c * grad[0] - b * grad[1]) / det,
                    -(a * grad[1] - b * grad[0]) / det,
                ];
                // concave: Newton's step would raise the ratio by half of grad . step; below
                // its rounding, this is the maximum to rounding (the gradient, from wrenches
                // that cancel when the centre is far, may not fall further)
                if 0.5 * (grad[0] * step[0] + grad[1] * step[1]) <= 1e-15 * f.abs() {
                    return Ok(self.done(f, e, it));
                }
                step
            } else {
                // not concave here: a gradient step of a tenth of a radian at most
                let s = (0.1 / gnorm.max(1e-300)).min(1.0 / (a.abs() + c.abs()).max(1e-300));
                [s * grad[0], s * grad[1]]
            };
            // backtrack until the ratio grows (it is quasi-concave: a longer ascent is safe)
            let mut moved = false;
            for _ in 0..40 {
                let cand = unit([
                    e[0] + step[0] * t1[0] + step[1] * t2[0],
                    e[1] + step[0] * t1[1] + step[1] * t2[1],
                    e[2] + step[0] * t1[2] + step[1] * t2[2],
                ]);
                let next = self.ratio(z, cand);
                if next.value > f {
                    (e, at, moved) = (cand, next, true);
                    break;
                }
                step = [0.5 * step[0], 0.5 * step[1]];
            }
            if !moved {
                // no direction within rounding does better: the maximum to rounding
                return Ok(self.done(at.value, e, it + 1));
            }
        }
        Err(Error::Convergence(format!(
            "the gauge of the wrench ({fx}, {fy}, {m}) did not converge in 60 Newton steps"
        )))
    }

    fn done(&self, value: f64, e: [f64; 3], iterations: usize) -> Gauge {
        Gauge {
            value,
            twist: [-e[0], -e[1], -e[2] / self.radius],
            iterations,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Result;

    fn pentagon() -> Polygon {
        Polygon::new(
            "p",
            &[
                [0.0, 0.0],
                [0.030, -0.004],
                [0.041, 0.016],
                [0.022, 0.031],
                [-0.006, 0.019],
            ],
        )
        .unwrap()
    }

    #[test]
    fn the_wrench_of_any_sliding_twist_lies_on_the_limit_surface() -> Result<()> {
        let p = pentagon();
        // uniform numbers in [-1, 1) from a 64-bit LCG
        let mut state = 9u64;
        let r: Vec<f64> = (0..120)
            .map(|_| {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                (state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
            })
            .collect();
        for k in 0..40 {
            let (v, w) = ([0.05 * r[3 * k], 0.05 * r[3 * k + 1]], 20.0 * r[3 * k + 2]);
            let z = p.wrench(v, w);
            let g = p.gauge(z[0], z[1], z[2])?;
            assert!(
                (g.value - 1.0).abs() < 1e-12,
                "twist {k}: gauge {}",
                g.value
            );
            // and it is attained at that twist (up to scale)
            let t = g.twist;
            let cos = (t[0] * v[0] + t[1] * v[1] + p.radius.powi(2) * t[2] * w)
                / ((t[0].powi(2) + t[1].powi(2) + (p.radius * t[2]).powi(2)).sqrt()
                    * (v[0].powi(2) + v[1].powi(2) + (p.radius * w).powi(2)).sqrt());
            assert!(cos > 1.0 - 1e-8, "twist {k}: {t:?} vs {v:?}, {w}");
            let inside = p.gauge(0.999 * z[0], 0.999 * z[1], 0.999 * z[2])?;
            assert!((inside.value - 0.999).abs() < 1e-12);
        }
        Ok(())
    }

    #[test]
    fn the_ratio_s_hessian_is_the_derivative_of_its_gradient() {
        let p = pentagon();
        let z = [0.3, -0.5, 0.012 / p.radius];
        // directions whose centres of rotation lie inside, near and outside the part, and a
        // nearly pure translation
        let dirs = [
            [0.2, 0.1, 0.9],
            [-0.7, 0.3, 0.4],
            [0.5, -0.8, 0.1],
            [0.9, 0.3, -0.05],
            [0.6, 0.6, 1e-3],
        ];
        let h = 1e-6;
        for e in dirs {
            let e = unit(e);
            let at = p.ratio(z, e);
            let scale = at.hess.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
            for k in 0..3 {
                let mut up = e;
                let mut down = e;
                up[k] += h;
                down[k] -= h;
                let (gu, gd) = (p.ratio(z, up).grad, p.ratio(z, down).grad);
                for j in 0..3 {
                    let want = (gu[j] - gd[j]) / (2.0 * h);
                    assert!(
                        (at.hess[j][k] - want).abs() < 1e-5 * scale,
                        "{e:?}: d²R[{j}][{k}] {} vs differences {want}",
                        at.hess[j][k]
                    );
                }
            }
        }
    }

    #[test]
    fn a_pure_moment_on_a_symmetric_part_holds_up_to_its_mean_distance() -> Result<()> {
        for p in [
            Polygon::new("sq", &[[0.0, 0.0], [0.02, 0.0], [0.02, 0.02], [0.0, 0.02]])?,
            Polygon::new(
                "hex",
                &(0..6)
                    .map(|k| {
                        let a = std::f64::consts::PI * k as f64 / 3.0;
                        [0.01 * a.cos(), 0.01 * a.sin()]
                    })
                    .collect::<Vec<_>>(),
            )?,
        ] {
            let g = p.gauge(0.0, 0.0, -p.mean_distance())?;
            assert!((g.value - 1.0).abs() < 1e-12, "{}", g.value);
            assert!(g.twist[0].abs() < 1e-9 && g.twist[1].abs() < 1e-9 && g.twist[2] > 0.0);
        }
        Ok(())
    }
}
