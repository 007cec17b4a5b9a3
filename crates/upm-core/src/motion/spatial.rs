//! Six-axis plate motions (beyond the thesis: docs/spec.md §10): harmonic accelerations of the
//! plate's centre along x, y, z and about x, y, z.
//!
//! Each axis is a sum of terms `A sin(k w t + p)` [m/s² or rad/s²]; its velocity is the zero-mean
//! integral `-A / (k w) cos(k w t + p)`. In the plane the plate moves as every other segment does,
//! `u = (x', y', gamma')`; out of the plane it changes the normal force on a part at `(x, y)`
//! through the normal acceleration `a_z = z'' + y alpha'' - x beta''` (small angles).

use std::f64::consts::TAU;

use crate::error::{Error, Result};

/// The axes, in order: translations along x, y, z [m/s²], rotations about x, y, z [rad/s²].
pub const AXES: [&str; 6] = ["x", "y", "z", "rx", "ry", "rz"];

/// Highest harmonic a term may have.
pub const MAX_HARMONIC: u32 = 64;
/// Largest translational acceleration amplitude accepted [m/s²] (about 100 g).
pub const MAX_ACCELERATION: f64 = 1000.0;
/// Largest rotation amplitude [rad] a term may cause: the model assumes small angles.
pub const MAX_ANGLE: f64 = 0.05;
/// Largest translation amplitude [m] a term may cause: the plate and world frames coincide.
pub const MAX_DISPLACEMENT: f64 = 0.01;

/// One harmonic term `amplitude sin(harmonic w t + phase)` of an axis's acceleration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Term {
    /// Multiple of the base frequency, 1..=[`MAX_HARMONIC`].
    pub harmonic: u32,
    /// [m/s²] or [rad/s²].
    pub amplitude: f64,
    /// [rad].
    pub phase: f64,
}

/// Harmonic accelerations of the six axes at base angular frequency `omega`.
#[derive(Debug, Clone, PartialEq)]
pub struct Spatial {
    /// `w = 2 pi f` [rad/s].
    pub omega: f64,
    /// The terms of each axis, in the order of [`AXES`].
    pub terms: [Vec<Term>; 6],
}

impl Spatial {
    /// The motion of base `frequency` [Hz] with `terms[axis]` for each of [`AXES`]; every value
    /// checked (finite, harmonics 1..=64, amplitudes within the small-motion model).
    pub fn new(frequency: f64, terms: [Vec<Term>; 6]) -> Result<Self> {
        if !(frequency.is_finite() && frequency > 0.0 && frequency <= 1e5) {
            return Err(Error::parameter(
                "frequency",
                format!("must be finite and in (0, 1e5] Hz; got {frequency}"),
            ));
        }
        let omega = TAU * frequency;
        for (axis, list) in AXES.iter().zip(&terms) {
            for (j, t) in list.iter().enumerate() {
                let at = |what: String| Error::parameter(*axis, format!("term {j}: {what}"));
                if !(1..=MAX_HARMONIC).contains(&t.harmonic) {
                    return Err(at(format!(
                        "harmonic must be 1..={MAX_HARMONIC}; got {}",
                        t.harmonic
                    )));
                }
                if !t.amplitude.is_finite() || !t.phase.is_finite() {
                    return Err(at(format!(
                        "amplitude and phase must be finite; got {} and {}",
                        t.amplitude, t.phase
                    )));
                }
                let w = f64::from(t.harmonic) * omega;
                let reach = t.amplitude.abs() / (w * w);
                let rotation = axis.starts_with('r');
                if rotation && reach > MAX_ANGLE {
                    return Err(at(format!(
                        "{} rad/s² at {:.4} Hz turns the plate by {reach:.3} rad; the model needs small \
                         angles (at most {MAX_ANGLE} rad)",
                        t.amplitude,
                        w / TAU
                    )));
                }
                if !rotation && (t.amplitude.abs() > MAX_ACCELERATION || reach > MAX_DISPLACEMENT) {
                    return Err(at(format!(
                        "{} m/s² at {:.4} Hz is out of range: at most {MAX_ACCELERATION} m/s² and a \
                         displacement of at most {MAX_DISPLACEMENT} m (this one: {reach:.2e} m)",
                        t.amplitude,
                        w / TAU
                    )));
                }
            }
        }
        Ok(Spatial { omega, terms })
    }

    /// Velocity and acceleration of every axis at time `t` [s].
    pub fn axes(&self, t: f64) -> ([f64; 6], [f64; 6]) {
        let mut v = [0.0; 6];
        let mut a = [0.0; 6];
        for (k, list) in self.terms.iter().enumerate() {
            for term in list {
                let w = f64::from(term.harmonic) * self.omega;
                let (s, c) = (w * t + term.phase).sin_cos();
                a[k] += term.amplitude * s;
                v[k] -= term.amplitude / w * c;
            }
        }
        (v, a)
    }

    /// The in-plane velocity `(x', y', gamma')` and its rate at `t`.
    pub fn at(&self, t: f64) -> ([f64; 3], [f64; 3]) {
        let (v, a) = self.axes(t);
        ([v[0], v[1], v[5]], [a[0], a[1], a[5]])
    }

    /// The out-of-plane velocities `(z', alpha', beta')` and accelerations `(z'', alpha'', beta'')`.
    pub fn normal(&self, t: f64) -> ([f64; 3], [f64; 3]) {
        let (v, a) = self.axes(t);
        ([v[2], v[3], v[4]], [a[2], a[3], a[4]])
    }

    /// Whether the plate moves out of its plane (any z, rx or ry term of non-zero amplitude).
    pub fn is_spatial(&self) -> bool {
        self.terms[2..5]
            .iter()
            .flatten()
            .any(|t| t.amplitude != 0.0)
    }

    /// The period of the base frequency [s].
    pub fn period(&self) -> f64 {
        TAU / self.omega
    }

    /// Highest frequency present [Hz].
    pub fn max_frequency(&self) -> f64 {
        let k = self
            .terms
            .iter()
            .flatten()
            .map(|t| t.harmonic)
            .max()
            .unwrap_or(1);
        f64::from(k) * self.omega / TAU
    }
}

/// The normal acceleration `a_z = z'' + y alpha'' - x beta''` at `p` from `(z'', alpha'', beta'')`.
#[inline]
pub fn normal_at(a: &[f64; 3], p: [f64; 2]) -> f64 {
    a[0] + p[1] * a[1] - p[0] * a[2]
}

impl super::PlateMotion {
    /// Harmonic accelerations of the six axes, repeating forever.
    pub fn spatial(motion: Spatial) -> Self {
        Self::single(super::Segment::Spatial(Box::new(motion)), None)
    }

    /// Whether any item moves the plate out of its plane (then the normal force varies).
    pub fn is_spatial(&self) -> bool {
        self.items
            .iter()
            .any(|i| matches!(&i.segment, super::Segment::Spatial(sp) if sp.is_spatial()))
    }

    /// The out-of-plane accelerations `(z'', alpha'', beta'')` at time `t` [s] (zero for items
    /// in the plane, outside the program and at rest). An envelope `e(t)` scales the velocities,
    /// so the accelerations are `e a + e' v`.
    pub fn normal(&self, t: f64) -> [f64; 3] {
        let i = self.starts.partition_point(|&s| s <= t).saturating_sub(1);
        let item = &self.items[i];
        let local = t - self.starts[i];
        let super::Segment::Spatial(sp) = &item.segment else {
            return [0.0; 3];
        };
        if t < 0.0 || item.duration.is_some_and(|d| local >= d) {
            return [0.0; 3];
        }
        let (v, a) = sp.normal(local);
        match item.envelope {
            None => a,
            Some(env) => {
                let (e, de) = env.at(local);
                std::array::from_fn(|k| e * a[k] + de * v[k])
            }
        }
    }

    /// Appends [`PlateMotion::normal`] at the sample time of every step in `steps` (the same
    /// times as [`PlateMotion::velocities_into`]).
    pub fn normals_into(&self, steps: std::ops::Range<usize>, dt: f64, out: &mut Vec<[f64; 3]>) {
        out.extend(steps.map(|s| self.normal(super::table::sample_time(s, dt))));
    }
}
