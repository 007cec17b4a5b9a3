//! Batches of small worlds run side by side. A world of a few point parts fills only a fraction
//! of a register tile, and one vector's steps form a dependency chain of some 60 cycles: run
//! alone, a world of 8 parts cost 5x a large world per part-step (the planner's rollouts). Here
//! the point parts of a group of worlds share the tiles, interleaved ([`Plate::interleaved`]):
//! eight worlds to a vector, one a lane, vector `i` of a set of eight worlds holding their part
//! `i`. A vector then reads its eight worlds' plate velocities with one load a component, and a
//! tile of one set's vectors (worlds of 8 points or more) reads them once for all its vectors, as
//! one world's tile reads its one table. Worlds of fewer points take several sets to a group
//! (worlds of 3 points: two sets, 16 worlds in six vectors), so no lane is padding but the last
//! group's. Each lane does exactly what it does in a world run alone, so the results are bitwise
//! the same.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

use rayon::prelude::*;

use super::base::{Base, PLANAR, STUCK};
use super::kernel::{self, Jets, Plate};
use super::points::{write, Points};
use super::record::{Rec, Recorder, RunState, Stacked};
use super::source::Source;
use super::timing::{self, by_timing};
use super::{half_side, moves_with_plate, Config, Error, PartsView, WorldRows};
use crate::motion::{Columns, JetStint, Phases, PlateMotion};

/// Worlds with at most this many point parts (and nothing else) are run in groups.
pub(super) const MAX_POINTS: usize = 32;

/// Sets of eight worlds a group of worlds of `m` points takes: as many as fill a tile of eight
/// vectors (at least one).
fn sets(m: usize) -> usize {
    (8 / m.max(1)).max(1)
}

/// Worlds per group for worlds of `m` points (every set's eight, the last group's may be
/// absent).
fn worlds_per_group(m: usize) -> usize {
    8 * sets(m)
}

/// The lanes of a group of worlds of `m` points.
fn lanes(m: usize) -> usize {
    8 * sets(m) * m
}

/// The lane of part `i` of world `w` of a group of worlds of `m` points: vector `i` of the
/// world's set of eight, lane `w % 8` (as [`Plate::column`] reads it). The copies of whole
/// arrays below walk the lanes in order instead (computing it for every part scattered the
/// stores: a 2-step call of 500 worlds took 0.25 µs a world against 0.19); the tests check them
/// against it.
fn lane(m: usize, w: usize, i: usize) -> usize {
    8 * (w / 8 * m + i) + w % 8
}

/// The [`PLANAR`] arrays of `lanes` lanes each of `plain` (world `w`'s part `i` in lane
/// `w m + i`) into `state`, each part in its lane (worlds of `m` points).
fn interleave(plain: &[f64], state: &mut [f64], m: usize, lanes: usize) {
    let (plain, state) = (&plain[..PLANAR * lanes], &mut state[..PLANAR * lanes]);
    for (from, to) in plain.chunks_exact(lanes).zip(state.chunks_exact_mut(lanes)) {
        // vector `g m + i`: part `i` of the eight worlds of set `g`, which start at `8 g m`
        for (set, to) in from.chunks_exact(8 * m).zip(to.chunks_exact_mut(8 * m)) {
            for (i, to) in to.chunks_exact_mut(8).enumerate() {
                for (r, to) in to.iter_mut().enumerate() {
                    *to = set[r * m + i];
                }
            }
        }
    }
}

/// What [`interleave`] does, undone, for the arrays a record reads: position, velocity, stuck
/// and the step of leaving (not `active`, and not the friction, which do not change).
fn deinterleave(state: &[f64], plain: &mut [f64], m: usize, lanes: usize) {
    for a in [0, 1, 2, 3, 4, 6] {
        let (from, to) = (
            &state[a * lanes..][..lanes],
            &mut plain[a * lanes..][..lanes],
        );
        for (from, set) in from.chunks_exact(8 * m).zip(to.chunks_exact_mut(8 * m)) {
            for (i, from) in from.chunks_exact(8).enumerate() {
                for (r, &x) in from.iter().enumerate() {
                    set[r * m + i] = x;
                }
            }
        }
    }
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
pub(super) fn simulate<E, B>(
    motions: &[&PlateMotion],
    parts: &PartsView,
    cfg: &Config,
    friction: Option<&WorldRows>,
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
    friction: Option<&'a WorldRows<'a>>,
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

/// Values of plate velocity a group tabulates at a time: 8 worlds at 128 steps, 24 KiB, within
/// the L1 cache.
const PIECE: usize = 3 * 8 * 128;

/// Steps a group of `width` columns tabulates at a time ([`PIECE`] values, at least 16 steps).
fn piece(width: usize) -> usize {
    (PIECE / (3 * width)).max(16)
}

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
/// samples of its timing ([`runs`]), into `table` (resized): world `w` in column `w` of a table
/// of `width` columns (see [`Plate`]; columns past the worlds zero); returns the table's values.
fn tabulate<'t>(
    worlds: &[Member],
    width: usize,
    shared: &[Option<Phases>],
    runs: &[(Range<usize>, Option<Phases>)],
    table: &'t mut Vec<Line>,
    steps: Range<usize>,
) -> &'t [f64] {
    // (every value is written below: the runs take every world's column)
    let len = 3 * width * steps.len();
    table.resize(len.div_ceil(8), Line([0.0; 8]));
    let values = &mut Line::values_mut(table)[..len];
    if worlds.len() < width {
        for row in values.chunks_exact_mut(width) {
            row[worlds.len()..].fill(0.0);
        }
    }
    let mut out = Columns { values, width };
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

/// The state of one group's points, kept from block to block: the point arrays' first
/// [`PLANAR`] (a group's points stay on the plane), each of as many lanes as the group has
/// ([`lanes`]), one after the other.
struct Group(Vec<f64>);

/// Group states kept from run to run: fresh memory costs a page fault per 4 KiB on every call
/// once the allocator has returned it to the system (that was a fifth of a 2-step call of 500
/// worlds of 8 points). At most [`SPARE_STATES`] (5 to 18 KiB each) are kept.
static SPARE: Mutex<Vec<Group>> = Mutex::new(Vec::new());
const SPARE_STATES: usize = 1024;

fn spare() -> std::sync::MutexGuard<'static, Vec<Group>> {
    SPARE.lock().unwrap_or_else(|e| e.into_inner())
}

std::thread_local! {
    /// Each thread's table of plate velocity ([`PIECE`] values, 24 KiB, or 16 steps'), kept
    /// from group to group: no lock (two threads contending for a shared one waited in the
    /// kernel) and no fresh memory.
    static TABLE: std::cell::Cell<Vec<Line>> = const { std::cell::Cell::new(Vec::new()) };
    /// Each thread's room for a group's points laid out world by world (`m` lanes a world, as a
    /// world run alone holds them), where they are read and recorded from.
    static PLAIN: std::cell::Cell<Vec<f64>> = const { std::cell::Cell::new(Vec::new()) };
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
        out.resize_with(n, || Group(Vec::new()));
        out
    }

    /// Keeps `groups` for the next run (within [`SPARE_STATES`]).
    fn give_back(groups: Vec<Group>) {
        let mut spare = spare();
        let room = SPARE_STATES.saturating_sub(spare.len());
        spare.extend(groups.into_iter().take(room));
    }

    /// Reads the points of `worlds` as their first block starts and records their initial state.
    /// Worlds that share their parts (no friction of their own) read them once, as world 0 holds
    /// them (`plain`'s first `m` lanes): each lane of the group takes its part's state but the
    /// stuck flag, which depends on its world's plate velocity at the start. Worlds with their
    /// own friction are each read as a world run alone holds them, then interleaved. Absent
    /// worlds' lanes (the last group's) are zero: no part, never recorded, and (inactive) frozen
    /// on a plate with an edge. (What an earlier run left there would change no result, lanes
    /// being independent, but it could be NaN or subnormal: slow.)
    fn start(
        &mut self,
        worlds: &[Member],
        m: usize,
        lanes: usize,
        cfg: &Config,
        start: &Start,
        plain: &mut [f64],
    ) {
        if start.friction.is_some() {
            for a in 0..PLANAR {
                plain[a * lanes + worlds.len() * m..(a + 1) * lanes].fill(0.0);
            }
            let base = Base::planar(plain, lanes);
            for (w, world) in worlds.iter().enumerate() {
                let own = start.friction.map(|f| f.world(start.parts, world.b));
                let parts = own.as_ref().unwrap_or(start.parts);
                let u0 = world.motion.velocity(0.0);
                let src = Source::new(parts, None, cfg, u0, start.not_finite);
                // SAFETY: the world's lanes are within the buffer, which nothing else addresses;
                // then just written.
                unsafe {
                    src.fill(&base, w * m, 0, m, false);
                    write(&base.chunk(w * m, m, false).0, 0, 0, &world.rec, None);
                }
            }
            interleave(plain, &mut self.0, m, lanes);
            return;
        }
        let base = Base::planar(plain, lanes);
        let u0 = worlds[0].motion.velocity(0.0);
        let src = Source::new(start.parts, None, cfg, u0, start.not_finite);
        // SAFETY: the first `m` lanes are within the buffer, which nothing else addresses.
        unsafe { src.fill(&base, 0, 0, m, false) };
        let n = worlds.len();
        let state = &mut self.0[..PLANAR * lanes];
        for (from, to) in plain.chunks_exact(lanes).zip(state.chunks_exact_mut(lanes)) {
            // vector `g m + i`: part `i` of the eight worlds of set `g` (those present)
            for (g, set) in to.chunks_exact_mut(8 * m).enumerate() {
                let present = n.saturating_sub(8 * g).min(8);
                for (&value, to) in from[..m].iter().zip(set.chunks_exact_mut(8)) {
                    to[..present].fill(value);
                    to[present..].fill(0.0);
                }
            }
        }
        let at = |a: usize| &plain[a * lanes..][..m];
        let (x, y, vx, vy) = (at(0), at(1), at(2), at(3));
        let mut stuck = [0.0; MAX_POINTS];
        for (w, world) in worlds.iter().enumerate() {
            let u = if w == 0 {
                u0
            } else {
                world.motion.velocity(0.0)
            };
            for (i, s) in stuck[..m].iter_mut().enumerate() {
                // (as `Source::fill` finds it)
                *s = if moves_with_plate([x[i], y[i]], [vx[i], vy[i]], u) {
                    1.0
                } else {
                    0.0
                };
                state[STUCK * lanes + lane(m, w, i)] = *s;
            }
            let row = RunState {
                x,
                y,
                vx,
                vy,
                stuck: &stuck[..m],
            };
            // SAFETY: row 0 and the parts below m, which this group alone writes for the world.
            unsafe { world.rec.points_run(0, 0, &row) };
            world.rec.fence();
        }
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
        let (lanes, width) = (lanes(m), worlds_per_group(m));
        assert!(
            m <= MAX_POINTS && worlds.len() <= width,
            "a group of {} worlds of {m} points",
            worlds.len()
        );
        let mut plain = PLAIN.take();
        for buf in [&mut self.0, &mut plain] {
            if buf.len() < PLANAR * lanes {
                buf.resize(PLANAR * lanes, 0.0);
            }
        }
        if first == 0 {
            self.start(worlds, m, lanes, cfg, start, &mut plain);
        }
        let rec = worlds[0].rec;
        // Jets the kernel evaluates itself, where it can (worlds of one timing, on the build
        // that does, in the stints where every world plays a jet): no table, and the same bits
        // as the table's. (Absent worlds' sets, the last group's, have zero coefficients: a
        // plate at rest.)
        let mut stints = Vec::new();
        if runs.len() == 1 && Plate::jets_built(kernel::simd()) {
            let phases = runs[0].1.as_ref().or(shared[worlds[0].timing].as_ref());
            let motions: Vec<&PlateMotion> = worlds.iter().map(|w| w.motion).collect();
            stints = (phases.expect("a timing's samples, shared or its own"))
                .jets(&motions, steps.clone());
            for coef in stints.iter_mut().filter_map(|st| st.coef.as_mut()) {
                coef.resize(sets(m), [[0.0; 8]; 5]);
            }
        }
        let jets = |st: &JetStint| st.coef.is_some();
        // Through the block a piece at a time: the piece's table stays in the core's L1 cache
        // while the kernel reads it (the whole block at once where no step needs a table).
        let len = if !stints.is_empty() && stints.iter().all(jets) {
            steps.len()
        } else {
            piece(width)
        };
        for piece in (first..steps.end).step_by(len) {
            let piece = piece..(piece + len).min(steps.end);
            let within = |st: &&JetStint| st.steps.start < piece.end && piece.start < st.steps.end;
            let values = if !stints.is_empty() && stints.iter().filter(within).all(jets) {
                &[][..]
            } else {
                tabulate(worlds, width, shared, &runs, &mut table, piece.clone())
            };
            let row = 3 * width; // values a step
            let mut done = piece.start;
            while done < piece.end {
                let mut end = rec.next_after(done).min(piece.end);
                let stint = stints.iter().find(|st| st.steps.contains(&done));
                let plate = match stint.and_then(|st| Some((st, st.coef.as_ref()?))) {
                    Some((st, coef)) => {
                        end = end.min(st.steps.end);
                        let from = st.steps.start;
                        let samples = &st.samples[done - from..end - from];
                        Plate::jets(Jets { samples, coef }, m)
                    }
                    None => {
                        // (to the stint's end at most, where the next may take jets)
                        end = end.min(stint.map_or(end, |st| st.steps.end));
                        let rows = &values[(done - piece.start) * row..(end - piece.start) * row];
                        Plate::interleaved(rows, width, m)
                    }
                };
                let base = Base::planar(&mut self.0, lanes);
                // SAFETY: every lane is written (above, or by an earlier block); nothing else
                // addresses the buffer while `all` lives.
                let (mut all, _) = unsafe { base.chunk(0, lanes, false) };
                kernel::run(plate, done, cfg.dt, half_side(cfg), &mut all);
                done = end;
                if let Some(row) = rec.row(done) {
                    // each world's state as a world run alone holds it
                    deinterleave(&self.0, &mut plain, m, lanes);
                    let base = Base::planar(&mut plain, lanes);
                    for (w, world) in worlds.iter().enumerate() {
                        // SAFETY: just written; nothing else addresses the buffer.
                        let (l, _) = unsafe { base.chunk(w * m, m, false) };
                        write(&l, 0, row, &world.rec, None);
                    }
                }
            }
        }
        if rec.last(first, steps.len()) {
            // (the last step is always recorded: `plain` holds the state it recorded)
            let base = Base::planar(&mut plain, lanes);
            for (w, world) in worlds.iter().enumerate() {
                // SAFETY: as above.
                let (l, _) = unsafe { base.chunk(w * m, m, false) };
                Points::ended(&l, None, 0, None, &world.rec, cfg.dt);
            }
        }
        PLAIN.set(plain);
        TABLE.set(table);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each part of each world lands in its lane, whose column is its world's, and comes back.
    #[test]
    fn interleaving_puts_each_part_in_its_worlds_lane_and_back() {
        for m in 1..=MAX_POINTS {
            let (lanes, width) = (lanes(m), worlds_per_group(m));
            assert!(
                lanes <= 8 * 8 * 4 && lanes.is_multiple_of(8),
                "{m} points: {lanes}"
            );
            let plain: Vec<f64> = (0..PLANAR * lanes).map(|k| k as f64).collect();
            let mut state = vec![f64::NAN; PLANAR * lanes];
            interleave(&plain, &mut state, m, lanes);
            let table = vec![0.0; 3 * width];
            let plate = Plate::interleaved(&table, width, m);
            let mut seen = vec![false; lanes];
            for w in 0..width {
                for i in 0..m {
                    let l = lane(m, w, i);
                    assert!(!seen[l], "{m} points: lane {l} twice");
                    seen[l] = true;
                    assert_eq!(plate.column(l), w, "{m} points: world {w}, part {i}");
                    for a in 0..PLANAR {
                        assert_eq!(state[a * lanes + l], plain[a * lanes + w * m + i]);
                    }
                }
            }
            let mut back = vec![f64::NAN; PLANAR * lanes];
            deinterleave(&state, &mut back, m, lanes);
            for a in [0, 1, 2, 3, 4, 6] {
                let arrays = a * lanes..(a + 1) * lanes;
                assert_eq!(back[arrays.clone()], plain[arrays], "{m} points, array {a}");
            }
        }
    }
}
