//! The point parts of one world: their state as structure of arrays (one array per quantity for
//! every point of the world), advanced in chunks of [`CHUNK_PARTS`] on rayon threads by the
//! [`kernel`], recording straight into the result ([`Rec`]).
//!
//! The state is read from the caller's parts chunk by chunk, on the thread that first advances
//! the chunk, just before its first steps: a call of a few steps on many parts reads each part,
//! records its initial state and steps it while its chunk is in the core's cache, instead of
//! building every array in one serial pass first.

use rayon::prelude::*;

use crate::buffer::{recycle, scratch};

use super::kernel::{self, Lanes, NEVER};
use super::lift::{self, Air};
use super::record::Rec;
use super::{half_side, moves_with_plate, off_plate, Config, PartsView};

/// Parts per chunk, the unit of work of a thread (a multiple of every SIMD tile).
pub const CHUNK_PARTS: usize = 256;

/// The arrays of the state, in the order of [`Points::arrays`]: x, y, vx, vy, stuck, active,
/// left (steps done when the part left the plate, [`NEVER`] while on it), slide (`mu g dt`),
/// hold (`mu_s g dt`), and on a plate that moves out of its plane the height above the plate,
/// its rate and the steps spent in flight.
const ARRAYS: usize = 12;
const PLANAR: usize = 9;

/// Where the points' initial state comes from, until every chunk has read it.
#[derive(Clone, Copy)]
struct Source<'p> {
    parts: PartsView<'p>,
    /// The points' places among the parts (`None`: the same).
    index: Option<&'p [usize]>,
    /// The plate velocity at the start.
    u0: [f64; 3],
    /// Half the plate's side.
    half: f64,
    /// `g dt`.
    scale: f64,
}

/// Every point part of a world.
pub(super) struct Points<'p> {
    /// The state arrays ([`ARRAYS`]; the last three empty on a planar plate), each with room for
    /// every point; their length is set once every chunk has been written.
    arrays: [Vec<f64>; ARRAYS],
    n: usize,
    spatial: bool,
    /// The parts to read the state from, until the first block has read it.
    source: Option<Source<'p>>,
    /// The run is one block: each chunk's state lives in its task's own buffer (in the core's
    /// cache) and only what is read after the run (`left`, `flight`) is kept in the arrays.
    once: bool,
}

/// One chunk's state for a run of one block (see [`Points::once`]).
type Local = [[f64; CHUNK_PARTS]; ARRAYS];

/// Whether array `i` is kept for the whole run (see [`ARRAYS`]): the planar state, and the air
/// state on a plate out of its plane; in a run of one block only `left` and `flight`.
fn kept(i: usize, spatial: bool, once: bool) -> bool {
    let used = i < if spatial { ARRAYS } else { PLANAR };
    used && (!once || i == 6 || i == 11)
}

/// The arrays' base addresses, shared by the chunk tasks (each reads and writes only its own
/// range).
#[derive(Clone, Copy)]
struct Base([*mut f64; ARRAYS]);

// SAFETY: the chunk tasks address disjoint ranges of the arrays, which outlive them.
unsafe impl Send for Base {}
unsafe impl Sync for Base {}

impl Base {
    /// A chunk's own buffer.
    fn local(local: &mut Local) -> Self {
        Base(std::array::from_fn(|i| local[i].as_mut_ptr()))
    }

    /// The lanes (and air state) of the `k` points from `at` on.
    ///
    /// # Safety
    /// The range is within every array's capacity and initialised, and no other live borrow
    /// overlaps it.
    unsafe fn chunk<'c>(&self, at: usize, k: usize, spatial: bool) -> (Lanes<'c>, Option<Air<'c>>) {
        let a = |i: usize| std::slice::from_raw_parts_mut(self.0[i].add(at), k);
        let lanes = Lanes {
            x: a(0),
            y: a(1),
            vx: a(2),
            vy: a(3),
            stuck: a(4),
            active: a(5),
            left: a(6),
            slide: a(7),
            hold: a(8),
        };
        let air = spatial.then(|| Air {
            h: a(9),
            hv: a(10),
            flight: a(11),
        });
        (lanes, air)
    }
}

impl<'p> Points<'p> {
    /// The parts `index` of `parts` (all of them with `None`), under the plate velocity `u0` at
    /// the start: room for their state, read from `parts` later, chunk by chunk; `once`: the
    /// whole run is one block.
    pub(super) fn new(
        parts: &PartsView<'p>,
        index: Option<&'p [usize]>,
        cfg: &Config,
        u0: [f64; 3],
        spatial: bool,
        once: bool,
    ) -> Self {
        let n = index.map_or(parts.len(), <[usize]>::len);
        Points {
            arrays: std::array::from_fn(|i| {
                if kept(i, spatial, once) {
                    scratch(n)
                } else {
                    Vec::new()
                }
            }),
            n,
            spatial,
            once,
            source: Some(Source {
                parts: *parts,
                index,
                u0,
                half: half_side(cfg),
                scale: cfg.g * cfg.dt,
            }),
        }
    }

    fn base(&mut self) -> Base {
        Base(std::array::from_fn(|i| self.arrays[i].as_mut_ptr()))
    }

    /// The chunks: each one's first point and number of points.
    fn chunks(&self) -> Vec<(usize, usize)> {
        (0..self.n)
            .step_by(CHUNK_PARTS)
            .map(|s| (s, CHUNK_PARTS.min(self.n - s)))
            .collect()
    }

    /// Marks every kept array written (after every chunk has read its state from the source).
    fn written(&mut self) {
        for (i, v) in self.arrays.iter_mut().enumerate() {
            if kept(i, self.spatial, self.once) {
                assert!(v.capacity() >= self.n);
                // SAFETY: every chunk wrote its range of every kept array (`fill`, or its copy
                // of `left` and `flight` in a run of one block), so the first n elements are
                // initialised.
                unsafe { v.set_len(self.n) };
            }
        }
        self.source = None;
    }

    /// Records every point's state after step `s` (1-based; 0: the initial state) if that step is
    /// recorded; `index` maps the points to their places among all parts (`None`: the same).
    /// The initial state is recorded by the first block (as each chunk reads it), not here.
    pub(super) fn record(&mut self, s: usize, rec: &Rec, index: Option<&[usize]>) {
        if self.source.is_some() {
            return;
        }
        assert!(!self.once, "a run of one block records as it runs");
        if let Some(row) = rec.row(s) {
            let (base, spatial) = (self.base(), self.spatial);
            self.chunks().par_iter().for_each(|&(start, k)| {
                // SAFETY: the arrays are written (no source left); chunks are disjoint.
                let (l, _) = unsafe { base.chunk(start, k, spatial) };
                write(&l, start, row, rec, index);
            });
        }
    }

    /// Advances every point through one block: `table[k]` is the plate velocity at the end of
    /// step `first + k` (0-based) and `normals[k]` its out-of-plane acceleration (empty for a
    /// plate that stays in its plane). The kernel runs each chunk through the block in segments
    /// that end at recorded steps, and the chunk records itself there. In the first block each
    /// chunk first reads its parts and records their initial state.
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
        let (base, spatial, source, once) = (self.base(), self.spatial, self.source, self.once);
        assert!(
            !once || (source.is_some() && first == 0),
            "a run of one block runs once"
        );
        let task = |local: &mut Option<Box<Local>>, (start, k): (usize, usize)| {
            // Where the chunk's state lives while it runs: its own buffer in a run of one block.
            let (at, state) = if once {
                let l = local.get_or_insert_with(|| Box::new([[0.0; CHUNK_PARTS]; ARRAYS]));
                (0, Base::local(l))
            } else {
                (start, base)
            };
            if let Some(src) = &source {
                // SAFETY: the range is within every kept array's capacity (or the chunk's own
                // buffer), and this task alone addresses it.
                unsafe { src.fill(&state, at, start, k, spatial) };
            }
            // SAFETY: the range is written (just now, or by the first block); chunks are
            // disjoint, and so are the tasks' own buffers.
            let (mut l, mut air) = unsafe { state.chunk(at, k, spatial) };
            if source.is_some() {
                write(&l, start, 0, rec, index);
            }
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
            if once {
                // Keep what is read after the run: when each part left the plate, its flight.
                // SAFETY: `left` and `flight` (on a plate out of its plane) are kept, with room
                // for every point; this task alone addresses the chunk's range.
                unsafe {
                    std::ptr::copy_nonoverlapping(l.left.as_ptr(), base.0[6].add(start), k);
                    if let Some(a) = &air {
                        std::ptr::copy_nonoverlapping(a.flight.as_ptr(), base.0[11].add(start), k);
                    }
                }
            }
        };
        self.chunks().into_par_iter().for_each_init(|| None, task);
        if source.is_some() {
            self.written();
        }
    }

    /// The time each point spent in flight [s], in the points' order (empty on a planar plate).
    pub(super) fn flight(&self, dt: f64) -> impl Iterator<Item = f64> + '_ {
        self.arrays[11].iter().map(move |&k| k * dt)
    }

    /// The time each point left the plate [s] (NaN: it did not), in the points' order.
    pub(super) fn left(&self, dt: f64) -> impl Iterator<Item = f64> + '_ {
        self.arrays[6]
            .iter()
            .map(move |&l| if l == NEVER { f64::NAN } else { l * dt })
    }
}

impl Source<'_> {
    /// Writes the initial state of the points `start .. start + k` at `at ..` of `base`'s arrays.
    ///
    /// # Safety
    /// The range `at .. at + k` is within the capacity of every array of `base` the run uses,
    /// and nothing else addresses it meanwhile.
    unsafe fn fill(&self, base: &Base, at: usize, start: usize, k: usize, spatial: bool) {
        let p = &self.parts;
        let put = |a: usize, j: usize, v: f64| base.0[a].add(at + j - start).write(v);
        for j in start..start + k {
            let i = self.index.map_or(j, |ix| ix[j]);
            let [x, y] = p.position[i];
            let [vx, vy] = p.velocity.map_or([0.0, 0.0], |v| v[i]);
            // On an unbounded plate (infinite `half`) every part is on it.
            let on = !off_plate(x, y, self.half);
            put(0, j, x);
            put(1, j, y);
            put(2, j, vx);
            put(3, j, vy);
            // A part that starts moving with the plate surface starts stuck.
            put(
                4,
                j,
                f64::from(u8::from(moves_with_plate([x, y], [vx, vy], self.u0))),
            );
            put(5, j, f64::from(u8::from(on)));
            put(6, j, if on { NEVER } else { 0.0 });
            put(7, j, p.mu(i) * self.scale);
            put(8, j, p.mu_s(i) * self.scale);
            if spatial {
                put(9, j, 0.0);
                put(10, j, 0.0);
                put(11, j, 0.0);
            }
        }
    }
}

impl Drop for Points<'_> {
    fn drop(&mut self) {
        for v in &mut self.arrays {
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
