//! Coulomb friction of a flat disk part under uniform pressure (docs/spec.md §1 extended to an area).
//!
//! Relative to the plate, a disk of radius `R` moves with a planar twist: the velocity `w` of its
//! centre and the spin `W`. The relative velocity over the footprint is a rotation at rate `W`
//! about the point at distance `d = |w| / |W|` from the centre (perpendicular to `w`), so the
//! friction is the rotation force field (thesis 4.8) averaged over the disk. By symmetry it depends
//! on one angle, `phi = atan2(R |W|, |w|)` in `[0, pi/2]`:
//!
//! * force  `= -mu m g f(phi) w / |w|`, with `f(0) = 1` (pure sliding), `f(pi/2) = 0`;
//! * torque `= -mu m g R t(phi) sgn(W)`, with `t(0) = 0`, `t(pi/2) = 2/3` (pure spinning).
//!
//! `f` and `t` are integrals over the polar angle around the rotation point, smooth in that angle,
//! computed with Gauss–Legendre quadrature; the tables used by the integrator are built once from
//! them and interpolated (the errors are measured in the tests): one over `phi` for the stick
//! test, one over `z = tan(phi) / (1 + tan(phi))`, a ratio of the state's magnitudes, for the
//! sliding solve (Halley's method, no `atan2`).
//!
//! The implicit step minimises `m |w' - w*|^2 / 2 + I (W' - W*)^2 / 2 + dt D(w', W')`, with `D`
//! the (convex, positively homogeneous) dissipation: the disk sticks when the wrench needed to stop
//! it lies inside the limit curve `(f, t)`; otherwise `w'` keeps the direction of `w*`, `W'` the
//! sign of `W*`, and their magnitudes follow from one monotone root in `phi`.

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
pub mod lanes;
mod stick;

use std::f64::consts::{FRAC_PI_2, PI};
use std::sync::OnceLock;

/// `(f, t)` at `phi` by quadrature: the rotation point sits at distance `d = cot(phi)` (in units of
/// `R`) from the centre.
pub fn force_torque(phi: f64) -> (f64, f64) {
    force_torque_panels(phi, 16)
}

/// [`force_torque`] with `panels` Gauss–Legendre panels (8 points each).
pub fn force_torque_panels(phi: f64, panels: usize) -> (f64, f64) {
    if phi <= 0.0 {
        return (1.0, 0.0);
    }
    if phi >= FRAC_PI_2 {
        return (0.0, 2.0 / 3.0);
    }
    let d = phi.cos() / phi.sin();
    // Polar angle theta = 3 pi / 2 + delta around the rotation point rho0 = (0, d); ray
    // u = (sin delta, -cos delta). The ray meets the unit disk for r in [r1, r2], the roots of
    // r^2 - 2 r d cos(delta) + d^2 - 1 = 0, whose discriminant is 1 - d^2 sin^2(delta).
    // Force along -w: (1/pi) int cos(delta) (r2^2 - r1^2)/2; torque: (1/pi) int
    // [-d cos(delta) (r2^2 - r1^2)/2 + (r2^3 - r1^3)/3], both over delta.
    let integrand = |delta: f64| {
        let (sd, cd) = delta.sin_cos();
        let ds = d * sd;
        let disc = 1.0 - ds * ds;
        if disc <= 0.0 {
            return (0.0, 0.0);
        }
        let (p, q) = (d * cd, disc.sqrt());
        if d >= 1.0 {
            // The whole chord [p - q, p + q] lies ahead; with r = p + x the two torque terms
            // -p r + r^2 integrate to 2 q^3 / 3 exactly, free of the cancellation of order d^3.
            (2.0 * cd * p * q, 2.0 * q * q * q / 3.0)
        } else {
            let r2 = p + q;
            let a2 = 0.5 * r2 * r2;
            (cd * a2, -p * a2 + r2 * r2 * r2 / 3.0)
        }
    };
    let (f, t) = if d < 1.0 {
        gauss_legendre(integrand, -PI, PI, panels)
    } else {
        // Only |delta| <= asin(1/d) meets the disk; the chord vanishes like a square root at both
        // ends, which delta = half sin(tau) smooths out.
        let half = (1.0 / d).asin();
        let smooth = |tau: f64| {
            let (a, b) = integrand(half * tau.sin());
            let j = half * tau.cos();
            (a * j, b * j)
        };
        gauss_legendre(smooth, -FRAC_PI_2, FRAC_PI_2, panels)
    };
    (f / PI, t / PI)
}

/// Composite Gauss–Legendre (8 points per panel, `panels` panels) of a pair-valued function.
fn gauss_legendre(g: impl Fn(f64) -> (f64, f64), a: f64, b: f64, panels: usize) -> (f64, f64) {
    const X: [f64; 4] = [
        0.183_434_642_495_649_8,
        0.525_532_409_916_329,
        0.796_666_477_413_626_7,
        0.960_289_856_497_536_3,
    ];
    const W: [f64; 4] = [
        0.362_683_783_378_362,
        0.313_706_645_877_887_3,
        0.222_381_034_453_374_5,
        0.101_228_536_290_376_26,
    ];
    let h = (b - a) / panels as f64;
    let (mut s0, mut s1) = (0.0, 0.0);
    for p in 0..panels {
        let mid = a + (p as f64 + 0.5) * h;
        for k in 0..4 {
            for sign in [-1.0, 1.0] {
                let (u, v) = g(mid + sign * X[k] * h / 2.0);
                s0 += W[k] * u;
                s1 += W[k] * v;
            }
        }
    }
    (s0 * h / 2.0, s1 * h / 2.0)
}

/// Entries of the `(f, t)` tables over `phi` in `[0, pi/2]`.
const TABLE: usize = 8193;

fn table() -> &'static [(f64, f64)] {
    static T: OnceLock<Vec<(f64, f64)>> = OnceLock::new();
    T.get_or_init(|| {
        (0..TABLE)
            .map(|i| force_torque(FRAC_PI_2 * i as f64 / (TABLE - 1) as f64))
            .collect()
    })
}

/// `(f, t)` at `phi` from the table (cubic Catmull–Rom interpolation).
pub fn limit_curve(phi: f64) -> (f64, f64) {
    let tab = table();
    let u = (phi.clamp(0.0, FRAC_PI_2) / FRAC_PI_2) * (TABLE - 1) as f64;
    let i = (u.floor() as usize).min(TABLE - 2);
    let s = u - i as f64;
    let at = |k: isize| tab[(i as isize + k).clamp(0, TABLE as isize - 1) as usize];
    let (p0, p1, p2, p3) = (at(-1), at(0), at(1), at(2));
    let cr = |a: f64, b: f64, c: f64, d: f64| {
        b + 0.5 * s * (c - a + s * (2.0 * a - 5.0 * b + 4.0 * c - d + s * (3.0 * (b - c) + d - a)))
    };
    (cr(p0.0, p1.0, p2.0, p3.0), cr(p0.1, p1.1, p2.1, p3.1))
}

/// Entries of the `(f, t)` table over `z = tan(phi) / (1 + tan(phi))` in `[0, 1]`.
const ZTABLE: usize = 16385;

/// `(f, t)` tabulated over `z`, a rational function of the disk's `(|w|, R |W|)`: `z = b / (a + b)`
/// (no `atan2` to find the entry). `phi = atan2(z, 1 - z)`, so `dphi/dz` lies in `[1, 2]`.
/// (The rows of [`ztable_padded`] between its repeated edge rows.)
fn ztable() -> &'static [[f64; 2]] {
    &ztable_padded()[1..=ZTABLE]
}

/// [`ztable`] with its first and last rows repeated once more at either end: row `i + 1` is the
/// table's row `i`, so the four rows `i - 1 ..= i + 2` that [`curve_z`] reads (with its indices
/// clamped to the table) lie together from row `i` on, for every `i` it takes (one wide load
/// each where a gather would read them one by one).
fn ztable_padded() -> &'static [[f64; 2]] {
    static T: OnceLock<Vec<[f64; 2]>> = OnceLock::new();
    T.get_or_init(|| {
        let row = |i: usize| {
            let z = i as f64 / (ZTABLE - 1) as f64;
            let (f, t) = force_torque(z.atan2(1.0 - z));
            [f, t]
        };
        let mut padded = Vec::with_capacity(ZTABLE + 2);
        padded.extend((0..ZTABLE).map(row));
        padded.insert(0, padded[0]);
        padded.push(padded[ZTABLE]);
        padded
    })
}

/// `(f, t, df/dz, dt/dz)` at `z = b / (a + b)` in `[0, 1]` (cubic Catmull–Rom on [`ztable`]).
pub fn limit_curve_z(z: f64) -> (f64, f64, f64, f64) {
    let [[f, df, _], [t, dt, _]] = curve_z(ztable(), z);
    (f, t, df, dt)
}

/// [`limit_curve_z`] on the table `tab`, with the second derivatives:
/// `[(f, f', f''), (t, t', t'')]` in `z`.
#[inline(always)]
fn curve_z(tab: &[[f64; 2]], z: f64) -> [[f64; 3]; 2] {
    let scale = (ZTABLE - 1) as f64;
    let u = z.clamp(0.0, 1.0) * scale;
    let i = (u as usize).min(ZTABLE - 2);
    let s = u - i as f64;
    let at = |k: usize| tab[k.min(ZTABLE - 1)];
    let (p0, p1, p2, p3) = (at(i.saturating_sub(1)), at(i), at(i + 1), at(i + 2));
    let cr = |a: f64, b: f64, c: f64, d: f64| {
        let (c1, c2, c3) = (
            0.5 * (c - a),
            a - 2.5 * b + 2.0 * c - 0.5 * d,
            1.5 * (b - c) + 0.5 * (d - a),
        );
        [
            b + s * (c1 + s * (c2 + s * c3)),
            (c1 + s * (2.0 * c2 + 3.0 * s * c3)) * scale,
            (2.0 * c2 + 6.0 * s * c3) * scale * scale,
        ]
    };
    [
        cr(p0[0], p1[0], p2[0], p3[0]),
        cr(p0[1], p1[1], p2[1], p3[1]),
    ]
}

/// The sliding magnitudes `(|w'|, R |W'|)` from `(a0, b0)` (both > 0) by Halley's method on
/// `z = b / (a + b)` of the result: `r(z) = (1 - z) b(z) - z a(z) = 0` with
/// `a(z) = a0 - c f(z)`, `b(z) = b0 - 2 c t(z)`, decreasing in `z` while the disk slides, from
/// `z = b0 / (a0 + b0)` (off by `O(c / (a0 + b0))`; the cubic convergence then needs one to three
/// look-ups). `None` when it does not settle in a few steps (a disk about to stop), for the
/// caller's slower, safe solve.
fn slide_newton(a0: f64, b0: f64, c: f64) -> Option<(f64, f64)> {
    let tab = ztable();
    let mut z = b0 / (a0 + b0);
    for _ in 0..HALLEY_STEPS {
        match halley(tab, a0, b0, c, z) {
            Halley::Next(next) => z = next,
            Halley::Done(ab) => return ab,
        }
    }
    None
}

/// The most Halley steps [`slide_newton`] takes before it gives up.
const HALLEY_STEPS: usize = 8;

/// One step of [`slide_newton`].
enum Halley {
    /// Not settled yet: the next `z`.
    Next(f64),
    /// Settled (`Some` magnitudes) or failed (`None`: the caller's safe solve).
    Done(Option<(f64, f64)>),
}

/// One Halley step of [`slide_newton`] from `z`.
#[inline(always)]
fn halley(tab: &[[f64; 2]], a0: f64, b0: f64, c: f64, z: f64) -> Halley {
    let [[f, df, ddf], [t, dt, ddt]] = curve_z(tab, z);
    let (a, b) = (a0 - c * f, b0 - 2.0 * c * t);
    let r = (1.0 - z) * b - z * a;
    let dr = -b - a - 2.0 * c * (1.0 - z) * dt + c * z * df;
    let ddr = 4.0 * c * dt + 2.0 * c * df - 2.0 * c * (1.0 - z) * ddt + c * z * ddf;
    if dr.is_nan() || dr >= 0.0 {
        return Halley::Done(None);
    }
    let newton = r / dr;
    let step = newton / (1.0 - 0.5 * newton * ddr / dr);
    let z = z - step;
    if !(0.0..=1.0).contains(&z) {
        return Halley::Done(None);
    }
    // Cubic convergence: once the step is below 1e-6 the next is below rounding, and the curve
    // at the new z is its second-order Taylor polynomial (the neglected term: c step^3 f3/6).
    if step.abs() <= 1e-6 {
        let h = 0.5 * step * step;
        let a = a0 - c * (f - df * step + ddf * h);
        let b = b0 - 2.0 * c * (t - dt * step + ddt * h);
        return Halley::Done((a > 0.0 && b > 0.0).then_some((a, b)));
    }
    Halley::Next(z)
}

/// Result of one implicit step of a disk.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// Velocity of the disk's centre relative to the plate after the step [m/s].
    pub w: [f64; 2],
    /// `R` times the spin relative to the plate after the step [m/s].
    pub s: f64,
    /// Whether the disk moves with the plate after the step.
    pub stuck: bool,
}

/// What the stick test and the closed forms leave of a disk's step ([`prepare`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pre {
    /// The step is done: stuck, pure sliding or pure spinning.
    Done(Step),
    /// The disk slides and spins: its magnitudes `(|w'|, R |W'|)` solve the sliding equations
    /// from `(a0, b0) = (|w_free|, |s_free|)`, both positive ([`slide`], then [`finish`]).
    Slide {
        /// `|w_free|` [m/s].
        a0: f64,
        /// `|s_free|` [m/s].
        b0: f64,
    },
}

/// The implicit Coulomb step of a uniform disk (`I = m R^2 / 2`): `w_free` and `s_free` are the
/// relative velocity and `R` times the relative spin the disk would have after the step without
/// friction; `slide = mu g dt`, `hold = mu_s g dt` (used while the disk is stuck).
pub fn implicit_step(
    w_free: [f64; 2],
    s_free: f64,
    slide: f64,
    hold: f64,
    was_stuck: bool,
) -> Step {
    match prepare(w_free, s_free, slide, hold, was_stuck) {
        Pre::Done(step) => step,
        Pre::Slide { a0, b0 } => {
            let (a, b) = self::slide(a0, b0, slide);
            finish(w_free, s_free, a0, a, b)
        }
    }
}

/// The first part of [`implicit_step`]: the stick test and the closed forms of pure sliding and
/// pure spinning; what remains is a [`Pre::Slide`] (solved one disk at a time by [`slide`], or
/// many at once by [`lanes::slide_many`]).
pub fn prepare(w_free: [f64; 2], s_free: f64, slide: f64, hold: f64, was_stuck: bool) -> Pre {
    decide(
        w_free,
        s_free,
        slide,
        magnitudes(w_free, s_free, slide, hold, was_stuck),
    )
}

/// The magnitudes [`prepare`] decides on: `|w_free|`, `|s_free|` and the wrench that would stop
/// the disk, in units of `mu m g` and `mu m g R` (for the static coefficient while stuck).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Magnitudes {
    /// `|w_free|` [m/s].
    pub a0: f64,
    /// `|s_free|` [m/s].
    pub b0: f64,
    /// The stopping force over `mu m g`.
    pub na: f64,
    /// The stopping torque over `mu m g R`.
    pub nb: f64,
}

/// [`Magnitudes`] of a disk's free step: branch-free arithmetic, so that in a pass over many
/// disks their square roots and divisions overlap (no branch waits on them).
#[inline(always)]
pub fn magnitudes(
    w_free: [f64; 2],
    s_free: f64,
    slide: f64,
    hold: f64,
    was_stuck: bool,
) -> Magnitudes {
    let a0 = (w_free[0] * w_free[0] + w_free[1] * w_free[1]).sqrt();
    let b0 = s_free.abs();
    let c = if was_stuck { hold } else { slide };
    Magnitudes {
        a0,
        b0,
        na: a0 / c,
        nb: 0.5 * b0 / c,
    }
}

/// [`prepare`]'s decision from the disk's [`Magnitudes`] `m`.
#[inline]
pub fn decide(w_free: [f64; 2], s_free: f64, slide: f64, m: Magnitudes) -> Pre {
    let Magnitudes { a0, b0, na, nb } = m;
    let stuck = Pre::Done(Step {
        w: [0.0; 2],
        s: 0.0,
        stuck: true,
    });
    if a0 == 0.0 && b0 == 0.0 {
        return stuck;
    }
    // Stick test: the wrench that stops the disk inside the limit curve, which lies in
    // [0, 1] x [0, 2/3].
    if na <= 1.0 && nb <= 2.0 / 3.0 && stick::holds(na, nb) {
        return stuck;
    }
    // Sliding: |w'| = |w_free| - slide f(phi'), |s'| = |s_free| - 2 slide t(phi'), with phi' the
    // angle of the result itself. Pure sliding and pure spinning are closed forms (f(0) = 1,
    // t(pi/2) = 2/3).
    if b0 == 0.0 {
        Pre::Done(finish(w_free, s_free, a0, a0 - slide, 0.0))
    } else if a0 == 0.0 {
        Pre::Done(finish(w_free, s_free, a0, 0.0, b0 - 4.0 / 3.0 * slide))
    } else {
        Pre::Slide { a0, b0 }
    }
}

/// The sliding magnitudes `(|w'|, R |W'|)` of a [`Pre::Slide`]: Halley's method on `z = b / (a +
/// b)` (`slide_newton`: no atan2, one to three table look-ups), and where it does not settle (a
/// disk about to stop) the safe solve [`slide_safe`].
pub fn slide(a0: f64, b0: f64, slide: f64) -> (f64, f64) {
    slide_newton(a0, b0, slide).unwrap_or_else(|| slide_safe(a0, b0, slide))
}

/// The slow, safe sliding solve: iterate `phi <- atan2(b(phi), a(phi))`, with Brent's method on
/// the monotone residual where that does not converge.
pub fn slide_safe(a0: f64, b0: f64, slide: f64) -> (f64, f64) {
    let ab = |p: f64| {
        let (f, t) = limit_curve(p);
        (a0 - slide * f, b0 - 2.0 * slide * t)
    };
    let mut phi = b0.atan2(a0);
    let mut converged = false;
    for _ in 0..30 {
        let (a, b) = ab(phi);
        let next = b.atan2(a);
        if !(0.0..=FRAC_PI_2).contains(&next) {
            break;
        }
        if (next - phi).abs() <= 1e-15 {
            phi = next;
            converged = true;
            break;
        }
        phi = next;
    }
    if !converged {
        phi = crate::roots::brent(
            |p| {
                let (a, b) = ab(p);
                p - b.atan2(a)
            },
            0.0,
            FRAC_PI_2,
            1e-15,
        );
    }
    ab(phi)
}

/// The step of a sliding disk from the magnitudes `(a, b)` of its result (`a0 = |w_free|`): `w'`
/// keeps the direction of `w_free`, `s'` the sign of `s_free`.
pub fn finish(w_free: [f64; 2], s_free: f64, a0: f64, a: f64, b: f64) -> Step {
    let (a, b) = (a.max(0.0), b.max(0.0));
    let scale = if a0 > 0.0 { a / a0 } else { 0.0 };
    Step {
        w: [w_free[0] * scale, w_free[1] * scale],
        s: b.copysign(s_free),
        stuck: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Independent reference: the mean over a fine grid of the unit disk (error ~1e-6).
    fn brute(phi: f64, n: usize) -> (f64, f64) {
        let (a, s) = (phi.cos(), phi.sin());
        let (mut f, mut t, mut count) = (0.0, 0.0, 0.0);
        for i in 0..n {
            for j in 0..n {
                let (x, y) = (
                    2.0 * (i as f64 + 0.5) / n as f64 - 1.0,
                    2.0 * (j as f64 + 0.5) / n as f64 - 1.0,
                );
                if x * x + y * y > 1.0 {
                    continue;
                }
                let (vx, vy) = (a - s * y, s * x);
                let r = vx.hypot(vy);
                f += vx / r;
                t += (x * vy - y * vx) / r;
                count += 1.0;
            }
        }
        (f / count, t / count)
    }

    #[test]
    fn quadrature_matches_a_brute_force_average_and_the_limits() {
        for phi in [0.05, 0.4, FRAC_PI_2 / 2.0, 0.9, 1.3, 1.55] {
            let (f, t) = force_torque(phi);
            let (bf, bt) = brute(phi, 1500);
            assert!(
                (f - bf).abs() < 2e-5 && (t - bt).abs() < 2e-5,
                "phi {phi}: ({f}, {t}) vs ({bf}, {bt})"
            );
        }
        let (f, t) = force_torque(1e-9);
        assert!((f - 1.0).abs() < 1e-8 && t.abs() < 1e-8);
        let (f, t) = force_torque(FRAC_PI_2 - 1e-9);
        assert!(f.abs() < 1e-8 && (t - 2.0 / 3.0).abs() < 1e-8);
    }

    #[test]
    fn quadrature_has_converged_and_the_table_interpolates_it() {
        // Measured: against 8x the panels the quadrature is within 2e-9 (worst where the rotation
        // point nears the rim, d ~ 1), and the table within 2e-9 of the quadrature.
        let (mut quad, mut tab): (f64, f64) = (0.0, 0.0);
        for k in 0..997 {
            let phi = FRAC_PI_2 * (k as f64 + 0.37) / 997.0;
            let (f, t) = force_torque(phi);
            let (f8, t8) = force_torque_panels(phi, 128);
            let (g, u) = limit_curve(phi);
            quad = quad.max((f - f8).abs()).max((t - t8).abs());
            tab = tab.max((f - g).abs()).max((t - u).abs());
        }
        assert!(quad < 2e-9, "quadrature error {quad:e}");
        assert!(tab < 2e-9, "table error {tab:e}");
    }

    #[test]
    fn implicit_step_sticks_inside_the_limit_curve_and_slides_outside() {
        let c = 0.01;
        // Pure translation: sticks iff |w| <= c, else loses exactly c.
        assert!(implicit_step([0.0059, 0.0079], 0.0, c, c, false).stuck);
        let s = implicit_step([0.03, 0.04], 0.0, c, c, false);
        assert!(!s.stuck && (s.w[0].hypot(s.w[1]) - 0.04).abs() < 1e-12 && s.s == 0.0);
        // Pure spin: torque 2/3 mu m g R, I = m R^2/2, so R W drops by 4/3 c.
        let s = implicit_step([0.0, 0.0], -0.05, c, c, false);
        assert!(!s.stuck && (s.s + 0.05 - 4.0 / 3.0 * c).abs() < 1e-9);
        assert!(implicit_step([0.0, 0.0], 0.013, c, c, false).stuck);
        // Static friction holds a stuck disk a little longer.
        assert!(implicit_step([0.012, 0.0], 0.0, c, 1.5 * c, true).stuck);
        assert!(!implicit_step([0.012, 0.0], 0.0, c, 1.5 * c, false).stuck);
    }

    #[test]
    fn the_step_solves_its_own_optimality_condition() {
        // w' = w* - c f(z') w'/|w'|, s' = s* - 2 c t(z') sgn(s'), z' = |s'| / (|w'| + |s'|), with
        // the step's own curve, and within the tables' error of the quadrature's.
        for (w, s) in [
            ([0.05, -0.02], 0.04),
            ([0.01, 0.0], -0.09),
            ([-0.2, 0.1], 0.001),
            ([0.003, 0.004], 0.006),
        ] {
            let c = 0.004;
            let st = implicit_step(w, s, c, c, false);
            let (a, b) = (st.w[0].hypot(st.w[1]), st.s.abs());
            let (f, t, ..) = limit_curve_z(b / (a + b));
            let a0 = w[0].hypot(w[1]);
            assert!((a - (a0 - c * f)).abs() < 1e-13, "{w:?} {s}");
            assert!((b - (s.abs() - 2.0 * c * t)).abs() < 1e-13, "{w:?} {s}");
            let (fq, tq) = force_torque(b.atan2(a));
            assert!((a - (a0 - c * fq)).abs() < 1e-10 * c, "{w:?} {s}");
            assert!(
                (b - (s.abs() - 2.0 * c * tq)).abs() < 1e-10 * c,
                "{w:?} {s}"
            );
        }
    }

    #[test]
    fn the_z_table_matches_the_quadrature_and_its_derivatives() {
        let (mut err, mut derr): (f64, f64) = (0.0, 0.0);
        for k in 0..1999 {
            let z = (k as f64 + 0.41) / 1999.0;
            let (f, t, df, dt) = limit_curve_z(z);
            let (fq, tq) = force_torque(z.atan2(1.0 - z));
            err = err.max((f - fq).abs()).max((t - tq).abs());
            // Central differences of the quadrature (error ~1e-7 here).
            let h = 1e-5;
            let (f1, t1) = force_torque((z + h).atan2(1.0 - z - h));
            let (f0, t0) = force_torque((z - h).atan2(1.0 - z + h));
            let (dfq, dtq) = ((f1 - f0) / (2.0 * h), (t1 - t0) / (2.0 * h));
            derr = derr.max((df - dfq).abs()).max((dt - dtq).abs());
        }
        assert!(err < 2e-9, "table error {err:e}");
        assert!(derr < 1e-3, "derivative error {derr:e}");
    }

    #[test]
    fn newton_agrees_with_the_angle_iteration() {
        // The slow, safe solve (Brent's method in phi on the phi table): the same magnitudes to
        // the two tables' difference, over sliding states from fast to nearly stopping.
        let c = 0.002;
        let (mut worst, mut solved): (f64, usize) = (0.0, 0);
        for i in 0..400 {
            let a0 = c * 10f64.powf(-0.2 + 3.0 * ((i * 37) % 400) as f64 / 400.0);
            let b0 = c * 10f64.powf(-0.2 + 3.0 * ((i * 91) % 400) as f64 / 400.0);
            let Some((a, b)) = slide_newton(a0, b0, c) else {
                continue;
            };
            solved += 1;
            let phi = crate::roots::brent(
                |p| {
                    let (f, t) = limit_curve(p);
                    p - (b0 - 2.0 * c * t).atan2(a0 - c * f)
                },
                0.0,
                FRAC_PI_2,
                1e-15,
            );
            let (f, t) = limit_curve(phi);
            let d = (a - (a0 - c * f)).abs().max((b - (b0 - 2.0 * c * t)).abs());
            worst = worst.max(d);
        }
        assert!(worst < 1e-10 * c, "worst difference {worst:e}");
        // Newton settles but for disks about to stop (a0 or b0 within a few c of zero).
        assert!(solved >= 300, "Newton settled in {solved} of 400 states");
    }
}
