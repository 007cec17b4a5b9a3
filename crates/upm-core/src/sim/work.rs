//! How much work a run is: blocks sized so that the caller's check between them (Ctrl-C) comes
//! often enough, and runs little enough to go on the calling thread alone.

use super::{Config, PartsView};

/// Steps of plate velocity tabulated at a time, at most.
const BLOCK_STEPS: usize = 4096;
/// Work of one block, in point-steps and disk-steps: about 0.17 s on one core (a point-step
/// costs about 0.62 ns), so that the caller's check between blocks (Ctrl-C) comes often enough
/// whatever the number of parts, and the points' state goes through memory (72 bytes a part,
/// each way) only once per block. A run of one block takes its points in one pass
/// (`short`): 2^28 keeps 1e6 points x 200 steps in one (at 1.6e8 it was two blocks of 160 and
/// 40 steps, 0.75 ns per point-step against 0.65 in one, Intel Xeon, one thread).
const BLOCK_POINT_STEPS: usize = 1 << 28;
const BLOCK_DISK_STEPS: usize = 200_000;

/// A polygon's step costs about this many disks' (its sliding solve is a Newton iteration).
pub(super) const POLYGON_DISKS: usize = 10;

/// Steps per block for `worlds` worlds of `points` points and `disks` disks (1..=BLOCK_STEPS).
/// The block length changes only when the caller checks for signals, never the results.
pub(super) fn block_steps(worlds: usize, points: usize, disks: usize) -> usize {
    let by_points = BLOCK_POINT_STEPS / (worlds * points).max(1);
    let by_disks = BLOCK_DISK_STEPS / (worlds * disks).max(1);
    by_points.min(by_disks).clamp(1, BLOCK_STEPS)
}
/// A disk's step costs about this many points' (the implicit stick-slip solve of its spin).
const DISK_POINTS: usize = 64;
/// Runs of fewer point-steps of work than this (about 40 us on one core, counting each disk as
/// [`DISK_POINTS`] points) run on the calling thread alone ([`crate::parallel::Alone`]).
const LITTLE_WORK: f64 = 65_536.0;

/// Whether `worlds` worlds of `points` point parts and `heavy` disks (a polygon counted as
/// [`POLYGON_DISKS`]) through `steps` steps are little work: fewer than [`LITTLE_WORK`]
/// point-steps, a disk counted as [`DISK_POINTS`] points.
pub(super) fn little(worlds: usize, steps: usize, points: usize, heavy: usize) -> bool {
    (worlds as f64) * (steps as f64) * ((points + DISK_POINTS * heavy) as f64) < LITTLE_WORK
}

/// Whether a run of `worlds` worlds of `parts` with `cfg` is little work, which runs on the
/// calling thread alone whatever the pool. A caller about to hand such a run to a pool of
/// threads (the Python binding's `threads=n`) runs it on its own thread instead: the hand-off
/// and the wait for a pool thread to wake cost more than the run (about 90 us against 17 for 8
/// points through 100 steps). Settings the run would reject count as little: it fails at once.
pub fn little_work(worlds: usize, parts: &PartsView, cfg: &Config) -> bool {
    let steps = cfg.step_count();
    if !(steps.is_finite() && steps <= 1e12) {
        return true;
    }
    let steps = steps as usize;
    let disks = (0..parts.len()).filter(|&i| parts.radius(i) > 0.0).count();
    let polygons = parts.polygons.len();
    let points = parts.len().saturating_sub(disks + polygons);
    little(worlds, steps, points, disks + POLYGON_DISKS * polygons)
}
