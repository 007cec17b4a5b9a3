//! The integration settings ([`Config`]) and their checks: against each other, and against a
//! motion's highest frequency (the one check a batch makes for each of its worlds).

use super::record::recorded_rows;
use crate::error::{positive, Error, Result};
use crate::motion::PlateMotion;

/// Largest number of recorded values (rows x parts) a simulation may allocate.
const MAX_RECORDED: usize = 1 << 30;

/// Integration settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Config {
    /// Time step [s].
    pub dt: f64,
    /// Simulated time [s]; the run takes `ceil(duration / dt)` steps.
    pub duration: f64,
    /// Gravity [m/s^2].
    pub g: f64,
    /// Side of the square plate centred at the origin [m]; parts whose centre leaves it stop
    /// being simulated. `None`: an unbounded plate.
    pub plate_size: Option<f64>,
    /// Record every this many steps (the initial state is always recorded).
    pub record_every: usize,
    /// Gravity's part in the plate's plane [m/s^2] (a plate that is not level: `g sin` of its
    /// slope along x and along y, downhill), pulling every part; `g` is then the normal part.
    /// Zero on a level plate.
    pub tilt: [f64; 2],
}

impl Config {
    /// The number of steps `duration` takes (at least one; not checked).
    pub(super) fn step_count(&self) -> f64 {
        (self.duration / self.dt - 1e-9).ceil().max(1.0)
    }

    /// The velocity gravity's in-plane part ([`Config::tilt`]) adds to a part in a step [m/s].
    pub(super) fn kick(&self) -> [f64; 2] {
        [self.tilt[0] * self.dt, self.tilt[1] * self.dt]
    }

    /// Number of steps, after checking every setting against the motion.
    pub fn steps(&self, motion: &PlateMotion, parts: usize) -> Result<usize> {
        positive("dt", self.dt)?;
        positive("duration", self.duration)?;
        positive("g", self.g)?;
        if !self.tilt.iter().all(|a| a.is_finite() && a.abs() <= self.g) {
            return Err(Error::parameter(
                "tilt",
                format!(
                    "must be finite and below g = {} m/s^2; got {:?}",
                    self.g, self.tilt
                ),
            ));
        }
        if let Some(size) = self.plate_size {
            positive("plate_size", size)?;
        }
        if self.record_every == 0 {
            return Err(Error::parameter("record_every", "must be >= 1; got 0"));
        }
        self.resolves(motion)?;
        let steps = self.step_count();
        if steps > 1e12 {
            return Err(Error::parameter(
                "dt",
                format!(
                    "gives {steps:e} steps for duration {}; at most 1e12",
                    self.duration
                ),
            ));
        }
        let steps = steps as usize;
        let rows = recorded_rows(steps, self.record_every);
        if rows.saturating_mul(parts.max(1)) > MAX_RECORDED {
            return Err(Error::parameter(
                "record_every",
                format!(
                    "is too small: {rows} recorded rows x {parts} parts exceeds {MAX_RECORDED} values; \
                     record every {} steps or more",
                    (steps * parts.max(1)) / MAX_RECORDED + 1
                ),
            ));
        }
        Ok(steps)
    }

    /// Checks that the steps resolve `motion`'s highest frequency: the one check of
    /// [`Config::steps`] that depends on the motion (a batch makes it for every world, and the
    /// others once).
    pub(super) fn resolves(&self, motion: &PlateMotion) -> Result<()> {
        if motion.is_spatial() && self.tilt != [0.0; 2] {
            return Err(Error::parameter(
                "tilt",
                "is modelled on a plate that moves in its plane only (not on the 6-DOF plate's \
                 motions out of it); give a planar motion or a level plate",
            ));
        }
        let f_max = motion.max_frequency();
        let dt_max = 1.0 / (20.0 * f_max);
        if f_max > 0.0 && self.dt > dt_max {
            return Err(Error::parameter(
                "dt",
                format!(
                    "is too large for the motion's highest frequency {f_max:.6e} Hz: at least 20 steps per \
                     period are needed, so dt <= {dt_max:.6e} s; got {}",
                    self.dt
                ),
            ));
        }
        Ok(())
    }
}

/// Half the plate's side [m], infinite for an unbounded plate.
pub(super) fn half_side(cfg: &Config) -> f64 {
    cfg.plate_size.map_or(f64::INFINITY, |s| 0.5 * s)
}
