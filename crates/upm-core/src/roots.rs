//! Rigorous scalar root finding used by the exact (root-based) averages.
//!
//! * [`sign_changes`] finds every sign change of a smooth function on an interval, given bounds on
//!   its first and second derivatives. An interval is discarded only when a bound *proves* it
//!   holds no sign change (Lipschitz test) or holds exactly one (monotonicity test); otherwise it
//!   is split. Nothing is decided by sampling alone, so close pairs of roots are never missed: only
//!   tangential zeros narrower than `h_min` are ignored, and those do not change any measure of
//!   sign by more than `h_min`.
//! * [`solve_bracketed`] refines one root inside a bracket (Newton, falling back to bisection).
//! * [`brent`] is Brent's method for a sign change of a monotone (possibly jumping) function.

/// Sign convention shared by every routine here: zero counts as positive.
#[inline]
fn positive(x: f64) -> bool {
    x >= 0.0
}

/// Bounds and resolution for [`sign_changes`].
#[derive(Debug, Clone, Copy)]
pub struct Isolation {
    /// Number of equal parts the interval starts as.
    pub n0: usize,
    /// Upper bounds of `|f'|`, `|f''|` and `|f'''|` on the interval.
    pub lip: [f64; 3],
    /// Sub-intervals narrower than this are not split further.
    pub h_min: f64,
    /// `f(b) = f(a)`: the value at `a` is reused at `b`, so a root at the seam is found once.
    pub periodic: bool,
}

/// Most sub-intervals [`sign_changes`] examines before giving up (a guard against bounds that do
/// not fit the function; correct bounds need a few hundred even at multiple roots).
const MAX_INTERVALS: usize = 200_000;

/// `g` cannot vanish on an interval of width `h` whose ends have values `g0`, `g1` of one sign,
/// given `|g'| <= lip` (the Lipschitz test).
#[inline]
fn no_zero(g0: f64, g1: f64, lip: f64, h: f64) -> bool {
    g0 * g1 > 0.0 && g0.abs() + g1.abs() > lip * h
}

/// Every point where `f` changes sign in `[a, b]`, sorted; `None` if the bounds are useless.
///
/// `f(x)` returns `[f, f', f'']`. An interval is settled when the bounds prove it holds no sign
/// change or exactly one. Monotonicity is proven either by `f'` having no zero (Lipschitz test
/// with `sup |f''|`) or by `f''` having none while `f'` keeps one sign at both ends (with
/// `sup |f'''|`); the second test keeps the work bounded at roots where `f'` vanishes too (a
/// triple root of a velocity's derivative is common: `sin t + cos(2t)/4` at `pi/2`). Roots are
/// located to about `4 eps` relative accuracy; tangential zeros (no sign change) narrower than
/// `iso.h_min` are not reported.
pub fn sign_changes<F>(f: F, a: f64, b: f64, iso: Isolation) -> Option<Vec<f64>>
where
    F: Fn(f64) -> [f64; 3],
{
    let Isolation {
        n0,
        lip,
        h_min,
        periodic,
    } = iso;
    if !lip.iter().all(|l| l.is_finite()) {
        return None;
    }
    let n0 = n0.max(1);
    let mut roots = Vec::new();
    let mut stack: Vec<(f64, [f64; 3], f64, [f64; 3])> = Vec::with_capacity(64);
    let fa = f(a);
    let (mut x_prev, mut f_prev) = (a, fa);
    for i in 1..=n0 {
        let x = if i == n0 {
            b
        } else {
            a + (b - a) * (i as f64) / (n0 as f64)
        };
        let fx = if i == n0 && periodic { fa } else { f(x) };
        stack.push((x_prev, f_prev, x, fx));
        x_prev = x;
        f_prev = fx;
    }
    let mut examined = 0;
    while let Some((x0, f0, x1, f1)) = stack.pop() {
        examined += 1;
        if examined > MAX_INTERVALS {
            return None;
        }
        let h = x1 - x0;
        let change = positive(f0[0]) != positive(f1[0]);
        let monotone = no_zero(f0[1], f1[1], lip[1], h)
            || (f0[1] * f1[1] > 0.0 && no_zero(f0[2], f1[2], lip[2], h));
        if !change && (monotone || no_zero(f0[0], f1[0], lip[0], h)) {
            continue;
        }
        if change && (monotone || h <= h_min) {
            let g = |x: f64| {
                let v = f(x);
                (v[0], v[1])
            };
            roots.push(solve_bracketed(&g, x0, f0[0], x1, f1[0]));
            continue;
        }
        if h <= h_min {
            continue;
        }
        let xm = 0.5 * (x0 + x1);
        let fm = f(xm);
        stack.push((x0, f0, xm, fm));
        stack.push((xm, fm, x1, f1));
    }
    roots.sort_by(f64::total_cmp);
    Some(roots)
}

/// The root of `f` in `[x0, x1]`, where `f(x0) = f0` and `f(x1) = f1` have opposite signs (zero
/// counting as positive). Newton steps are accepted while they stay inside the bracket and shrink
/// at least geometrically; otherwise the bracket is bisected (the `rtsafe` safeguard), so
/// convergence is quadratic near simple roots and never slower than bisection.
pub fn solve_bracketed<F>(f: &F, x0: f64, f0: f64, x1: f64, f1: f64) -> f64
where
    F: Fn(f64) -> (f64, f64),
{
    if f0 == 0.0 {
        return x0;
    }
    if f1 == 0.0 {
        return x1;
    }
    // neg: f < 0 there; pos: f >= 0 there.
    let (mut neg, mut pos) = if positive(f0) { (x1, x0) } else { (x0, x1) };
    let mut step_old = (x1 - x0).abs();
    let mut step = step_old;
    let mut x = 0.5 * (x0 + x1);
    let (mut fx, mut dx) = f(x);
    for _ in 0..200 {
        if fx == 0.0 {
            return x;
        }
        let outside = ((x - pos) * dx - fx) * ((x - neg) * dx - fx) > 0.0;
        if outside || (2.0 * fx).abs() > (step_old * dx).abs() {
            step_old = step;
            step = 0.5 * (pos - neg);
            x = neg + step;
        } else {
            step_old = step;
            step = fx / dx;
            x -= step;
        }
        if step.abs() <= 2.0 * f64::EPSILON * x.abs().max(1.0)
            || (pos - neg).abs() <= 4.0 * f64::EPSILON * x.abs().max(1.0)
        {
            return x;
        }
        (fx, dx) = f(x);
        if positive(fx) {
            pos = x;
        } else {
            neg = x;
        }
    }
    x
}

/// Brent's method: a point where `g` changes sign in `[a, b]`, to absolute tolerance `tol`.
///
/// `g(a)` and `g(b)` must have opposite signs or one of them be zero. `g` need not be continuous:
/// at a jump the method converges to the jump's location (the fallback is bisection).
pub fn brent<G>(g: G, mut a: f64, mut b: f64, tol: f64) -> f64
where
    G: Fn(f64) -> f64,
{
    let mut fa = g(a);
    let mut fb = g(b);
    if fa == 0.0 {
        return a;
    }
    if fb == 0.0 {
        return b;
    }
    let mut c = a;
    let mut fc = fa;
    let mut d = b - a;
    let mut e = d;
    for _ in 0..400 {
        if (fb > 0.0) == (fc > 0.0) {
            c = a;
            fc = fa;
            d = b - a;
            e = d;
        }
        if fc.abs() < fb.abs() {
            a = b;
            b = c;
            c = a;
            fa = fb;
            fb = fc;
            fc = fa;
        }
        let tol1 = 2.0 * f64::EPSILON * b.abs() + 0.5 * tol;
        let xm = 0.5 * (c - b);
        if xm.abs() <= tol1 || fb == 0.0 {
            return b;
        }
        if e.abs() >= tol1 && fa.abs() > fb.abs() {
            // Inverse quadratic interpolation, or the secant step when only two points differ.
            let s = fb / fa;
            let (mut p, mut q);
            if a == c {
                p = 2.0 * xm * s;
                q = 1.0 - s;
            } else {
                let qa = fa / fc;
                let r = fb / fc;
                p = s * (2.0 * xm * qa * (qa - r) - (b - a) * (r - 1.0));
                q = (qa - 1.0) * (r - 1.0) * (s - 1.0);
            }
            if p > 0.0 {
                q = -q;
            }
            p = p.abs();
            let min1 = 3.0 * xm * q - (tol1 * q).abs();
            let min2 = (e * q).abs();
            if 2.0 * p < min1.min(min2) {
                e = d;
                d = p / q;
            } else {
                d = xm;
                e = d;
            }
        } else {
            d = xm;
            e = d;
        }
        a = b;
        fa = fb;
        b += if d.abs() > tol1 { d } else { tol1.copysign(xm) };
        fb = g(b);
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn finds_all_roots_of_a_trig_polynomial() {
        // sin(5x) has 10 sign changes in [0, 2 pi): k pi / 5, k = 0..9 (x = 0 is found at 2 pi).
        let f = |x: f64| {
            [
                (5.0 * x).sin(),
                5.0 * (5.0 * x).cos(),
                -25.0 * (5.0 * x).sin(),
            ]
        };
        let iso = Isolation {
            n0: 4,
            lip: [5.0, 25.0, 125.0],
            h_min: 1e-12,
            periodic: true,
        };
        let r = sign_changes(f, 0.0, 2.0 * PI, iso).unwrap();
        assert_eq!(r.len(), 10, "{r:?}");
        for (k, x) in r.iter().enumerate() {
            let want = (k + 1) as f64 * PI / 5.0;
            assert!((x - want).abs() < 1e-13, "root {k}: {x} vs {want}");
        }
    }

    #[test]
    fn does_not_miss_a_close_pair_of_roots() {
        // (x - 1)(x - 1 - 1e-7) on [0, 3]: two roots 1e-7 apart, invisible to any coarse grid.
        let f = |x: f64| [(x - 1.0) * (x - 1.0 - 1e-7), 2.0 * x - 2.0 - 1e-7, 2.0];
        let iso = Isolation {
            n0: 3,
            lip: [4.0, 2.0, 0.0],
            h_min: 1e-13,
            periodic: false,
        };
        let r = sign_changes(f, 0.0, 3.0, iso).unwrap();
        assert_eq!(r.len(), 2, "{r:?}");
        assert!((r[0] - 1.0).abs() < 1e-14 && (r[1] - 1.0 - 1e-7).abs() < 1e-14);
    }

    #[test]
    fn ignores_tangential_zeros() {
        let f = |x: f64| [(x - 1.0).powi(2), 2.0 * (x - 1.0), 2.0];
        let iso = Isolation {
            n0: 3,
            lip: [4.0, 2.0, 0.0],
            h_min: 1e-12,
            periodic: false,
        };
        assert!(sign_changes(f, 0.0, 3.0, iso).unwrap().is_empty());
    }

    #[test]
    fn a_triple_root_is_found_once_with_little_work() {
        // cos x (1 - sin x) ~ -(x - pi/2)^3 / 2 near pi/2: f and f' vanish there together.
        let f = |x: f64| {
            let (s, c) = x.sin_cos();
            [
                c * (1.0 - s),
                -s * (1.0 - s) - c * c,
                -c * (1.0 - s) + 3.0 * s * c,
            ]
        };
        let iso = Isolation {
            n0: 12,
            lip: [3.0, 5.0, 10.0],
            h_min: 1e-11,
            periodic: true,
        };
        let r = sign_changes(f, 0.0, 2.0 * PI, iso).expect("bounded work");
        assert_eq!(r.len(), 2, "{r:?}");
        assert!(
            (r[0] - PI / 2.0).abs() < 1e-5 && (r[1] - 1.5 * PI).abs() < 1e-12,
            "{r:?}"
        );
    }

    #[test]
    fn useless_bounds_give_none_instead_of_spinning() {
        let f = |x: f64| [x.sin(), x.cos(), -x.sin()];
        let iso = Isolation {
            n0: 4,
            lip: [f64::INFINITY, 1.0, 1.0],
            h_min: 1e-12,
            periodic: true,
        };
        assert!(sign_changes(f, 0.0, 2.0 * PI, iso).is_none());
    }

    #[test]
    fn brent_finds_a_jump_and_a_smooth_root() {
        let step = |x: f64| if x < 0.3 { 1.0 } else { -1.0 };
        assert!((brent(step, 0.0, 1.0, 1e-14) - 0.3).abs() < 1e-13);
        let cubic = |x: f64| x * x * x - 2.0;
        assert!((brent(cubic, 0.0, 2.0, 1e-15) - 2f64.cbrt()).abs() < 1e-14);
    }
}
