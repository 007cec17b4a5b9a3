//! Worlds of a batch whose motions share their timing ([`PlateMotion::timing`]: the planner's
//! rollouts, one kind of pulse at many places) share their phasor samples: a block's samples are
//! taken once for all of them ([`shared`]) and each world's plate velocity is evaluated from them,
//! to the bit what its own samples give. Taking them world by world cost worlds of 64 points
//! almost half as much again as their stepping.

use std::collections::HashMap;
use std::ops::Range;

use rayon::prelude::*;

use crate::motion::{Phases, PlateMotion};

/// Each motion's timing class, numbered in the order each first appears.
pub(super) fn classes(motions: &[&PlateMotion]) -> Vec<usize> {
    if motions.len() == 1 {
        return vec![0]; // (no key to build: a world alone)
    }
    let mut numbers: HashMap<Vec<u64>, usize> = HashMap::new();
    // (a motion of the previous one's timing, compared word by word, builds no key and skips
    // the hash: a batch's rollouts mostly are)
    let mut last: Option<(&PlateMotion, usize)> = None;
    motions
        .iter()
        .map(|&m| {
            let class = match last {
                Some((prev, class)) if prev.same_timing(m) => class,
                _ => {
                    let next = numbers.len();
                    *numbers.entry(m.timing()).or_insert(next)
                }
            };
            last = Some((m, class));
            class
        })
        .collect()
}

/// The order in which to run `motions`, as `(timing, index)` pairs: those with the same timing
/// class ([`classes`]) are neighbours, in their order within it.
pub(super) fn by_timing(motions: &[&PlateMotion]) -> Vec<(usize, usize)> {
    let mut order: Vec<(usize, usize)> = classes(motions)
        .into_iter()
        .enumerate()
        .map(|(b, class)| (class, b))
        .collect();
    order.sort_unstable(); // by timing, then index
    order
}

/// The phasor samples of the block `steps` for every timing class of more than `more_than` of
/// `worlds` (`(class, motion)` pairs; classes numbered below `count`), indexed by class: `None`
/// for the others, which take their own. Where no class has that many, no parallel section
/// runs (called from outside the pool, one hands its work to the pool's threads: every block of
/// every call would pay for nothing).
pub(super) fn shared<'m>(
    worlds: impl Iterator<Item = (usize, &'m PlateMotion)>,
    count: usize,
    more_than: usize,
    steps: Range<usize>,
    dt: f64,
) -> Vec<Option<Phases>> {
    let mut leads: Vec<(Option<&PlateMotion>, usize)> = vec![(None, 0); count];
    for (class, motion) in worlds {
        let (lead, n) = &mut leads[class];
        lead.get_or_insert(motion);
        *n += 1;
    }
    if leads.iter().all(|&(_, n)| n <= more_than) {
        return (0..count).map(|_| None).collect();
    }
    leads
        .into_par_iter()
        .with_min_len(crate::parallel::min_len())
        .map(|(lead, n)| {
            lead.filter(|_| n > more_than)
                .map(|m| Phases::of(m, steps.clone(), dt))
        })
        .collect()
}
