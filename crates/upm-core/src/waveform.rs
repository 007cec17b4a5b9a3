//! Periodic one-dimensional plate velocities `v(t)` [m/s] of period `T` [s].
//!
//! Internally every waveform is evaluated in the phase `x = 2 pi t / T` (radians), so root finding
//! works on `[0, 2 pi)` whatever the physical frequency. A waveform is split once into
//! [`Pieces`]: maximal intervals of phase on which `v` is monotone (or constant). Every exact
//! average in [`crate::friction`] is computed from those pieces by solving `v(x) = level` once per
//! piece, never by sampling.

use std::f64::consts::{PI, TAU};

use crate::error::{finite, positive, Error, Result};
use crate::roots::{self, Isolation};

/// Sub-intervals of phase narrower than this are not split further when isolating extrema.
/// A tangential pair of extrema closer than this is ignored, which moves any measure by less.
const H_MIN: f64 = 1e-11;

/// A finite harmonic series `v(t) = sum_k cos[k-1] cos(k w t) + sin[k-1] sin(k w t)`,
/// `w = 2 pi frequency` (docs/spec.md §2.2, §3). It has zero mean over a period.
#[derive(Debug, Clone, PartialEq)]
pub struct Harmonics {
    frequency: f64,
    /// Largest coefficient magnitude; `cos` and `sin` are stored divided by it, so root finding
    /// works on numbers of order one whatever the physical scale (1e-300 or 1e300 m/s alike).
    scale: f64,
    cos: Vec<f64>,
    sin: Vec<f64>,
}

impl Harmonics {
    /// A harmonic series. `cos` and `sin` may differ in length (missing terms are zero); at
    /// least one coefficient must be non-zero, since a plate at rest has no level crossings.
    pub fn new(cos: Vec<f64>, sin: Vec<f64>, frequency: f64) -> Result<Self> {
        positive("frequency", frequency)?;
        for (name, c) in [("cos", &cos), ("sin", &sin)] {
            if let Some(k) = c.iter().position(|x| !x.is_finite()) {
                return Err(Error::parameter(
                    format!("{name}[{k}]"),
                    format!("must be finite; got {}", c[k]),
                ));
            }
        }
        let n = cos.len().max(sin.len());
        let (mut cos, mut sin) = (cos, sin);
        cos.resize(n, 0.0);
        sin.resize(n, 0.0);
        while cos.last() == Some(&0.0) && sin.last() == Some(&0.0) {
            cos.pop();
            sin.pop();
        }
        if cos.is_empty() {
            return Err(Error::parameter(
                "cos, sin",
                "must contain a non-zero coefficient: the waveform is identically zero, so it \
                 has no sign change and feeds nothing",
            ));
        }
        let scale = cos.iter().chain(&sin).fold(0.0f64, |m, c| m.max(c.abs()));
        for c in cos.iter_mut().chain(sin.iter_mut()) {
            *c /= scale;
        }
        Ok(Harmonics {
            frequency,
            scale,
            cos,
            sin,
        })
    }

    /// `v(t) = amplitude (sin(w t) + b sin(2 w t + phi))`, the two-harmonic drive of (3.13).
    pub fn two_harmonic(b: f64, phi: f64, amplitude: f64, frequency: f64) -> Result<Self> {
        finite("b", b)?;
        finite("phi", phi)?;
        finite("amplitude", amplitude)?;
        if amplitude == 0.0 {
            return Err(Error::parameter("amplitude", "must be non-zero; got 0"));
        }
        let (s, c) = phi.sin_cos();
        Harmonics::new(
            vec![0.0, amplitude * b * s],
            vec![amplitude, amplitude * b * c],
            frequency,
        )
    }

    /// Highest harmonic with a non-zero coefficient.
    pub fn degree(&self) -> usize {
        self.cos.len()
    }

    /// Base frequency [Hz].
    pub fn frequency(&self) -> f64 {
        self.frequency
    }

    /// `sum_k k^p |(cos_k, sin_k)|`: an upper bound of `|d^p v / dx^p|` (in units of `scale`).
    fn bound(&self, p: i32) -> f64 {
        self.cos
            .iter()
            .zip(&self.sin)
            .enumerate()
            .map(|(i, (a, b))| ((i + 1) as f64).powi(p) * a.hypot(*b))
            .sum()
    }

    /// `v / scale` at phase `x` (the first entry of [`Harmonics::derivs`], computed alike).
    #[inline]
    fn value(&self, x: f64) -> f64 {
        let (s1, c1) = x.sin_cos();
        self.value_of(c1, s1)
    }

    /// `v / scale` at the phase whose cosine and sine are `c1`, `s1`.
    #[inline]
    pub(crate) fn value_of(&self, c1: f64, s1: f64) -> f64 {
        let (mut s, mut c) = (s1, c1);
        let mut v = 0.0;
        for (a, b) in self.cos.iter().zip(&self.sin) {
            v += a * c + b * s;
            let cn = c * c1 - s * s1;
            s = s * c1 + c * s1;
            c = cn;
        }
        v
    }

    /// The cosine and sine coefficients, divided by the scale (what [`Harmonics::value_of`]
    /// sums; of one length).
    pub(crate) fn terms(&self) -> (&[f64], &[f64]) {
        (&self.cos, &self.sin)
    }

    /// Angular frequency of the fundamental [rad/s] and the velocity scale [m/s]: the velocity
    /// at time `t` is `scale * value_of(cos wt, sin wt)` with `w = 2 pi frequency`.
    #[inline]
    pub(crate) fn omega_scale(&self) -> (f64, f64) {
        (TAU * self.frequency, self.scale)
    }

    /// `[v, v', v'', v''', v''''] / scale` (derivatives in the phase `x`) at phase `x`.
    #[inline]
    fn derivs(&self, x: f64) -> [f64; 5] {
        let (s1, c1) = x.sin_cos();
        let (mut s, mut c) = (s1, c1);
        let mut d = [0.0; 5];
        for (i, (a, b)) in self.cos.iter().zip(&self.sin).enumerate() {
            let k = (i + 1) as f64;
            let even = a * c + b * s; // the term itself
            let odd = k * (b * c - a * s); // its first derivative
            let k2 = k * k;
            d[0] += even;
            d[1] += odd;
            d[2] -= k2 * even;
            d[3] -= k2 * odd;
            d[4] += k2 * k2 * even;
            // cos((k+1)x), sin((k+1)x) by the angle-addition recurrence.
            let cn = c * c1 - s * s1;
            s = s * c1 + c * s1;
            c = cn;
        }
        d
    }
}

/// `a_max * period` [m/s], checked to be a normal positive float (it scales every velocity).
pub(crate) fn velocity_scale(a_max: f64, period: f64) -> Result<f64> {
    positive("a_max", a_max)?;
    positive("period", period)?;
    let scale = a_max * period;
    if !(scale.is_finite() && scale >= f64::MIN_POSITIVE) {
        return Err(Error::parameter(
            "a_max * period",
            format!("must be a normal positive float (the velocity scale); got {scale:e}"),
        ));
    }
    Ok(scale)
}

/// Bang-bang acceleration (docs/spec.md §2.1, 3.6–3.8): `+a_max` on `[0, t1)`, `0` on `[t1, t2)`,
/// `-a_max` on `[t2, T)`, `t1 = (1 - z) T / 2`, `t2 = (1 + z) T / 2`, zero-mean velocity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BangBang {
    z: f64,
    a_max: f64,
    period: f64,
}

impl BangBang {
    /// A bang-bang drive with dwell fraction `z` in `[0, 1)`, peak acceleration `a_max > 0`
    /// [m/s^2] and period `period > 0` [s].
    pub fn new(z: f64, a_max: f64, period: f64) -> Result<Self> {
        if !(z.is_finite() && (0.0..1.0).contains(&z)) {
            return Err(Error::parameter(
                "z",
                format!("must lie in [0, 1); got {z}"),
            ));
        }
        velocity_scale(a_max, period)?;
        Ok(BangBang { z, a_max, period })
    }

    /// `(v_min, v_max)` of the velocity (3.8).
    pub fn velocity_range(&self) -> (f64, f64) {
        let s = self.a_max * self.period / 4.0;
        (s * (self.z * self.z - 1.0), s * (self.z - 1.0).powi(2))
    }

    /// `(v, dv/dx) / (a_max T)` at phase `x` in `[0, 2 pi)`: the velocity in units of `a_max T`.
    fn at_phase(&self, x: f64) -> (f64, f64) {
        let (z, u) = (self.z, x / TAU);
        let slope = 1.0 / TAU;
        if u < (1.0 - z) / 2.0 {
            ((z * z - 1.0) / 4.0 + u, slope)
        } else if u < (1.0 + z) / 2.0 {
            ((z - 1.0).powi(2) / 4.0, 0.0)
        } else {
            ((z * z + 3.0) / 4.0 - u, -slope)
        }
    }

    /// Velocity and acceleration at time `t` in `[0, T)`.
    fn at(&self, t: f64) -> (f64, f64) {
        let (z, a, p) = (self.z, self.a_max, self.period);
        let (t1, t2) = ((1.0 - z) * p / 2.0, (1.0 + z) * p / 2.0);
        if t < t1 {
            (a * (p / 4.0 * (z * z - 1.0) + t), a)
        } else if t < t2 {
            (a * p / 4.0 * (z - 1.0).powi(2), 0.0)
        } else {
            (a * (p / 4.0 * (z * z + 3.0) - t), -a)
        }
    }
}

/// A periodic plate velocity.
#[derive(Debug, Clone, PartialEq)]
pub enum Waveform {
    /// A finite harmonic series (includes the two-harmonic drive).
    Harmonics(Harmonics),
    /// Piecewise-constant acceleration.
    BangBang(BangBang),
}

impl From<Harmonics> for Waveform {
    fn from(h: Harmonics) -> Self {
        Waveform::Harmonics(h)
    }
}

impl From<BangBang> for Waveform {
    fn from(b: BangBang) -> Self {
        Waveform::BangBang(b)
    }
}

impl Waveform {
    /// Period [s].
    pub fn period(&self) -> f64 {
        match self {
            Waveform::Harmonics(h) => 1.0 / h.frequency,
            Waveform::BangBang(b) => b.period,
        }
    }

    /// Highest frequency present [Hz]: the top harmonic, or for bang-bang (whose acceleration
    /// jumps) ten times the base frequency, enough to place its corners in a fine time step.
    pub fn max_frequency(&self) -> f64 {
        match self {
            Waveform::Harmonics(h) => h.frequency * h.degree() as f64,
            Waveform::BangBang(b) => 10.0 / b.period,
        }
    }

    /// Velocity [m/s] at time `t` [s].
    pub fn velocity(&self, t: f64) -> f64 {
        match self {
            Waveform::Harmonics(h) => h.scale * h.value(TAU * h.frequency * t),
            Waveform::BangBang(b) => b.at(t.rem_euclid(b.period)).0,
        }
    }

    /// Acceleration [m/s^2] at time `t` [s] (bang-bang: the one-sided value from the right).
    pub fn acceleration(&self, t: f64) -> f64 {
        match self {
            Waveform::Harmonics(h) => {
                let w = TAU * h.frequency;
                h.scale * w * h.derivs(w * t)[1]
            }
            Waveform::BangBang(b) => b.at(t.rem_euclid(b.period)).1,
        }
    }

    /// The velocity scale [m/s] that [`Waveform::at_phase`] divides by.
    pub(crate) fn scale(&self) -> f64 {
        match self {
            Waveform::Harmonics(h) => h.scale,
            Waveform::BangBang(b) => b.a_max * b.period,
        }
    }

    /// `(v, dv/dx) / scale` at phase `x` (radians; any real `x`, the waveform is periodic).
    #[inline]
    pub(crate) fn at_phase(&self, x: f64) -> (f64, f64) {
        match self {
            Waveform::Harmonics(h) => {
                let d = h.derivs(x);
                (d[0], d[1])
            }
            Waveform::BangBang(b) => b.at_phase(x.rem_euclid(TAU)),
        }
    }

    /// Mean of `sgn(v - level)` over a period, `level` in m/s. For a harmonic series this
    /// isolates the sign changes of `v - level` directly (cheaper than [`Waveform::pieces`] when
    /// only one level is wanted); the result is the same to rounding.
    pub fn mean_sign(&self, level: f64) -> Result<f64> {
        let Waveform::Harmonics(h) = self else {
            return Ok(self.pieces()?.mean_sign(level));
        };
        let level = level / h.scale;
        let iso = Isolation {
            n0: 4 * h.degree() + 4,
            lip: [h.bound(1), h.bound(2), h.bound(3)],
            h_min: H_MIN,
            periodic: true,
        };
        let f = |x: f64| {
            let d = h.derivs(x);
            [d[0] - level, d[1], d[2]]
        };
        let roots = roots::sign_changes(f, 0.0, TAU, iso)
            .ok_or_else(|| Error::Convergence("could not isolate the level crossings".into()))?;
        // Between consecutive sign changes the sign is constant; it starts as the sign at 0
        // (zero counting as positive, as in the isolation) and flips at every root.
        let mut positive = f(0.0)[0] >= 0.0;
        let (mut sum, mut last) = (0.0, 0.0);
        for &r in &roots {
            sum += if positive { r - last } else { last - r };
            positive = !positive;
            last = r;
        }
        sum += if positive { TAU - last } else { last - TAU };
        Ok((sum / TAU).clamp(-1.0, 1.0))
    }

    /// The waveform split into monotone pieces over one period.
    pub fn pieces(&self) -> Result<Pieces<'_>> {
        let breaks: Vec<f64> = match self {
            Waveform::Harmonics(h) => {
                // Extrema of v are the sign changes of v'; isolate them with bounds on v''..v''''.
                let iso = Isolation {
                    n0: 4 * h.degree() + 4,
                    lip: [h.bound(2), h.bound(3), h.bound(4)],
                    h_min: H_MIN,
                    periodic: true,
                };
                let c = roots::sign_changes(
                    |x| {
                        let d = h.derivs(x);
                        [d[1], d[2], d[3]]
                    },
                    0.0,
                    TAU,
                    iso,
                )
                .ok_or_else(|| {
                    Error::Convergence("could not isolate the extrema of the waveform".into())
                })?;
                if c.len() < 2 {
                    return Err(Error::Convergence(format!(
                        "found {} extrema of a non-constant periodic waveform; expected at least 2",
                        c.len()
                    )));
                }
                c
            }
            Waveform::BangBang(b) => {
                let x1 = (1.0 - b.z) * PI;
                let x2 = (1.0 + b.z) * PI;
                if b.z > 0.0 {
                    vec![0.0, x1, x2]
                } else {
                    vec![0.0, x1]
                }
            }
        };
        let mut pieces = Vec::with_capacity(breaks.len());
        let values: Vec<f64> = match self {
            // Bang-bang breakpoints are known exactly; evaluate the closed form at them.
            Waveform::BangBang(b) => {
                let (lo, hi) = ((b.z * b.z - 1.0) / 4.0, (b.z - 1.0).powi(2) / 4.0);
                if b.z > 0.0 {
                    vec![lo, hi, hi]
                } else {
                    vec![lo, hi]
                }
            }
            Waveform::Harmonics(_) => breaks.iter().map(|&x| self.at_phase(x).0).collect(),
        };
        for i in 0..breaks.len() {
            let j = (i + 1) % breaks.len();
            let x1 = if j == 0 { breaks[0] + TAU } else { breaks[j] };
            pieces.push(Piece {
                x0: breaks[i],
                x1,
                v0: values[i],
                v1: values[j],
            });
        }
        let vmin = values.iter().copied().fold(f64::INFINITY, f64::min);
        let vmax = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Ok(Pieces {
            wave: self,
            scale: self.scale(),
            pieces,
            vmin,
            vmax,
        })
    }
}

/// An interval of phase `[x0, x1]` on which the waveform is monotone, with its end values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Piece {
    /// Start phase [rad].
    pub x0: f64,
    /// End phase [rad] (may exceed 2 pi for the piece that wraps around).
    pub x1: f64,
    /// Velocity at `x0`.
    pub v0: f64,
    /// Velocity at `x1`.
    pub v1: f64,
}

/// A waveform's monotone pieces covering one period, with velocities in units of `scale`.
#[derive(Debug, Clone)]
pub struct Pieces<'a> {
    wave: &'a Waveform,
    scale: f64,
    pieces: Vec<Piece>,
    vmin: f64,
    vmax: f64,
}

impl Pieces<'_> {
    /// The pieces, in order of phase.
    pub fn pieces(&self) -> &[Piece] {
        &self.pieces
    }

    /// `(min v, max v)` over a period [m/s] (exact: the values at the extrema).
    pub fn range(&self) -> (f64, f64) {
        (self.scale * self.vmin, self.scale * self.vmax)
    }

    /// Fractions of the period with `v > level` and with `v < level` (`level` in m/s).
    pub fn measure(&self, level: f64) -> (f64, f64) {
        self.measure_scaled(level / self.scale)
    }

    fn measure_scaled(&self, level: f64) -> (f64, f64) {
        let (mut above, mut below, mut total) = (0.0, 0.0, 0.0);
        for p in &self.pieces {
            let len = p.x1 - p.x0;
            total += len;
            let (lo, hi) = if p.v0 <= p.v1 {
                (p.v0, p.v1)
            } else {
                (p.v1, p.v0)
            };
            if lo == hi {
                if level < lo {
                    above += len;
                } else if level > lo {
                    below += len;
                }
            } else if level <= lo {
                above += len;
            } else if level >= hi {
                below += len;
            } else {
                let g = |x: f64| {
                    let (v, d) = self.wave.at_phase(x);
                    (v - level, d)
                };
                let r = roots::solve_bracketed(&g, p.x0, p.v0 - level, p.x1, p.v1 - level);
                if p.v1 > p.v0 {
                    above += p.x1 - r;
                    below += r - p.x0;
                } else {
                    above += r - p.x0;
                    below += p.x1 - r;
                }
            }
        }
        // Dividing by the summed lengths (not 2 pi) keeps saturated forces exactly +-1.
        (above / total, below / total)
    }

    /// Mean of `sgn(v - level)` over a period (zero where `v = level`).
    pub fn mean_sign(&self, level: f64) -> f64 {
        let (above, below) = self.measure(level);
        above - below
    }

    /// The median of `v` over a period [m/s]: the level above which `v` spends at most half the
    /// period and below which it spends at most half.
    pub fn median(&self) -> f64 {
        let tol = 1e-15 * (self.vmax - self.vmin);
        let sign = |m: f64| {
            let (above, below) = self.measure_scaled(m);
            above - below
        };
        self.scale * roots::brent(sign, self.vmin, self.vmax, tol)
    }
}

#[cfg(test)]
#[path = "waveform_tests.rs"]
mod tests;
