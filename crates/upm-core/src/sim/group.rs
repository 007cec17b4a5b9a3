//! Batches of small worlds run side by side. A world of a few point parts fills only a fraction
//! of a register tile, and one vector's steps form a dependency chain of some 60 cycles: run
//! alone, a world of 8 parts cost 5x a large world per part-step (the planner's rollouts). Here
//! the point parts of up to [`LANES`] / `stride` worlds share one tile, world `w` in the lanes
//! `w * stride ..` (padded to whole vectors), each vector stepping under its own world's plate
//! velocity ([`Plate::worlds`]). Each lane does exactly what it does in a world run alone, so the
//! results are bitwise the same.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

use rayon::prelude::*;

use super::kernel::{self, Plate};
use super::points::{write, zeroed, Base, Points, Source, ARRAYS};
use super::record::{Rec, Recorder, Stacked};
use super::timing::{self, by_timing};
use super::{half_side, Config, Error, PartsView, WorldFriction};
use crate::motion::{Columns, Phases, PlateMotion};

/// Lanes of a group: one full register tile of the widest build.
const LANES: usize = 64;

/// Worlds with at most this many point parts (and nothing else) are run in groups.
pub(super) const MAX_POINTS: usize = 32;

/// The lanes a world of `m` points takes in a group: whole vectors of eight.
fn stride(m: usize) -> usize {
    m.div_ceil(8).max(1) * 8
}

/// Worlds per group for worlds of `m` points.
fn worlds_per_group(m: usize) -> usize {
    (LANES / stride(m)).max(1)
}

/// A world of a batch run in a group: its motion, its timing's number among the batch's (see
/// [`by_timing`]), its place in the batch and where it records. (No more: a batch of many small
/// worlds pays for what each world carries.)
struct Member<'a> {
    motion: &'a PlateMotion,
    timing: usize,
    b: usize,
    rec: Rec,
}

/// Runs `motions` (worlds of at most [`MAX_POINTS`] point parts, `parts`, with `friction`'s rows
/// where given; on the plane), grouped, for `steps` steps a block of `block` steps at a time,
/// recording into `recorder`; `between` as [`super::simulate_stacked`] calls it.
#[allow(clippy::too_many_arguments)]
pub(super) fn simulate<E, B>(
    motions: &[&PlateMotion],
    parts: &PartsView,
    cfg: &Config,
    friction: Option<&WorldFriction>,
    steps: usize,
    block: usize,
    mut recorder: Recorder,
    mut between: B,
) -> std::result::Result<Stacked, E>
where
    E: From<Error>,
    B: FnMut(usize) -> std::result::Result<(), E>,
{
    // Worlds with the same timing are neighbours: a group turns their phasors once.
    let members: Vec<Member> = by_timing(motions)
        .into_iter()
        .map(|(timing, b)| Member {
            motion: motions[b],
            timing,
            b,
            rec: recorder.rec(b, steps, cfg.record_every),
        })
        .collect();
    recorder.times(0, 0, steps, cfg.record_every, cfg.dt);
    // (the points record their initial state as their group reads them)
    let per_group = worlds_per_group(parts.len());
    let mut groups = Group::take(members.len().div_ceil(per_group));
    let not_finite = AtomicBool::new(false);
    let first_block = Start {
        parts,
        friction,
        not_finite: &not_finite,
    };
    let mut first = 0;
    while first < steps {
        let end = (first + block).min(steps);
        let shared = shared_phases(&members, per_group, first..end, cfg.dt);
        members
            .par_chunks(per_group)
            .zip(groups.par_iter_mut())
            .with_min_len(crate::parallel::min_len())
            .for_each(|(ws, g)| g.run(ws, &shared, first..end, cfg, &first_block));
        if first == 0 && not_finite.load(Ordering::Relaxed) {
            parts.check()?; // names the first part whose state is not finite
        }
        recorder.times(first + 1, end, steps, cfg.record_every, cfg.dt);
        between(end)?;
        first = end;
    }
    Group::give_back(groups);
    // SAFETY: every row of every world was written: row 0 and every recorded step's row by its
    // group, in the block of that step; its times of leaving the plate in its last block.
    Ok(unsafe { recorder.finish() })
}

/// Where a group reads its worlds' points from as their first block starts.
struct Start<'a, 'p> {
    parts: &'a PartsView<'p>,
    friction: Option<&'a WorldFriction<'a>>,
    not_finite: &'a AtomicBool,
}

/// The phasor samples of the block `steps` for every timing whose worlds fill more than one
/// group, taken once here instead of once per group (indexed by timing; `None` for the other
/// timings, whose one group takes its own). `worlds` are in the order of [`by_timing`].
fn shared_phases(
    worlds: &[Member],
    per_group: usize,
    steps: Range<usize>,
    dt: f64,
) -> Vec<Option<Phases>> {
    let classes = worlds.last().map_or(0, |w| w.timing + 1);
    let members = worlds.iter().map(|w| (w.timing, w.motion));
    timing::shared(members, classes, per_group, steps, dt)
}

/// Steps whose plate velocities a group tabulates at a time: 8 worlds at 128 steps take
/// 24 KiB, within the L1 cache.
const PIECE: usize = 128;

/// The runs of one timing among `worlds` (neighbours, sorted so by [`by_timing`]), each with the
/// samples of the block `steps`: the batch's in `shared` where the timing spans groups (`None`
/// here), else the run's own, taken now.
fn runs(
    worlds: &[Member],
    shared: &[Option<Phases>],
    steps: Range<usize>,
    dt: f64,
) -> Vec<(Range<usize>, Option<Phases>)> {
    let mut out = Vec::new();
    let mut from = 0;
    while from < worlds.len() {
        let timing = worlds[from].timing;
        let to = from
            + worlds[from..]
                .iter()
                .take_while(|w| w.timing == timing)
                .count();
        let own = shared[timing]
            .is_none()
            .then(|| Phases::of(worlds[from].motion, steps.clone(), dt));
        out.push((from..to, own));
        from = to;
    }
    out
}

/// The plate velocity of each of `worlds` at each step of `steps` (within the block), from the
/// samples of its timing ([`runs`]), into `table` (resized): world `w` in column `w` of a
/// table of as many columns as worlds (see [`Plate`]); returns the table's values.
fn tabulate<'t>(
    worlds: &[Member],
    shared: &[Option<Phases>],
    runs: &[(Range<usize>, Option<Phases>)],
    table: &'t mut Vec<Line>,
    steps: Range<usize>,
) -> &'t [f64] {
    // (every value is written below: the runs take every column)
    let len = 3 * worlds.len() * steps.len();
    table.resize(len.div_ceil(8), Line([0.0; 8]));
    let mut out = Columns {
        values: &mut Line::values_mut(table)[..len],
        width: worlds.len(),
    };
    let mut motions: Vec<&PlateMotion> = Vec::with_capacity(worlds.len());
    for (run, own) in runs {
        let phases = own
            .as_ref()
            .or(shared[worlds[run.start].timing].as_ref())
            .expect("a timing's samples, shared or its own");
        motions.clear();
        motions.extend(worlds[run.clone()].iter().map(|w| w.motion));
        phases.extend_across(&motions, steps.clone(), &mut out, run.start);
    }
    &Line::values_mut(table)[..len]
}

/// A cache line of the velocity table. The table is kept in whole lines so that a row of eight
/// worlds (a vector's store) never straddles two: straddling stores took twice the time (the
/// table was 6 % of a batch of 8-point worlds, and is 3 % aligned; Intel Xeon).
#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct Line([f64; 8]);

impl Line {
    /// The values of `lines`, in order.
    fn values_mut(lines: &mut [Line]) -> &mut [f64] {
        // SAFETY: a line is eight f64 and nothing else (repr C, size 64, no padding).
        unsafe { std::slice::from_raw_parts_mut(lines.as_mut_ptr().cast(), 8 * lines.len()) }
    }
}

/// The state of one group's points, kept from block to block.
struct Group(Box<[[f64; LANES]; ARRAYS]>);

/// Group states kept from run to run: fresh memory costs a page fault per 4 KiB on every call
/// once the allocator has returned it to the system (that was a fifth of a 2-step call of 500
/// worlds of 8 points). At most [`SPARE_STATES`] (6 KiB each) are kept.
static SPARE: Mutex<Vec<Group>> = Mutex::new(Vec::new());
const SPARE_STATES: usize = 1024;

fn spare() -> std::sync::MutexGuard<'static, Vec<Group>> {
    SPARE.lock().unwrap_or_else(|e| e.into_inner())
}

std::thread_local! {
    /// Each thread's table of plate velocity (up to 8 worlds' at [`PIECE`] steps, 24 KiB), kept
    /// from group to group: no lock (two threads contending for a shared one waited in the
    /// kernel) and no fresh memory.
    static TABLE: std::cell::Cell<Vec<Line>> = const { std::cell::Cell::new(Vec::new()) };
}

impl Group {
    /// `n` groups, in memory given back by earlier runs ([`Group::give_back`]) where there is
    /// some. Their state is cleared as their first block starts ([`Group::run`]).
    fn take(n: usize) -> Vec<Group> {
        let mut out = {
            let mut spare = spare();
            let keep = spare.len().saturating_sub(n);
            spare.split_off(keep)
        };
        out.resize_with(n, || Group(zeroed()));
        out
    }

    /// Keeps `groups` for the next run (within [`SPARE_STATES`]).
    fn give_back(groups: Vec<Group>) {
        let mut spare = spare();
        let room = SPARE_STATES.saturating_sub(spare.len());
        spare.extend(groups.into_iter().take(room));
    }

    /// Advances the point parts of `worlds` through the block of `steps`, recording as
    /// [`Points::run`] does (their initial state read from `start` as the first block starts);
    /// `shared` holds the samples of the timings that span groups ([`shared_phases`]).
    fn run(
        &mut self,
        worlds: &[Member],
        shared: &[Option<Phases>],
        steps: Range<usize>,
        cfg: &Config,
        start: &Start,
    ) {
        let first = steps.start;
        let mut table = TABLE.take();
        let runs = runs(worlds, shared, steps.clone(), cfg.dt);
        let m = start.parts.len();
        let stride = stride(m);
        let lanes = stride * worlds.len();
        assert!(lanes <= LANES, "a group of {lanes} lanes");
        if first == 0 {
            // Zero lanes between worlds: no part, never recorded, and (inactive) frozen on a
            // plate with an edge. The state may be an earlier run's: lanes are independent, so
            // what it left there changes no result, but it could be NaN or subnormal (slow).
            // SAFETY: every byte zero is every f64 0.0.
            unsafe { std::ptr::write_bytes(&mut *self.0, 0, 1) };
        }
        let base = Base::local(&mut self.0);
        if first == 0 {
            for (w, world) in worlds.iter().enumerate() {
                let own = start.friction.map(|f| f.world(start.parts, world.b));
                let parts = own.as_ref().unwrap_or(start.parts);
                let u0 = world.motion.velocity(0.0);
                let src = Source::new(parts, None, cfg, u0, start.not_finite);
                // SAFETY: the world's lanes are within the group's buffer, which this call
                // alone addresses.
                unsafe { src.fill(&base, w * stride, 0, m, false) };
                // SAFETY: just written.
                let (l, _) = unsafe { base.chunk(w * stride, m, false) };
                write(&l, 0, 0, &world.rec, None);
            }
        }
        let rec = worlds[0].rec;
        // Through the block a piece at a time: the piece's table stays in the core's L1 cache
        // while the kernel reads it.
        for piece in (first..steps.end).step_by(PIECE) {
            let piece = piece..(piece + PIECE).min(steps.end);
            let values = tabulate(worlds, shared, &runs, &mut table, piece.clone());
            let row = 3 * worlds.len(); // values a step
            let mut done = piece.start;
            while done < piece.end {
                let end = rec.next_after(done).min(piece.end);
                let rows = &values[(done - piece.start) * row..(end - piece.start) * row];
                // SAFETY: every world's lanes are written (above, or by an earlier block), and
                // the padding is zero; nothing else addresses the buffer while `all` lives.
                let (mut all, _) = unsafe { base.chunk(0, lanes, false) };
                kernel::run(
                    Plate::worlds(rows, worlds.len(), stride),
                    done,
                    cfg.dt,
                    half_side(cfg),
                    &mut all,
                );
                done = end;
                if let Some(row) = rec.row(done) {
                    for (w, world) in worlds.iter().enumerate() {
                        // SAFETY: as above (`all` is gone).
                        let (l, _) = unsafe { base.chunk(w * stride, m, false) };
                        write(&l, 0, row, &world.rec, None);
                    }
                }
            }
        }
        let steps = steps.len();
        if rec.last(first, steps) {
            for (w, world) in worlds.iter().enumerate() {
                // SAFETY: as above.
                let (l, _) = unsafe { base.chunk(w * stride, m, false) };
                Points::ended(&l, None, 0, None, &world.rec, cfg.dt);
            }
        }
        TABLE.set(table);
    }
}
