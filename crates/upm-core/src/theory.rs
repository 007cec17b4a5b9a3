//! Closed forms of the Coulomb pump (thesis ch. 3) and of two-sinusoid feeding (section 6.4).
//!
//! Velocities in m/s, accelerations in m/s^2, periods in s; forces are `force / (mu m g)`.
//! Each function states the equation it implements; docs/spec.md lists the checked values and the
//! errata (E1–E3) that the tests document. Where the thesis gives no closed form (`gamma`, E2) the
//! value is computed exactly from the waveform's extrema.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use crate::error::{finite, positive, Error, Result};
use crate::friction::check_pair;
use crate::waveform::{velocity_scale, BangBang, Harmonics, Waveform};

/// The unit triangle wave of period `2 pi`: `1 - 2|x|/pi` on `[-pi, pi]` (6.13).
pub fn triangle(x: f64) -> f64 {
    let y = (x + PI).rem_euclid(TAU) - PI;
    1.0 - 2.0 * y.abs() / PI
}

/// Theorem 1 (6.12–6.13): force / (mu m g) at rest under `cos(n1 t) - cos(n2 (t - psi))`,
/// `Tri(n1 n2 psi) / (n2^2 - n1^2)`. The theorem assumes exactly one of `n1, n2` is even; when
/// both are odd the force is exactly 0 for every `psi` (Lemma 1), and that is returned.
pub fn theorem1_force(n1: i64, n2: i64, psi: f64) -> Result<f64> {
    check_pair(n1, n2)?;
    finite("psi", psi)?;
    if n1 % 2 == 1 && n2 % 2 == 1 {
        return Ok(0.0);
    }
    let (a, b) = (n1 as f64, n2 as f64);
    // Reduce n1 n2 psi modulo 2 pi in two steps so large products keep their accuracy.
    let x = (a * crate::friction::harmonic_phase(n2, psi)?).rem_euclid(TAU);
    Ok(triangle(x) / (b * b - a * a))
}

/// Bang-bang feed rate (3.11): `a_max T z^2 / 4` for `z <= 1/2`, `v_max = a_max T (z-1)^2 / 4`
/// beyond (the part cannot outrun the plate).
pub fn bang_bang_feed_rate(z: f64, a_max: f64, period: f64) -> Result<f64> {
    let b = BangBang::new(z, a_max, period)?;
    let (_, v_max) = b.velocity_range();
    Ok((a_max * period * z * z / 4.0).min(v_max))
}

/// Bang-bang average force / (mu m g) on a part at `part_velocity` (3.10):
/// `z^2 - 4 v_p / (a_max T)` for `v_min <= v_p < v_max`, `+1` below `v_min`, `-1` above `v_max`.
pub fn bang_bang_force(z: f64, part_velocity: f64, a_max: f64, period: f64) -> Result<f64> {
    let b = BangBang::new(z, a_max, period)?;
    finite("part_velocity", part_velocity)?;
    let (v_min, v_max) = b.velocity_range();
    Ok(if part_velocity < v_min {
        1.0
    } else if part_velocity >= v_max {
        // At exactly v_max the part rides the dwell (z > 0) and is pushed back elsewhere.
        if part_velocity == v_max && z > 0.0 {
            -1.0 + z
        } else {
            -1.0
        }
    } else {
        z * z - 4.0 * part_velocity / (a_max * period)
    })
}

/// Bang-bang velocity range `(v_min, v_max)` (3.8).
pub fn bang_bang_velocity_range(z: f64, a_max: f64, period: f64) -> Result<(f64, f64)> {
    Ok(BangBang::new(z, a_max, period)?.velocity_range())
}

/// Bang-bang efficiencies (3.5): `eta1 = v_eq / (a_max T)`, `eta2 = v_eq / |v_min|`.
/// Maxima `1/16` and `1/3` at `z = 1/2`.
pub fn bang_bang_efficiency(z: f64) -> Result<(f64, f64)> {
    let v_eq = bang_bang_feed_rate(z, 1.0, 1.0)?;
    let (v_min, _) = bang_bang_velocity_range(z, 1.0, 1.0)?;
    Ok((v_eq, v_eq / v_min.abs()))
}

/// Gain of the viscous model (3.12), `f = K (v_eq - v_p)`: `K = 4 mu m g / (a_max T)` [N s/m]
/// (with `mu_m_g = 1`, `K / (mu m g)` [s/m]).
pub fn viscous_gain(a_max: f64, period: f64, mu_m_g: f64) -> Result<f64> {
    velocity_scale(a_max, period)?;
    positive("mu_m_g", mu_m_g)?;
    let k = 4.0 * mu_m_g / (a_max * period);
    if !k.is_finite() {
        return Err(Error::parameter(
            "mu_m_g",
            format!("makes the gain overflow; got {mu_m_g:e}"),
        ));
    }
    Ok(k)
}

/// Two-harmonic feed rate for `v = amplitude (sin t + b sin(2t + phi))` (3.16–3.17):
/// `b sin(phi)` for `|b| <= 1/2`; for `phi = +-pi/2` and `|b| > 1/2`, `+-1/(4|b|)` (in units of
/// `amplitude`). Elsewhere the thesis has no closed form: use the exact `feed_rate`.
pub fn two_harmonic_feed_rate(b: f64, phi: f64, amplitude: f64) -> Result<f64> {
    finite("b", b)?;
    finite("phi", phi)?;
    finite("amplitude", amplitude)?;
    if b.abs() <= 0.5 {
        return Ok(amplitude * b * phi.sin());
    }
    let (s, c) = phi.sin_cos();
    if c.abs() <= 1e-12 {
        return Ok(amplitude * (b * s).signum() / (4.0 * b.abs()));
    }
    Err(Error::parameter(
        "b, phi",
        format!(
            "have no closed-form feed rate for |b| > 1/2 unless phi = +-pi/2 (eq. 3.16-3.17); \
             got b = {b}, phi = {phi}: use upm.feed_rate for the exact value"
        ),
    ))
}

/// Force / (mu m g) at rest under `v = sin t + b cos 2t`, eq. (3.15), with
/// `c1 = asin((1 - sqrt(1+8b^2)) / 4b)`, `c2 = asin((1 + sqrt(1+8b^2)) / 4b)`:
/// `-2 c1/pi + (2 c2/pi - 1 if |b| > 1 else 0)` for `b >= 0`, and odd in `b`.
///
/// The thesis prints `1 - 2 c2/pi` for the `b < -1` branch; evaluated as printed that is not odd in
/// `b` and disagrees with the exact average, so the odd extension is used (tested).
pub fn two_harmonic_force_at_rest(b: f64) -> Result<f64> {
    finite("b", b)?;
    if b == 0.0 {
        return Ok(0.0);
    }
    let a = b.abs();
    // With r = sqrt(1 + 8 a^2): (1 - r)/(4a) = -2 / (1/a + r/a) and (1 + r)/(4a) = (1/a + r/a) / 4,
    // free of cancellation and of overflow for any finite a.
    let inv = 1.0 / a;
    let r_over_a = inv.hypot(8f64.sqrt());
    let c1 = (-2.0 / (inv + r_over_a)).asin();
    let mut f = -2.0 * c1 / PI;
    if a > 1.0 {
        let c2 = ((inv + r_over_a) / 4.0).min(1.0).asin();
        f += 2.0 * c2 / PI - 1.0;
    }
    Ok(f.copysign(b))
}

/// `gamma(b) = max_t |cos t - 2b sin 2t|`, the normaliser of the optimal drive (3.18), computed
/// exactly from the extrema (erratum E2: the printed closed form does not reproduce 1.7602).
pub fn gamma(b: f64) -> Result<f64> {
    finite("b", b)?;
    let w: Waveform = Harmonics::new(vec![1.0], vec![0.0, -2.0 * b], 1.0)?.into();
    let (lo, hi) = w.pieces()?.range();
    Ok(lo.abs().max(hi.abs()))
}

/// The normalised two-harmonic drive of (3.18–3.20) and what it achieves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalizedDrive {
    /// `max_t |cos t - 2b sin 2t|`.
    pub gamma: f64,
    /// Lowest plate velocity [m/s].
    pub v_min: f64,
    /// Highest plate velocity [m/s].
    pub v_max: f64,
    /// Feed rate [m/s].
    pub v_eq: f64,
    /// `v_eq / (a_max T)`.
    pub eta1: f64,
    /// `v_eq / |v_min|`.
    pub eta2: f64,
}

/// Acceleration `a_s = (a_max/gamma)[cos wt - 2b sin 2wt]` (peak exactly `a_max`), velocity
/// `(a_max T / (2 pi gamma)) [sin wt + b cos 2wt]`. At `b = 1/2`: `v_min = -3 a_max T/(4 pi gamma)`,
/// `v_max = 3 a_max T/(8 pi gamma)`, `v_eq = a_max T/(4 pi gamma)`, `eta1 = 0.0452`, `eta2 = 1/3`.
pub fn normalized_drive(b: f64, a_max: f64, period: f64) -> Result<NormalizedDrive> {
    if !(b.is_finite() && b >= 0.0) {
        return Err(Error::parameter(
            "b",
            format!("must be finite and >= 0; got {b}"),
        ));
    }
    velocity_scale(a_max, period)?;
    let g = gamma(b)?;
    let scale = a_max * period / (TAU * g);
    // In units of `scale`: sin t + b cos 2t = b + s - 2 b s^2 with s = sin t in [-1, 1]. The
    // efficiencies are ratios of these, so they never see an underflowing `scale`.
    let top = if b >= 0.25 {
        b + 1.0 / (8.0 * b)
    } else {
        1.0 - b
    };
    let bottom = 1.0 + b;
    let feed = two_harmonic_feed_rate(b, FRAC_PI_2, 1.0)?;
    Ok(NormalizedDrive {
        gamma: g,
        v_min: -scale * bottom,
        v_max: scale * top,
        v_eq: scale * feed,
        eta1: feed / (TAU * g),
        eta2: feed / bottom,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangle_wave() {
        assert_eq!(triangle(0.0), 1.0);
        assert!((triangle(PI) + 1.0).abs() < 1e-15);
        assert!((triangle(FRAC_PI_2)).abs() < 1e-15);
        assert!((triangle(TAU + 0.3) - triangle(0.3)).abs() < 1e-14);
        assert!((triangle(-0.3) - triangle(0.3)).abs() < 1e-15);
    }

    #[test]
    fn theorem1_peaks() {
        // docs/spec.md §3 known answers: peak 1/(n2^2 - n1^2).
        for (n1, n2, want) in [
            (1, 2, 1.0 / 3.0),
            (2, 3, 0.2),
            (1, 4, 1.0 / 15.0),
            (2, 5, 1.0 / 21.0),
            (3, 4, 1.0 / 7.0),
        ] {
            assert!((theorem1_force(n1, n2, 0.0).unwrap() - want).abs() < 1e-15);
        }
        assert_eq!(theorem1_force(1, 3, 0.4).unwrap(), 0.0);
        assert!(theorem1_force(2, 4, 0.0).is_err());
    }
}
