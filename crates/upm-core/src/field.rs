//! Average force fields of plate motions on (quasi-)stationary parts (docs/spec.md §1, §4, §7).
//!
//! Every field here is dimensionless, `force / (mu m g)`, at points `P` in the plate frame [m]:
//! the time average of the unit vector `(v_s(P, t) - v_p) / |v_s(P, t) - v_p|` (4.5, 6.2).
//!
//! * [`rotation_field`], [`rotation_curl`]: the unit tangential field of a rotation (4.8, 5.1)
//!   and its curl (4.11), closed forms.
//! * [`jet_field`]: the jet of (6.4), integrated over its `6 pi` period between the roots of the
//!   relative velocity's components, which are isolated rigorously; each piece is integrated
//!   adaptively, so the result is exact to the tolerance, not to a sampling rate.
//! * [`average_field`]: any [`PlateMotion`], by adaptive Gauss–Kronrod quadrature over one pass
//!   of the program, split at its item and envelope boundaries.

use std::f64::consts::PI;

use crate::error::{finite, positive, Error, Result};
use crate::motion::PlateMotion;
use crate::quadrature::integrate;
use crate::roots::{sign_changes, Isolation};

/// Default absolute tolerance of the averages (the fields are bounded by 1).
pub const TOL: f64 = 1e-10;

fn check_point(name: &str, p: [f64; 2]) -> Result<()> {
    finite(name, p[0])?;
    finite(name, p[1])?;
    Ok(())
}

/// `R90(P - C) / |P - C|`: the unit tangential field of a rotation about `C` (4.8, 5.1). At `C`
/// itself the plate does not move, so a resting part feels no force: `(0, 0)`.
pub fn rotation_field(p: [f64; 2], c: [f64; 2]) -> [f64; 2] {
    let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
    let r = dx.hypot(dy);
    if r == 0.0 {
        [0.0, 0.0]
    } else {
        [-dy / r, dx / r]
    }
}

/// Curl of [`rotation_field`]: `1 / |P - C|` [1/m] (4.11); infinite at `C`.
pub fn rotation_curl(p: [f64; 2], c: [f64; 2]) -> f64 {
    1.0 / (p[0] - c[0]).hypot(p[1] - c[1])
}

/// Average force / (mu m g) of the jet (6.4) focused at `center`, feeding along `direction`,
/// with radius `rho` [m], on a resting part at `p` (docs/spec.md §7), to absolute accuracy `tol`.
pub fn jet_field(
    p: [f64; 2],
    center: [f64; 2],
    direction: [f64; 2],
    rho: f64,
    tol: f64,
) -> Result<[f64; 2]> {
    check_point("points", p)?;
    check_point("center", center)?;
    check_point("direction", direction)?;
    positive("rho", rho)?;
    positive("tol", tol)?;
    let n = direction[0].hypot(direction[1]);
    if !(n > 0.0 && n.is_finite()) {
        return Err(Error::parameter(
            "direction",
            format!(
                "must be a non-zero vector; got ({}, {})",
                direction[0], direction[1]
            ),
        ));
    }
    let d = [direction[0] / n, direction[1] / n];
    let dp = [-d[1], d[0]];
    // The velocity / |d| is g(t) d + h(t) dp with e = (2/rho) R90(P - C):
    // g = cos t - cos 2t + (e.d) sin(2t/3), h = (e.dp) sin(2t/3).
    let e = [
        -2.0 * (p[1] - center[1]) / rho,
        2.0 * (p[0] - center[0]) / rho,
    ];
    let c1 = e[0] * d[0] + e[1] * d[1];
    let c2 = e[0] * dp[0] + e[1] * dp[1];
    let g = |t: f64| {
        let s = (2.0 * t / 3.0).sin_cos();
        [
            t.cos() - (2.0 * t).cos() + c1 * s.0,
            -t.sin() + 2.0 * (2.0 * t).sin() + c1 * 2.0 / 3.0 * s.1,
            -t.cos() + 4.0 * (2.0 * t).cos() - c1 * 4.0 / 9.0 * s.0,
        ]
    };
    let period = 6.0 * PI;
    let c = c1.abs();
    let iso = Isolation {
        n0: 48,
        lip: [
            3.0 + c * 2.0 / 3.0,
            5.0 + c * 4.0 / 9.0,
            9.0 + c * 8.0 / 27.0,
        ],
        h_min: 1e-13 * period,
        periodic: true,
    };
    let roots = sign_changes(g, 0.0, period, iso).ok_or_else(|| {
        Error::Convergence("could not isolate the roots of the jet's velocity".into())
    })?;
    let mut breaks = vec![0.0, period];
    breaks.extend(roots);
    // The rotating term vanishes at t = 3 pi k / 2.
    breaks.extend((1..4).map(|k| 1.5 * PI * k as f64));
    breaks.sort_by(f64::total_cmp);
    breaks.dedup();
    let avg = if c2 == 0.0 {
        // One-dimensional: the mean sign of g, exact from its roots.
        let mut m = 0.0;
        for w in breaks.windows(2) {
            let s = g(0.5 * (w[0] + w[1]))[0];
            m += (w[1] - w[0])
                * if s > 0.0 {
                    1.0
                } else if s < 0.0 {
                    -1.0
                } else {
                    0.0
                };
        }
        [m / period, 0.0]
    } else {
        let unit = |t: f64| {
            let gt = g(t)[0];
            let ht = c2 * (2.0 * t / 3.0).sin();
            let r = gt.hypot(ht);
            if r == 0.0 {
                [0.0, 0.0]
            } else {
                [gt / r, ht / r]
            }
        };
        let v = integrate(unit, &breaks, tol * period)?;
        [v[0] / period, v[1] / period]
    };
    Ok([
        avg[0] * d[0] + avg[1] * dp[0],
        avg[0] * d[1] + avg[1] * dp[1],
    ])
}

/// Most quadrature pieces one average may take (32 a period of the highest frequency).
const MAX_PIECES: f64 = 2_000_000.0;

/// Average force / (mu m g) that `motion` exerts on a part at `p` moving at `part_velocity`
/// [m/s], over one pass of the program ([`PlateMotion::span`]), to absolute accuracy `tol`.
pub fn average_field(
    motion: &PlateMotion,
    p: [f64; 2],
    part_velocity: [f64; 2],
    tol: f64,
) -> Result<[f64; 2]> {
    check_point("points", p)?;
    check_point("part_velocity", part_velocity)?;
    positive("tol", tol)?;
    let span = motion.span()?;
    let mut breaks = motion.breakpoints()?;
    // Start with pieces no longer than 1/32 of the shortest period present, so a feature of the
    // velocity wider than about 1/500 of that period reaches a node of the first rules.
    let f_max = motion.max_frequency();
    // The pieces are counted before any is allocated: a program of millions of periods is refused
    // here, not by a failed allocation that would abort the process.
    let h = if f_max > 0.0 {
        1.0 / (32.0 * f_max)
    } else {
        f64::INFINITY
    };
    let pieces = |w: &[f64]| ((w[1] - w[0]) / h).ceil().max(1.0);
    let count: f64 = breaks.windows(2).map(pieces).sum();
    if count.is_nan() || count > MAX_PIECES {
        return Err(Error::parameter(
            "motion",
            format!(
                "is too long to average: {:.4} periods of its highest frequency ({} Hz); at most {:.0} \
                 are averaged in one call: average one period or a shorter span",
                span * f_max,
                f_max,
                MAX_PIECES / 32.0,
            ),
        ));
    }
    if f_max > 0.0 {
        let mut refined = Vec::with_capacity(count as usize + 1);
        for w in breaks.windows(2) {
            let k = pieces(w) as usize;
            refined.extend((0..k).map(|i| w[0] + (w[1] - w[0]) * i as f64 / k as f64));
        }
        refined.push(span);
        breaks = refined;
    }
    let unit = |t: f64| {
        let u = motion.velocity(t);
        let v = [
            u[0] - u[2] * p[1] - part_velocity[0],
            u[1] + u[2] * p[0] - part_velocity[1],
        ];
        let r = v[0].hypot(v[1]);
        if r == 0.0 {
            [0.0, 0.0]
        } else {
            [v[0] / r, v[1] / r]
        }
    };
    let v = integrate(unit, &breaks, tol * span)?;
    Ok([v[0] / span, v[1] / span])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_field_is_unit_and_tangential() {
        let f = rotation_field([3.0, 4.0], [0.0, 0.0]);
        assert_eq!(f, [-0.8, 0.6]);
        assert_eq!(rotation_field([1.0, 1.0], [1.0, 1.0]), [0.0, 0.0]);
        assert_eq!(rotation_curl([3.0, 4.0], [0.0, 0.0]), 0.2);
    }
}
