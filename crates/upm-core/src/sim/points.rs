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

use super::kernel::{self, Lanes, Plate, NEVER};
use super::lift::{self, Air};
use super::record::{Rec, RunState};
use super::{half_side, moves_with_plate, off_plate, Config, PartsView};

/// Parts per chunk, the unit of work of a thread (a multiple of every SIMD tile).
pub const CHUNK_PARTS: usize = 256;

/// The arrays of the state, in the order of [`Points::arrays`]: x, y, vx, vy, stuck, active,
/// left (steps done when the part left the plate, [`NEVER`] while on it), slide (`mu g dt`),
/// hold (`mu_s g dt`), and on a plate that moves out of its plane the height above the plate,
/// its rate and the steps spent in flight.
pub(super) const ARRAYS: usize = 12;
pub(super) const PLANAR: usize = 9;
/// The stuck flags' array among them.
pub(super) const STUCK: usize = 4;

/// Where the points' initial state comes from, until every chunk has read it.
#[derive(Clone, Copy)]
pub(super) struct Source<'p> {
    pub(super) parts: PartsView<'p>,
    /// The points' places among the parts (`None`: the same).
    index: Option<&'p [usize]>,
    /// The plate velocity at the start.
    pub(super) u0: [f64; 3],
    /// Half the plate's side.
    pub(super) half: f64,
    /// Gravity's in-plane velocity a step [m/s] ([`Config::tilt`] `dt`).
    pub(super) kick: [f64; 2],
    /// `g dt`.
    pub(super) scale: f64,
    /// Set when a point's position or velocity is not finite (the run then stops after its
    /// first block with the full check's error).
    pub(super) not_finite: &'p AtomicBool,
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
    /// cache), and no array is kept.
    once: bool,
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

/// The arrays' base addresses, shared by the chunk tasks (each reads and writes only its own
/// range).
#[derive(Clone, Copy)]
pub(super) struct Base([*mut f64; ARRAYS]);

// SAFETY: the chunk tasks address disjoint ranges of the arrays, which outlive them.
unsafe impl Send for Base {}
unsafe impl Sync for Base {}

impl Base {
    /// A chunk's own buffer (or a group's, of `N` lanes).
    pub(super) fn local<const N: usize>(local: &mut [[f64; N]; ARRAYS]) -> Self {
        Base(std::array::from_fn(|i| local[i].as_mut_ptr()))
    }

    /// A group's buffer (`sim::group`): [`PLANAR`] arrays of `lanes` lanes each, one after the
    /// other (a group's points stay on the plane: the arrays of the air point nowhere, and
    /// [`Base::chunk`] must not be asked for them).
    pub(super) fn planar(buf: &mut [f64], lanes: usize) -> Self {
        assert!(
            buf.len() >= PLANAR * lanes,
            "a buffer of {PLANAR} x {lanes} lanes"
        );
        let p = buf.as_mut_ptr();
        // SAFETY: within the buffer (checked).
        Base(std::array::from_fn(|i| {
            if i < PLANAR {
                unsafe { p.add(i * lanes) }
            } else {
                std::ptr::null_mut()
            }
        }))
    }

    /// The lanes (and air state) of the `k` points from `at` on.
    ///
    /// # Safety
    /// The range is within every array's capacity and initialised, and no other live borrow
    /// overlaps it.
    pub(super) unsafe fn chunk<'c>(
        &self,
        at: usize,
        k: usize,
        spatial: bool,
    ) -> (Lanes<'c>, Option<Air<'c>>) {
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
            kick: [0.0; 2],
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
            && simd != kernel::Simd::Portable
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

impl<'p> Source<'p> {
    /// The points of `parts` (at `index` among them; `None`: every part) on a plate whose
    /// velocity at the start is `u0`; `not_finite` is set if a state read is not finite.
    pub(super) fn new(
        parts: &PartsView<'p>,
        index: Option<&'p [usize]>,
        cfg: &Config,
        u0: [f64; 3],
        not_finite: &'p AtomicBool,
    ) -> Self {
        Source {
            parts: *parts,
            index,
            u0,
            half: half_side(cfg),
            kick: cfg.kick(),
            scale: cfg.g * cfg.dt,
            not_finite,
        }
    }

    /// Writes the initial state of the points `start .. start + k` at `at ..` of `base`'s arrays.
    ///
    /// # Safety
    /// The range `at .. at + k` is within the capacity of every array of `base` the run uses,
    /// and nothing else addresses it meanwhile.
    pub(super) unsafe fn fill(
        &self,
        base: &Base,
        at: usize,
        start: usize,
        k: usize,
        spatial: bool,
    ) {
        #[cfg(target_arch = "x86_64")]
        if super::simd() != super::Simd::Portable {
            return self.fill_avx2(base, at, start, k, spatial);
        }
        self.fill_any(base, at, start, k, spatial)
    }

    /// [`Source::fill`] compiled for AVX2 (the same operations, so the same results: no
    /// contraction into fused multiply–adds).
    ///
    /// # Safety
    /// As [`Source::fill`]; the CPU must support AVX2 and FMA (as [`super::simd`] found).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn fill_avx2(&self, base: &Base, at: usize, start: usize, k: usize, spatial: bool) {
        self.fill_any(base, at, start, k, spatial)
    }

    /// [`Source::fill`] in plain Rust, one array at a time in branch-free loops the compiler
    /// vectorises when the points are all the parts (no index).
    #[inline(always)]
    unsafe fn fill_any(&self, base: &Base, at: usize, start: usize, k: usize, spatial: bool) {
        use std::mem::MaybeUninit;
        let p = &self.parts;
        let out = |a: usize| std::slice::from_raw_parts_mut(base.0[a].add(at).cast(), k);
        let [x, y, vx, vy, stuck, active, left, slide, hold]: [&mut [MaybeUninit<f64>]; 9] =
            std::array::from_fn(out);
        let ix = |q: usize| self.index.map_or(start + q, |ix| ix[start + q]);
        // Whether every value read is finite, found as it is copied (reading the lanes back
        // with vectors right after the scalar stores would wait for the stores to complete).
        let finite = |a: f64, b: f64| a.is_finite() & b.is_finite();
        let mut ok = true;
        match self.index {
            None => {
                for (q, &[a, b]) in p.position[start..start + k].iter().enumerate() {
                    x[q].write(a);
                    y[q].write(b);
                    ok &= finite(a, b);
                }
            }
            Some(_) => {
                for q in 0..k {
                    let [a, b] = p.position[ix(q)];
                    x[q].write(a);
                    y[q].write(b);
                    ok &= finite(a, b);
                }
            }
        }
        match (self.index, p.velocity) {
            (_, None) => {
                vx.fill(MaybeUninit::new(0.0));
                vy.fill(MaybeUninit::new(0.0));
            }
            (None, Some(v)) => {
                for (q, &[a, b]) in v[start..start + k].iter().enumerate() {
                    vx[q].write(a);
                    vy[q].write(b);
                    ok &= finite(a, b);
                }
            }
            (Some(_), Some(v)) => {
                for q in 0..k {
                    let [a, b] = v[ix(q)];
                    vx[q].write(a);
                    vy[q].write(b);
                    ok &= finite(a, b);
                }
            }
        }
        let [x, y, vx, vy] =
            [x, y, vx, vy].map(|a| &*(a as *const [MaybeUninit<f64>] as *const [f64]));
        if !ok {
            self.not_finite.store(true, Ordering::Relaxed);
        }
        let (u0, half) = (self.u0, self.half);
        for q in 0..k {
            // A part that starts moving with the plate surface starts stuck.
            let s = moves_with_plate([x[q], y[q]], [vx[q], vy[q]], u0);
            stuck[q].write(if s { 1.0 } else { 0.0 });
            // On an unbounded plate (infinite `half`) every part is on it.
            let on = !off_plate(x[q], y[q], half);
            active[q].write(if on { 1.0 } else { 0.0 });
            left[q].write(if on { NEVER } else { 0.0 });
        }
        if p.mu.len() == 1 && p.mu_s.len() == 1 {
            slide.fill(MaybeUninit::new(p.mu(0) * self.scale));
            hold.fill(MaybeUninit::new(p.mu_s(0) * self.scale));
        } else {
            for q in 0..k {
                let i = ix(q);
                slide[q].write(p.mu(i) * self.scale);
                hold[q].write(p.mu_s(i) * self.scale);
            }
        }
        if spatial {
            for a in 9..ARRAYS {
                out(a).fill(MaybeUninit::new(0.0));
            }
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
