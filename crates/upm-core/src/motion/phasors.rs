//! The phasors of the velocity table ([`super`]): each phase of a program (a harmonic drive's,
//! a jet's and its 2/3 harmonic's, an envelope ramp's) is a unit phasor turned by one complex
//! multiplication a step, seeded exactly where the table says, and what every motion of one
//! timing reads of them at a step ([`Sample`]).

use std::f64::consts::PI;

use super::{feed, Stretch};
use crate::motion::{Item, Segment};
use crate::waveform::Waveform;

/// `e^{i x}` for a phase `x` that grows by `step` every time step.
#[derive(Debug, Clone, Copy, Default)]
struct Turn {
    c: f64,
    s: f64,
    cd: f64,
    sd: f64,
}

impl Turn {
    fn new(step: f64) -> Self {
        let (sd, cd) = step.sin_cos();
        Turn {
            c: 1.0,
            s: 0.0,
            cd,
            sd,
        }
    }

    #[inline]
    fn seed(&mut self, x: f64) {
        (self.s, self.c) = x.sin_cos();
    }

    #[inline]
    fn advance(&mut self) {
        let c = self.c * self.cd - self.s * self.sd;
        self.s = self.s * self.cd + self.c * self.sd;
        self.c = c;
    }
}

/// The segment's phase at time `t` [s] and a jet's `2/3` phase (`None`: a segment with no
/// phase); at `t = dt`, the angles the phasors turn by each step. (The same expressions as
/// [`Segment::velocity`]'s.)
fn phases(item: &Item, t: f64) -> Option<(f64, Option<f64>)> {
    match &item.segment {
        Segment::Translation {
            wave: Waveform::Harmonics(h),
            ..
        }
        | Segment::Rotation {
            wave: Waveform::Harmonics(h),
            ..
        } => Some((h.omega_scale().0 * t, None)),
        Segment::Jet { omega, .. } => {
            let x = omega * t;
            Some((x, Some(2.0 * x / 3.0)))
        }
        _ => None,
    }
}

/// The phasors of one stretch: the segment's phase, a jet's `2/3` phase, the envelope's ramp
/// (each turned only where the stretch reads it).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Phasors {
    wave: Turn,
    slow: Turn,
    ramp: Turn,
    /// Which of `wave`, `slow` and `ramp` the stretch reads.
    used: [bool; 3],
}

impl Phasors {
    /// Phasors for `item` in `stretch` on steps of `dt` [s] (the angles they turn by each step).
    pub(super) fn new(item: &Item, stretch: Stretch, dt: f64) -> Self {
        let mut out = Phasors::default();
        if let Some((wave, slow)) = phases(item, dt) {
            out.wave = Turn::new(wave);
            out.used[0] = true;
            if let Some(slow) = slow {
                out.slow = Turn::new(slow);
                out.used[1] = true;
            }
        }
        if let Some(env) = item.envelope {
            match stretch {
                Stretch::Attack => out.ramp = Turn::new(PI * dt / env.attack),
                Stretch::Decay => out.ramp = Turn::new(-PI * dt / env.decay),
                Stretch::Off | Stretch::Hold => {}
            }
            out.used[2] = matches!(stretch, Stretch::Attack | Stretch::Decay);
        }
        if stretch == Stretch::Off {
            out.used = [false; 3]; // the plate rests: nothing is read
        }
        out
    }

    /// Every phasor evaluated exactly at local time `local` [s] (the same expressions as
    /// [`Segment::velocity`] and the envelope's value).
    pub(super) fn seed(&mut self, item: &Item, stretch: Stretch, local: f64) {
        if stretch == Stretch::Off {
            return;
        }
        if let Some((wave, slow)) = phases(item, local) {
            self.wave.seed(wave);
            if let Some(slow) = slow {
                self.slow.seed(slow);
            }
        }
        if let Some(env) = item.envelope {
            match stretch {
                Stretch::Attack => self.ramp.seed(PI * local / env.attack),
                Stretch::Decay => self.ramp.seed(PI * (env.duration() - local) / env.decay),
                Stretch::Off | Stretch::Hold => {}
            }
        }
    }

    #[inline]
    pub(super) fn advance(&mut self) {
        let [wave, slow, ramp] = self.used;
        if wave {
            self.wave.advance();
        }
        if slow {
            self.slow.advance();
        }
        if ramp {
            self.ramp.advance();
        }
    }
}

/// What every motion of one timing reads at one step: the segment's phase (`c`, `s`), the
/// envelope's factor (exactly 1 outside its ramps), and for a jet its feeding profile and the
/// sine of its `2/3` phase, each times the envelope's factor.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Sample {
    pub(super) c: f64,
    pub(super) s: f64,
    pub(super) env: f64,
    pub(crate) feed: f64,
    pub(crate) spin: f64,
}

impl Phasors {
    #[inline]
    pub(super) fn sample(&self, stretch: Stretch) -> Sample {
        // (only an item with an envelope has ramps; times 1 leaves every value as it is)
        let env = match stretch {
            Stretch::Attack | Stretch::Decay => 0.5 - 0.5 * self.ramp.c,
            Stretch::Off | Stretch::Hold => 1.0,
        };
        Sample {
            c: self.wave.c,
            s: self.wave.s,
            env,
            feed: feed(self.wave.c, self.wave.s) * env,
            spin: self.slow.s * env,
        }
    }
}
