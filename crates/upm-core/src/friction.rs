//! Coulomb sliding friction averaged over a periodic plate motion (docs/spec.md §1–3).
//!
//! Forces are dimensionless: `force / (mu m g)`. A part moving at constant velocity `v_p` on a
//! plate whose surface velocity is `v(t)` receives the instantaneous force `mu m g sgn(v - v_p)`
//! (3.2); its average over a period is `mean(sgn(v - v_p))` (3.3, 6.7). Everything here is exact:
//! the time spent above and below `v_p` comes from the roots of `v(t) = v_p`, one per monotone
//! piece of the waveform (see [`crate::waveform`]).

use crate::error::{finite, Error, Result};
use crate::waveform::{Harmonics, Waveform};

/// Average friction force / (mu m g) on a part moving at `part_velocity` [m/s] (3.4, 6.7).
pub fn mean_force(wave: &Waveform, part_velocity: f64) -> Result<f64> {
    finite("part_velocity", part_velocity)?;
    wave.mean_sign(part_velocity)
}

/// [`mean_force`] at many part velocities; the waveform is split into pieces once.
pub fn mean_forces(wave: &Waveform, part_velocities: &[f64]) -> Result<Vec<f64>> {
    for &v in part_velocities {
        finite("part_velocity", v)?;
    }
    let pieces = wave.pieces()?;
    Ok(part_velocities
        .iter()
        .map(|&v| pieces.mean_sign(v))
        .collect())
}

/// The quasi-static feed rate [m/s]: the part velocity at which the average force vanishes,
/// which is the median of `v(t)` over one period (docs/spec.md §2). Exact to a few ulps of `max |v|`.
pub fn feed_rate(wave: &Waveform) -> Result<f64> {
    Ok(wave.pieces()?.median())
}

/// Checks the pair of harmonics of Theorem 1 / Lemmas 1–3: `1 <= n1 < n2`, `gcd(n1, n2) = 1`.
pub fn check_pair(n1: i64, n2: i64) -> Result<()> {
    if n1 < 1 {
        return Err(Error::parameter(
            "n1",
            format!("must be an integer >= 1; got {n1}"),
        ));
    }
    if n2 <= n1 {
        return Err(Error::parameter(
            "n2",
            format!("must be greater than n1 = {n1}; got {n2}"),
        ));
    }
    if n2 > 1_000_000 {
        return Err(Error::parameter(
            "n2",
            format!("must be at most 1000000; got {n2}"),
        ));
    }
    let g = gcd(n1, n2);
    if g != 1 {
        return Err(Error::parameter(
            "n1, n2",
            format!("must be coprime; gcd({n1}, {n2}) = {g} (divide both by it: same force)"),
        ));
    }
    Ok(())
}

/// Greatest common divisor of non-negative integers.
pub fn gcd(mut a: i64, mut b: i64) -> i64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a.abs()
}

/// `n psi` reduced to `[0, 2 pi)`; an error naming `psi` if the product overflows.
pub(crate) fn harmonic_phase(n: i64, psi: f64) -> Result<f64> {
    let x = n as f64 * psi;
    if !x.is_finite() {
        return Err(Error::parameter(
            "psi",
            format!("is too large: {n} * psi overflows; got {psi:e}"),
        ));
    }
    Ok(x.rem_euclid(std::f64::consts::TAU))
}

/// Average force / (mu m g) at rest under `v(t) = cos(n1 t) - b cos(n2 (t - psi))`, computed
/// exactly from the roots (the numerical side of Theorem 1, 6.12).
pub fn two_sinusoid_force(n1: i64, n2: i64, psi: f64, b: f64) -> Result<f64> {
    check_pair(n1, n2)?;
    finite("psi", psi)?;
    finite("b", b)?;
    let (n1u, n2u) = (n1 as usize, n2 as usize);
    let mut cos = vec![0.0; n2u];
    let mut sin = vec![0.0; n2u];
    // cos(n2 (t - psi)) = cos(n2 t) cos(n2 psi) + sin(n2 t) sin(n2 psi).
    let (s, c) = harmonic_phase(n2, psi)?.sin_cos();
    cos[n1u - 1] = 1.0;
    cos[n2u - 1] = -b * c;
    sin[n2u - 1] = -b * s;
    let wave: Waveform = Harmonics::new(cos, sin, 1.0 / std::f64::consts::TAU)?.into();
    mean_force(&wave, 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pair_checks() {
        assert!(check_pair(2, 4).is_err());
        assert!(check_pair(3, 3).is_err());
        assert!(check_pair(0, 3).is_err());
        assert!(check_pair(2, 3).is_ok());
        assert_eq!(gcd(12, 18), 6);
    }
}
