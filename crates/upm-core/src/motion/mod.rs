//! Plate motion programs: the plate's in-plane velocity `(u1, u2, u3)(t)` (docs/spec.md §1, 4.2).
//!
//! Frames and units: the fixed (world) frame, metres and seconds. The plate's surface velocity at a
//! point `P = (x, y)` is `v_s(P) = (u1 - u3 y, u2 + u3 x)` [m/s]; `u3` is the angular rate [rad/s].
//! Plate displacements are assumed small (micrometres to millimetres), so the plate frame and the
//! world frame coincide for contact purposes.
//!
//! A program is a list of items played one after another. An item without a duration repeats
//! forever (it must be the last); after the last timed item the plate is at rest.

use std::f64::consts::{PI, TAU};

use crate::error::{finite, positive, Error, Result};
use crate::waveform::Waveform;

pub mod spatial;
mod table;

pub use spatial::{Spatial, Term};
use table::{about, along, feed, jet, Stretch};
pub(crate) use table::{Columns, JetStint, Phases, Sample};

/// One kind of plate motion.
#[derive(Debug, Clone, PartialEq)]
pub enum Segment {
    /// `(u1, u2) = direction * v(t)`, `direction` a unit vector.
    Translation {
        /// Unit direction.
        direction: [f64; 2],
        /// Speed along `direction` [m/s].
        wave: Waveform,
    },
    /// Rotation about `center` at angular rate `w(t)` [rad/s]: `v_s(P) = w R90(P - C)`.
    Rotation {
        /// Centre of rotation [m].
        center: [f64; 2],
        /// Angular rate [rad/s].
        wave: Waveform,
    },
    /// A jet (6.4), scaled: `v(P, t) = A d [cos wt - cos 2wt] + (2A/rho) sin(2wt/3) R90(P - C)`.
    Jet {
        /// Focus of the jet [m].
        center: [f64; 2],
        /// Unit feeding direction.
        direction: [f64; 2],
        /// Radius where the feeding and rotating terms have equal peaks [m].
        rho: f64,
        /// Amplitude `A` [m/s].
        amplitude: f64,
        /// `w = 2 pi frequency` [rad/s].
        omega: f64,
    },
    /// The plate at rest.
    Rest,
    /// Harmonic accelerations of all six axes: the plate may leave its plane (docs/spec.md §10).
    Spatial(Box<Spatial>),
    /// Measured or synthesised samples, linearly interpolated: `t` strictly increasing from 0.
    Samples {
        /// Sample times [s], starting at 0.
        t: Vec<f64>,
        /// `(u1, u2, u3)` at each sample.
        u: Vec<[f64; 3]>,
    },
}

/// Raised-cosine envelope: rises over `attack`, holds for `sustain`, falls over `decay` [s].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Envelope {
    /// Rise time [s].
    pub attack: f64,
    /// Hold time [s].
    pub sustain: f64,
    /// Fall time [s].
    pub decay: f64,
}

impl Envelope {
    /// Total length [s].
    pub fn duration(&self) -> f64 {
        self.attack + self.sustain + self.decay
    }

    /// Which stretch `t` [s] falls in (outside `[0, duration]`: `Off`).
    #[inline]
    fn stretch(&self, t: f64) -> Stretch {
        if t < 0.0 || t > self.duration() {
            Stretch::Off
        } else if t < self.attack {
            Stretch::Attack
        } else if t <= self.attack + self.sustain {
            Stretch::Hold
        } else {
            Stretch::Decay
        }
    }

    /// `e(t)` alone (one cosine on the ramps, none on the hold).
    #[inline]
    fn value(&self, t: f64) -> f64 {
        match self.stretch(t) {
            Stretch::Off => 0.0,
            Stretch::Attack => 0.5 - 0.5 * (PI * t / self.attack).cos(),
            Stretch::Hold => 1.0,
            Stretch::Decay => 0.5 - 0.5 * (PI * (self.duration() - t) / self.decay).cos(),
        }
    }

    /// `(e(t), e'(t))`.
    fn at(&self, t: f64) -> (f64, f64) {
        let ramp = |s: f64, len: f64| {
            (
                0.5 - 0.5 * (PI * s / len).cos(),
                0.5 * PI / len * (PI * s / len).sin(),
            )
        };
        match self.stretch(t) {
            Stretch::Off => (0.0, 0.0),
            Stretch::Attack => ramp(t, self.attack),
            Stretch::Hold => (1.0, 0.0),
            Stretch::Decay => {
                let (e, d) = ramp(self.duration() - t, self.decay);
                (e, -d)
            }
        }
    }
}

/// One item of a program: a segment, optionally timed and shaped by an envelope.
#[derive(Debug, Clone, PartialEq)]
pub struct Item {
    /// What the plate does.
    pub segment: Segment,
    /// How long [s]; `None` repeats forever.
    pub duration: Option<f64>,
    /// Optional envelope (its length is the item's duration).
    pub envelope: Option<Envelope>,
}

/// A plate motion program.
#[derive(Debug, Clone, PartialEq)]
pub struct PlateMotion {
    items: Vec<Item>,
    /// Start time of each item [s].
    starts: Vec<f64>,
}

fn unit(name: &str, d: [f64; 2]) -> Result<[f64; 2]> {
    finite(name, d[0])?;
    finite(name, d[1])?;
    let n = d[0].hypot(d[1]);
    if !(n > 0.0 && n.is_finite()) {
        return Err(Error::parameter(
            name,
            format!("must be a non-zero vector; got ({}, {})", d[0], d[1]),
        ));
    }
    Ok([d[0] / n, d[1] / n])
}

fn point(name: &str, p: [f64; 2]) -> Result<[f64; 2]> {
    finite(name, p[0])?;
    finite(name, p[1])?;
    Ok(p)
}

impl Segment {
    /// `(u, du/dt)` of the segment at local time `t` [s].
    fn at(&self, t: f64) -> ([f64; 3], [f64; 3]) {
        match self {
            Segment::Translation { direction: d, wave } => {
                let (v, a) = (wave.velocity(t), wave.acceleration(t));
                (along(d, v), along(d, a))
            }
            Segment::Rotation { center: c, wave } => {
                let (w, a) = (wave.velocity(t), wave.acceleration(t));
                (about(c, w), about(c, a))
            }
            Segment::Jet {
                center: c,
                direction: d,
                rho,
                amplitude,
                omega,
            } => {
                let x = omega * t;
                let g = x.cos() - (2.0 * x).cos();
                let dg = omega * (-x.sin() + 2.0 * (2.0 * x).sin());
                let k = 2.0 * amplitude / rho;
                let w = k * (2.0 * x / 3.0).sin();
                let dw = k * 2.0 * omega / 3.0 * (2.0 * x / 3.0).cos();
                let (tx, ty) = (amplitude * d[0], amplitude * d[1]);
                (
                    [tx * g + w * c[1], ty * g - w * c[0], w],
                    [tx * dg + dw * c[1], ty * dg - dw * c[0], dw],
                )
            }
            Segment::Rest => ([0.0; 3], [0.0; 3]),
            Segment::Spatial(sp) => sp.at(t),
            Segment::Samples { t: ts, u } => {
                let n = ts.len();
                if t <= ts[0] || t >= ts[n - 1] {
                    let i = if t <= ts[0] { 0 } else { n - 1 };
                    return (u[i], [0.0; 3]);
                }
                let i = ts.partition_point(|&s| s <= t) - 1;
                let h = ts[i + 1] - ts[i];
                let s = (t - ts[i]) / h;
                let mut v = [0.0; 3];
                let mut a = [0.0; 3];
                for k in 0..3 {
                    v[k] = u[i][k] + s * (u[i + 1][k] - u[i][k]);
                    a[k] = (u[i + 1][k] - u[i][k]) / h;
                }
                (v, a)
            }
        }
    }

    /// `u` alone at local time `t` [s]: the first half of [`Segment::at`] with fewer
    /// trigonometric evaluations (a jet's `cos 2wt` from `sin_cos(wt)`).
    #[inline]
    fn velocity(&self, t: f64) -> [f64; 3] {
        match self {
            Segment::Translation { direction: d, wave } => along(d, wave.velocity(t)),
            Segment::Rotation { center: c, wave } => about(c, wave.velocity(t)),
            Segment::Jet {
                center: c,
                direction: d,
                rho,
                amplitude,
                omega,
            } => {
                let x = omega * t;
                let (s1, c1) = x.sin_cos();
                let w = 2.0 * amplitude / rho * (2.0 * x / 3.0).sin();
                jet(c, (amplitude * d[0], amplitude * d[1]), feed(c1, s1), w)
            }
            Segment::Rest => [0.0; 3],
            Segment::Spatial(sp) => sp.at(t).0,
            Segment::Samples { .. } => self.at(t).0,
        }
    }

    /// The segment's natural period [s] (`None`: not periodic).
    pub(crate) fn period(&self) -> Option<f64> {
        match self {
            Segment::Translation { wave, .. } | Segment::Rotation { wave, .. } => {
                Some(wave.period())
            }
            Segment::Jet { omega, .. } => Some(3.0 * TAU / omega),
            Segment::Spatial(sp) => Some(sp.period()),
            Segment::Rest | Segment::Samples { .. } => None,
        }
    }

    /// Highest frequency present [Hz] (0 for rest; samples: the Nyquist rate of their spacing).
    pub(crate) fn max_frequency(&self) -> f64 {
        match self {
            Segment::Translation { wave, .. } | Segment::Rotation { wave, .. } => {
                wave.max_frequency()
            }
            Segment::Jet { omega, .. } => 2.0 * omega / TAU,
            Segment::Spatial(sp) => sp.max_frequency(),
            Segment::Rest => 0.0,
            Segment::Samples { t, .. } => {
                let h = t
                    .windows(2)
                    .map(|w| w[1] - w[0])
                    .fold(f64::INFINITY, f64::min);
                0.5 / h
            }
        }
    }
}

impl PlateMotion {
    fn single(segment: Segment, duration: Option<f64>) -> Self {
        PlateMotion {
            items: vec![Item {
                segment,
                duration,
                envelope: None,
            }],
            starts: vec![0.0],
        }
    }

    /// Translation along `direction` with speed `wave(t)` [m/s].
    pub fn translation(direction: [f64; 2], wave: Waveform) -> Result<Self> {
        Ok(Self::single(
            Segment::Translation {
                direction: unit("direction", direction)?,
                wave,
            },
            None,
        ))
    }

    /// Rotation about `center` [m] at angular rate `wave(t)` [rad/s].
    pub fn rotation(center: [f64; 2], wave: Waveform) -> Result<Self> {
        Ok(Self::single(
            Segment::Rotation {
                center: point("center", center)?,
                wave,
            },
            None,
        ))
    }

    /// The jet of (6.4) focused at `center`, feeding along `direction`, with radius `rho` [m],
    /// amplitude [m/s] and base `frequency` [Hz]; period `3 / frequency`.
    pub fn jet(
        center: [f64; 2],
        direction: [f64; 2],
        rho: f64,
        amplitude: f64,
        frequency: f64,
    ) -> Result<Self> {
        let segment = Segment::Jet {
            center: point("center", center)?,
            direction: unit("direction", direction)?,
            rho: positive("rho", rho)?,
            amplitude: finite("amplitude", amplitude)?,
            omega: TAU * positive("frequency", frequency)?,
        };
        Ok(Self::single(segment, None))
    }

    /// The plate at rest for `duration` [s].
    pub fn rest(duration: f64) -> Result<Self> {
        Ok(Self::single(
            Segment::Rest,
            Some(positive("duration", duration)?),
        ))
    }

    /// Linear interpolation of samples `u[i] = (u1, u2, u3)` at strictly increasing times `t` [s];
    /// the motion lasts `t[last] - t[0]`.
    pub fn from_samples(t: &[f64], u: &[[f64; 3]]) -> Result<Self> {
        if t.len() < 2 || t.len() != u.len() {
            return Err(Error::Shape(format!(
                "samples need at least 2 times and one (u1, u2, u3) per time; got {} times and {} rows",
                t.len(),
                u.len()
            )));
        }
        for (i, (&ti, ui)) in t.iter().zip(u).enumerate() {
            finite("t", ti).map_err(|e| e.with_context(&format!("sample {i}")))?;
            for &x in ui {
                finite("u", x).map_err(|e| e.with_context(&format!("sample {i}")))?;
            }
        }
        if let Some(i) = t.windows(2).position(|w| w[1] <= w[0]) {
            return Err(Error::parameter(
                "t",
                format!(
                    "must be strictly increasing; t[{}] = {} >= t[{}] = {}",
                    i,
                    t[i],
                    i + 1,
                    t[i + 1]
                ),
            ));
        }
        let t0 = t[0];
        let ts: Vec<f64> = t.iter().map(|x| x - t0).collect();
        let duration = ts[ts.len() - 1];
        Ok(Self::single(
            Segment::Samples {
                t: ts,
                u: u.to_vec(),
            },
            Some(duration),
        ))
    }

    /// This motion limited to `seconds` (a single item only).
    pub fn for_duration(mut self, seconds: f64) -> Result<Self> {
        positive("seconds", seconds)?;
        self.single_item("for_duration")?.duration = Some(seconds);
        Ok(self)
    }

    /// This motion shaped by a raised-cosine envelope; its duration becomes `attack + sustain + decay`.
    pub fn with_envelope(mut self, attack: f64, sustain: f64, decay: f64) -> Result<Self> {
        for (name, x) in [("attack", attack), ("sustain", sustain), ("decay", decay)] {
            if !(x.is_finite() && x >= 0.0) {
                return Err(Error::parameter(
                    name,
                    format!("must be finite and >= 0; got {x}"),
                ));
            }
        }
        let env = Envelope {
            attack,
            sustain,
            decay,
        };
        positive("attack + sustain + decay", env.duration())?;
        let item = self.single_item("with_envelope")?;
        item.envelope = Some(env);
        item.duration = Some(env.duration());
        Ok(self)
    }

    fn single_item(&mut self, what: &str) -> Result<&mut Item> {
        if self.items.len() != 1 {
            return Err(Error::parameter(
                "motion",
                format!("{what} applies to a single motion, not a sequence of {}; apply it to the parts", self.items.len()),
            ));
        }
        Ok(&mut self.items[0])
    }

    /// The motions one after another. Every motion but the last needs a duration.
    pub fn sequence(motions: Vec<PlateMotion>) -> Result<Self> {
        let items: Vec<Item> = motions.into_iter().flat_map(|m| m.items).collect();
        if items.is_empty() {
            return Err(Error::parameter(
                "motions",
                "must contain at least one motion",
            ));
        }
        let mut starts = Vec::with_capacity(items.len());
        let mut t = 0.0;
        for (i, item) in items.iter().enumerate() {
            starts.push(t);
            match item.duration {
                Some(d) => t += d,
                None if i + 1 < items.len() => {
                    return Err(Error::parameter(
                        "motions",
                        format!("item {i} repeats forever, so nothing after it would run; give it a duration (for_duration)"),
                    ))
                }
                None => {}
            }
        }
        Ok(PlateMotion { items, starts })
    }

    /// The items of the program.
    pub fn items(&self) -> &[Item] {
        &self.items
    }

    /// Total duration [s]; `None` when the last item repeats forever.
    pub fn duration(&self) -> Option<f64> {
        let last = self.items.len() - 1;
        self.items[last].duration.map(|d| self.starts[last] + d)
    }

    /// Highest frequency in the program [Hz] (bounds the integrator's time step).
    pub fn max_frequency(&self) -> f64 {
        self.items
            .iter()
            .map(|i| i.segment.max_frequency())
            .fold(0.0, f64::max)
    }

    /// `(u, du/dt)` at time `t` [s]: `u = (u1, u2, u3)` in m/s, m/s, rad/s.
    pub fn at(&self, t: f64) -> ([f64; 3], [f64; 3]) {
        let i = self.starts.partition_point(|&s| s <= t).saturating_sub(1);
        let item = &self.items[i];
        let local = t - self.starts[i];
        if t < 0.0 || item.duration.is_some_and(|d| local >= d) {
            return ([0.0; 3], [0.0; 3]);
        }
        let (u, a) = item.segment.at(local);
        match item.envelope {
            None => (u, a),
            Some(env) => {
                let (e, de) = env.at(local);
                (
                    u.map(|x| e * x),
                    std::array::from_fn(|k| e * a[k] + de * u[k]),
                )
            }
        }
    }

    /// Plate velocity `(u1, u2, u3)` at time `t`.
    pub fn velocity(&self, t: f64) -> [f64; 3] {
        let i = self.starts.partition_point(|&s| s <= t).saturating_sub(1);
        self.velocity_in(i, t)
    }

    /// The velocity at `t` [s] of item `i` (zero outside it or before the program starts).
    #[inline]
    fn velocity_in(&self, i: usize, t: f64) -> [f64; 3] {
        let item = &self.items[i];
        let local = t - self.starts[i];
        if t < 0.0 || item.duration.is_some_and(|d| local >= d) {
            return [0.0; 3];
        }
        let u = item.segment.velocity(local);
        match item.envelope {
            None => u,
            Some(env) => {
                let e = env.value(local);
                u.map(|x| e * x)
            }
        }
    }

    /// Start time of each item [s].
    pub fn starts(&self) -> &[f64] {
        &self.starts
    }

    /// The span one pass of the program covers [s]: its duration, or up to the end of the first
    /// period of an item that repeats forever.
    pub fn span(&self) -> Result<f64> {
        match self.duration() {
            Some(d) => Ok(d),
            None => {
                let last = self.items.len() - 1;
                let p = self.items[last].segment.period().ok_or_else(|| {
                    Error::parameter(
                        "motion",
                        "repeats forever without a period: give it a duration",
                    )
                })?;
                Ok(self.starts[last] + p)
            }
        }
    }

    /// Times in `[0, span]` where the velocity or its derivative may jump or bend: item starts,
    /// envelope phase ends, sample times. Sorted, without duplicates, ending with `span`.
    pub fn breakpoints(&self) -> Result<Vec<f64>> {
        let span = self.span()?;
        let mut out = vec![0.0, span];
        for (item, &start) in self.items.iter().zip(&self.starts) {
            out.push(start);
            if let Some(d) = item.duration {
                out.push(start + d);
            }
            if let Some(env) = item.envelope {
                out.push(start + env.attack);
                out.push(start + env.attack + env.sustain);
            }
            if let Segment::Samples { t, .. } = &item.segment {
                out.extend(t.iter().map(|x| start + x));
            }
        }
        out.retain(|&t| (0.0..=span).contains(&t));
        out.sort_by(f64::total_cmp);
        out.dedup();
        Ok(out)
    }

    /// The plate's net displacement `(dx, dy, dtheta)` of the material point at the origin over
    /// the program (one period if it repeats forever), integrated with RK4 on `steps` steps.
    pub fn displacement(&self) -> Result<[f64; 3]> {
        let span = self.span()?;
        let total = ((span * self.max_frequency().max(1.0 / span) * 400.0).ceil() as usize)
            .clamp(1000, 2_000_000);
        let mut s = [0.0; 3];
        // RK4 on each stretch between breakpoints, sampling the velocity strictly inside the
        // stretch: where the velocity jumps (a drive switched on or off) each side uses its own
        // one-sided value.
        for w in self.breakpoints()?.windows(2) {
            let (a, b) = (w[0], w[1]);
            let steps = ((total as f64 * (b - a) / span).ceil() as usize).max(4);
            let h = (b - a) / steps as f64;
            let inset = 1e-9 * (b - a);
            let rhs = |t: f64, s: [f64; 3]| {
                let u = self.velocity(t.clamp(a + inset, b - inset));
                [u[0] - u[2] * s[1], u[1] + u[2] * s[0], u[2]]
            };
            for i in 0..steps {
                let t = a + i as f64 * h;
                let k1 = rhs(t, s);
                let k2 = rhs(t + h / 2.0, std::array::from_fn(|j| s[j] + h / 2.0 * k1[j]));
                let k3 = rhs(t + h / 2.0, std::array::from_fn(|j| s[j] + h / 2.0 * k2[j]));
                let k4 = rhs(t + h, std::array::from_fn(|j| s[j] + h * k3[j]));
                s = std::array::from_fn(|j| {
                    s[j] + h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
                });
            }
        }
        Ok(s)
    }

    /// Whether the plate returns home: `|displacement| <= tol` (metres and radians alike).
    pub fn is_closed(&self, tol: f64) -> Result<bool> {
        Ok(self.displacement()?.iter().all(|x| x.abs() <= tol))
    }
}
