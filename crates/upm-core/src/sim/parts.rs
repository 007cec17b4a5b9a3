//! The parts a simulation starts from: owned ([`Parts`]) or borrowed ([`PartsView`], the
//! binding's zero-copy view of the caller's NumPy arrays, where friction may be one value for
//! every part and velocities, radii, angles and spins may be absent).

use super::FrictionMap;
use crate::error::{positive, Error, Result};
use crate::polygon::Polygon;

/// Parts (points and disks): initial state and friction coefficients, one entry per part.
#[derive(Debug, Clone, PartialEq)]
pub struct Parts {
    /// Positions [m].
    pub position: Vec<[f64; 2]>,
    /// Velocities [m/s].
    pub velocity: Vec<[f64; 2]>,
    /// Sliding friction coefficient.
    pub mu: Vec<f64>,
    /// Static friction coefficient, `>= mu`.
    pub mu_s: Vec<f64>,
    /// Disk radius [m]; 0 for a point part.
    pub radius: Vec<f64>,
    /// Orientation [rad] (disks; points keep 0).
    pub angle: Vec<f64>,
    /// Angular velocity [rad/s] (disks; points keep 0).
    pub spin: Vec<f64>,
    /// Polygon parts: `(part, shape)`, parts in increasing order, each with radius 0. A polygon
    /// part's position is its frame's origin (the vertices' frame), its velocity its centroid's.
    pub polygons: Vec<(usize, Polygon)>,
}

impl Parts {
    /// Point parts at `position` with `velocity`, friction `mu` and `mu_s`.
    pub fn points(
        position: Vec<[f64; 2]>,
        velocity: Vec<[f64; 2]>,
        mu: Vec<f64>,
        mu_s: Vec<f64>,
    ) -> Self {
        let m = position.len();
        Parts {
            position,
            velocity,
            mu,
            mu_s,
            radius: vec![0.0; m],
            angle: vec![0.0; m],
            spin: vec![0.0; m],
            polygons: Vec::new(),
        }
    }

    /// A borrowed view of every array.
    pub fn view(&self) -> PartsView<'_> {
        PartsView {
            position: &self.position,
            velocity: Some(&self.velocity),
            mu: &self.mu,
            mu_s: &self.mu_s,
            radius: Some(&self.radius),
            angle: Some(&self.angle),
            spin: Some(&self.spin),
            polygons: &self.polygons,
            surface: None,
        }
    }

    /// Checks lengths, finiteness, `mu_s >= mu > 0` and `radius >= 0`.
    pub fn check(&self) -> Result<()> {
        self.view().check()
    }
}

/// Borrowed parts: `mu` and `mu_s` hold one value per part or one for all; an absent velocity is
/// zero (at rest), an absent radius zero (point parts), an absent angle or spin zero.
#[derive(Debug, Clone, Copy)]
pub struct PartsView<'a> {
    /// Positions [m].
    pub position: &'a [[f64; 2]],
    /// Velocities [m/s].
    pub velocity: Option<&'a [[f64; 2]]>,
    /// Sliding friction coefficient, per part or one value.
    pub mu: &'a [f64],
    /// Static friction coefficient, `>= mu`, per part or one value.
    pub mu_s: &'a [f64],
    /// Disk radius [m]; 0 for a point part.
    pub radius: Option<&'a [f64]>,
    /// Orientation [rad].
    pub angle: Option<&'a [f64]>,
    /// Angular velocity [rad/s].
    pub spin: Option<&'a [f64]>,
    /// Polygon parts, as [`Parts::polygons`].
    pub polygons: &'a [(usize, Polygon)],
    /// The plate's friction over its surface, a factor on every part's `mu` and `mu_s` where
    /// it is (`None`: the same everywhere).
    pub surface: Option<&'a FrictionMap>,
}

/// Entry `i` of a per-part array, or its one value.
#[inline]
fn one_or(a: &[f64], i: usize) -> f64 {
    if a.len() == 1 {
        a[0]
    } else {
        a[i]
    }
}

impl PartsView<'_> {
    /// The number of parts.
    pub fn len(&self) -> usize {
        self.position.len()
    }

    /// Whether there are no parts.
    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }

    /// Part `i`'s velocity.
    #[inline]
    pub fn velocity(&self, i: usize) -> [f64; 2] {
        self.velocity.map_or([0.0; 2], |v| v[i])
    }

    /// Part `i`'s sliding friction coefficient.
    #[inline]
    pub fn mu(&self, i: usize) -> f64 {
        one_or(self.mu, i)
    }

    /// Part `i`'s static friction coefficient.
    #[inline]
    pub fn mu_s(&self, i: usize) -> f64 {
        one_or(self.mu_s, i)
    }

    /// Part `i`'s radius (0: a point).
    #[inline]
    pub fn radius(&self, i: usize) -> f64 {
        self.radius.map_or(0.0, |r| r[i])
    }

    /// Part `i`'s orientation.
    #[inline]
    pub fn angle(&self, i: usize) -> f64 {
        self.angle.map_or(0.0, |a| a[i])
    }

    /// Part `i`'s angular velocity.
    #[inline]
    pub fn spin(&self, i: usize) -> f64 {
        self.spin.map_or(0.0, |s| s[i])
    }

    /// Checks lengths, finiteness, `mu_s >= mu > 0` and `radius >= 0`: one pass over every array
    /// first, and the part-by-part search for the first offender only when it fails.
    pub fn check(&self) -> Result<()> {
        self.check_with(true)
    }

    /// [`PartsView::check`], with the finiteness of the positions and velocities left out unless
    /// `states` (the simulator checks point parts' as it reads them).
    pub(crate) fn check_with(&self, states: bool) -> Result<()> {
        let m = self.len();
        let per_part = |a: &[f64]| a.len() == m || a.len() == 1;
        let opt = |a: Option<&[f64]>| a.is_none_or(|a| a.len() == m);
        if !(per_part(self.mu)
            && per_part(self.mu_s)
            && self.velocity.is_none_or(|v| v.len() == m)
            && opt(self.radius)
            && opt(self.angle)
            && opt(self.spin))
        {
            let len = |a: Option<&[f64]>| a.map_or(m, <[f64]>::len);
            return Err(Error::Shape(format!(
                "parts: {m} positions but {:?} velocities, mu, mu_s, radius, angle, spin; all must be equal \
                 (mu and mu_s may also hold one value)",
                [
                    self.velocity.map_or(m, <[[f64; 2]]>::len),
                    self.mu.len(),
                    self.mu_s.len(),
                    len(self.radius),
                    len(self.angle),
                    len(self.spin),
                ]
            )));
        }
        let finite = |a: &[f64]| a.iter().fold(true, |ok, v| ok & v.is_finite());
        let pairs = |a: &[[f64; 2]]| {
            a.iter()
                .fold(true, |ok, v| ok & v[0].is_finite() & v[1].is_finite())
        };
        let friction = (0..self.mu.len().max(self.mu_s.len())).fold(true, |ok, i| {
            let (mu, mu_s) = (self.mu(i), self.mu_s(i));
            ok & (mu > 0.0) & mu.is_finite() & mu_s.is_finite() & (mu_s >= mu)
        });
        let fine = (!states || (pairs(self.position) && self.velocity.is_none_or(pairs)))
            && friction
            && self.radius.is_none_or(|r| {
                r.iter()
                    .fold(true, |ok, &v| ok & (v >= 0.0) & v.is_finite())
            })
            && self.angle.is_none_or(finite)
            && self.spin.is_none_or(finite);
        if !fine {
            return self.first_offender();
        }
        self.check_polygons()
    }

    /// Checks that the polygon parts name parts in increasing order and have no radius.
    fn check_polygons(&self) -> Result<()> {
        let mut last = None;
        for (i, _) in self.polygons {
            let i = *i;
            if i >= self.len() || last.is_some_and(|l| l >= i) {
                return Err(Error::parameter(
                    "polygons",
                    format!(
                        "must name parts in increasing order below {}; got part {i} after {last:?}",
                        self.len()
                    ),
                ));
            }
            if self.radius(i) != 0.0 {
                return Err(Error::parameter(
                    "radius",
                    format!(
                        "must be 0 for a polygon part; part {i} has {}",
                        self.radius(i)
                    ),
                ));
            }
            last = Some(i);
        }
        Ok(())
    }

    /// The error of the first part that fails [`PartsView::check`].
    fn first_offender(&self) -> Result<()> {
        for i in 0..self.len() {
            let at = |e: Error| e.with_context(&format!("part {i}"));
            for (name, v) in [
                ("position", self.position[i]),
                ("velocity", self.velocity(i)),
            ] {
                if !(v[0].is_finite() && v[1].is_finite()) {
                    return Err(at(Error::parameter(
                        name,
                        format!("must be finite; got ({}, {})", v[0], v[1]),
                    )));
                }
            }
            positive("mu", self.mu(i)).map_err(at)?;
            let r = self.radius(i);
            if !(r.is_finite() && r >= 0.0) {
                return Err(at(Error::parameter(
                    "radius",
                    format!("must be finite and >= 0; got {r}"),
                )));
            }
            for (name, v) in [("angle", self.angle(i)), ("spin", self.spin(i))] {
                crate::error::finite(name, v).map_err(at)?;
            }
            let (mu, mu_s) = (self.mu(i), self.mu_s(i));
            if !(mu_s.is_finite() && mu_s >= mu) {
                return Err(at(Error::parameter(
                    "mu_s",
                    format!("must be finite and >= mu = {mu}; got {mu_s}"),
                )));
            }
        }
        Ok(())
    }
}

/// What differs from world to world of a batch: world `b`'s parts take `mu` and `mu_s` from rows
/// `b * width .. (b + 1) * width`, `width` the number of parts or 1 (one value for all its parts),
/// and, when `position` is given, their start from its rows `b * m .. (b + 1) * m` (a vector of
/// environments, each with its own layout), and likewise their start angle from `angle`.
#[derive(Debug, Clone, Copy)]
pub struct WorldRows<'a> {
    /// Sliding friction, `worlds * width` values.
    pub mu: &'a [f64],
    /// Static friction, `worlds * width` values.
    pub mu_s: &'a [f64],
    /// Values per world: 1 or the number of parts.
    pub width: usize,
    /// Start positions [m], `worlds * parts` values, or `None`: every world starts as `parts`.
    pub position: Option<&'a [[f64; 2]]>,
    /// Start angles [rad], `worlds * parts` values, or `None`: every world starts as `parts`.
    pub angle: Option<&'a [f64]>,
}

impl<'a> WorldRows<'a> {
    /// Checks the lengths against `worlds` worlds of `parts` parts.
    pub fn check(&self, worlds: usize, parts: usize) -> Result<()> {
        let ok = (self.width == 1 || self.width == parts)
            && self.mu.len() == worlds * self.width
            && self.mu_s.len() == worlds * self.width;
        if let Some(p) = self.position {
            if p.len() != worlds * parts {
                return Err(Error::Shape(format!(
                    "positions per world must hold {worlds} x {parts} pairs; got {}",
                    p.len()
                )));
            }
        }
        if let Some(a) = self.angle {
            if a.len() != worlds * parts {
                return Err(Error::Shape(format!(
                    "angles per world must hold {worlds} x {parts} values; got {}",
                    a.len()
                )));
            }
        }
        if ok {
            return Ok(());
        }
        Err(Error::Shape(format!(
            "friction per world: mu and mu_s must each hold {worlds} x {parts} or {worlds} x 1 values; \
             got {} and {} ({} per world)",
            self.mu.len(),
            self.mu_s.len(),
            self.width
        )))
    }

    /// `parts` with world `b`'s friction.
    pub fn world<'p>(&self, parts: &PartsView<'p>, b: usize) -> PartsView<'p>
    where
        'a: 'p,
    {
        let r = b * self.width..(b + 1) * self.width;
        let m = parts.len();
        PartsView {
            mu: &self.mu[r.clone()],
            mu_s: &self.mu_s[r],
            position: self
                .position
                .map_or(parts.position, |p| &p[b * m..(b + 1) * m]),
            angle: self.angle.map(|a| &a[b * m..(b + 1) * m]).or(parts.angle),
            ..*parts
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_world_reads_its_own_rows_and_bad_lengths_are_refused() {
        let parts = Parts::points(
            vec![[0.0, 0.0], [0.1, 0.0]],
            vec![[0.0; 2]; 2],
            vec![0.3; 2],
            vec![0.3; 2],
        );
        let view = parts.view();
        let mu = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6];
        let mu_s = [0.2, 0.3, 0.4, 0.5, 0.6, 0.7];
        let f = WorldRows {
            mu: &mu,
            mu_s: &mu_s,
            width: 2,
            position: None,
            angle: None,
        };
        f.check(3, 2).unwrap();
        let w = f.world(&view, 2);
        assert_eq!((w.mu(0), w.mu(1), w.mu_s(1)), (0.5, 0.6, 0.7));
        assert_eq!(w.position, view.position);
        let one = WorldRows {
            mu: &mu[..3],
            mu_s: &mu_s[..3],
            width: 1,
            position: None,
            angle: None,
        };
        one.check(3, 2).unwrap();
        assert_eq!(one.world(&view, 1).mu(1), 0.2); // one value for every part of world 1
        assert!(matches!(f.check(2, 2), Err(Error::Shape(_))));
        assert!(matches!(one.check(4, 2), Err(Error::Shape(_))));
        let odd = WorldRows { width: 3, ..f };
        assert!(odd.check(2, 2).is_err());
        let turns = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6];
        let turned = WorldRows {
            angle: Some(&turns),
            ..f
        };
        turned.check(3, 2).unwrap();
        assert_eq!(turned.world(&view, 1).angle(1), 0.4);
        assert!(WorldRows {
            angle: Some(&turns[..4]),
            ..f
        }
        .check(3, 2)
        .is_err());
    }
}
