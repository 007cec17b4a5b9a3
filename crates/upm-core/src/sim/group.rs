//! Batches of small worlds run side by side. A world of a few point parts fills only a fraction
//! of a register tile, and one vector's steps form a dependency chain of some 60 cycles: run
//! alone, a world of 8 parts cost 5x a large world per part-step (the planner's rollouts). Here
//! the point parts of up to [`LANES`] / `stride` worlds share one tile, world `w` in the lanes
//! `w * stride ..` (padded to whole vectors), each vector stepping under its own world's plate
//! velocity ([`Plate::worlds`]). Each lane does exactly what it does in a world run alone, so the
//! results are bitwise the same.

use std::collections::HashMap;
use std::ops::Range;
use std::sync::Mutex;

use rayon::prelude::*;

use super::kernel::{self, Plate};
use super::points::{write, zeroed, Base, Points, ARRAYS};
use super::{half_side, Config, World};
use crate::motion::{Phases, PlateMotion};

/// Lanes of a group: one full register tile of the widest build.
const LANES: usize = 64;

/// Worlds with at most this many point parts (and nothing else) are run in groups.
pub(super) const MAX_POINTS: usize = 32;

/// The lanes a world of `m` points takes in a group: whole vectors of eight.
pub(super) fn stride(m: usize) -> usize {
    m.div_ceil(8).max(1) * 8
}

/// Worlds per group for worlds of `m` points.
pub(super) fn worlds_per_group(m: usize) -> usize {
    (LANES / stride(m)).max(1)
}

/// The order in which to run `motions`, as `(timing, index)` pairs: those with the same timing
/// (see `PlateMotion::timing`; numbered in the order each first appears) are neighbours, in their
/// order within it. A group of neighbours turns its plate's phasors once (each world records
/// into its own place, so the order is free).
pub(super) fn by_timing(motions: &[&PlateMotion]) -> Vec<(usize, usize)> {
    let mut classes: HashMap<Vec<u64>, usize> = HashMap::new();
    // (a motion of the previous one's timing, compared word by word, builds no key and skips
    // the hash: a batch's rollouts mostly are)
    let mut last: Option<(&PlateMotion, usize)> = None;
    let mut order: Vec<(usize, usize)> = motions
        .iter()
        .enumerate()
        .map(|(b, m)| {
            let class = match last {
                Some((prev, class)) if prev.timing_words().eq(m.timing_words()) => class,
                _ => {
                    let next = classes.len();
                    *classes.entry(m.timing()).or_insert(next)
                }
            };
            last = Some((m, class));
            (class, b)
        })
        .collect();
    order.sort_unstable(); // by timing, then index
    order
}

/// The phasor samples of the block `steps` for every timing whose worlds fill more than one
/// group, taken once here instead of once per group (indexed by timing; `None` for the other
/// timings, whose one group takes its own). `worlds` are in the order of [`by_timing`].
pub(super) fn shared_phases(
    worlds: &[World],
    per_group: usize,
    steps: Range<usize>,
    dt: f64,
) -> Vec<Option<Phases>> {
    let classes = worlds.last().map_or(0, |w| w.timing + 1);
    let mut leads: Vec<(Option<&PlateMotion>, usize)> = vec![(None, 0); classes];
    for w in worlds {
        let (lead, count) = &mut leads[w.timing];
        lead.get_or_insert(w.motion);
        *count += 1;
    }
    leads
        .into_par_iter()
        .map(|(lead, count)| {
            lead.filter(|_| count > per_group)
                .map(|m| Phases::of(m, steps.clone(), dt))
        })
        .collect()
}

/// Steps whose plate velocities a group tabulates at a time: 8 worlds' tables of 128 steps take
/// 24 KiB, within the L1 cache.
const PIECE: usize = 128;

/// The runs of one timing among `worlds` (neighbours, sorted so by [`by_timing`]), each with the
/// samples of the block `steps`: the batch's in `shared` where the timing spans groups (`None`
/// here), else the run's own, taken now.
fn runs(
    worlds: &[World],
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

/// The plate velocity of each of `worlds` (into the same place of `tables`, emptied first) at
/// each step of `steps` (within the block), from the samples of its timing ([`runs`]).
fn tabulate(
    worlds: &[World],
    shared: &[Option<Phases>],
    runs: &[(Range<usize>, Option<Phases>)],
    tables: &mut [Vec<[f64; 3]>],
    steps: Range<usize>,
) {
    tables.iter_mut().for_each(Vec::clear);
    for (run, own) in runs {
        let phases = own
            .as_ref()
            .or(shared[worlds[run.start].timing].as_ref())
            .expect("a timing's samples, shared or its own");
        for (w, table) in worlds[run.clone()].iter().zip(&mut tables[run.clone()]) {
            phases.extend_steps(w.motion, steps.clone(), table);
        }
    }
}

/// The state of one group's points, kept from block to block.
pub(super) struct Group(Box<[[f64; LANES]; ARRAYS]>);

/// Memory kept from run to run: group states and sets of tables given back by finished runs.
/// Fresh memory costs a page fault per 4 KiB on every call once the allocator has returned it
/// to the system: that was a fifth of a 2-step call of 500 worlds of 8 points.
struct Spare {
    states: Vec<Group>,
    tables: Vec<Vec<Vec<[f64; 3]>>>,
}

/// At most this many group states (6 KiB each) and sets of tables (one a thread at work: up to 8
/// tables of [`PIECE`] rows, 24 KiB) are kept.
const SPARE_STATES: usize = 1024;
const SPARE_TABLES: usize = 64;

fn spare() -> std::sync::MutexGuard<'static, Spare> {
    static SPARE: Mutex<Spare> = Mutex::new(Spare {
        states: Vec::new(),
        tables: Vec::new(),
    });
    SPARE.lock().unwrap_or_else(|e| e.into_inner())
}

impl Group {
    /// `n` groups, in memory given back by earlier runs ([`Group::give_back`]) where there is
    /// some. Their state is cleared as their first block starts ([`Group::run`]).
    pub(super) fn take(n: usize) -> Vec<Group> {
        let mut out = {
            let mut spare = spare();
            let keep = spare.states.len().saturating_sub(n);
            spare.states.split_off(keep)
        };
        out.resize_with(n, || Group(zeroed()));
        out
    }

    /// Keeps `groups` for the next run (within [`SPARE_STATES`]).
    pub(super) fn give_back(groups: Vec<Group>) {
        let mut spare = spare();
        let room = SPARE_STATES.saturating_sub(spare.states.len());
        spare.states.extend(groups.into_iter().take(room));
    }

    /// Room for `n` tables of plate velocity, empty: a set given back by an earlier group when
    /// one is kept.
    fn tables(n: usize) -> Vec<Vec<[f64; 3]>> {
        let mut t = spare().tables.pop().unwrap_or_default();
        t.resize_with(n, Vec::new);
        t.iter_mut().for_each(Vec::clear);
        t
    }

    /// Advances the point parts of `worlds` through the block of `steps`, recording as
    /// [`Points::run`] does; `shared` holds the samples of the timings that span groups
    /// ([`shared_phases`]).
    pub(super) fn run(
        &mut self,
        worlds: &mut [World],
        shared: &[Option<Phases>],
        steps: Range<usize>,
        cfg: &Config,
    ) {
        let first = steps.start;
        let mut tables = Group::tables(worlds.len());
        let runs = runs(worlds, shared, steps.clone(), cfg.dt);
        let m = worlds[0].points.len();
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
        for (w, world) in worlds.iter_mut().enumerate() {
            if let Some(src) = world.points.take_source() {
                // SAFETY: the world's lanes are within the group's buffer, which this call
                // alone addresses.
                unsafe { src.fill(&base, w * stride, 0, m, false) };
                // SAFETY: just written.
                let (l, _) = unsafe { base.chunk(w * stride, m, false) };
                write(&l, 0, 0, &world.rec, None);
            }
        }
        let rec = worlds[0].rec;
        // Through the block a piece at a time: the piece's tables stay in the core's L1 cache
        // while the kernel reads them.
        for piece in (first..steps.end).step_by(PIECE) {
            let piece = piece..(piece + PIECE).min(steps.end);
            tabulate(worlds, shared, &runs, &mut tables, piece.clone());
            let mut done = piece.start;
            while done < piece.end {
                let end = rec.next_after(done).min(piece.end);
                let rows: Vec<&[[f64; 3]]> = tables[..worlds.len()]
                    .iter()
                    .map(|t| &t[done - piece.start..end - piece.start])
                    .collect();
                // SAFETY: every world's lanes are written (above, or by an earlier block), and
                // the padding is zero; nothing else addresses the buffer while `all` lives.
                let (mut all, _) = unsafe { base.chunk(0, lanes, false) };
                kernel::run(
                    Plate::worlds(&rows, stride),
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
        let mut spare = spare();
        if spare.tables.len() < SPARE_TABLES {
            spare.tables.push(tables);
        }
    }
}
