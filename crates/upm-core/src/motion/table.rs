//! The plate's velocity on the simulator's uniform steps, its sines carried by rotation.
//!
//! A harmonic drive, a jet and an envelope's ramps need a sine or cosine of a phase that grows by
//! the same angle every step. Evaluating each afresh (`sin_cos` and friends) cost more than the
//! integrator's whole step for a world of a few parts (the planner's batches: about 60 % of the
//! time in `libm`). Here each such phase is a unit phasor turned by one complex multiplication a
//! step (`phasors.rs`), and evaluated exactly again at every `RESEED`-th step and wherever a step enters a new
//! stretch of the program (another item, or another part of an envelope), so the rounding it
//! gathers stays within a few units in the last place of the amplitude. Where each phasor is
//! seeded depends on the step's index alone, never on how the steps are split into calls, so
//! the table is the same to the bit for any block size or thread count.
//!
//! Motions of one timing (the same items' times, envelopes and phases; the planner's rollouts:
//! one kind of pulse at many places) turn the phasors once for all of them: the phasors are
//! sampled over a block of steps ([`Phases`]), and each motion's segment is evaluated on the
//! samples (with 8-wide vectors where the CPU has AVX-512). A batch takes each timing's samples
//! once per block for all its worlds.
//!
//! The velocity formulas of a translation, a rotation and a jet, and the stretches of an item's
//! envelope, live here once for both this table and [`PlateMotion::velocity`].

use std::ops::Range;

use super::{Item, PlateMotion, Segment};
use crate::waveform::Waveform;

/// Steps between exact evaluations of every phasor.
const RESEED: usize = 32;

/// Where a time falls within an item: the factor its envelope applies there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Stretch {
    /// Before the program, past the item's duration or outside its envelope: the plate rests.
    Off,
    /// The envelope's rising ramp.
    Attack,
    /// Full amplitude (the envelope's hold, or no envelope).
    Hold,
    /// The envelope's falling ramp.
    Decay,
}

/// `u` of a translation along `d` at speed `v`.
#[inline]
pub(super) fn along(d: &[f64; 2], v: f64) -> [f64; 3] {
    [d[0] * v, d[1] * v, 0.0]
}

/// `u` of a rotation about `c` at rate `w`.
#[inline]
pub(super) fn about(c: &[f64; 2], w: f64) -> [f64; 3] {
    [w * c[1], -w * c[0], w]
}

/// A jet's feeding profile `cos(w t) - cos(2 w t)` from the cosine and sine of its phase.
#[inline]
pub(super) fn feed(c1: f64, s1: f64) -> f64 {
    c1 - (c1 - s1) * (c1 + s1)
}

/// `u` of a jet about `c` from its feeding profile `g` ([`feed`]) and its spin
/// `w = 2A/rho sin(2wt/3)`; `(tx, ty) = A d`.
#[inline]
pub(super) fn jet(c: &[f64; 2], (tx, ty): (f64, f64), g: f64, w: f64) -> [f64; 3] {
    [tx * g + w * c[1], ty * g - w * c[0], w]
}

/// The sample time of step `s`: a hair before the step's end.
#[inline]
pub(super) fn sample_time(s: usize, dt: f64) -> f64 {
    ((s + 1) as f64 - 1e-6) * dt
}

impl PlateMotion {
    /// The item playing at `t` [s] (the first one before the program starts).
    fn item_at(&self, t: f64) -> usize {
        self.starts.partition_point(|&s| s <= t).saturating_sub(1)
    }

    /// The stretch of item `i` at program time `t` [s] (as [`PlateMotion::velocity`] decides
    /// between rest, ramp and hold).
    fn stretch(&self, i: usize, t: f64) -> Stretch {
        let item = &self.items[i];
        let local = t - self.starts[i];
        if t < 0.0 || item.duration.is_some_and(|d| local >= d) {
            return Stretch::Off;
        }
        item.envelope
            .map_or(Stretch::Hold, |env| env.stretch(local))
    }

    /// The item and stretch of step `s`.
    fn place(&self, s: usize, dt: f64) -> (usize, Stretch) {
        let t = sample_time(s, dt);
        let i = self.item_at(t);
        (i, self.stretch(i, t))
    }
}

impl PlateMotion {
    /// Appends the velocity at `t_s = (s + 1 - 1e-6) dt` for every step `s` in `steps` to `out`:
    /// the simulator's table of a block of steps (the sample a hair before each step's end puts a
    /// program boundary on a step end in the step before it, whatever the rounding). Equal to
    /// [`PlateMotion::velocity`] at each `t_s` to a few units in the last place of the amplitude,
    /// its sines carried from step to step by rotation (see the module), and the same to the bit
    /// however the steps are split into calls.
    pub fn velocities_into(&self, steps: Range<usize>, dt: f64, out: &mut Vec<[f64; 3]>) {
        fill(self, steps, dt, out);
    }

    /// What the table's phasors and stretches depend on: the items' start times, durations and
    /// envelopes, and the phases their segments turn (a harmonic drive's fundamental, a jet's).
    /// Motions with equal keys have the same phasors at every step, so [`fill_many`] turns them
    /// once for all of them (the planner's rollouts: one kind of pulse at many places).
    pub(crate) fn timing(&self) -> Vec<u64> {
        let starts = self.starts.iter().map(|s| s.to_bits());
        starts
            .chain(self.items.iter().flat_map(timing_words))
            .collect()
    }

    /// Whether `other`'s [`PlateMotion::timing`] is this motion's, compared word by word without
    /// building either key (a batch compares each of its motions with the one before: most are
    /// alike; chained iterators took about a tenth of a 2-step call of 500 worlds).
    pub(crate) fn same_timing(&self, other: &PlateMotion) -> bool {
        let bits = |a: &f64, b: &f64| a.to_bits() == b.to_bits();
        self.starts.len() == other.starts.len()
            && self.items.len() == other.items.len()
            && self
                .starts
                .iter()
                .zip(&other.starts)
                .all(|(a, b)| bits(a, b))
            && (self.items.iter().zip(&other.items)).all(|(a, b)| {
                // (word by word into one: `==` on the arrays called `memcmp`, a twentieth of a
                // 2-step call of 500 worlds)
                let (a, b) = (timing_words(a), timing_words(b));
                a.iter().zip(&b).fold(0, |d, (x, y)| d | (x ^ y)) == 0
            })
    }
}

/// An item's words of [`PlateMotion::timing`]: the phase its segment turns, its envelope and its
/// duration.
fn timing_words(item: &Item) -> [u64; 8] {
    let phase = match &item.segment {
        Segment::Translation {
            wave: Waveform::Harmonics(h),
            ..
        }
        | Segment::Rotation {
            wave: Waveform::Harmonics(h),
            ..
        } => [1, h.omega_scale().0.to_bits()],
        Segment::Jet { omega, .. } => [2, omega.to_bits()],
        _ => [0, 0], // no phasor: the segment's own formula at each step's time
    };
    let env = item.envelope.map_or([0; 4], |e| {
        [1.0, e.attack, e.sustain, e.decay].map(f64::to_bits)
    });
    let duration = item.duration.map_or([0, 0], |d| [1, d.to_bits()]);
    let mut out = [0; 8];
    out[..2].copy_from_slice(&phase);
    out[2..6].copy_from_slice(&env);
    out[6..].copy_from_slice(&duration);
    out
}

/// Appends the velocity of `motion` at the sample time of every step in `steps` (see
/// [`PlateMotion::velocities_into`]). A step's phasors were seeded at the latest step, at or
/// before it, that is a multiple of [`RESEED`] or the first of its stretch.
pub(super) fn fill(motion: &PlateMotion, steps: Range<usize>, dt: f64, out: &mut Vec<[f64; 3]>) {
    fill_many(&[motion], steps, dt, std::slice::from_mut(out));
}

/// [`fill`] for each of `motions` into the same place of `outs`, the phasors turned once for
/// all: the motions share their [`PlateMotion::timing`]. Each table is bitwise the one [`fill`]
/// makes of its motion alone.
pub(crate) fn fill_many(
    motions: &[&PlateMotion],
    steps: Range<usize>,
    dt: f64,
    outs: &mut [Vec<[f64; 3]>],
) {
    assert_eq!(motions.len(), outs.len(), "a table for each motion");
    let Some(&lead) = motions.first() else {
        return;
    };
    debug_assert!(motions.iter().all(|m| m.timing() == lead.timing()));
    for out in outs.iter_mut() {
        out.reserve(steps.len());
    }
    // (a long table a span at a time: the samples stay a few hundred KB, whatever its length)
    for from in steps.clone().step_by(SPAN) {
        let phases = Phases::of(lead, from..(from + SPAN).min(steps.end), dt);
        for (motion, out) in motions.iter().zip(outs.iter_mut()) {
            phases.extend(motion, out);
        }
    }
}

/// Steps whose samples [`fill_many`] takes at a time (the table is the same to the bit however
/// its steps are split).
const SPAN: usize = 4096;

/// The phasor samples of one timing (see [`PlateMotion::timing`]) over a block of steps, taken
/// once and read by every motion of that timing: the stints of the block (runs of steps within
/// one stretch of one item, in order) and each step's [`Sample`].
pub(crate) struct Phases {
    stints: Vec<Stint>,
    /// The samples of the block's steps, from its first.
    samples: Vec<Sample>,
    /// The block's steps.
    steps: Range<usize>,
}

/// A run of steps within one stretch of one item: where it lies, and how many steps it has.
struct Stint {
    item: usize,
    stretch: Stretch,
    at: At,
    len: usize,
}

impl Phases {
    /// The samples of `lead`'s timing at every step of `steps`, `dt` [s] apart.
    pub(crate) fn of(lead: &PlateMotion, steps: Range<usize>, dt: f64) -> Self {
        let mut out = Phases {
            stints: Vec::new(),
            samples: Vec::with_capacity(steps.len()),
            steps: steps.clone(),
        };
        let Some(first) = steps.clone().next() else {
            return out;
        };
        let (mut i, mut stretch) = lead.place(first, dt);
        // the anchor of the first step, found by walking back through its stretch
        let mut anchor = first;
        while !anchor.is_multiple_of(RESEED) && lead.place(anchor - 1, dt) == (i, stretch) {
            anchor -= 1;
        }
        let mut ph = Phasors::new(&lead.items[i], stretch, dt);
        ph.seed(
            &lead.items[i],
            stretch,
            sample_time(anchor, dt) - lead.starts[i],
        );
        for _ in anchor..first {
            ph.advance();
        }
        let mut s = first;
        // run after run of steps in one stretch, sampled step by step
        loop {
            let run = Run {
                motion: lead,
                i,
                stretch,
                end: steps.end,
                dt,
            };
            let stop = run.stop(s);
            let (item, start) = (&lead.items[i], lead.starts[i]);
            for k in s..stop {
                out.samples.push(ph.sample(stretch));
                let next = k + 1;
                if next < stop {
                    if next.is_multiple_of(RESEED) {
                        ph.seed(item, stretch, sample_time(next, dt) - start);
                    } else {
                        ph.advance();
                    }
                }
            }
            out.stints.push(Stint {
                item: i,
                stretch,
                at: At {
                    first: s,
                    start,
                    dt,
                },
                len: stop - s,
            });
            s = stop;
            if stop >= steps.end {
                return out;
            }
            (i, stretch) = lead.place(stop, dt);
            ph = Phasors::new(&lead.items[i], stretch, dt);
            ph.seed(&lead.items[i], stretch, sample_time(s, dt) - lead.starts[i]);
        }
    }

    /// Appends the velocity of `motion` (of the timing these samples were taken for) at every
    /// step of the block to `out`.
    pub(crate) fn extend(&self, motion: &PlateMotion, out: &mut Vec<[f64; 3]>) {
        self.extend_steps(motion, self.steps.clone(), out);
    }

    /// [`Phases::extend`] for the steps `steps` of the block only.
    pub(crate) fn extend_steps(
        &self,
        motion: &PlateMotion,
        steps: Range<usize>,
        out: &mut Vec<[f64; 3]>,
    ) {
        assert!(
            self.steps.start <= steps.start && steps.end <= self.steps.end,
            "steps {steps:?} outside the block {:?}",
            self.steps
        );
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx512f") {
            /// The same loops with 8-wide vectors: the same operations in the same order, so
            /// the same bits.
            #[target_feature(enable = "avx512f")]
            unsafe fn wide(p: &Phases, m: &PlateMotion, s: Range<usize>, o: &mut Vec<[f64; 3]>) {
                p.extend_with(m, s, o);
            }
            // SAFETY: the CPU has AVX-512F (checked just above).
            return unsafe { wide(self, motion, steps, out) };
        }
        self.extend_with(motion, steps, out);
    }

    #[inline(always)]
    fn extend_with(&self, motion: &PlateMotion, steps: Range<usize>, out: &mut Vec<[f64; 3]>) {
        out.reserve(steps.len());
        for (st, first, piece) in self.pieces(steps) {
            let at = At { first, ..st.at };
            at.extend(&motion.items[st.item].segment, st.stretch, piece, out);
        }
    }

    /// The stints that overlap `steps` (within the block), each with its first step among them
    /// and its samples over them, in order.
    #[inline(always)]
    fn pieces(&self, steps: Range<usize>) -> impl Iterator<Item = (&Stint, usize, &[Sample])> {
        let base = self.steps.start;
        self.stints.iter().filter_map(move |st| {
            let (lo, hi) = (
                st.at.first.max(steps.start),
                (st.at.first + st.len).min(steps.end),
            );
            (lo < hi).then(|| (st, lo, &self.samples[lo - base..hi - base]))
        })
    }
}

/// Where a piece of samples lies: its first step, its item's start time [s], the step [s].
#[derive(Clone, Copy)]
struct At {
    first: usize,
    start: f64,
    dt: f64,
}

impl At {
    /// Appends the velocity of `segment` at each of the piece's `samples` in `stretch` (the
    /// envelope's factor applied), with its arithmetic chosen once for the piece.
    #[inline(always)]
    fn extend(
        &self,
        segment: &Segment,
        stretch: Stretch,
        samples: &[Sample],
        out: &mut Vec<[f64; 3]>,
    ) {
        match (segment, stretch) {
            (_, Stretch::Off) => out.resize(out.len() + samples.len(), [0.0; 3]),
            (
                Segment::Translation {
                    direction: d,
                    wave: Waveform::Harmonics(h),
                },
                _,
            ) => {
                let scale = h.omega_scale().1;
                put(out, samples, |_, p| {
                    along(d, scale * h.value_of(p.c, p.s) * p.env)
                });
            }
            (
                Segment::Rotation {
                    center: c,
                    wave: Waveform::Harmonics(h),
                },
                _,
            ) => {
                let scale = h.omega_scale().1;
                put(out, samples, |_, p| {
                    about(c, scale * h.value_of(p.c, p.s) * p.env)
                });
            }
            (
                Segment::Jet {
                    center: c,
                    direction: d,
                    rho,
                    amplitude,
                    ..
                },
                _,
            ) => {
                let k = 2.0 * amplitude / rho;
                let a = (amplitude * d[0], amplitude * d[1]);
                put(out, samples, |_, p| jet(c, a, p.feed, k * p.spin));
            }
            (other, _) => put(out, samples, |k, p| {
                let u = other.velocity(sample_time(self.first + k, self.dt) - self.start);
                u.map(|x| p.env * x)
            }),
        }
    }
}

/// Appends `u(k, sample)` for each of `samples`, written in place (a loop the compiler can
/// vectorise, not a push at a time).
#[inline(always)]
fn put(out: &mut Vec<[f64; 3]>, samples: &[Sample], u: impl Fn(usize, &Sample) -> [f64; 3]) {
    out.reserve(samples.len());
    let n = out.len();
    let room = &mut out.spare_capacity_mut()[..samples.len()];
    for (k, (o, p)) in room.iter_mut().zip(samples).enumerate() {
        o.write(u(k, p));
    }
    // SAFETY: the first `samples.len()` slots past the length were written just now.
    unsafe { out.set_len(n + samples.len()) };
}

/// A run of steps within one stretch of one item.
struct Run<'a> {
    motion: &'a PlateMotion,
    i: usize,
    stretch: Stretch,
    end: usize,
    dt: f64,
}

impl Run<'_> {
    /// The first step from `s` (whose place is the run's) up to `end` that lies in another
    /// item or stretch (`end` if none does). Places only move forward in time (an item's
    /// stretches follow each other, then the next item's), so a binary search finds it.
    fn stop(&self, s: usize) -> usize {
        let here = (self.i, self.stretch);
        let (mut lo, mut hi) = (s, self.end); // place(lo) == here; the answer is in (lo, hi]
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            if self.motion.place(mid, self.dt) == here {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        hi
    }
}

#[path = "across.rs"]
mod across;
pub(crate) use across::{Columns, JetStint};
#[path = "phasors.rs"]
mod phasors;
use phasors::Phasors;
pub(crate) use phasors::Sample;

#[cfg(test)]
#[path = "table_tests.rs"]
mod tests;
