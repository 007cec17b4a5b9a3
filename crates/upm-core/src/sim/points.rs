//! The point parts of one world: their state as structure of arrays (one array per quantity for
//! every point of the world), advanced in chunks of [`CHUNK_PARTS`] on rayon threads by the
//! [`kernel`], recording straight into the result ([`Rec`]).

use rayon::prelude::*;

use crate::buffer::{recycle, scratch};

use super::kernel::{self, Lanes, NEVER};
use super::lift::{self, Air};
use super::record::Rec;
use super::{half_side, moves_with_plate, off_plate, Config, PartsView};

/// Parts per chunk, the unit of work of a thread (a multiple of every SIMD tile).
pub const CHUNK_PARTS: usize = 256;

/// Every point part of a world.
pub(super) struct Points {
    x: Vec<f64>,
    y: Vec<f64>,
    vx: Vec<f64>,
    vy: Vec<f64>,
    stuck: Vec<f64>,
    active: Vec<f64>,
    /// Steps done when the part left the plate ([`NEVER`] while on it).
    left: Vec<f64>,
    slide: Vec<f64>, // mu g dt
    hold: Vec<f64>,  // mu_s g dt
    /// Height above the plate, its rate and the steps spent in flight, on a plate that moves out
    /// of its plane (empty otherwise).
    h: Vec<f64>,
    hv: Vec<f64>,
    flight: Vec<f64>,
}

/// One chunk: its first point's place among the world's points, its arrays and its air state.
type Chunk<'a> = (usize, Lanes<'a>, Option<Air<'a>>);

impl Points {
    /// The parts `index` of `parts` (all of them with `None`), under the plate velocity `u0` at
    /// the start.
    pub(super) fn new(
        parts: &PartsView,
        index: Option<&[usize]>,
        cfg: &Config,
        u0: [f64; 3],
        spatial: bool,
    ) -> Self {
        let n = index.map_or(parts.len(), <[usize]>::len);
        let at = |j: usize| index.map_or(j, |ix| ix[j]);
        let half = half_side(cfg);
        let mut p = Points {
            x: scratch(n),
            y: scratch(n),
            vx: scratch(n),
            vy: scratch(n),
            stuck: scratch(n),
            active: scratch(n),
            left: scratch(n),
            slide: scratch(n),
            hold: scratch(n),
            h: Vec::new(),
            hv: Vec::new(),
            flight: Vec::new(),
        };
        if spatial {
            for v in [&mut p.h, &mut p.hv, &mut p.flight] {
                *v = scratch(n);
                v.resize(n, 0.0);
            }
        }
        let scale = cfg.g * cfg.dt;
        // Each array in one pass over slices (vectorised when the points are all the parts).
        match index {
            None => {
                p.x.extend(parts.position.iter().map(|q| q[0]));
                p.y.extend(parts.position.iter().map(|q| q[1]));
            }
            Some(ix) => {
                p.x.extend(ix.iter().map(|&i| parts.position[i][0]));
                p.y.extend(ix.iter().map(|&i| parts.position[i][1]));
            }
        }
        match (parts.velocity, index) {
            (None, _) => {
                p.vx.resize(n, 0.0);
                p.vy.resize(n, 0.0);
            }
            (Some(v), None) => {
                p.vx.extend(v.iter().map(|q| q[0]));
                p.vy.extend(v.iter().map(|q| q[1]));
            }
            (Some(v), Some(ix)) => {
                p.vx.extend(ix.iter().map(|&i| v[i][0]));
                p.vy.extend(ix.iter().map(|&i| v[i][1]));
            }
        }
        // A part that starts moving with the plate surface starts stuck.
        p.stuck
            .extend(p.x.iter().zip(&p.y).zip(p.vx.iter().zip(&p.vy)).map(
                |((&x, &y), (&vx, &vy))| {
                    f64::from(u8::from(moves_with_plate([x, y], [vx, vy], u0)))
                },
            ));
        if half.is_finite() {
            p.active
                .extend((0..n).map(|j| f64::from(u8::from(!off_plate(p.x[j], p.y[j], half)))));
            p.left
                .extend(p.active.iter().map(|&a| if a > 0.0 { NEVER } else { 0.0 }));
        } else {
            p.active.resize(n, 1.0);
            p.left.resize(n, NEVER);
        }
        if parts.mu.len() == 1 && parts.mu_s.len() == 1 {
            p.slide.resize(n, parts.mu[0] * scale);
            p.hold.resize(n, parts.mu_s[0] * scale);
        } else {
            p.slide.extend((0..n).map(|j| parts.mu(at(j)) * scale));
            p.hold.extend((0..n).map(|j| parts.mu_s(at(j)) * scale));
        }
        p
    }

    /// The chunks, each borrowing its share of every array.
    fn chunks(&mut self) -> Vec<Chunk<'_>> {
        let mut out = Vec::with_capacity(self.x.len().div_ceil(CHUNK_PARTS));
        let (mut x, mut y, mut vx, mut vy) = (
            &mut self.x[..],
            &mut self.y[..],
            &mut self.vx[..],
            &mut self.vy[..],
        );
        let (mut stuck, mut active, mut left) = (
            &mut self.stuck[..],
            &mut self.active[..],
            &mut self.left[..],
        );
        let (mut slide, mut hold) = (&self.slide[..], &self.hold[..]);
        let spatial = !self.h.is_empty();
        let (mut h, mut hv, mut flight) = (&mut self.h[..], &mut self.hv[..], &mut self.flight[..]);
        let mut start = 0;
        while !x.is_empty() {
            let k = CHUNK_PARTS.min(x.len());
            fn take<'s, T>(a: &mut &'s mut [T], k: usize) -> &'s mut [T] {
                let (head, tail) = std::mem::take(a).split_at_mut(k);
                *a = tail;
                head
            }
            let lanes = Lanes {
                x: take(&mut x, k),
                y: take(&mut y, k),
                vx: take(&mut vx, k),
                vy: take(&mut vy, k),
                stuck: take(&mut stuck, k),
                active: take(&mut active, k),
                left: take(&mut left, k),
                slide: {
                    let (head, tail) = slide.split_at(k);
                    slide = tail;
                    head
                },
                hold: {
                    let (head, tail) = hold.split_at(k);
                    hold = tail;
                    head
                },
            };
            let air = spatial.then(|| Air {
                h: take(&mut h, k),
                hv: take(&mut hv, k),
                flight: take(&mut flight, k),
            });
            out.push((start, lanes, air));
            start += k;
        }
        out
    }

    /// Records every point's state after step `s` (1-based; 0: the initial state) if that step is
    /// recorded; `index` maps the points to their places among all parts (`None`: the same).
    pub(super) fn record(&mut self, s: usize, rec: &Rec, index: Option<&[usize]>) {
        if let Some(row) = rec.row(s) {
            self.chunks()
                .par_iter()
                .for_each(|(start, l, _)| write(l, *start, row, rec, index));
        }
    }

    /// Advances every point through one block: `table[k]` is the plate velocity at the end of
    /// step `first + k` (0-based) and `normals[k]` its out-of-plane acceleration (empty for a
    /// plate that stays in its plane). The kernel runs each chunk through the block in segments
    /// that end at recorded steps, and the chunk records itself there.
    pub(super) fn run(
        &mut self,
        table: &[[f64; 3]],
        normals: &[[f64; 3]],
        first: usize,
        cfg: &Config,
        rec: &Rec,
        index: Option<&[usize]>,
    ) {
        let half = half_side(cfg);
        self.chunks()
            .into_par_iter()
            .for_each(|(start, mut l, mut air)| {
                let mut done = 0;
                while done < table.len() {
                    let end = (rec.next_after(first + done) - first).min(table.len());
                    let (t, dt) = (&table[done..end], cfg.dt);
                    match air.as_mut() {
                        None => kernel::run(t, first + done, dt, half, &mut l),
                        Some(a) => {
                            let steps = lift::Steps {
                                u: t,
                                normals: &normals[done..end],
                                first: first + done,
                                dt,
                                half,
                                g: cfg.g,
                            };
                            lift::run(&steps, &mut l, a)
                        }
                    }
                    done = end;
                    if let Some(row) = rec.row(first + done) {
                        write(&l, start, row, rec, index);
                    }
                }
            });
    }

    /// The time each point spent in flight [s], in the points' order (empty on a planar plate).
    pub(super) fn flight(&self, dt: f64) -> impl Iterator<Item = f64> + '_ {
        self.flight.iter().map(move |&k| k * dt)
    }

    /// The time each point left the plate, in the points' order.
    pub(super) fn left(&self, dt: f64) -> impl Iterator<Item = Option<f64>> + '_ {
        self.left
            .iter()
            .map(move |&l| (l != NEVER).then_some(l * dt))
    }
}

impl Drop for Points {
    fn drop(&mut self) {
        for v in [
            &mut self.x,
            &mut self.y,
            &mut self.vx,
            &mut self.vy,
            &mut self.stuck,
            &mut self.active,
            &mut self.left,
            &mut self.slide,
            &mut self.hold,
            &mut self.h,
            &mut self.hv,
            &mut self.flight,
        ] {
            recycle(std::mem::take(v));
        }
    }
}

/// Writes a chunk's state into `row`.
fn write(l: &Lanes, start: usize, row: usize, rec: &Rec, index: Option<&[usize]>) {
    for q in 0..l.x.len() {
        let part = index.map_or(start + q, |ix| ix[start + q]);
        // SAFETY: row < rows (from Rec::row), part < m, and each part belongs to one chunk.
        unsafe {
            rec.point(
                row,
                part,
                [l.x[q], l.y[q]],
                [l.vx[q], l.vy[q]],
                l.stuck[q] > 0.0,
            );
        }
    }
}
