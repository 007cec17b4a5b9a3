//! The point parts of one world: their state as structure of arrays (one array per quantity for
//! every point of the world), advanced in chunks of [`CHUNK_PARTS`] on rayon threads by the
//! [`kernel`], recording straight into the result ([`Rec`]).
//!
//! The state is read from the caller's parts chunk by chunk, on the thread that first advances
//! the chunk, just before its first steps: a call of a few steps on many parts reads each part,
//! records its initial state and steps it while its chunk is in the core's cache, instead of
//! building every array in one serial pass first.

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use crate::buffer::{recycle, scratch};
use crate::simd::Simd;

use super::base::{Base, ARRAYS, PLANAR, SLIDE};
use super::kernel::{self, Lanes, Plate, NEVER};
use super::lift::{self, Air};
use super::record::{Rec, RunState};
use super::source::Source;
use super::{half_side, Config, FrictionMap, PartsView};

/// Parts per chunk, the unit of work of a thread (a multiple of every SIMD tile).
pub const CHUNK_PARTS: usize = 256;

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
    /// cache), and no array is kept.
    once: bool,
    /// The plate's friction over its surface, and the parts whose friction it scales.
    surface: Option<Surface<'p>>,
}

/// A [`FrictionMap`] under the points: each block's chunks set their friction from it.
#[derive(Clone, Copy)]
struct Surface<'p> {
    map: &'p FrictionMap,
    parts: PartsView<'p>,
    index: Option<&'p [usize]>,
    /// `g dt`.
    scale: f64,
}

impl Surface<'_> {
    /// Sets the friction thresholds of the `k` points at `at ..` of `base` (the world's points
    /// from `start` on) where each will be `ahead` [s] from now at its present velocity (the
    /// middle of the block they start).
    ///
    /// # Safety
    /// As [`Base::chunk`]: the range is within every array's capacity and initialised, and no
    /// other live borrow overlaps it.
    unsafe fn apply(&self, base: &Base, at: usize, start: usize, k: usize, ahead: f64) {
        let [x, y, vx, vy] = [0, 1, 2, 3].map(|a| base.0[a].add(at).cast_const());
        let slide = std::slice::from_raw_parts_mut(base.0[SLIDE].add(at), k);
        let hold = std::slice::from_raw_parts_mut(base.0[SLIDE + 1].add(at), k);
        for q in 0..k {
            let i = self.index.map_or(start + q, |ix| ix[start + q]);
            let (px, py) = (
                *x.add(q) + *vx.add(q) * ahead,
                *y.add(q) + *vy.add(q) * ahead,
            );
            let f = self.map.factor(px, py) * self.scale;
            (slide[q], hold[q]) = (self.parts.mu(i) * f, self.parts.mu_s(i) * f);
        }
    }
}

/// One chunk's state in a run of one block (see [`Points::once`]).
pub(super) type Local = [[f64; CHUNK_PARTS]; ARRAYS];

/// A zeroed buffer of `N` lanes of each array (a [`Local`] with `CHUNK_PARTS`) on the heap,
/// built in place (not on the stack and then copied).
pub(super) fn zeroed<const N: usize>() -> Box<[[f64; N]; ARRAYS]> {
    let mut b = Box::<[[f64; N]; ARRAYS]>::new_uninit();
    // SAFETY: every byte zero is every f64 0.0, so the buffer is initialised.
    unsafe {
        b.as_mut_ptr().write_bytes(0, 1);
        b.assume_init()
    }
}

/// Whether array `i` is kept from block to block (see [`ARRAYS`]): the planar state, and the
/// air state on a plate out of its plane; nothing in a run of one block.
fn kept(i: usize, spatial: bool, once: bool) -> bool {
    !once && i < if spatial { ARRAYS } else { PLANAR }
}

impl<'p> Points<'p> {
    /// The parts `index` of `parts` (all of them with `None`), under the plate velocity `u0` at
    /// the start: room for their state, read from `parts` later, chunk by chunk; `once`: the
    /// whole run is one block (no array is kept).
    pub(super) fn new(
        parts: &PartsView<'p>,
        index: Option<&'p [usize]>,
        cfg: &Config,
        u0: [f64; 3],
        spatial: bool,
        once: bool,
        not_finite: &'p AtomicBool,
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
            source: Some(Source::new(parts, index, cfg, u0, not_finite)),
            surface: parts.surface.map(|map| Surface {
                map,
                parts: *parts,
                index,
                scale: cfg.g * cfg.dt,
            }),
        }
    }

    /// Records when the points of `l` (from the world's point `start` on) left the plate and how
    /// long they flew, at the end of the run.
    pub(super) fn ended(
        l: &Lanes,
        air: Option<&Air>,
        start: usize,
        index: Option<&[usize]>,
        rec: &Rec,
        dt: f64,
    ) {
        if index.is_none() && air.is_none() {
            // SAFETY: the chunk's parts are below m, and belong to this chunk alone.
            unsafe { rec.left_run(start, l.left, dt) };
            return;
        }
        for q in 0..l.x.len() {
            let left = (l.left[q] != NEVER).then(|| l.left[q] * dt);
            let flown = air.map_or(0.0, |a| a.flight[q] * dt);
            // SAFETY: the part is below m, and belongs to this chunk alone.
            unsafe { rec.ended(index.map_or(start + q, |ix| ix[start + q]), left, flown) };
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
                // SAFETY: every chunk wrote its range of every kept array (`fill`), so the first
                // n elements are initialised.
                unsafe { v.set_len(self.n) };
            }
        }
        self.source = None;
    }

    /// Whether the world has no points.
    pub(super) fn is_empty(&self) -> bool {
        self.n == 0
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
        let surface = self.surface;
        assert!(
            !once || (source.is_some() && first == 0),
            "a run of one block runs once"
        );
        // A run of one block of points alone on a vector build: each tile of the chunk reads,
        // records and steps its points in one pass (`super::short`), but the last few.
        #[cfg(target_arch = "x86_64")]
        let simd = kernel::simd();
        #[cfg(target_arch = "x86_64")]
        let short = once
            && index.is_none()
            && !spatial
            && !table.is_empty()
            && simd != Simd::Portable
            && surface.is_none()
            && !super::short::OFF.load(Ordering::Relaxed);
        let task = |local: &mut Option<Box<Local>>, (start, k): (usize, usize)| {
            #[cfg(target_arch = "x86_64")]
            let (start, k) = match &source {
                Some(src) if short => {
                    // SAFETY: simd() only reports builds the CPU has; the chunk's points are
                    // the source's and this task's alone.
                    let done = unsafe { src.short(simd, start, k, table, cfg.dt, rec) };
                    if done == k {
                        return;
                    }
                    (start + done, k - done)
                }
                _ => (start, k),
            };
            // Where the chunk's state lives while it runs: its own buffer in a run of one block.
            let (at, state) = if once {
                let l = local.get_or_insert_with(zeroed);
                (0, Base::local(l))
            } else {
                (start, base)
            };
            if let Some(src) = &source {
                // SAFETY: the range is within every kept array's capacity (or the chunk's own
                // buffer), and this task alone addresses it.
                unsafe { src.fill(&state, at, start, k, spatial) };
            }
            if let Some(s) = &surface {
                // SAFETY: as for the chunk below (the arrays are distinct, the state only read).
                unsafe { s.apply(&state, at, start, k, 0.5 * table.len() as f64 * cfg.dt) };
            }
            // SAFETY: the range is written (just now, or by the first block); chunks are
            // disjoint, and so are the tasks' own buffers.
            let (mut l, mut air) = unsafe { state.chunk(at, k, spatial) };
            l.kick = cfg.kick();
            if source.is_some() {
                write(&l, start, 0, rec, index);
            }
            let mut done = 0;
            while done < table.len() {
                let end = (rec.next_after(first + done) - first).min(table.len());
                let (t, dt) = (&table[done..end], cfg.dt);
                match air.as_mut() {
                    None => kernel::run(Plate::shared(t), first + done, dt, half, &mut l),
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
            if rec.last(first, table.len()) {
                Points::ended(&l, air.as_ref(), start, index, rec, cfg.dt);
            }
        };
        self.chunks()
            .into_par_iter()
            .with_min_len(crate::parallel::min_len())
            .for_each_init(|| None, task);
        if source.is_some() {
            self.written();
        }
    }
}

impl Drop for Points<'_> {
    fn drop(&mut self) {
        // (a run of one block keeps no array: nothing to give back, for each of a batch's many
        // small worlds)
        for v in self.arrays.iter_mut().filter(|v| v.capacity() > 0) {
            recycle(std::mem::take(v));
        }
    }
}

/// Writes a chunk's state into `row`.
pub(super) fn write(l: &Lanes, start: usize, row: usize, rec: &Rec, index: Option<&[usize]>) {
    if index.is_none() {
        let s = RunState {
            x: l.x,
            y: l.y,
            vx: l.vx,
            vy: l.vy,
            stuck: l.stuck,
        };
        // SAFETY: row < rows, the chunk's parts are below m, and this chunk alone writes them.
        unsafe { rec.points_run(row, start, &s) };
        rec.fence();
        return;
    }
    for q in 0..l.x.len() {
        let part = index.map_or(start + q, |ix| ix[start + q]);
        // SAFETY: row < rows (from Rec::row), part < m, and each part belongs to one chunk.
        unsafe {
            let state = ([l.x[q], l.y[q]], [l.vx[q], l.vy[q]], l.stuck[q] > 0.0);
            rec.point_streamed(row, part, state);
        }
    }
    rec.fence();
}
