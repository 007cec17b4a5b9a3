//! Actuation kinematics, plate dynamics and sensing (docs/spec.md §6; thesis 5.2–5.4).
//!
//! Frames and units: the plate frame, origin at the plate's centre [m]; motor amplitudes are
//! forces [N] (or any unit the board uses, consistently); angular rates [rad/s].
//!
//! Four voice coils `X1, X2, Y1, Y2` push on the plate's sides at lever arm `r` (5.8):
//! `fx = X1 - X2`, `fy = Y1 - Y2`, `tau = r [(Y1 + Y2) - (X1 + X2)]`. Each motor's force has the
//! shape `cos wt - sin 2wt` (5.9); far above every resonance the plate's velocity is the integral of
//! force over mass (5.10): `(fx/M, fy/M, tau/I) (1/w) [sin wt + cos(2wt)/2]`. (The thesis prints the
//! rotational entry as `r tau / I` with `tau` already carrying `r`; that is not dimensionally a
//! rate, so `tau / I` is used.)

use nalgebra::DMatrix;

use crate::error::{finite, positive, Error, Result};
use crate::solve::{lstsq, Options};

/// The plate as the motors see it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plate {
    /// Moving mass [kg].
    pub mass: f64,
    /// Moment of inertia about the centre [kg m^2].
    pub inertia: f64,
    /// Distance from the centre to each motor's line of action [m].
    pub lever: f64,
}

/// `(fx, fy, tau)` of the motor amplitudes `(X1, X2, Y1, Y2)` (5.8).
pub fn wrench(motors: [f64; 4], lever: f64) -> [f64; 3] {
    let [x1, x2, y1, y2] = motors;
    [x1 - x2, y1 - y2, lever * ((y1 + y2) - (x1 + x2))]
}

/// Plate velocity `(u1, u2, u3)` that makes `center` the centre of rotation at angular rate
/// `omega` (4.6): `omega (cy, -cx, 1)`.
pub fn rotation_about(center: [f64; 2], omega: f64) -> [f64; 3] {
    [omega * center[1], -omega * center[0], omega]
}

/// Centre of rotation and angular rate of a plate velocity `(u1, u2, u3)` (4.6, 5.7):
/// `c = (-u2/u3, u1/u3)`. A pure translation has none: an error.
pub fn center_of_rotation(u: [f64; 3]) -> Result<([f64; 2], f64)> {
    for &x in &u {
        finite("velocity", x)?;
    }
    let scale = u[0].abs().max(u[1].abs());
    if u[2] == 0.0 || u[2].abs() * 1e12 < scale {
        return Err(Error::parameter(
            "velocity",
            format!(
                "is a translation (angular rate {} against {scale:e} m/s): the centre of rotation is at infinity",
                u[2]
            ),
        ));
    }
    Ok(([-u[1] / u[2], u[0] / u[2]], u[2]))
}

impl Plate {
    /// A plate; every parameter finite and positive.
    pub fn new(mass: f64, inertia: f64, lever: f64) -> Result<Self> {
        Ok(Plate {
            mass: positive("mass", mass)?,
            inertia: positive("inertia", inertia)?,
            lever: positive("lever", lever)?,
        })
    }

    /// The plate velocity per unit of the velocity waveform `(1/w)[sin wt + cos(2wt)/2]`:
    /// `(fx/M, fy/M, tau/I)` (5.10).
    pub fn velocity_amplitudes(&self, motors: [f64; 4]) -> [f64; 3] {
        let f = wrench(motors, self.lever);
        [f[0] / self.mass, f[1] / self.mass, f[2] / self.inertia]
    }

    /// Motor amplitudes giving the velocity amplitudes `u` (inverse of
    /// [`Plate::velocity_amplitudes`]): the minimum-norm solution plus the multiple of
    /// `(1, 1, 1, 1)` (the one combination that moves nothing) closest to zero that keeps every
    /// `|motor| <= limit`. An error says by how much the target is out of reach.
    pub fn motors_for(&self, u: [f64; 3], limit: Option<f64>) -> Result<[f64; 4]> {
        for &x in &u {
            finite("velocity", x)?;
        }
        let (fx, fy, tau) = (self.mass * u[0], self.mass * u[1], self.inertia * u[2]);
        let t = tau / (4.0 * self.lever);
        let base = [fx / 2.0 - t, -fx / 2.0 - t, fy / 2.0 + t, -fy / 2.0 + t];
        let Some(limit) = limit else {
            return Ok(base);
        };
        positive("limit", limit)?;
        let lo = base
            .iter()
            .map(|b| -limit - b)
            .fold(f64::NEG_INFINITY, f64::max);
        let hi = base.iter().map(|b| limit - b).fold(f64::INFINITY, f64::min);
        if lo > hi * (1.0 + 1e-12) + 1e-300 {
            let spread = base.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                - base.iter().copied().fold(f64::INFINITY, f64::min);
            return Err(Error::parameter(
                "center",
                format!(
                    "is out of reach: the motors would need a spread of {spread:.4e} between the strongest \
                     and weakest, more than 2 x limit = {:.4e}; lower the angular rate or move the centre \
                     closer to the plate",
                    2.0 * limit
                ),
            ));
        }
        let shift = 0.0f64.clamp(lo.min(hi), hi);
        Ok(base.map(|b| b + shift))
    }
}

/// One axis of the plate's suspension: `f = m q'' + b q' + k q` (5.26).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Axis {
    /// Mass [kg] (or inertia [kg m^2] for the rotation).
    pub mass: f64,
    /// Damping [N s/m].
    pub damping: f64,
    /// Stiffness [N/m].
    pub stiffness: f64,
}

impl Axis {
    /// An axis; mass positive, damping and stiffness non-negative.
    pub fn new(mass: f64, damping: f64, stiffness: f64) -> Result<Self> {
        positive("mass", mass)?;
        for (name, v) in [("damping", damping), ("stiffness", stiffness)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::parameter(
                    name,
                    format!("must be finite and >= 0; got {v}"),
                ));
            }
        }
        Ok(Axis {
            mass,
            damping,
            stiffness,
        })
    }

    /// Damped resonance `w0 = sqrt(k/m - (b/2m)^2)` [rad/s] (5.27); `None` when over-damped.
    pub fn resonance(&self) -> Option<f64> {
        let w2 = self.stiffness / self.mass - (self.damping / (2.0 * self.mass)).powi(2);
        (w2 > 0.0).then(|| w2.sqrt())
    }

    /// Velocity per force at angular frequency `w` [rad/s], as `(re, im)`:
    /// `i w / (k - m w^2 + i b w)`.
    pub fn velocity_response(&self, w: f64) -> [f64; 2] {
        let (re, im) = (self.stiffness - self.mass * w * w, self.damping * w);
        let d = re * re + im * im;
        // i w (re - i im) / d
        [w * im / d, w * re / d]
    }

    /// The axis under force samples `f` every `dt` [s] from position `q0` and velocity `v0`,
    /// stepped by semi-implicit Euler (5.26): `v[n] = v[n-1] + dt (f[n] - b v[n-1] - k q[n-1]) / m`,
    /// `q[n] = q[n-1] + dt v[n]`, with `a[n] = (f[n] - b v[n-1] - k q[n-1]) / m`. Writes `acc`,
    /// `vel` and `pos`, each as long as `f`.
    pub fn steps(
        &self,
        f: &[f64],
        dt: f64,
        q0: f64,
        v0: f64,
        acc: &mut [f64],
        vel: &mut [f64],
        pos: &mut [f64],
    ) {
        let (m, b, k) = (self.mass, self.damping, self.stiffness);
        let (mut q, mut v) = (q0, v0);
        for (n, &force) in f.iter().enumerate() {
            let a = (force - b * v - k * q) / m;
            v += dt * a;
            q += dt * v;
            (acc[n], vel[n], pos[n]) = (a, v, q);
        }
    }
}

/// A least-squares harmonic fit `a(t) = offset + sum_h c_h cos(h w t) + s_h sin(h w t)` (5.13).
#[derive(Debug, Clone, PartialEq)]
pub struct HarmonicFit {
    /// `[c_1, s_1, c_2, s_2, ...]` in the order of the harmonics asked for.
    pub coefficients: Vec<f64>,
    /// The constant term.
    pub offset: f64,
    /// Root-mean-square residual of the fit.
    pub residual: f64,
}

/// Fits harmonics `multiples` (e.g. `[1, 2]`, or `[1, 2, 2/3]` for jets) of `frequency` [Hz] to
/// samples taken at `sample_rate` [Hz] from `t = 0`.
pub fn harmonic_fit(
    samples: &[f64],
    sample_rate: f64,
    frequency: f64,
    multiples: &[f64],
) -> Result<HarmonicFit> {
    positive("sample_rate", sample_rate)?;
    positive("frequency", frequency)?;
    if multiples.is_empty() {
        return Err(Error::parameter(
            "harmonics",
            "must name at least one harmonic",
        ));
    }
    for &h in multiples {
        positive("harmonics", h)?;
    }
    for &x in samples {
        finite("samples", x)?;
    }
    let lowest = multiples.iter().copied().fold(f64::INFINITY, f64::min);
    let highest = multiples.iter().copied().fold(0.0, f64::max);
    let span = samples.len() as f64 / sample_rate;
    if span * lowest * frequency < 1.0 {
        return Err(Error::parameter(
            "samples",
            format!(
                "must span at least one period of the lowest harmonic ({:.4e} s); got {} samples at {sample_rate} Hz = {span:.4e} s",
                1.0 / (lowest * frequency),
                samples.len()
            ),
        ));
    }
    if highest * frequency * 2.0 >= sample_rate {
        return Err(Error::parameter(
            "sample_rate",
            format!(
                "must exceed twice the highest harmonic ({} Hz) to resolve it; got {sample_rate}",
                highest * frequency
            ),
        ));
    }
    if samples.iter().all(|&x| x == 0.0) {
        return Err(Error::parameter(
            "samples",
            "are all zero: no signal to fit (is the sensor connected?)",
        ));
    }
    let w = std::f64::consts::TAU * frequency;
    let cols = 1 + 2 * multiples.len();
    let a = DMatrix::from_fn(samples.len(), cols, |n, j| {
        let t = n as f64 / sample_rate;
        if j == 0 {
            1.0
        } else {
            let x = multiples[(j - 1) / 2] * w * t;
            if j % 2 == 1 {
                x.cos()
            } else {
                x.sin()
            }
        }
    });
    let sol = lstsq(&a, samples, &Options::default())?;
    Ok(HarmonicFit {
        coefficients: sol.x[1..].to_vec(),
        offset: sol.x[0],
        residual: sol.residual / (samples.len() as f64).sqrt(),
    })
}

/// Velocity coefficients from acceleration coefficients `[c, s]` per harmonic (5.14): the
/// integral of `c cos(h w t) + s sin(h w t)` is `(-s cos + c sin) / (h w)`.
pub fn velocity_from_fit(
    coefficients: &[f64],
    frequency: f64,
    multiples: &[f64],
) -> Result<Vec<f64>> {
    positive("frequency", frequency)?;
    if coefficients.len() != 2 * multiples.len() {
        return Err(Error::Shape(format!(
            "coefficients has {} entries; {} harmonics need {}",
            coefficients.len(),
            multiples.len(),
            2 * multiples.len()
        )));
    }
    let w = std::f64::consts::TAU * frequency;
    Ok(multiples
        .iter()
        .enumerate()
        .flat_map(|(k, h)| {
            let (c, s) = (coefficients[2 * k], coefficients[2 * k + 1]);
            [-s / (h * w), c / (h * w)]
        })
        .collect())
}

/// The positive-force test (5.15) on the acceleration coefficients `[c1, s1, c2, s2]`: the
/// average friction force on a resting part along the axis is positive iff
/// `2 s1 c1 c2 + s2 (s1^2 - c1^2) > 0`.
pub fn positive_force(c: [f64; 4]) -> bool {
    let [c1, s1, c2, s2] = c;
    2.0 * s1 * c1 * c2 + s2 * (s1 * s1 - c1 * c1) > 0.0
}

/// What two accelerometers say about the plate's rotation.
#[derive(Debug, Clone, PartialEq)]
pub struct Rotation {
    /// Centre of rotation [m].
    pub center: [f64; 2],
    /// Angular velocity coefficients `[c_h, s_h, ...]` [rad/s] in the fitted basis.
    pub omega: Vec<f64>,
    /// Root-mean-square fit residual of the four channels [m/s^2].
    pub residual: f64,
}

/// Centre of rotation from two 2-axis accelerometers at `r1` and `-r1` (5.11–5.12, 5.20–5.21),
/// through harmonic fits of the raw samples (`(T, 2)` each, at `sample_rate` [Hz]).
///
/// Each fitted velocity coefficient `v_k` at both sensors satisfies `v2 - v1 = w_k R90(-2 r1)` and
/// `v1 + v2 = -2 w_k R90(C)` for a rotation about `C`; both are solved in the least-squares sense
/// over the coefficients.
pub fn cor_from_accelerometers(
    first: &[[f64; 2]],
    second: &[[f64; 2]],
    r1: [f64; 2],
    sample_rate: f64,
    frequency: f64,
    multiples: &[f64],
) -> Result<Rotation> {
    if first.len() != second.len() {
        return Err(Error::Shape(format!(
            "the accelerometers' records differ in length: {} and {} samples",
            first.len(),
            second.len()
        )));
    }
    finite("r1", r1[0])?;
    finite("r1", r1[1])?;
    let rr = 4.0 * (r1[0] * r1[0] + r1[1] * r1[1]);
    if rr == 0.0 {
        return Err(Error::parameter(
            "r1",
            "must be away from the centre (the sensors sit at r1 and -r1)",
        ));
    }
    let channel =
        |rec: &[[f64; 2]], axis: usize| -> Vec<f64> { rec.iter().map(|a| a[axis]).collect() };
    let mut fits = Vec::with_capacity(4);
    for (name, rec) in [("first", first), ("second", second)] {
        for axis in 0..2 {
            let fit = harmonic_fit(&channel(rec, axis), sample_rate, frequency, multiples)
                .map_err(|e| match &e {
                    Error::Parameter { name: p, message }
                        if p == "samples" && message.starts_with("are all zero") =>
                    {
                        Error::parameter(
                            name,
                            format!(
                                "accelerometer's axis {axis} reads all zero (is it connected?)"
                            ),
                        )
                    }
                    _ => e,
                })?;
            fits.push(fit);
        }
    }
    let vel: Vec<Vec<f64>> = fits
        .iter()
        .map(|f| velocity_from_fit(&f.coefficients, frequency, multiples))
        .collect::<Result<_>>()?;
    // R90(-2 r1) = (2 r1y, -2 r1x).
    let g = [2.0 * r1[1], -2.0 * r1[0]];
    let mut omega = Vec::with_capacity(vel[0].len());
    let (mut num, mut den) = ([0.0; 2], 0.0);
    for (((&x1, &y1), &x2), &y2) in vel[0].iter().zip(&vel[1]).zip(&vel[2]).zip(&vel[3]) {
        let v1 = [x1, y1];
        let v2 = [x2, y2];
        let w = ((v2[0] - v1[0]) * g[0] + (v2[1] - v1[1]) * g[1]) / rr;
        omega.push(w);
        // C = R90(v1 + v2) / (2 w), in the least-squares sense over the coefficients.
        let s = [v1[0] + v2[0], v1[1] + v2[1]];
        num[0] += w * -s[1];
        num[1] += w * s[0];
        den += 2.0 * w * w;
    }
    let peak = omega.iter().map(|w| w.abs()).fold(0.0, f64::max);
    let speed = vel.iter().flatten().map(|v| v.abs()).fold(0.0, f64::max);
    if den == 0.0 || peak * rr.sqrt() < 1e-9 * speed {
        return Err(Error::parameter(
            "accelerometers",
            "show no rotation (both sensors move alike): the plate translates, its centre of rotation is at infinity",
        ));
    }
    let residual = (fits.iter().map(|f| f.residual * f.residual).sum::<f64>() / 4.0).sqrt();
    Ok(Rotation {
        center: [num[0] / den, num[1] / den],
        omega,
        residual,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn motors_round_trip_and_respect_limits() {
        let plate = Plate::new(2.0, 0.05, 0.2).unwrap();
        let u = rotation_about([0.03, -0.02], 1.5);
        let m = plate.motors_for(u, None).unwrap();
        let back = plate.velocity_amplitudes(m);
        for k in 0..3 {
            assert!((back[k] - u[k]).abs() < 1e-12);
        }
        let (c, w) = center_of_rotation(back).unwrap();
        assert!(
            (c[0] - 0.03).abs() < 1e-12 && (c[1] + 0.02).abs() < 1e-12 && (w - 1.5).abs() < 1e-12
        );
        let bound = m.iter().map(|x| x.abs()).fold(0.0, f64::max);
        let tight = plate.motors_for(u, Some(bound * 0.95));
        // The null direction can lower the largest amplitude, or the target is out of reach.
        match tight {
            Ok(t) => assert!(t.iter().all(|x| x.abs() <= bound * 0.95 * (1.0 + 1e-12))),
            Err(e) => assert!(e.to_string().contains("out of reach"), "{e}"),
        }
        assert!(plate.motors_for(u, Some(1e-9)).is_err());
    }
}
