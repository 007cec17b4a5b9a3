//! The recorded trajectory, written once, in place: every recorded state goes straight from the
//! integrator into the buffers that become the result (and, through the binding, the NumPy
//! arrays), with no per-row staging and no copy.
//!
//! Positions, velocities and stuck flags are reserved uninitialised (in buffers handed back by
//! earlier results when they fit: see [`buffer::result_pairs`], [`buffer::result_flags`]) and written
//! exactly once per `(row, part)`; angles and spins only when some part turns (a run of point
//! parts leaves them empty: see [`super::simulate_stacked`]), allocated zeroed when some parts
//! are points (their cells are never written), else reserved like the positions ([`Turning`]).

use crate::buffer;
use crate::error::Result;

mod stream;
use stream::left_time;
pub(super) use stream::FLAG_BYTES;
#[cfg(target_arch = "x86_64")]
pub(super) use stream::{cells, left_times};
#[cfg(target_arch = "x86_64")]
use stream::{flags, pairs, times};

/// Whether step `s` (1-based) is recorded: every `every`-th step, and always the last one.
#[inline]
pub(super) fn recorded(s: usize, steps: usize, every: usize) -> bool {
    s.is_multiple_of(every) || s == steps
}

/// Rows recorded for `steps` steps: the initial state, every `every`-th step and the last step.
pub(super) fn recorded_rows(steps: usize, every: usize) -> usize {
    steps / every + 1 + usize::from(!steps.is_multiple_of(every))
}

/// What the worlds of a run recorded, stacked: world `b`'s rows follow world `b - 1`'s. Arrays
/// are row-major: `positions`, `velocities`, `stuck`, `angles` and `spins` are
/// `(worlds, rows, parts)`, `left` and `flight` `(worlds, parts)`, and `t` `(rows,)`, shared.
/// What is zero throughout is left empty, never allocated: `angles` and `spins` when no part
/// turns (no disk, no polygon), and `flight` on a plate that stays in its plane.
#[derive(Debug, Clone, PartialEq)]
pub struct Stacked {
    /// Recorded times [s].
    pub t: Vec<f64>,
    /// Positions [m].
    pub positions: Vec<[f64; 2]>,
    /// Velocities [m/s].
    pub velocities: Vec<[f64; 2]>,
    /// Whether each part was stuck to the plate.
    pub stuck: Vec<bool>,
    /// Orientations [rad] (empty: all zero).
    pub angles: Vec<f64>,
    /// Angular velocities [rad/s] (empty: all zero).
    pub spins: Vec<f64>,
    /// Time each part's centre left the plate [s] (NaN: it did not).
    pub left: Vec<f64>,
    /// Whether each part's centre left the plate (`left` is not NaN).
    pub left_plate: Vec<bool>,
    /// Time each part spent in flight [s] (empty: all zero).
    pub flight: Vec<f64>,
}

/// Which parts turn (disks and polygons do; points do not), for their angles and spins.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Turning {
    None,
    Some,
    All,
}

impl Turning {
    /// The angles' (or spins') buffer of `cells` cells: empty, zeroed, or room that the run
    /// fills ([`Recorder::new`]).
    fn buffer(self, cells: usize, what: &str) -> Result<Vec<f64>> {
        match self {
            Turning::None => Ok(Vec::new()),
            Turning::Some => buffer::zeroed(cells, what),
            Turning::All => buffer::result(cells, what),
        }
    }
}

/// The result buffers of every world of a run while it runs, stacked: world `b`'s rows follow
/// world `b - 1`'s, so a batch is one set of arrays `(worlds, rows, parts)`.
pub(super) struct Recorder {
    out: Stacked,
    /// Flight times are recorded (some world's plate leaves its plane).
    flying: bool,
    turning: Turning,
    m: usize,
    rows: usize,
    worlds: usize,
}

/// Where and when a world records: shared by every thread of the world (raw pointers into the
/// [`Recorder`]'s buffers; each `(row, part)` is written by one thread, once).
#[derive(Clone, Copy)]
pub(super) struct Rec {
    pos: *mut [f64; 2],
    vel: *mut [f64; 2],
    stuck: *mut bool,
    angle: *mut f64,
    spin: *mut f64,
    /// The world's `(parts,)` times of leaving the plate, whether each left, and the times of
    /// flight (null: none recorded).
    left: *mut f64,
    gone: *mut bool,
    flight: *mut f64,
    m: usize,
    rows: usize,
    steps: usize,
    every: usize,
    /// Points' positions and velocities go to memory with non-temporal stores (a result larger
    /// than the caches, which nothing reads during the run: no line is read for ownership).
    stream: bool,
}

/// A row's position, velocity and stuck cells of a part ([`Rec::row_cells`]).
pub(super) type RowCells = (*mut [f64; 2], *mut [f64; 2], *mut bool);

/// Results of more bytes than this are written with non-temporal stores (see [`Rec::stream`]).
const STREAM_BYTES: usize = 16 << 20;

// SAFETY: the pointers address the Recorder's buffers, which outlive every use of a Rec (the
// world's run); threads write disjoint (row, part) cells.
unsafe impl Send for Rec {}
unsafe impl Sync for Rec {}

impl Recorder {
    /// Buffers for `worlds` worlds of `rows` rows of `m` parts (reserved fallibly: an error, not
    /// an abort); angles and spins only if some part is `turning` (a disk or a polygon), flight
    /// times only if some world is `flying` (moves out of the plate's plane); else they are left
    /// empty.
    ///
    /// Where every part turns (`Turning::All`) the run writes every angle and spin, so they are
    /// taken like the positions, from buffers handed back by earlier results where one fits
    /// (fresh zeroed memory costs a page fault per 4 KiB on first write: disks recorded every
    /// step spent a third of their time in the kernel for it); where some parts are points,
    /// whose angle and spin stay zero and are never written, they are allocated zeroed.
    pub(super) fn new(
        worlds: usize,
        rows: usize,
        m: usize,
        turning: Turning,
        flying: bool,
    ) -> Result<Self> {
        let cells = worlds
            .checked_mul(rows)
            .and_then(|r| r.checked_mul(m))
            .ok_or_else(|| {
                crate::Error::parameter(
                    "record_every",
                    "is too small: the number of records overflows",
                )
            })?;
        let mut out = Stacked {
            t: Vec::new(),
            positions: buffer::result_pairs(cells, "the positions")?,
            velocities: buffer::result_pairs(cells, "the velocities")?,
            stuck: buffer::result_flags(cells, "the stuck flags")?,
            angles: turning.buffer(cells, "the angles")?,
            spins: turning.buffer(cells, "the spins")?,
            left: buffer::scratch(worlds * m),
            left_plate: buffer::result_flags(worlds * m, "the flags of leaving")?,
            flight: if flying {
                buffer::scratch(worlds * m)
            } else {
                Vec::new()
            },
        };
        buffer::reserve(&mut out.t, rows, "the recorded times")?;
        Ok(Recorder {
            out,
            flying,
            turning,
            m,
            rows,
            worlds,
        })
    }

    /// The writer of world `world` for a run of `steps` steps recording every `every`-th.
    pub(super) fn rec(&mut self, world: usize, steps: usize, every: usize) -> Rec {
        assert!(world < self.worlds, "world {world} of {}", self.worlds);
        let base = world * self.rows * self.m;
        // SAFETY: base is within the reserved capacity (world < worlds).
        let at = |p: *mut f64| unsafe { p.add(base) };
        let flight = if !self.flying {
            std::ptr::null_mut()
        } else {
            // SAFETY: world * m < worlds * m, the flight times' length.
            unsafe { self.out.flight.as_mut_ptr().add(world * self.m) }
        };
        Rec {
            pos: unsafe { self.out.positions.as_mut_ptr().add(base) },
            vel: unsafe { self.out.velocities.as_mut_ptr().add(base) },
            stuck: unsafe { self.out.stuck.as_mut_ptr().add(base) },
            angle: at(self.out.angles.as_mut_ptr()),
            spin: at(self.out.spins.as_mut_ptr()),
            // SAFETY: as for `flight`.
            left: unsafe { self.out.left.as_mut_ptr().add(world * self.m) },
            // SAFETY: as for `left`.
            gone: unsafe { self.out.left_plate.as_mut_ptr().add(world * self.m) },
            flight,
            stream: cfg!(target_arch = "x86_64")
                && self.worlds * self.rows * self.m * 32 > STREAM_BYTES
                && (self.out.positions.as_ptr() as usize).is_multiple_of(16)
                && (self.out.velocities.as_ptr() as usize).is_multiple_of(16),
            m: self.m,
            rows: self.rows,
            steps,
            every,
        }
    }

    /// The stacked result, once every `(row, part)` of every world has been written through its
    /// [`Rec`], and every part's times ([`Rec::ended`]).
    ///
    /// # Safety
    /// Every cell of every row of every world must have been written, and every part's times.
    pub(super) unsafe fn finish(mut self) -> Stacked {
        let cells = self.worlds * self.rows * self.m;
        self.out.left.set_len(self.worlds * self.m);
        self.out.left_plate.set_len(self.worlds * self.m);
        if self.flying {
            self.out.flight.set_len(self.worlds * self.m);
        }
        self.out.positions.set_len(cells);
        self.out.velocities.set_len(cells);
        if self.turning == Turning::All {
            self.out.angles.set_len(cells);
            self.out.spins.set_len(cells);
        }
        self.out.stuck.set_len(cells);
        self.out
    }

    /// Records the times of rows: `s dt` for every recorded step `s` (1-based) in `from..=to`.
    pub(super) fn times(&mut self, from: usize, to: usize, steps: usize, every: usize, dt: f64) {
        self.out.t.extend(
            (from..=to)
                .filter(|&s| recorded(s, steps, every))
                .map(|s| s as f64 * dt),
        );
    }
}

/// A run of points' state, one slice per quantity ([`Rec::points_run`]); `stuck` is 1.0 or 0.0.
pub(super) struct RunState<'a> {
    pub x: &'a [f64],
    pub y: &'a [f64],
    pub vx: &'a [f64],
    pub vy: &'a [f64],
    pub stuck: &'a [f64],
}

impl Rec {
    /// The row step `s` (1-based; 0 is the initial state) is recorded in, if it is recorded.
    #[inline]
    pub(super) fn row(&self, s: usize) -> Option<usize> {
        if s == 0 {
            Some(0)
        } else if s == self.steps {
            Some(self.rows - 1)
        } else if s.is_multiple_of(self.every) {
            Some(s / self.every)
        } else {
            None
        }
    }

    /// The next recorded step after `s` (1-based).
    pub(super) fn next_after(&self, s: usize) -> usize {
        ((s / self.every + 1) * self.every).min(self.steps)
    }

    /// Writes a point's (or a disk's translational) state.
    ///
    /// # Safety
    /// `row < rows`, `part < m`, and no other thread writes this cell.
    #[inline]
    pub(super) unsafe fn point(
        &self,
        row: usize,
        part: usize,
        p: [f64; 2],
        v: [f64; 2],
        stuck: bool,
    ) {
        debug_assert!(row < self.rows && part < self.m);
        let i = row * self.m + part;
        self.pos.add(i).write(p);
        self.vel.add(i).write(v);
        self.stuck.add(i).write(stuck);
    }

    /// [`Rec::point`] for a point; after a run of these calls the writer calls [`Rec::fence`].
    ///
    /// # Safety
    /// As [`Rec::point`].
    #[inline(always)]
    pub(super) unsafe fn point_streamed(
        &self,
        row: usize,
        part: usize,
        state: ([f64; 2], [f64; 2], bool),
    ) {
        let (p, v, stuck) = state;
        #[cfg(target_arch = "x86_64")]
        if self.stream {
            use std::arch::x86_64::{_mm_set_pd, _mm_stream_pd};
            debug_assert!(row < self.rows && part < self.m);
            let i = row * self.m + part;
            // SAFETY (alignment): both buffers start 16-byte aligned (checked with `stream`),
            // and each cell is 16 bytes.
            _mm_stream_pd(self.pos.add(i).cast(), _mm_set_pd(p[1], p[0]));
            _mm_stream_pd(self.vel.add(i).cast(), _mm_set_pd(v[1], v[0]));
            self.stuck.add(i).write(stuck);
            return;
        }
        self.point(row, part, p, v, stuck);
    }

    /// Writes the states of the points `part .. part + x.len()` (in order) in row `row`: whole
    /// 32-byte pairs of cells where the build has AVX (two parts' positions, or velocities, a
    /// store), non-temporal where the result is streamed (a cache line fills in two, which
    /// [`Rec::point_streamed`]'s 16-byte stores, two streams interleaved, did not do at memory
    /// speed on AMD Zen 3); else one part at a time. The caller then calls [`Rec::fence`].
    ///
    /// # Safety
    /// `row < rows`, `part + x.len() <= m`, the slices have one length, and no other thread
    /// writes these cells.
    pub(super) unsafe fn points_run(&self, row: usize, part: usize, s: &RunState) {
        let k = s.x.len();
        debug_assert!(row < self.rows && part + k <= self.m);
        debug_assert!([s.y.len(), s.vx.len(), s.vy.len(), s.stuck.len()] == [k; 4]);
        #[cfg(target_arch = "x86_64")]
        if crate::simd::simd() != crate::simd::Simd::Portable {
            let i = row * self.m + part;
            unsafe fn cells<const NT: bool>(rec: &Rec, i: usize, s: &RunState) {
                use std::arch::x86_64::_CMP_GT_OQ;
                pairs::<NT>(rec.pos.add(i), s.x, s.y);
                pairs::<NT>(rec.vel.add(i), s.vx, s.vy);
                flags::<_CMP_GT_OQ, NT>(rec.stuck.add(i), s.stuck, 0.0);
            }
            match self.stream {
                true => cells::<true>(self, i, s),
                false => cells::<false>(self, i, s),
            }
            return;
        }
        for q in 0..k {
            let state = ([s.x[q], s.y[q]], [s.vx[q], s.vy[q]], s.stuck[q] > 0.0);
            self.point_streamed(row, part + q, state);
        }
    }

    /// The position, velocity and stuck cells of `part` in `row` (each part's after them).
    ///
    /// # Safety
    /// `row < rows` and `part < m`.
    pub(super) unsafe fn row_cells(&self, row: usize, part: usize) -> RowCells {
        debug_assert!(row < self.rows && part < self.m);
        let i = row * self.m + part;
        (self.pos.add(i), self.vel.add(i), self.stuck.add(i))
    }

    /// The time of leaving the plate and its flag of `part` (each part's after them).
    ///
    /// # Safety
    /// `part < m`.
    pub(super) unsafe fn left_cells(&self, part: usize) -> (*mut f64, *mut bool) {
        debug_assert!(part < self.m);
        (self.left.add(part), self.gone.add(part))
    }

    /// Whether the result goes to memory with non-temporal stores (see [`Rec::stream`]).
    #[inline]
    pub(super) fn streams(&self) -> bool {
        self.stream
    }

    /// Orders the non-temporal stores of [`Rec::point_streamed`] before whatever the thread does
    /// next (the run's end is seen by other threads only after them).
    #[inline]
    pub(super) fn fence(&self) {
        #[cfg(target_arch = "x86_64")]
        if self.stream {
            // SAFETY: SSE is part of x86-64.
            unsafe { std::arch::x86_64::_mm_sfence() };
        }
    }

    /// Whether the block of `len` steps after `first` ends the run.
    #[inline]
    pub(super) fn last(&self, first: usize, len: usize) -> bool {
        first + len == self.steps
    }

    /// Records when `part` left the plate (`None`: it did not, recorded as NaN) and how long it
    /// flew [s] (kept only where flight times are recorded).
    ///
    /// # Safety
    /// `part < m`, and no other thread writes this part's times.
    #[inline]
    pub(super) unsafe fn ended(&self, part: usize, left: Option<f64>, flight: f64) {
        debug_assert!(part < self.m);
        self.left.add(part).write(left.unwrap_or(f64::NAN));
        self.gone.add(part).write(left.is_some());
        if !self.flight.is_null() {
            self.flight.add(part).write(flight);
        }
    }

    /// [`Rec::ended`] for the parts `part ..` of a chunk that never leaves the plate's plane:
    /// `steps[q]` is the step count when part `part + q` left the plate ([`super::kernel::NEVER`]:
    /// it did not), written as a time (NaN: it did not) and a flag, whole vectors at a time where
    /// the build has AVX2 (non-temporal where the result is streamed, then fenced).
    ///
    /// # Safety
    /// `part + steps.len() <= m`, and no other thread writes these parts' times.
    pub(super) unsafe fn left_run(&self, part: usize, steps: &[f64], dt: f64) {
        debug_assert!(part + steps.len() <= self.m);
        #[cfg(target_arch = "x86_64")]
        if crate::simd::simd() != crate::simd::Simd::Portable {
            use std::arch::x86_64::_CMP_NEQ_OQ;
            let (left, gone, never) = (
                self.left.add(part),
                self.gone.add(part),
                super::kernel::NEVER,
            );
            if self.stream {
                times::<true>(left, steps, dt);
                flags::<_CMP_NEQ_OQ, true>(gone, steps, never);
                self.fence();
            } else {
                times::<false>(left, steps, dt);
                flags::<_CMP_NEQ_OQ, false>(gone, steps, never);
            }
            return;
        }
        for (q, &s) in steps.iter().enumerate() {
            self.left.add(part + q).write(left_time(s, dt));
            self.gone.add(part + q).write(s != super::kernel::NEVER);
        }
    }

    /// Writes a disk's state.
    ///
    /// # Safety
    /// As [`Rec::point`].
    #[inline]
    pub(super) unsafe fn disk(
        &self,
        row: usize,
        part: usize,
        state: ([f64; 2], [f64; 2], f64, f64, bool),
    ) {
        let (p, v, angle, spin, stuck) = state;
        self.point(row, part, p, v, stuck);
        let i = row * self.m + part;
        self.angle.add(i).write(angle);
        self.spin.add(i).write(spin);
        // The part's cells of the next row, fetched for writing while it takes its next step: a
        // part is recorded down its column, a cache line a row and array, and each store that
        // missed held up the stores behind it (hexagons recorded every step cost 308-312 ns per
        // part-step against 272-281 recording the last only; with this 275-283; disks on a
        // translating plate 31-32 -> 19-21 ns, kernel bench with EVERY=1, Intel Xeon).
        #[cfg(target_arch = "x86_64")]
        if row + 1 < self.rows {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_ET0};
            let j = i + self.m;
            _mm_prefetch::<_MM_HINT_ET0>(self.pos.add(j).cast());
            _mm_prefetch::<_MM_HINT_ET0>(self.vel.add(j).cast());
            _mm_prefetch::<_MM_HINT_ET0>(self.stuck.add(j).cast());
            _mm_prefetch::<_MM_HINT_ET0>(self.angle.add(j).cast());
            _mm_prefetch::<_MM_HINT_ET0>(self.spin.add(j).cast());
        }
    }
}
