//! Batches of small worlds run side by side. A world of a few point parts fills only a fraction
//! of a register tile, and one vector's steps form a dependency chain of some 60 cycles: run
//! alone, a world of 8 parts cost 5x a large world per part-step (the planner's rollouts). Here
//! the point parts of up to [`LANES`] / `stride` worlds share one tile, world `w` in the lanes
//! `w * stride ..` (padded to whole vectors), each vector stepping under its own world's plate
//! velocity ([`Plate::worlds`]). Each lane does exactly what it does in a world run alone, so the
//! results are bitwise the same.

use std::collections::HashMap;
use std::ops::Range;

use super::kernel::{self, Plate};
use super::points::{write, zeroed, Base, Points, ARRAYS};
use super::{half_side, Config, World};
use crate::motion::PlateMotion;

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
pub(super) fn by_timing(motions: &[PlateMotion]) -> Vec<(usize, usize)> {
    let mut classes: HashMap<Vec<u64>, usize> = HashMap::new();
    let mut order: Vec<(usize, usize)> = motions
        .iter()
        .enumerate()
        .map(|(b, m)| {
            let next = classes.len();
            (*classes.entry(m.timing()).or_insert(next), b)
        })
        .collect();
    order.sort_unstable(); // by timing, then index
    order
}

/// The state of one group's points, kept from block to block.
pub(super) struct Group(Box<[[f64; LANES]; ARRAYS]>);

impl Default for Group {
    fn default() -> Self {
        // Zero lanes between worlds: no part, never recorded, and (inactive) frozen on a plate
        // with an edge.
        Group(zeroed())
    }
}

impl Group {
    /// Advances the point parts of `worlds` through the block of `steps`, recording as
    /// [`Points::run`] does; `tables` is room for the worlds' plate velocities (the caller's,
    /// reused from group to group).
    pub(super) fn run(
        &mut self,
        worlds: &mut [World],
        tables: &mut Vec<Vec<[f64; 3]>>,
        steps: Range<usize>,
        cfg: &Config,
    ) {
        let first = steps.start;
        tables.resize_with(worlds.len(), Vec::new);
        tables.iter_mut().for_each(Vec::clear);
        // Sampled a hair before each step's end (see `velocities_into`); neighbours with the
        // same timing (sorted so by `by_timing`) share the work of turning the phasors.
        let mut from = 0;
        while from < worlds.len() {
            let timing = worlds[from].timing;
            let to = from
                + worlds[from..]
                    .iter()
                    .take_while(|w| w.timing == timing)
                    .count();
            let motions: Vec<&PlateMotion> = worlds[from..to].iter().map(|w| w.motion).collect();
            PlateMotion::velocities_of_all(&motions, steps.clone(), cfg.dt, &mut tables[from..to]);
            from = to;
        }
        let m = worlds[0].points.len();
        let stride = stride(m);
        let lanes = stride * worlds.len();
        assert!(lanes <= LANES, "a group of {lanes} lanes");
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
        let steps = steps.len();
        let rec = worlds[0].rec;
        let mut done = 0;
        while done < steps {
            let end = (rec.next_after(first + done) - first).min(steps);
            let rows: Vec<&[[f64; 3]]> = tables[..worlds.len()]
                .iter()
                .map(|t| &t[done..end])
                .collect();
            // SAFETY: every world's lanes are written (above, or by an earlier block), and the
            // padding is zero; nothing else addresses the buffer while `all` lives.
            let (mut all, _) = unsafe { base.chunk(0, lanes, false) };
            kernel::run(
                Plate::worlds(&rows, stride),
                first + done,
                cfg.dt,
                half_side(cfg),
                &mut all,
            );
            done = end;
            if let Some(row) = rec.row(first + done) {
                for (w, world) in worlds.iter().enumerate() {
                    // SAFETY: as above (`all` is gone).
                    let (l, _) = unsafe { base.chunk(w * stride, m, false) };
                    write(&l, 0, row, &world.rec, None);
                }
            }
        }
        if rec.last(first, steps) {
            for (w, world) in worlds.iter().enumerate() {
                // SAFETY: as above.
                let (l, _) = unsafe { base.chunk(w * stride, m, false) };
                Points::ended(&l, None, 0, None, &world.rec, cfg.dt);
            }
        }
    }
}
