//! The disk's stick test: whether the wrench `(na, nb)` that would stop a disk (in units of
//! `mu m g` and `mu m g R`) lies inside the limit curve `(f, t)` of [`super::limit_curve`].
//!
//! The curve is convex and contains the chord `f + 3t/2 <= 1`, so only between the chord and the
//! curve is the curve consulted: by its squared radius in the wrench's direction, tabulated over
//! the ratio `nb / (na + nb)` (no `atan2`), and within [`STICK_MARGIN`] of it by the exact test,
//! Brent's method on the curve's polar angle. Every decision is the exact test's.

use std::f64::consts::FRAC_PI_2;
use std::sync::OnceLock;

use super::limit_curve;

/// Whether the wrench `(na, nb)`, with `na <= 1` and `nb <= 2/3`, lies inside the limit curve.
pub(super) fn holds(na: f64, nb: f64) -> bool {
    if na + 1.5 * nb <= 1.0 {
        return true;
    }
    let r2 = na * na + nb * nb;
    let edge = stick_radius2(nb / (na + nb));
    if r2 <= edge * (1.0 - STICK_MARGIN) {
        return true;
    }
    r2 < edge * (1.0 + STICK_MARGIN) && inside_exactly(na, nb)
}

/// `na^2 + nb^2 <= f^2 + t^2` at the limit curve's point in the direction of `(na, nb)`, found
/// by Brent's method on the curve's polar angle (the stick test's exact form).
fn inside_exactly(na: f64, nb: f64) -> bool {
    let (f, t) = limit_curve(curve_angle(nb.atan2(na)));
    na * na + nb * nb <= f * f + t * t
}

/// The curve parameter `phi` whose point `(f, t)` lies at polar angle `psi`.
fn curve_angle(psi: f64) -> f64 {
    crate::roots::brent(
        |p| {
            let (f, t) = limit_curve(p);
            t.atan2(f) - psi
        },
        0.0,
        FRAC_PI_2,
        1e-15,
    )
}

/// Entries of the stick test's table over `u = nb / (na + nb)` in `[0, 1]`.
const UTABLE: usize = 8193;

/// Relative band about the tabulated curve within which the stick test is taken exactly: above
/// the table's interpolation error (measured in the tests) by two orders of magnitude.
const STICK_MARGIN: f64 = 1e-6;

/// The limit curve's squared radius `f^2 + t^2` at the point whose direction has
/// `t / (f + t) = u`, at `UTABLE` evenly spread `u`, each from [`curve_angle`].
fn utable() -> &'static [f64] {
    static T: OnceLock<Vec<f64>> = OnceLock::new();
    T.get_or_init(|| {
        (0..UTABLE)
            .map(|i| {
                let u = i as f64 / (UTABLE - 1) as f64;
                let (f, t) = limit_curve(curve_angle(u.atan2(1.0 - u)));
                f * f + t * t
            })
            .collect()
    })
}

/// The limit curve's squared radius in the direction with `t / (f + t) = u` (cubic
/// Catmull–Rom on [`utable`]).
fn stick_radius2(u: f64) -> f64 {
    let tab = utable();
    let x = u.clamp(0.0, 1.0) * (UTABLE - 1) as f64;
    let i = (x as usize).min(UTABLE - 2);
    let s = x - i as f64;
    let at = |k: usize| tab[k.min(UTABLE - 1)];
    let (a, b, c, d) = (at(i.saturating_sub(1)), at(i), at(i + 1), at(i + 2));
    b + 0.5 * s * (c - a + s * (2.0 * a - 5.0 * b + 4.0 * c - d + s * (3.0 * (b - c) + d - a)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::disk::{prepare, Pre};

    #[test]
    fn the_stick_table_is_within_its_margin_of_the_exact_curve() {
        // the tabulated squared radius against the exact test's, at ratios between the nodes and
        // close to both ends (pure sliding, pure spinning)
        let mut worst = 0.0f64;
        let n = 20_000;
        for k in 0..=n {
            let v = k as f64 / n as f64;
            for u in [v, v * v * v * 1e-3, 1.0 - v * v * v * 1e-3] {
                let (f, t) = limit_curve(curve_angle(u.atan2(1.0 - u)));
                let exact = f * f + t * t;
                worst = worst.max((stick_radius2(u) / exact - 1.0).abs());
            }
        }
        assert!(
            worst < STICK_MARGIN / 100.0,
            "worst relative error {worst:e}"
        );
        // and the decision is the exact one on both sides of the curve, near it and far from it
        for k in 1..400 {
            let psi = FRAC_PI_2 * k as f64 / 400.0;
            let (f, t) = limit_curve(curve_angle(psi));
            let r = f.hypot(t);
            for scale in [0.5, 0.999, 1.0 - 1e-12, 1.0 + 1e-12, 1.001, 1.2] {
                let (na, nb) = (scale * r * psi.cos(), scale * r * psi.sin());
                let (w, s) = ([na * 0.01, 0.0], 2.0 * nb * 0.01);
                let fast = matches!(prepare(w, s, 0.01, 0.01, false), Pre::Done(st) if st.stuck);
                let exact = na + 1.5 * nb <= 1.0 || inside_exactly(na, nb);
                assert_eq!(fast, exact, "psi {psi}, scale {scale}");
            }
        }
    }
}
