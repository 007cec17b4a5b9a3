//! The friction of four polygon parts at once, one in each lane ([`Quad`]): the fan integrals
//! ([`super::Polygon::fan`]) about each lane's centre of rotation, the edges taken one after
//! another, each vertex's distance and its reciprocal computed once for the two edges that meet
//! there; then the wrench and Hessian, and for a sliding solve `Phi` and its Newton step
//! ([`Quad::evaluate`], [`super::newton::Eval`]). The integrator steps eight parts of a planar
//! plate this way, in two quads (their sliding solves side by side, `sim::polygons`,
//! [`evaluate_pair`]: one vector of eight on AVX-512, `super::avx512`), and
//! [`super::Stepper::step`] takes its solve from a guess in a lane of its own.
//!
//! A lane's arithmetic does not depend on the other lanes (a lane with fewer edges adds nothing
//! for the others': its sums are left as they are), and the AVX-512 and AVX2 builds
//! ([`super::avx2::evals_four`]) and the portable one ([`fan_lane`], [`friction_lane`],
//! [`Eval::of`]) compute the same bits (no fused multiply–adds, the edges summed in order): a
//! part's step is the same whatever parts share its lanes, and whichever build takes it. The
//! fan's terms are [`super::lanes`]'s, summed in another order: they agree with
//! [`super::Polygon::friction_hessian`] to rounding, not to the bit.

use super::lanes::{ln_1p, log_arg};
use super::newton::{Eval, Evals};
use super::{Fan, Friction, Polygon, FAR};
#[cfg(target_arch = "x86_64")]
use crate::simd::{simd, Simd};

/// Parts in lanes.
pub const FOUR: usize = 4;

/// Parts in the lanes of two quads ([`evaluate_pair`]).
pub const EIGHT: usize = 2 * FOUR;

/// What a sliding solve asks about ([`super::Solve::asked`]): the friction at `twist`, and
/// `Phi` at the scaled twist `y` toward `target` with `c` and `1 / k` ([`Eval::of`]).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Asked {
    pub(crate) twist: [f64; 3],
    pub(crate) y: [f64; 3],
    pub(crate) target: [f64; 3],
    pub(crate) c: f64,
    pub(crate) kinv: f64,
}

/// One sixth (a product with it costs less than a division by 6).
pub(super) const SIXTH: f64 = 1.0 / 6.0;

/// Up to four polygons' outlines in lanes: vertex `j` of lane `l` at `(x[j][l], y[j][l])` about
/// its centroid, edge `k` from vertex `k` to vertex `k + 1` along `(ex, ey)[k][l]` for
/// `len[k][l]`. A lane with fewer edges than the most (or no polygon) repeats its vertex 0 past
/// its own and its edges there are not `live`.
#[derive(Debug, Clone)]
pub struct Quad {
    pub(super) x: Vec<[f64; FOUR]>,
    pub(super) y: Vec<[f64; FOUR]>,
    pub(super) ex: Vec<[f64; FOUR]>,
    pub(super) ey: Vec<[f64; FOUR]>,
    pub(super) len: Vec<[f64; FOUR]>,
    /// Lane masks (all ones where edge `k` of lane `l` is one of its polygon's).
    pub(super) live: Vec<[u64; FOUR]>,
    /// The reciprocal of each lane's area (1 in a lane with no polygon).
    pub(super) inv_area: [f64; FOUR],
    /// Each edge's `ex², ey², ex ey, 2 ex ey, ey² - ex²` in lanes: the products of its direction
    /// and its normal `(ey, -ex)` that the curvature takes.
    pub(super) squares: Vec<[[f64; FOUR]; 5]>,
}

impl Quad {
    /// Room for polygons of up to `edges` edges, no lane holding one.
    pub fn new(edges: usize) -> Self {
        Quad {
            x: vec![[1.0; FOUR]; edges + 1],
            y: vec![[0.0; FOUR]; edges + 1],
            ex: vec![[1.0; FOUR]; edges],
            ey: vec![[0.0; FOUR]; edges],
            len: vec![[0.0; FOUR]; edges],
            live: vec![[0; FOUR]; edges],
            inv_area: [1.0; FOUR],
            squares: vec![
                [
                    [1.0; FOUR],
                    [0.0; FOUR],
                    [0.0; FOUR],
                    [0.0; FOUR],
                    [-1.0; FOUR]
                ];
                edges
            ],
        }
    }

    /// The outlines of `shapes` (lane `l` holds `shapes[l]`, if any).
    pub fn of(shapes: [Option<&Polygon>; FOUR]) -> Self {
        let edges = shapes.iter().map(|s| s.map_or(0, |p| p.vertices.len()));
        let mut q = Quad::new(edges.max().unwrap_or(0));
        for (l, p) in shapes.into_iter().enumerate() {
            q.set(l, p);
        }
        q
    }

    /// Puts `shape` (if any) in lane `l`, making room for its edges.
    pub fn set(&mut self, l: usize, shape: Option<&Polygon>) {
        self.grow(shape.map_or(0, |p| p.vertices.len()));
        let edges = self.edges();
        let Some(p) = shape else {
            for j in 0..=edges {
                (self.x[j][l], self.y[j][l]) = (1.0, 0.0);
            }
            for k in 0..edges {
                self.edge(k, l, [1.0, 0.0, 0.0], false);
            }
            self.inv_area[l] = 1.0;
            return;
        };
        let v = &p.vertices;
        let n = v.len();
        self.inv_area[l] = 1.0 / p.area;
        for j in 0..=edges {
            let at = if j < n { v[j] } else { v[0] };
            (self.x[j][l], self.y[j][l]) = (at[0], at[1]);
        }
        for k in 0..edges {
            if k < n {
                let (a, b) = (v[k], v[(k + 1) % n]);
                let d = [b[0] - a[0], b[1] - a[1]];
                let len = (d[0] * d[0] + d[1] * d[1]).sqrt();
                self.edge(k, l, [d[0] / len, d[1] / len, len], true);
            } else {
                self.edge(k, l, [1.0, 0.0, 0.0], false);
            }
        }
    }

    /// Room for `edges` edges in every lane: the lanes' outlines go on past their own edges
    /// with their vertex 0 and edges that are not live.
    fn grow(&mut self, edges: usize) {
        let had = self.edges();
        if edges <= had {
            return;
        }
        let (x0, y0) = (self.x[0], self.y[0]); // (a quad has vertex 0 in every lane)
        self.x.resize(edges + 1, x0);
        self.y.resize(edges + 1, y0);
        let (ex, ey, len, live, squares) = {
            let mut q = Quad::new(1);
            (q.ex[0], q.ey[0], q.len[0], q.live[0], q.squares.remove(0))
        };
        self.ex.resize(edges, ex);
        self.ey.resize(edges, ey);
        self.len.resize(edges, len);
        self.live.resize(edges, live);
        self.squares.resize(edges, squares);
    }

    /// Sets edge `k` of lane `l`: its direction `(ex, ey)` and length, whether it is `live`.
    fn edge(&mut self, k: usize, l: usize, [ex, ey, len]: [f64; 3], live: bool) {
        (self.ex[k][l], self.ey[k][l], self.len[k][l]) = (ex, ey, len);
        self.live[k][l] = if live { u64::MAX } else { 0 };
        let xy = ex * ey;
        let squares = [ex * ex, ey * ey, xy, 2.0 * xy, ey * ey - ex * ex];
        for (s, v) in self.squares[k].iter_mut().zip(squares) {
            s[l] = v;
        }
    }

    /// Edges of the lane with the most.
    pub(super) fn edges(&self) -> usize {
        self.len.len()
    }

    /// [`Polygon::friction_hessian`] of `shapes[l]` (the polygons the quad holds, in their
    /// lanes) at the relative twists `(v, omega)` of `twists[l]`, in the lanes that are `live`
    /// (the others give the default): each lane's bits are those it would have with any other
    /// lanes. The fan's regime (a rotation about a centre within [`FAR`] radii, uniform
    /// pressure on the whole footprint) is taken in lanes, any other one by
    /// [`Polygon::friction_hessian`].
    pub fn friction_hessian(
        &self,
        shapes: [Option<&Polygon>; FOUR],
        twists: [[f64; 3]; FOUR],
        live: [bool; FOUR],
    ) -> [Friction; FOUR] {
        let fanned: [bool; FOUR] = std::array::from_fn(|l| match shapes[l] {
            Some(p) if live[l] => fans(p, twists[l]),
            _ => false,
        });
        // (a lane out of the fan's regime turns about its centroid, inside the part: finite)
        let turning = std::array::from_fn(|l| {
            if fanned[l] {
                twists[l]
            } else {
                [0.0, 0.0, 1.0]
            }
        });
        let mut out = friction_four(self, turning, fanned);
        for l in 0..FOUR {
            out[l] = match shapes[l] {
                Some(p) if live[l] && !fanned[l] => {
                    let [vx, vy, omega] = twists[l];
                    p.friction_hessian([vx, vy], omega)
                }
                _ if fanned[l] => out[l],
                _ => Friction::default(),
            };
        }
        out
    }
}

impl Quad {
    /// `Phi` ([`Eval::of`]) at what the sliding solves of `shapes[l]` (the polygons the quad
    /// holds, in their lanes) ask about, into `out` in the lanes that ask (the others are left
    /// as they are): the friction and `Phi` in lanes
    /// where the fan's regime allows ([`Quad::friction_hessian`]), each lane's bits those it
    /// would have with any other lanes.
    pub(crate) fn evaluate(
        &self,
        shapes: [Option<&Polygon>; FOUR],
        asks: &[Option<Asked>; FOUR],
        out: &mut Evals,
    ) {
        #[cfg(target_arch = "x86_64")]
        if simd() == Simd::Avx512 {
            // (this build's lanes everywhere: the quad's own lanes beside a copy of them)
            let mut pair = [*out, Evals::default()];
            let shapes = std::array::from_fn(|l| if l < FOUR { shapes[l] } else { None });
            let asks = std::array::from_fn(|l| if l < FOUR { asks[l] } else { None });
            eight([self, self], shapes, &asks, &mut pair);
            *out = pair[0];
            return;
        }
        let fanned: [bool; FOUR] = std::array::from_fn(|l| match (shapes[l], asks[l]) {
            (Some(p), Some(a)) => fans(p, a.twist),
            _ => false,
        });
        #[cfg(target_arch = "x86_64")]
        let lanes = fanned.iter().filter(|&&f| f).count() > 0
            && matches!(simd(), Simd::Avx2 | Simd::Avx512);
        #[cfg(not(target_arch = "x86_64"))]
        let lanes = false;
        #[cfg(target_arch = "x86_64")]
        if lanes {
            // SAFETY: simd() chooses these builds only on a CPU that has AVX2.
            unsafe { super::avx2::evals_four(self, &vector_asks(asks, fanned), out) };
        }
        for l in 0..FOUR {
            let (Some(p), Some(a)) = (shapes[l], asks[l]) else {
                continue;
            };
            if fanned[l] && lanes {
                continue;
            }
            let f = if fanned[l] {
                friction_lane(self, l, a.twist)
            } else {
                p.friction_hessian([a.twist[0], a.twist[1]], a.twist[2])
            };
            out.set(l, &Eval::of(&f, a.y, a.target, a.c, a.kinv));
        }
    }
}

/// [`Quad::evaluate`] of two quads' lanes at once (lanes `0..4` of `shapes`, `asks` and `out`
/// the first quad's, `4..8` the second's): on the AVX-512 build in vectors of eight
/// (`avx512::evals_eight`) when the quads have as many edges, else quad by quad. A lane's bits
/// are the same either way.
pub(crate) fn evaluate_pair(
    q: [&Quad; 2],
    shapes: [Option<&Polygon>; EIGHT],
    asks: &[Option<Asked>; EIGHT],
    out: &mut [Evals; 2],
) {
    #[cfg(target_arch = "x86_64")]
    if simd() == Simd::Avx512 && q[0].edges() == q[1].edges() {
        return eight(q, shapes, asks, out);
    }
    for (h, out) in out.iter_mut().enumerate() {
        let lanes = FOUR * h..FOUR * (h + 1);
        let (shapes, asks) = (&shapes[lanes.clone()], &asks[lanes]);
        q[h].evaluate(
            std::array::from_fn(|l| shapes[l]),
            &std::array::from_fn(|l| asks[l]),
            out,
        );
    }
}

/// [`evaluate_pair`] on the AVX-512 build (the quads of as many edges): the lanes in the fan's
/// regime in vectors of eight, any other one by [`Polygon::friction_hessian`].
#[cfg(target_arch = "x86_64")]
fn eight(
    q: [&Quad; 2],
    shapes: [Option<&Polygon>; EIGHT],
    asks: &[Option<Asked>; EIGHT],
    out: &mut [Evals; 2],
) {
    let fanned: [bool; EIGHT] = std::array::from_fn(|l| match (shapes[l], asks[l]) {
        (Some(p), Some(a)) => fans(p, a.twist),
        _ => false,
    });
    if fanned.contains(&true) {
        // SAFETY: simd() chooses the AVX-512 build only on a CPU that has AVX-512F.
        unsafe { super::avx512::evals_eight(q, &vector_asks(asks, fanned), out) };
    }
    for l in (0..EIGHT).filter(|&l| !fanned[l]) {
        if let (Some(p), Some(a)) = (shapes[l], asks[l]) {
            let f = p.friction_hessian([a.twist[0], a.twist[1]], a.twist[2]);
            out[l / FOUR].set(l % FOUR, &Eval::of(&f, a.y, a.target, a.c, a.kinv));
        }
    }
}

/// What each lane of a vector build is asked: a lane in the fan's regime (`fanned`) what it
/// asks, any other one a turn about its centroid (inside the part: finite; its result unused).
#[cfg(target_arch = "x86_64")]
fn vector_asks<const N: usize>(asks: &[Option<Asked>; N], fanned: [bool; N]) -> [Asked; N] {
    std::array::from_fn(|l| match asks[l] {
        Some(a) if fanned[l] => a,
        _ => Asked {
            twist: [0.0, 0.0, 1.0],
            kinv: 1.0,
            ..Asked::default()
        },
    })
}

/// Whether the friction of `p` at `[vx, vy, omega]` is the fan's ([`Polygon::friction_hessian`]):
/// a rotation about a centre within [`FAR`] radii, under uniform pressure on the whole
/// footprint.
fn fans(p: &Polygon, [vx, vy, omega]: [f64; 3]) -> bool {
    let near = FAR * p.radius * omega;
    p.tripod.is_none() && p.load == [0.0; 2] && omega != 0.0 && vx * vx + vy * vy <= near * near
}

/// The friction ([`Polygon::friction_hessian`], the fan's regime) of the polygons in the lanes
/// that are `live` (the others: any) at the relative twists `(v, omega)` of `twists` (omega
/// not zero), on the build the simulations take (`crate::simd::simd`) when more than one lane is live,
/// else lane by lane.
pub(super) fn friction_four(
    q: &Quad,
    twists: [[f64; 3]; FOUR],
    live: [bool; FOUR],
) -> [Friction; FOUR] {
    #[cfg(target_arch = "x86_64")]
    if live.iter().filter(|&&l| l).count() > 1 && matches!(simd(), Simd::Avx2 | Simd::Avx512) {
        // SAFETY: simd() chooses these builds only on a CPU that has AVX2 (AVX-512 has it).
        return unsafe { super::avx2::friction_four(q, twists) };
    }
    std::array::from_fn(|l| {
        if live[l] {
            friction_lane(q, l, twists[l])
        } else {
            Friction::default()
        }
    })
}

/// Lane `l` of [`friction_four`], portable: [`Polygon::friction_about`] with the reciprocals
/// of omega and of the area.
pub(super) fn friction_lane(q: &Quad, l: usize, [vx, vy, omega]: [f64; 3]) -> Friction {
    let inv = 1.0 / omega;
    let r0 = [-vy * inv, vx * inv];
    let fan = fan_lane(q, l, r0);
    let (dist, [ux, uy], [gxx, gxy, gyy]) = (fan.dist, fan.unit, fan.curvature);
    let area = q.inv_area[l];
    let s = area.copysign(omega);
    let wrench = [s * uy, -(s * ux), -(s * ((dist + r0[0] * ux) + r0[1] * uy))];
    let scale = inv.abs() * area;
    let (px, py) = (-r0[1], r0[0]);
    let (g3x, g3y) = (px * gxx + py * gxy, px * gxy + py * gyy);
    let [hxx, hxy, hx3, hyy, hy3, h33] =
        [gxx, gxy, g3x, gyy, g3y, px * g3x + py * g3y].map(|g| scale * g);
    Friction {
        wrench,
        work: omega.abs() * dist * area,
        hessian: [[hxx, hxy, hx3], [hxy, hyy, hy3], [hx3, hy3, h33]],
    }
}

/// The fan integrals (curvature included) of lane `l` about `r0`, portable.
pub(super) fn fan_lane(q: &Quad, l: usize, r0: [f64; 2]) -> Fan {
    // a vertex about r0, its distance and the distance's reciprocal
    let about = |j: usize| {
        let d = [q.x[j][l] - r0[0], q.y[j][l] - r0[1]];
        let r = (d[0] * d[0] + d[1] * d[1]).sqrt();
        (d, r, 1.0 / r)
    };
    let mut at = about(0);
    let mut acc = [0.0; 6];
    for k in 0..q.edges() {
        let next = about(k + 1);
        let (ex, ey, len) = (q.ex[k][l], q.ey[k][l], q.len[k][l]);
        let ([ax, ay], ra, ia) = at;
        let (_, rb, ib) = next;
        let h = ax * ey - ay * ex;
        let skip = q.live[k][l] == 0 || h == 0.0;
        let ta = ax * ex + ay * ey;
        let tb = ta + len;
        let drho = len * (ta + tb) / (ra + rb);
        let arg = log_arg(h, ta, tb, ra, rb, len, drho, skip);
        let h = if skip { 0.0 } else { h };
        let d = ln_1p(arg);
        // (the edge's normal is n = (e_y, -e_x): its products with e are the quad's squares)
        let h2 = h * h;
        let dist = h * SIXTH * ((len * rb + ta * drho) + h2 * d);
        let (half, hd) = (0.5 * h, h * d);
        let ux = half * (hd * ey + ex * drho);
        let uy = half * (ey * drho - hd * ex);
        let s = (len * ra - ta * drho) * ia * ib;
        let c = ia - ib;
        let (nn, ne, ee) = (h * s, h2 * c, h * (d - s));
        let [xx, yy, xy, twice, diff] = q.squares[k].map(|v| v[l]);
        let gxx = (nn * yy + ne * twice) + ee * xx;
        let gxy = (ee - nn) * xy + ne * diff;
        let gyy = (nn * xx - ne * twice) + ee * yy;
        // a lane of no area (not the polygon's, or r0 on the edge's line) adds nothing: it may
        // hold infinities (r0 at a vertex)
        if !skip {
            for (acc, t) in acc.iter_mut().zip([dist, ux, uy, gxx, gxy, gyy]) {
                *acc += t;
            }
        }
        at = next;
    }
    Fan {
        dist: acc[0],
        unit: [acc[1], acc[2]],
        curvature: [acc[3], acc[4], acc[5]],
    }
}

#[cfg(test)]
#[path = "four_tests.rs"]
mod tests;
