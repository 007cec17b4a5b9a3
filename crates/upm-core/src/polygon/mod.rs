//! Convex polygon parts under uniform pressure: their geometry and the exact friction wrench of
//! any relative planar motion (docs/spec.md §11).
//!
//! A part moving over the plate with relative twist `(V, Omega)` at its centroid (its velocity
//! less the plate surface's, and its spin less the plate's) slides at `u(r) = V + Omega z x r`
//! under the point `r` from the centroid. Under uniform pressure `p = N / A` the friction force
//! and moment about the centroid are
//!
//! ```text
//! F = -mu p ∫ u/|u| dA        M = -mu p ∫ r x u/|u| dA
//! ```
//!
//! [`Polygon::wrench`] returns them divided by `mu N` (`F` dimensionless, `M` in metres). When
//! `Omega != 0` the motion is a rotation about the instantaneous centre `r0`, `u = Omega z x (r -
//! r0)`, and both integrals follow from `∫ |r - r0| dA` and `∫ (r - r0)/|r - r0| dA`, which have
//! closed forms over the triangles that fan from `r0` to each edge ([`Polygon::fan`], eight
//! edges at a time in `lanes`): no quadrature, exact to rounding. When `r0` is far from the part
//! (more than [`FAR`] times its radius, or a pure translation) the fan's triangles cancel each
//! other and the closed forms lose digits, while the integrand is nearly constant over the part:
//! Gauss–Legendre quadrature over the triangles that fan from the centroid, or the first terms of
//! its series, is then exact to rounding instead (`far`).

use crate::error::{Error, Result};

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
mod begin;
mod far;
mod four;
mod lanes;
mod limit;
mod load;
mod newton;
mod step;
mod tripod;
pub use begin::Request;
pub(crate) use begin::Solve;
pub(crate) use four::evaluate_pair;
pub use four::{Quad, EIGHT, FOUR};
pub use limit::Gauge;
pub(crate) use newton::Evals;
pub use step::{Step, Stepper};
pub use tripod::Tripod;

/// Beyond this many part radii the instantaneous centre is "far" (quadrature, see the module).
pub const FAR: f64 = 1e3;
/// Beyond this many part radii the friction under a linearly varying pressure is integrated by
/// quadrature, 6 x 6 points and beyond 5 times as far 4 x 4 ([`load`]'s closed forms lose
/// digits to cancellation there).
pub const LOADED_FAR: f64 = 20.0;

/// Relative size under which a turn between consecutive edges counts as straight (a degenerate
/// vertex).
const STRAIGHT: f64 = 1e-12;

/// A convex polygon with its vertices counter-clockwise about its centroid.
#[derive(Debug, Clone, PartialEq)]
pub struct Polygon {
    /// Vertices relative to the centroid, counter-clockwise [m].
    pub vertices: Vec<[f64; 2]>,
    /// Where the centroid is in the frame the vertices were given in [m].
    pub centroid: [f64; 2],
    /// Area [m²].
    pub area: f64,
    /// Polar second moment of area about the centroid, `∫ |r|² dA` [m⁴]: the moment of inertia
    /// is `mass * polar / area`.
    pub polar: f64,
    /// Largest distance of a vertex from the centroid [m].
    pub radius: f64,
    /// The edges in lanes, with their directions and lengths ([`lanes`]).
    lanes: Vec<lanes::Edges>,
    /// `∫ r r^T dA / A` about the centroid as `(xx, xy, yy)` [m²] ([`far`]).
    second: [f64; 3],
    /// The pressure's gradient over its mean, `k` of `p(r) = (N / A) (1 + k . r)` [1/m]
    /// ([`load`]); zero (the default) for uniform pressure.
    load: [f64; 2],
    /// Three feet the part rests on instead of its footprint ([`tripod`]), if it does.
    tripod: Option<Box<Tripod>>,
    /// The far field's quadrature points, 3 x 3, 4 x 4, 6 x 6 and 8 x 8 a triangle
    /// ([`far::rules`]), shared by the clones.
    nodes: std::sync::Arc<[far::Nodes; 4]>,
}

/// The friction of a relative twist ([`Polygon::friction_hessian`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Friction {
    /// The wrench `(Fx, Fy, M) / (mu N)` (`M` in metres).
    pub wrench: [f64; 3],
    /// The rate of work `∫ |u| dA / A` per `mu N` [m/s].
    pub work: f64,
    /// The Hessian of the rate of work in `(vx, vy, omega)` (zero unless asked for).
    pub hessian: [[f64; 3]; 3],
}

/// The fan integrals over the polygon about a point `r0` ([`Polygon::fan`]), `d = r - r0`,
/// `rho = |d|`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fan {
    /// `∫ rho dA` [m³].
    pub dist: f64,
    /// `∫ d / rho dA` [m²].
    pub unit: [f64; 2],
    /// `∫ d d^T / rho³ dA` as `(xx, xy, yy)` [m]: the curvature of the rate of work.
    pub curvature: [f64; 3],
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

impl Polygon {
    /// A polygon from its vertices in the part's frame, counter-clockwise. Refused, naming
    /// `name` (the vertices' name) and the reason: fewer than 3 vertices, non-finite coordinates, clockwise order,
    /// repeated or collinear vertices (zero area included), a non-convex outline.
    pub fn new(name: &str, vertices: &[[f64; 2]]) -> Result<Self> {
        let bad = |why: String| Err(Error::parameter(name, why));
        let n = vertices.len();
        if n < 3 {
            return bad(format!("need at least 3 points; got {n}"));
        }
        if let Some(k) = vertices
            .iter()
            .position(|v| !v[0].is_finite() || !v[1].is_finite())
        {
            return bad(format!("must be finite; point {k} is {:?}", vertices[k]));
        }
        let scale = vertices
            .iter()
            .map(|v| v[0].abs().max(v[1].abs()))
            .fold(0.0, f64::max);
        if scale == 0.0 {
            return bad("all lie at one point".into());
        }
        // shoelace area and the turn at every vertex, relative to the polygon's size
        let (mut twice, mut cx, mut cy) = (0.0, 0.0, 0.0);
        for k in 0..n {
            let (a, b) = (vertices[k], vertices[(k + 1) % n]);
            let c = cross(a, b);
            twice += c;
            cx += (a[0] + b[0]) * c;
            cy += (a[1] + b[1]) * c;
        }
        if twice <= STRAIGHT * scale * scale {
            return if twice < -STRAIGHT * scale * scale {
                bad("run clockwise; give them counter-clockwise".into())
            } else {
                bad("enclose no area (they are collinear)".into())
            };
        }
        for k in 0..n {
            let (a, b, c) = (vertices[k], vertices[(k + 1) % n], vertices[(k + 2) % n]);
            let (e, f) = (sub(b, a), sub(c, b));
            let turn = cross(e, f);
            let size = e[0].hypot(e[1]) * f[0].hypot(f[1]);
            let at = (k + 1) % n;
            if size <= STRAIGHT * scale * scale {
                return bad(format!("repeat point {at} {:?}", vertices[at]));
            }
            if turn <= STRAIGHT * size {
                return if turn < -STRAIGHT * size {
                    bad(format!(
                        "are not convex: the outline turns clockwise at point {at} {:?}",
                        vertices[at]
                    ))
                } else {
                    bad(format!(
                        "have point {at} {:?} on a straight line between its neighbours",
                        vertices[at]
                    ))
                };
            }
        }
        // a convex outline turns once: the edges' directions must not wind twice
        let mut winding = 0.0;
        for k in 0..n {
            let (a, b, c) = (vertices[k], vertices[(k + 1) % n], vertices[(k + 2) % n]);
            let (e, f) = (sub(b, a), sub(c, b));
            winding += cross(e, f).atan2(e[0] * f[0] + e[1] * f[1]);
        }
        if winding > 3.0 * std::f64::consts::PI {
            return bad("are not convex: the outline crosses itself".into());
        }
        let area = 0.5 * twice;
        let centroid = [cx / (3.0 * twice), cy / (3.0 * twice)];
        let vertices: Vec<[f64; 2]> = vertices.iter().map(|&v| sub(v, centroid)).collect();
        let mut polar = 0.0;
        for k in 0..n {
            let (a, b) = (vertices[k], vertices[(k + 1) % n]);
            let dot =
                a[0] * a[0] + a[0] * b[0] + b[0] * b[0] + a[1] * a[1] + a[1] * b[1] + b[1] * b[1];
            polar += cross(a, b) * dot / 12.0;
        }
        let radius = vertices
            .iter()
            .map(|v| v[0].hypot(v[1]))
            .fold(0.0, f64::max);
        let lanes = lanes::edges(&vertices);
        let nodes = std::sync::Arc::new(far::rules(&vertices));
        let mut second = [0.0; 3];
        for k in 0..n {
            let (a, b) = (vertices[k], vertices[(k + 1) % n]);
            let c = cross(a, b) / area;
            second[0] += c * (a[0] * a[0] + a[0] * b[0] + b[0] * b[0]) / 12.0;
            second[1] +=
                c * (2.0 * a[0] * a[1] + a[0] * b[1] + b[0] * a[1] + 2.0 * b[0] * b[1]) / 24.0;
            second[2] += c * (a[1] * a[1] + a[1] * b[1] + b[1] * b[1]) / 12.0;
        }
        Ok(Self {
            vertices,
            centroid,
            area,
            polar,
            radius,
            lanes,
            second,
            load: [0.0; 2],
            tripod: None,
            nodes,
        })
    }

    /// Rests the part on three feet, given in the frame its vertices were given in, instead of
    /// its whole footprint (three-point support, [`tripod`]); `None` restores the footprint.
    /// Refused, naming `name`: feet that are not finite, lie on one line or outside the outline,
    /// or do not surround the centroid (the part would tip).
    pub fn set_feet(&mut self, name: &str, feet: Option<[[f64; 2]; 3]>) -> Result<()> {
        self.tripod = feet
            .map(|f| Tripod::new(name, f, self.centroid, &self.vertices).map(Box::new))
            .transpose()?;
        let load = self.load;
        self.load = [0.0; 2];
        self.set_load(load)
    }

    /// The three feet the part rests on, if it does ([`Polygon::set_feet`]).
    pub fn tripod(&self) -> Option<&Tripod> {
        self.tripod.as_deref()
    }

    /// `(∫ |r - r0| dA, ∫ (r - r0)/|r - r0| dA)` over the polygon, `r0` relative to the centroid
    /// ([`Polygon::fan`]).
    pub fn moments(&self, r0: [f64; 2]) -> (f64, [f64; 2]) {
        let f = self.fan_of::<false>(r0);
        (f.dist, f.unit)
    }

    /// The integrals of [`Fan`] about `r0` (relative to the centroid): the sums over the edges
    /// of the triangles that fan from `r0` (signed: a triangle turning clockwise about `r0`
    /// counts negatively), each in closed form.
    pub fn fan(&self, r0: [f64; 2]) -> Fan {
        self.fan_of::<true>(r0)
    }

    /// [`Polygon::fan`], its curvature only if `CURVATURE` (zero otherwise).
    fn fan_of<const CURVATURE: bool>(&self, r0: [f64; 2]) -> Fan {
        lanes::fan::<CURVATURE>(self, r0)
    }

    /// The friction wrench `(Fx, Fy, M) / (mu N)` on the part sliding with relative twist
    /// `(v, omega)` at its centroid (module docs); zero at no relative motion, where friction
    /// is whatever holds the part.
    pub fn wrench(&self, v: [f64; 2], omega: f64) -> [f64; 3] {
        self.friction(v, omega).0
    }

    /// [`Polygon::wrench`] and the rate of work of friction, `∫ |u| dA / A` (per `mu N`) [m/s]:
    /// the support function of the limit set (the wrench is minus its gradient).
    pub fn friction(&self, v: [f64; 2], omega: f64) -> ([f64; 3], f64) {
        let f = self.friction_of::<false>(v, omega);
        (f.wrench, f.work)
    }

    /// [`Polygon::friction`] and the Hessian of the rate of work in `(vx, vy, omega)` (the
    /// Jacobian of minus the wrench): zero at no relative motion, where it is unbounded.
    pub fn friction_hessian(&self, v: [f64; 2], omega: f64) -> Friction {
        self.friction_of::<true>(v, omega)
    }

    /// `∫ r r^T dA / A` about the centroid, in the part's frame, as `(xx, xy, yy)` [m²].
    pub fn second_moments(&self) -> [f64; 3] {
        self.second
    }

    /// The pressure's gradient over its mean, `k` of `p(r) = (N / A) (1 + k . r)` [1/m], `r`
    /// from the centroid in the part's frame (zero: uniform pressure).
    pub fn load(&self) -> [f64; 2] {
        self.load
    }

    /// Sets the pressure's gradient [`Polygon::load`], which every friction of the polygon then
    /// takes (a part on a plate that rocks). Refused unless finite and the pressure is nowhere
    /// negative (`1 + k . r >= 0` at every vertex; on three feet, every foot pressed with the
    /// centre of pressure at `S k`, `S` the second moments over the area).
    pub fn set_load(&mut self, k: [f64; 2]) -> Result<()> {
        let q = self.centre_of_pressure(k);
        if let Some(t) = &mut self.tripod {
            crate::error::finite("load", k[0])?;
            crate::error::finite("load", k[1])?;
            t.set_centre(q)?;
            self.load = k;
            return Ok(());
        }
        let low = self
            .vertices
            .iter()
            .map(|v| 1.0 + k[0] * v[0] + k[1] * v[1])
            .fold(f64::INFINITY, f64::min);
        if !(k[0].is_finite() && k[1].is_finite() && low >= 0.0) {
            return Err(Error::parameter(
                "load",
                format!(
                    "must be finite and leave the pressure 1 + k.r >= 0 at every vertex; got \
                     {k:?} (lowest {low})"
                ),
            ));
        }
        self.load = k;
        Ok(())
    }

    /// The centre of pressure under the pressure gradient `k`, `S k` from the centroid [m].
    fn centre_of_pressure(&self, k: [f64; 2]) -> [f64; 2] {
        let [xx, xy, yy] = self.second;
        [xx * k[0] + xy * k[1], xy * k[0] + yy * k[1]]
    }

    /// `k` shortened, if need be, until the part stays flat: until the pressure is nowhere
    /// negative (a hair short of zero where it is least, so that rounding cannot leave it
    /// negative), or on three feet until every foot is pressed. A part whose load would lift
    /// an edge or a foot tips; that is not modelled, its load goes all on the rest.
    pub fn steady_load(&self, k: [f64; 2]) -> [f64; 2] {
        let f = match &self.tripod {
            Some(t) => t.steady(self.centre_of_pressure(k)),
            None => {
                let low = self
                    .vertices
                    .iter()
                    .map(|v| k[0] * v[0] + k[1] * v[1])
                    .fold(0.0, f64::min);
                if 1.0 + low < 0.0 {
                    1.0 / -low
                } else {
                    1.0
                }
            }
        };
        if f < 1.0 {
            let f = f * (1.0 - 1e-12);
            [k[0] * f, k[1] * f]
        } else {
            k
        }
    }

    fn friction_of<const HESSIAN: bool>(&self, v: [f64; 2], omega: f64) -> Friction {
        if let Some(t) = &self.tripod {
            return t.friction::<HESSIAN>(v, omega);
        }
        // squares, not hypot: the speed only decides the path (an overflow to inf means far)
        let speed2 = v[0] * v[0] + v[1] * v[1];
        if omega == 0.0 && speed2 == 0.0 {
            return Friction::default();
        }
        let loaded = self.load != [0.0; 2];
        let near = FAR * self.radius * omega;
        if omega == 0.0 || speed2 > near * near {
            if loaded {
                // (the series' first terms are for uniform pressure)
                return far::quadrature::<HESSIAN, 4>(self, v, omega);
            }
            return far::friction::<HESSIAN>(self, v, omega);
        }
        let loaded_near = LOADED_FAR * self.radius * omega;
        if loaded && speed2 > loaded_near * loaded_near {
            // the load's terms cancel `|k| |r0|` times more than the fan's own: quadrature
            // instead, its error the first terms of the series in R / |r0| it leaves out: 6 x 6
            // points, 4 x 4 beyond 5 LOADED_FAR (both meet the 8 x 8 rule to 5e-16, measured,
            // and to 2e-15 or 1e-12, tested)
            let nearer = 5.0 * loaded_near;
            if speed2 > nearer * nearer {
                return far::quadrature::<HESSIAN, 4>(self, v, omega);
            }
            return far::quadrature::<HESSIAN, 6>(self, v, omega);
        }
        let r0 = [-v[1] / omega, v[0] / omega];
        let fan = if loaded {
            // the load's terms from the fan's own pass over the edges
            let k = self.load;
            let w0 = 1.0 + k[0] * r0[0] + k[1] * r0[1];
            let (fan, l) = lanes::fan_loaded::<HESSIAN, true>(self, r0, k);
            Fan {
                dist: w0 * fan.dist + l.dist,
                unit: [w0 * fan.unit[0] + l.unit[0], w0 * fan.unit[1] + l.unit[1]],
                curvature: std::array::from_fn(|i| w0 * fan.curvature[i] + l.curvature[i]),
            }
        } else {
            self.fan_of::<HESSIAN>(r0)
        };
        self.friction_about(fan, r0, omega)
    }

    /// The friction of a rotation at `omega` about `r0` (from the centroid, within [`FAR`]
    /// radii) from the fan's integrals about `r0` (the curvature zero when no Hessian is asked
    /// for: it then gives a zero Hessian).
    fn friction_about(&self, fan: Fan, r0: [f64; 2], omega: f64) -> Friction {
        let (dist, [ux, uy]) = (fan.dist, fan.unit);
        // u/|u| = sign(omega) z x (r - r0)/|r - r0|; r x (z x d) = (r . d) z
        let s = omega.signum() / self.area;
        let wrench = [s * uy, -s * ux, -s * (dist + r0[0] * ux + r0[1] * uy)];
        // the Hessian of |u| is J^T (I - û û^T) J / |u|, J = d u / d(v, omega) = [I, z x r];
        // here I - û û^T = d d^T / rho², |u| = |omega| rho and J^T d = (d, r0 x d), so it
        // is T G T^T / (|omega| A), G = ∫ d d^T / rho³ dA, T = [I; (-r0_y, r0_x)]
        let [gxx, gxy, gyy] = fan.curvature;
        let q = 1.0 / (omega.abs() * self.area);
        let (px, py) = (-r0[1], r0[0]);
        let (g3x, g3y) = (px * gxx + py * gxy, px * gxy + py * gyy);
        let hessian = [
            [q * gxx, q * gxy, q * g3x],
            [q * gxy, q * gyy, q * g3y],
            [q * g3x, q * g3y, q * (px * g3x + py * g3y)],
        ];
        Friction {
            wrench,
            work: omega.abs() * dist / self.area,
            hessian,
        }
    }

    /// [`Polygon::wrench`] by Gauss–Legendre quadrature (8 x 8 points on each triangle fanning
    /// from the centroid): exact to rounding where `u/|u|` is nearly constant over the part.
    pub fn wrench_quadrature(&self, v: [f64; 2], omega: f64) -> [f64; 3] {
        far::quadrature::<false, 8>(self, v, omega).wrench
    }

    /// Mean distance from the centroid, `∫ |r| dA / A` [m]: the largest friction moment about
    /// the centroid is this times `mu N` (a part spinning in place). On three feet, their mean
    /// distance weighted by their shares of the load.
    pub fn mean_distance(&self) -> f64 {
        match &self.tripod {
            Some(t) => t.largest_moment(),
            None => self.moments([0.0, 0.0]).0 / self.area,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn regular(n: usize, circumradius: f64) -> Polygon {
        let v: Vec<[f64; 2]> = (0..n)
            .map(|k| {
                let a = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
                [circumradius * a.cos() + 0.3, circumradius * a.sin() - 0.2]
            })
            .collect();
        Polygon::new("part", &v).unwrap()
    }

    #[test]
    fn spinning_in_place_gives_the_closed_forms() {
        let square = Polygon::new("s", &[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]).unwrap();
        let sq = (2f64.sqrt() + (1.0 + 2f64.sqrt()).ln()) / 6.0;
        assert!((square.mean_distance() - sq).abs() < 1e-15);
        assert!((sq - 0.382598).abs() < 1e-6);
        let w = square.wrench([0.0, 0.0], 3.0);
        assert!(w[0].abs() < 1e-15 && w[1].abs() < 1e-15 && (w[2] + sq).abs() < 1e-15);
        let s3 = 3f64.sqrt();
        let tri = Polygon::new("t", &[[0.0, 0.0], [1.0, 0.0], [0.5, s3 / 2.0]]).unwrap();
        let t = (2.0 * s3 + (2.0 + s3).ln()) / 18.0;
        assert!((tri.mean_distance() - t).abs() < 1e-15 && (t - 0.265614).abs() < 1e-6);
        // regular n-gon of inradius h: (h/3)(sec f + ln(sec f + tan f)/tan f), f = pi/n
        for n in [5, 6, 8, 64] {
            let p = regular(n, 0.02);
            let f = std::f64::consts::PI / n as f64;
            let h = 0.02 * f.cos();
            let want = h / 3.0 * (1.0 / f.cos() + (1.0 / f.cos() + f.tan()).ln() / f.tan());
            assert!((p.mean_distance() - want).abs() < 1e-15, "n {n}");
        }
        // many sides: the disk's 2R/3
        let p = regular(4096, 1.0);
        assert!((p.mean_distance() - 2.0 / 3.0).abs() < 1e-6);
    }

    #[test]
    fn translation_is_mu_n_against_the_motion_without_moment() {
        let p = Polygon::new("p", &[[0.0, 0.0], [0.03, 0.0], [0.04, 0.02], [0.0, 0.01]]).unwrap();
        let w = p.wrench([0.3, -0.4], 0.0);
        assert!((w[0] + 0.6).abs() < 1e-15 && (w[1] - 0.8).abs() < 1e-15 && w[2].abs() < 1e-16);
    }

    #[test]
    fn the_closed_form_and_the_quadrature_agree_where_both_hold() {
        let p = Polygon::new("p", &[[0.0, 0.0], [0.03, 0.0], [0.04, 0.02], [0.0, 0.01]]).unwrap();
        // an instantaneous centre 50 to 1000 radii away: the quadrature converges fast there
        for far in [50.0, 200.0, 999.0] {
            let omega = 2.0;
            let v = [0.0, -omega * far * p.radius];
            let (a, b) = (p.wrench(v, omega), p.wrench_quadrature(v, omega));
            for k in 0..3 {
                assert!((a[k] - b[k]).abs() < 1e-11, "far {far}: {a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn the_hessian_is_the_derivative_of_minus_the_wrench() {
        let p = Polygon::new("p", &[[0.0, 0.0], [0.03, 0.0], [0.04, 0.02], [0.0, 0.01]]).unwrap();
        let r = p.radius;
        // instantaneous centres at the centroid, inside, on a vertex's far side, outside, near
        // an edge's line, and far (the quadrature): omega = 3, r0 = (-vy, vx) / omega
        let centres = [
            [0.0, 0.0],
            [0.004, -0.002],
            [0.3 * r, 0.2 * r],
            [1.7 * r, -0.4 * r],
            [-0.5 * r, 3.0 * r],
            [1e-3 * r, -0.0101 + 1e-9],
            [40.0 * r, -20.0 * r],
            [1500.0 * r, 700.0 * r],
        ];
        for (i, c) in centres.iter().enumerate() {
            let omega = if i % 2 == 0 { 3.0 } else { -2.0 };
            let x = [omega * c[1], -omega * c[0], omega];
            let got = p.friction_hessian([x[0], x[1]], x[2]);
            assert_eq!(got.wrench, p.wrench([x[0], x[1]], x[2]), "centre {i}");
            // the Hessian's size, the spin's row and column in units of the part's radius
            let sigma = [1.0, 1.0, r];
            let norm = (0..3)
                .map(|k| got.hessian[k][k] / (sigma[k] * sigma[k]))
                .fold(0.0, f64::max);
            assert!(norm > 0.0, "centre {i}");
            for j in 0..3 {
                // central differences of the (exact) wrench, each component on its own scale
                let h = 1e-6 * (x[0].hypot(x[1]) + r * x[2].abs()) / if j == 2 { r } else { 1.0 };
                let (mut up, mut down) = (x, x);
                up[j] += h;
                down[j] -= h;
                let (wu, wd) = (
                    p.wrench([up[0], up[1]], up[2]),
                    p.wrench([down[0], down[1]], down[2]),
                );
                for k in 0..3 {
                    let want = -(wu[k] - wd[k]) / (2.0 * h);
                    assert!(
                        (got.hessian[k][j] - want).abs() <= 1e-6 * norm * sigma[k] * sigma[j],
                        "centre {i}: d w{k} / d x{j}: {} vs {want}",
                        got.hessian[k][j]
                    );
                }
            }
        }
    }

    #[test]
    fn bad_outlines_are_refused_with_the_reason() {
        let msg = |v: &[[f64; 2]]| {
            Polygon::new("parts[2].vertices", v)
                .unwrap_err()
                .to_string()
        };
        assert!(msg(&[[0.0, 0.0], [1.0, 0.0]]).contains("at least 3"));
        assert!(msg(&[[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]]).contains("clockwise"));
        assert!(msg(&[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]).contains("no area"));
        assert!(
            msg(&[[0.0, 0.0], [2.0, 0.0], [1.0, 0.2], [2.0, 2.0], [0.0, 2.0]])
                .contains("not convex")
        );
        assert!(msg(&[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [1.0, 1.0]]).contains("straight line"));
        assert!(msg(&[[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 1.0]]).contains("repeat point"));
        assert!(msg(&[[0.0, 0.0], [f64::NAN, 0.0], [1.0, 1.0]]).contains("must be finite; point 1"));
        // a pentagram's points in star order turn the same way at every vertex but wind twice
        let star: Vec<[f64; 2]> = (0..5)
            .map(|k| {
                let a = 4.0 * std::f64::consts::PI * k as f64 / 5.0;
                [a.cos(), a.sin()]
            })
            .collect();
        assert!(msg(&star).contains("crosses itself"));
        assert!(msg(&[[0.0, 0.0], [1.0, 0.0]]).starts_with("parts[2].vertices need"));
    }
}
