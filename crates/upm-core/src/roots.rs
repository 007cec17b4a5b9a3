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
    /// An upper bound of `|f'|` on the interval.
    pub lip_f: f64,
    /// An upper bound of `|f''|` on the interval.
    pub lip_df: f64,
    /// Sub-intervals narrower than this are not split further.
    pub h_min: f64,
    /// `f(b) = f(a)`: the value at `a` is reused at `b`, so a root at the seam is found once.
    pub periodic: bool,
}

/// Every point where `f` changes sign in `[a, b]`, sorted.
///
/// `f(x)` returns `(f, f')`. Roots are located to about `4 eps` relative accuracy; tangential zeros
/// (no sign change) narrower than `iso.h_min` are not reported.
pub fn sign_changes<F>(f: F, a: f64, b: f64, iso: Isolation) -> Vec<f64>
where
    F: Fn(f64) -> (f64, f64),
{
    let Isolation { n0, lip_f, lip_df, h_min, periodic } = iso;
    let n0 = n0.max(1);
    let mut roots = Vec::new();
    // (x0, f0, d0, x1, f1, d1)
    let mut stack: Vec<[f64; 6]> = Vec::with_capacity(64);
    let fa = f(a);
    let (mut x_prev, mut fd_prev) = (a, fa);
    for i in 1..=n0 {
        let x = if i == n0 { b } else { a + (b - a) * (i as f64) / (n0 as f64) };
        let fd = if i == n0 && periodic { fa } else { f(x) };
        stack.push([x_prev, fd_prev.0, fd_prev.1, x, fd.0, fd.1]);
        x_prev = x;
        fd_prev = fd;
    }
    while let Some([x0, f0, d0, x1, f1, d1]) = stack.pop() {
        let h = x1 - x0;
        let change = positive(f0) != positive(f1);
        let monotone = d0 * d1 > 0.0 && d0.abs() + d1.abs() > lip_df * h;
        if !change && (f0.abs() + f1.abs() > lip_f * h || monotone) {
            continue;
        }
        if change && (monotone || h <= h_min) {
            roots.push(solve_bracketed(&f, x0, f0, x1, f1));
            continue;
        }
        if h <= h_min {
            continue;
        }
        let xm = 0.5 * (x0 + x1);
        let (fm, dm) = f(xm);
        stack.push([x0, f0, d0, xm, fm, dm]);
        stack.push([xm, fm, dm, x1, f1, d1]);
    }
    roots.sort_by(f64::total_cmp);
    roots
}

/// The root of `f` in `[x0, x1]`, where `f(x0) = f0` and `f(x1) = f1` have opposite signs (zero
/// counting as positive). Newton steps are taken from the best point and accepted only while they
/// stay inside the bracket and shrink it fast; otherwise the bracket is bisected.
pub fn solve_bracketed<F>(f: &F, x0: f64, f0: f64, x1: f64, f1: f64) -> f64
where
    F: Fn(f64) -> (f64, f64),
{
    if f0 == 0.0 {
        return x0;
    }
    // Orient the bracket so that f(lo) < 0 <= f(hi).
    let (mut lo, mut hi) = if positive(f0) { (x1, x0) } else { (x0, x1) };
    let _ = f1;
    let mut x = 0.5 * (lo + hi);
    let mut width = (hi - lo).abs();
    for _ in 0..200 {
        let (fx, dx) = f(x);
        if fx == 0.0 {
            return x;
        }
        if positive(fx) {
            hi = x;
        } else {
            lo = x;
        }
        let new_width = (hi - lo).abs();
        let tol = 4.0 * f64::EPSILON * x.abs().max(1.0);
        if new_width <= tol {
            return 0.5 * (lo + hi);
        }
        let newton = x - fx / dx;
        let inside = dx != 0.0 && newton.is_finite() && (newton - lo) * (newton - hi) < 0.0;
        // Bisect whenever Newton leaves the bracket or the bracket is not at least halving.
        if inside && new_width <= 0.5 * width {
            if (newton - x).abs() <= tol {
                return newton;
            }
            x = newton;
        } else {
            x = 0.5 * (lo + hi);
        }
        width = new_width;
    }
    0.5 * (lo + hi)
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
        let f = |x: f64| ((5.0 * x).sin(), 5.0 * (5.0 * x).cos());
        let iso = Isolation { n0: 4, lip_f: 25.0, lip_df: 125.0, h_min: 1e-12, periodic: true };
        let r = sign_changes(f, 0.0, 2.0 * PI, iso);
        assert_eq!(r.len(), 10, "{r:?}");
        for (k, x) in r.iter().enumerate() {
            let want = (k + 1) as f64 * PI / 5.0;
            assert!((x - want).abs() < 1e-13, "root {k}: {x} vs {want}");
        }
    }

    #[test]
    fn does_not_miss_a_close_pair_of_roots() {
        // (x - 1)(x - 1 - 1e-7) on [0, 3]: two roots 1e-7 apart, invisible to any coarse grid.
        let f = |x: f64| ((x - 1.0) * (x - 1.0 - 1e-7), 2.0 * x - 2.0 - 1e-7);
        let iso = Isolation { n0: 3, lip_f: 4.0, lip_df: 2.0, h_min: 1e-13, periodic: false };
        let r = sign_changes(f, 0.0, 3.0, iso);
        assert_eq!(r.len(), 2, "{r:?}");
        assert!((r[0] - 1.0).abs() < 1e-14 && (r[1] - 1.0 - 1e-7).abs() < 1e-14);
    }

    #[test]
    fn ignores_tangential_zeros() {
        let f = |x: f64| ((x - 1.0).powi(2), 2.0 * (x - 1.0));
        let iso = Isolation { n0: 3, lip_f: 4.0, lip_df: 2.0, h_min: 1e-12, periodic: false };
        assert!(sign_changes(f, 0.0, 3.0, iso).is_empty());
    }

    #[test]
    fn brent_finds_a_jump_and_a_smooth_root() {
        let step = |x: f64| if x < 0.3 { 1.0 } else { -1.0 };
        assert!((brent(step, 0.0, 1.0, 1e-14) - 0.3).abs() < 1e-13);
        let cubic = |x: f64| x * x * x - 2.0;
        assert!((brent(cubic, 0.0, 2.0, 1e-15) - 2f64.cbrt()).abs() < 1e-14);
    }
}
