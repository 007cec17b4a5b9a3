//! The contacts' settings and the parts' start checked: coefficients in range, finite walls, and
//! no part overlapping another or a wall ([`Contacts::check`], [`Contacts::prepare`]); the
//! closest pair and wall gaps that [`super::ContactWorld`] also uses to skip rapier's step.

use rapier2d_f64::parry;
use rapier2d_f64::prelude::*;

use super::{convex, Contacts};
use crate::error::{Error, Result};
use crate::polygon::Polygon;
use crate::sim::PartsView;

/// A polygon part for the start-up check: centroid [m], angle [rad], shape, index among all parts.
pub(super) type PolygonAt<'a> = ([f64; 2], f64, &'a Polygon, usize);

/// Distance from `p` to the segment `[a, b]`.
fn segment_distance(p: [f64; 2], [a, b]: [[f64; 2]; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
}

impl Contacts {
    /// Checks the settings against the disks (`(position, radius)` of every disk, with its index
    /// among all parts): coefficients in range, finite walls, and no disk overlapping another or
    /// a wall at the start.
    pub fn check(&self, disks: &[([f64; 2], f64, usize)], parts: usize) -> Result<()> {
        self.check_with(disks, &[], parts)
    }

    /// Checks the settings and the parts' start (as [`Contacts::check_with`]) and returns the
    /// mass of every disk (`disks`: their indices among `parts`) and then of every polygon: the
    /// given ones, or by default proportional to the area (`r²` for a disk, `area / pi` for a
    /// polygon: equal thickness and density).
    pub(in crate::sim) fn prepare(&self, parts: &PartsView, disks: &[usize]) -> Result<Vec<f64>> {
        let round: Vec<_> = disks
            .iter()
            .map(|&i| (parts.position[i], parts.radius(i), i))
            .collect();
        let polygons: Vec<PolygonAt> = parts
            .polygons
            .iter()
            .map(|(i, shape)| {
                let (p, a) = (parts.position[*i], parts.angle(*i));
                let (c, s) = (a.cos(), a.sin());
                let o = shape.centroid;
                (
                    [p[0] + c * o[0] - s * o[1], p[1] + s * o[0] + c * o[1]],
                    a,
                    shape,
                    *i,
                )
            })
            .collect();
        self.check_with(&round, &polygons, parts.len())?;
        let default = |i: usize, area: f64| self.mass.as_ref().map_or(area, |m| m[i]);
        Ok(disks
            .iter()
            .map(|&i| default(i, parts.radius(i) * parts.radius(i)))
            .chain(
                parts
                    .polygons
                    .iter()
                    .map(|(i, shape)| default(*i, shape.area / std::f64::consts::PI)),
            )
            .collect())
    }

    /// [`Contacts::check`] with polygon parts too: none may overlap a disk, another polygon or a
    /// wall at the start (parry's contact queries, where bounding circles meet).
    pub(in crate::sim) fn check_with(
        &self,
        disks: &[([f64; 2], f64, usize)],
        polygons: &[PolygonAt],
        parts: usize,
    ) -> Result<()> {
        if !(self.restitution.is_finite() && (0.0..=1.0).contains(&self.restitution)) {
            return Err(Error::parameter(
                "restitution",
                format!("must be in [0, 1]; got {}", self.restitution),
            ));
        }
        if !(self.part_friction.is_finite() && self.part_friction >= 0.0) {
            return Err(Error::parameter(
                "part_friction",
                format!("must be finite and >= 0; got {}", self.part_friction),
            ));
        }
        if self.iterations == 0 || self.iterations > 1000 {
            return Err(Error::parameter(
                "contact_iterations",
                format!("must be in [1, 1000]; got {}", self.iterations),
            ));
        }
        for (k, w) in self.walls.iter().enumerate() {
            if !w.iter().flatten().all(|x| x.is_finite()) {
                return Err(Error::parameter(
                    "walls",
                    format!("must be finite; wall {k} is {w:?}"),
                ));
            }
            if w[0] == w[1] {
                return Err(Error::parameter(
                    "walls",
                    format!("wall {k} has zero length (both ends at {:?})", w[0]),
                ));
            }
        }
        if let Some(mass) = &self.mass {
            if mass.len() != parts {
                return Err(Error::Shape(format!(
                    "mass must have one entry per part ({parts}); got {}",
                    mass.len()
                )));
            }
            let with_mass = disks
                .iter()
                .map(|d| d.2)
                .chain(polygons.iter().map(|p| p.3));
            for i in with_mass {
                if !(mass[i].is_finite() && mass[i] > 0.0) {
                    return Err(Error::parameter(
                        "mass",
                        format!("must be finite and > 0; got {} for part {i}", mass[i]),
                    ));
                }
            }
        }
        let centres: Vec<([f64; 2], f64)> = disks.iter().map(|&(p, r, _)| (p, r)).collect();
        if let Some((gap, a, b)) = closest_pair(&centres) {
            let (ra, rb) = (centres[a].1, centres[b].1);
            if gap < -1e-9 * (ra + rb) {
                let (i, j) = (disks[a].2.min(disks[b].2), disks[a].2.max(disks[b].2));
                return Err(Error::parameter(
                    "parts",
                    format!(
                        "disks {i} and {j} overlap by {:.6e} m at the start; contacts need \
                         separated disks",
                        -gap
                    ),
                ));
            }
        }
        self.check_polygons(disks, polygons)?;
        for &(p, r, i) in disks {
            if let Some((gap, k)) = wall_gap(p, r, &self.walls) {
                if gap < -1e-9 * r {
                    return Err(Error::parameter(
                        "walls",
                        format!(
                            "wall {k} cuts disk {i} by {:.6e} m at the start; move the disk or \
                             the wall",
                            -gap
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}

impl Contacts {
    /// The polygons against the disks, each other and the walls (see [`Contacts::check_with`]).
    fn check_polygons(
        &self,
        disks: &[([f64; 2], f64, usize)],
        polygons: &[PolygonAt],
    ) -> Result<()> {
        use parry::shape::{Ball, Segment, Shape};
        let pose = |c: [f64; 2], angle: f64| parry::math::Pose::new(Vector::new(c[0], c[1]), angle);
        let overlap =
            |a: (parry::math::Pose, &dyn Shape), b: (parry::math::Pose, &dyn Shape), size: f64| {
                parry::query::contact(&a.0, a.1, &b.0, b.1, 0.0)
                    .ok()
                    .flatten()
                    .map(|c| -c.dist)
                    .filter(|&depth| depth > 1e-9 * size)
            };
        let shapes: Vec<_> = polygons
            .iter()
            .map(|&(c, angle, shape, i)| (pose(c, angle), convex(shape, 1.0), shape.radius, c, i))
            .collect();
        let fail = |what: String, depth: f64| {
            Err(Error::parameter(
                "parts",
                format!(
                    "{what} overlap by {depth:.6e} m at the start; contacts need separated parts"
                ),
            ))
        };
        for (n, (pa, sa, ra, ca, i)) in shapes.iter().enumerate() {
            let Some(sa) = sa else { continue };
            for (pb, sb, rb, cb, j) in &shapes[n + 1..] {
                let Some(sb) = sb else { continue };
                if (ca[0] - cb[0]).hypot(ca[1] - cb[1]) < ra + rb {
                    if let Some(depth) = overlap((*pa, sa), (*pb, sb), ra + rb) {
                        return fail(format!("polygons {i} and {j}"), depth);
                    }
                }
            }
            for &(p, r, j) in disks {
                if (ca[0] - p[0]).hypot(ca[1] - p[1]) < ra + r {
                    let ball = Ball::new(r);
                    if let Some(depth) = overlap((*pa, sa), (pose(p, 0.0), &ball), ra + r) {
                        return fail(format!("polygon {i} and disk {j}"), depth);
                    }
                }
            }
            for (k, &[a, b]) in self.walls.iter().enumerate() {
                if segment_distance(*ca, [a, b]) < *ra {
                    let seg = Segment::new(Vector::new(a[0], a[1]), Vector::new(b[0], b[1]));
                    if let Some(depth) = overlap((*pa, sa), (pose([0.0; 2], 0.0), &seg), *ra) {
                        return fail(format!("wall {k} and polygon {i}"), depth);
                    }
                }
            }
        }
        Ok(())
    }
}

/// The closest two of `disks` (`(position, radius)`): `(rim-to-rim gap [m], i, j)` with `i`, `j`
/// their indices, by a sweep along x that skips pairs farther apart in x than the best gap so
/// far; `None` for fewer than two.
pub(super) fn closest_pair(disks: &[([f64; 2], f64)]) -> Option<(f64, usize, usize)> {
    let mut order: Vec<usize> = (0..disks.len()).collect();
    order.sort_by(|&a, &b| (disks[a].0[0] - disks[a].1).total_cmp(&(disks[b].0[0] - disks[b].1)));
    let mut best: Option<(f64, usize, usize)> = None;
    for (n, &a) in order.iter().enumerate() {
        let (pa, ra) = disks[a];
        for &b in &order[n + 1..] {
            let (pb, rb) = disks[b];
            let bound = best.map_or(f64::INFINITY, |(g, _, _)| g);
            if pb[0] - rb - (pa[0] + ra) >= bound {
                break;
            }
            let gap = (pa[0] - pb[0]).hypot(pa[1] - pb[1]) - ra - rb;
            if gap < bound {
                best = Some((gap, a, b));
            }
        }
    }
    best
}

/// The nearest of `walls` to a disk at `p` of radius `r`: `(rim-to-wall gap [m], wall index)`.
pub(super) fn wall_gap(p: [f64; 2], r: f64, walls: &[[[f64; 2]; 2]]) -> Option<(f64, usize)> {
    walls
        .iter()
        .enumerate()
        .map(|(k, &w)| (segment_distance(p, w) - r, k))
        .min_by(|a, b| a.0.total_cmp(&b.0))
}
