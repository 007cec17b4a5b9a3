//! Dense least squares for the solvers of [`crate::solve`]: `A x = b` by the singular value
//! decomposition (nalgebra), with an optional Tikhonov damping, a cut-off of small singular values,
//! and a bound on every `|x_j|`.
//!
//! Square systems are solved exactly, redundant ones (more columns than rows) give the
//! minimum-norm solution. Undamped full-rank systems reach the same solution through one
//! Householder bidiagonalisation and the bidiagonal's singular values, without the SVD's vectors
//! ([`bidiagonal`]). Singular values below `rcond * s_max` are truncated and `damping` adds
//! Tikhonov regularisation. `max_strength` bounds every `|x_j|` by an active-set bounded
//! least-squares solve (Lawson–Hanson, extended to two-sided bounds) and reports the residual it
//! costs.

mod bidiagonal;

use bidiagonal::bidiagonal_solve;
pub(crate) use bidiagonal::pyth;

use nalgebra::{DMatrix, DVector};

use crate::error::{Error, Result};

/// Options shared by every solver here.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// Relative cut-off for small singular values; `None`: `eps * max(rows, columns)`.
    pub rcond: Option<f64>,
    /// Tikhonov damping `lambda`: minimises `|A x - b|^2 + lambda^2 |x|^2` (0: none).
    pub damping: f64,
    /// Bound on every `|x_j|` (`None`: unbounded).
    pub max_strength: Option<f64>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            rcond: None,
            damping: 0.0,
            max_strength: None,
        }
    }
}

impl Options {
    pub(crate) fn check(&self) -> Result<()> {
        if let Some(r) = self.rcond {
            if !(r.is_finite() && (0.0..1.0).contains(&r)) {
                return Err(Error::parameter(
                    "rcond",
                    format!("must be in [0, 1); got {r}"),
                ));
            }
        }
        if !(self.damping.is_finite() && self.damping >= 0.0) {
            return Err(Error::parameter(
                "damping",
                format!("must be finite and >= 0; got {}", self.damping),
            ));
        }
        if let Some(k) = self.max_strength {
            if !(k.is_finite() && k > 0.0) {
                return Err(Error::parameter(
                    "max_strength",
                    format!("must be finite and > 0; got {k}"),
                ));
            }
        }
        Ok(())
    }
}

/// The solution of one linear system.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// The solution `x` (length = columns).
    pub x: Vec<f64>,
    /// `A x`.
    pub ax: Vec<f64>,
    /// Singular values of `A`, descending (`min(rows, columns)` of them).
    pub singular_values: Vec<f64>,
    /// Number of singular values above the cut-off.
    pub rank: usize,
    /// `|A x - b|` of the solution returned.
    pub residual: f64,
    /// `|A x - b|` minus the same for the solution without `max_strength` (0 when no bound binds).
    pub bound_cost: f64,
}

impl Solution {
    /// `s_max / s_min` (infinite when `s_min = 0`).
    pub fn condition_number(&self) -> f64 {
        condition(&self.singular_values)
    }
}

/// `s_max / s_min` of descending singular values: infinite when `s_min = 0`, NaN when empty.
pub(crate) fn condition(singular_values: &[f64]) -> f64 {
    match (singular_values.first(), singular_values.last()) {
        (Some(&hi), Some(&lo)) if lo > 0.0 => hi / lo,
        (Some(_), Some(_)) => f64::INFINITY,
        _ => f64::NAN,
    }
}

/// `(U, S, V^T)` of `a` (thin), checked: `|A - U S V^T|_F <= 64 eps sqrt(m n) |A|_F`.
///
/// nalgebra's SVD is tried first (the faster for these small systems), on the tall orientation.
/// In 0.35 it occasionally returns factors that do not reproduce the matrix: about one in a
/// thousand random 20 x 24 systems of condition number ~1e6 came back with `|A - U S V^T|`
/// between 1e-7 and 1e-4. Every factorisation is therefore checked against the matrix, and a
/// failed one is redone with faer's SVD, which is checked too.
fn checked_svd(a: &DMatrix<f64>) -> Result<(DMatrix<f64>, DVector<f64>, DMatrix<f64>)> {
    let (m, n) = a.shape();
    let tol = 64.0 * f64::EPSILON * ((m * n) as f64).sqrt() * a.norm();
    let reproduces = |u: &DMatrix<f64>, s: &DVector<f64>, v_t: &DMatrix<f64>| {
        let mut us = u.clone();
        for (k, mut col) in us.column_iter_mut().enumerate() {
            col *= s[k];
        }
        (us * v_t - a).norm() <= tol
    };
    let wide = m < n;
    let svd = nalgebra::SVD::try_new(
        if wide { a.transpose() } else { a.clone() },
        true,
        true,
        f64::EPSILON,
        0,
    );
    if let Some(nalgebra::SVD {
        u: Some(u),
        v_t: Some(v_t),
        singular_values: s,
    }) = svd
    {
        // A = U S V^T, or for a wide A factored as A^T = U S V^T: A = V S U^T.
        let (u, v_t) = if wide {
            (v_t.transpose(), u.transpose())
        } else {
            (u, v_t)
        };
        if reproduces(&u, &s, &v_t) {
            return Ok((u, s, v_t));
        }
    }
    let f = faer::Mat::<f64>::from_fn(m, n, |i, j| a[(i, j)]);
    let svd = f.thin_svd().map_err(|e| {
        Error::Convergence(format!(
            "the singular value decomposition did not converge ({e:?})"
        ))
    })?;
    let k = m.min(n);
    let (fu, fs, fv) = (svd.U(), svd.S().column_vector(), svd.V());
    let u = DMatrix::from_fn(m, k, |i, j| fu[(i, j)]);
    let s = DVector::from_fn(k, |i, _| fs[i]);
    let v_t = DMatrix::from_fn(k, n, |i, j| fv[(j, i)]);
    if reproduces(&u, &s, &v_t) {
        Ok((u, s, v_t))
    } else {
        Err(Error::Convergence(
            "the singular value decomposition did not reproduce the system to working accuracy"
                .into(),
        ))
    }
}

/// `sqrt(a^2 + b^2)` without `hypot`'s care for overflow (glibc's `hypot` is ~10x slower, and a
/// solve takes about a thousand): distances in metres and bidiagonal entries of the order of the
/// system's norm are far from 1e150.
/// Filtered SVD solve of `A x = b`: `x = V diag(phi(s)) U^T b` with `phi(s) = s / (s^2 + lambda^2)`
/// above `cutoff` and 0 below. Returns `(x, singular values, rank)`.
fn svd_solve(
    a: DMatrix<f64>,
    b: &DVector<f64>,
    rcond: Option<f64>,
    damping: f64,
) -> Result<(DVector<f64>, Vec<f64>, usize)> {
    let (m, n) = a.shape();
    if m == 0 || n == 0 {
        // No constraints (or no unknowns): the minimum-norm solution is zero, of rank 0.
        return Ok((DVector::zeros(n), Vec::new(), 0));
    }
    let rcond = rcond.unwrap_or(f64::EPSILON * m.max(n) as f64);
    if damping == 0.0 && m.min(n) > 0 {
        if let Some(solved) = bidiagonal_solve(&a, b, rcond)? {
            return Ok(solved);
        }
    }
    let (u, s, v_t) = checked_svd(&a)?;
    let s_max = s.iter().copied().fold(0.0, f64::max);
    let cutoff = rcond * s_max;
    let mut rank = 0;
    let mut c = u.tr_mul(b);
    for (k, ck) in c.iter_mut().enumerate() {
        let sk = s[k];
        if sk > cutoff && sk > 0.0 {
            rank += 1;
            *ck *= sk / (sk * sk + damping * damping);
        } else {
            *ck = 0.0;
        }
    }
    let x = v_t.tr_mul(&c);
    let mut sv: Vec<f64> = s.iter().copied().collect();
    sv.sort_by(|p, q| q.total_cmp(p));
    Ok((x, sv, rank))
}

/// `|A x - b|^2 + lambda^2 |x|^2` is minimised over `|x_j| <= bound` by an active-set method:
/// variables are free or held at a bound; each round solves the free ones in the least-squares
/// sense (minimum norm), steps back to the feasible box if that solution leaves it, and releases a
/// held variable whose gradient points into the box. Starts from `x = 0` with every variable
/// free, so when no bound binds the result is the unbounded solution.
fn bounded_solve(
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    bound: f64,
    rcond: Option<f64>,
    damping: f64,
    s_max: f64,
) -> Result<DVector<f64>> {
    let n = a.ncols();
    let mut x = DVector::<f64>::zeros(n);
    // 0: free; +1 / -1: held at +bound / -bound.
    let mut held = vec![0i8; n];
    let mut not_again: Option<usize> = None;
    let b_norm = b.norm();
    let tol = 1e3 * f64::EPSILON * s_max * (s_max * bound * (n as f64).sqrt() + b_norm);
    for _ in 0..(20 * n + 50) {
        let free: Vec<usize> = (0..n).filter(|&j| held[j] == 0).collect();
        let mut r = b.clone();
        for j in (0..n).filter(|&j| held[j] != 0) {
            r.axpy(-x[j], &a.column(j), 1.0);
        }
        let z = if free.is_empty() {
            DVector::zeros(0)
        } else {
            svd_solve(a.select_columns(&free), &r, rcond, damping)?.0
        };
        // Longest step from x towards z that stays in the box.
        let mut alpha = 1.0;
        let mut blocking = None;
        for (k, &j) in free.iter().enumerate() {
            let target = if z[k] > bound {
                bound
            } else if z[k] < -bound {
                -bound
            } else {
                continue;
            };
            let step = (target - x[j]) / (z[k] - x[j]);
            if step < alpha {
                alpha = step.max(0.0);
                blocking = Some(j);
            }
        }
        if let Some(jb) = blocking {
            for (k, &j) in free.iter().enumerate() {
                x[j] += alpha * (z[k] - x[j]);
                if j == jb || x[j].abs() >= bound * (1.0 - 1e-12) {
                    x[j] = bound.copysign(x[j]);
                    held[j] = if x[j] > 0.0 { 1 } else { -1 };
                }
            }
            // A variable released last round that cannot move inwards stays held this round.
            not_again = if alpha == 0.0 && Some(jb) == not_again {
                Some(jb)
            } else {
                None
            };
            continue;
        }
        for (k, &j) in free.iter().enumerate() {
            x[j] = z[k];
        }
        // Gradient of -objective/2: positive entries want x_j larger.
        let g = a.tr_mul(&(b - a * &x)) - &x * (damping * damping);
        let release = (0..n)
            .filter(|&j| Some(j) != not_again)
            .filter(|&j| (held[j] > 0 && g[j] < -tol) || (held[j] < 0 && g[j] > tol))
            .max_by(|&i, &j| g[i].abs().total_cmp(&g[j].abs()));
        match release {
            None => return Ok(x),
            Some(j) => {
                held[j] = 0;
                not_again = Some(j);
            }
        }
    }
    Err(Error::Convergence(format!(
        "the bounded least-squares solve (max_strength = {bound}) did not settle within {} rounds",
        20 * n + 50
    )))
}

/// Solves `A x = b` in the least-squares sense with `opts` (see the module documentation).
pub fn lstsq(a: &DMatrix<f64>, b: &[f64], opts: &Options) -> Result<Solution> {
    opts.check()?;
    if b.len() != a.nrows() {
        return Err(Error::Shape(format!(
            "b has {} entries; the system has {} rows",
            b.len(),
            a.nrows()
        )));
    }
    let b = DVector::from_column_slice(b);
    let (x0, singular_values, rank) = svd_solve(a.clone(), &b, opts.rcond, opts.damping)?;
    let residual0 = (a * &x0 - &b).norm();
    let x = match opts.max_strength {
        Some(k) if x0.iter().any(|v| v.abs() > k) => {
            let s_max = singular_values.first().copied().unwrap_or(0.0);
            bounded_solve(a, &b, k, opts.rcond, opts.damping, s_max)?
        }
        _ => x0,
    };
    let ax = a * &x;
    let residual = (&ax - &b).norm();
    Ok(Solution {
        x: x.iter().copied().collect(),
        ax: ax.iter().copied().collect(),
        singular_values,
        rank,
        residual,
        bound_cost: (residual - residual0).max(0.0),
    })
}

#[cfg(test)]
mod tests {
    use super::bidiagonal::bidiagonal_singular_values;
    use super::*;
    #[test]
    fn bounded_equals_unbounded_when_the_bound_does_not_bind() {
        let a = DMatrix::from_row_slice(2, 3, &[1.0, 0.5, 0.0, 0.0, 1.0, 2.0]);
        let free = lstsq(&a, &[1.0, 1.0], &Options::default()).unwrap();
        let loose = Options {
            max_strength: Some(10.0),
            ..Options::default()
        };
        let bounded = lstsq(&a, &[1.0, 1.0], &loose).unwrap();
        assert_eq!(free.x, bounded.x);
        assert_eq!(bounded.bound_cost, 0.0);
    }

    /// A reproducible pseudo-random matrix with singular values spread over `spread` decades.
    fn graded(m: usize, n: usize, seed: u64, spread: f64) -> DMatrix<f64> {
        let mut state = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let a = DMatrix::from_fn(m, n, |_, _| next());
        let k = m.min(n);
        let scale = DMatrix::from_fn(n, n, |i, j| {
            if i == j {
                10f64.powf(-spread * (i.min(k - 1)) as f64 / (k - 1).max(1) as f64)
            } else {
                0.0
            }
        });
        a * scale
    }

    #[test]
    fn bidiagonal_singular_values_match_the_full_svd() {
        for (seed, (m, n, spread)) in [
            (20, 24, 0.0),
            (20, 24, 6.0),
            (24, 20, 3.0),
            (9, 9, 10.0),
            (1, 3, 0.0),
        ]
        .into_iter()
        .enumerate()
        {
            let a = graded(m, n, seed as u64, spread);
            let want = nalgebra::SVD::new(a.clone(), false, false).singular_values;
            let mut want: Vec<f64> = want.iter().copied().collect();
            want.sort_by(|p, q| q.total_cmp(p));
            let bd = if m < n { a.transpose() } else { a.clone() }.bidiagonalize();
            let got =
                bidiagonal_singular_values(bd.diagonal().as_slice(), bd.off_diagonal().as_slice())
                    .unwrap();
            for (g, w) in got.iter().zip(&want) {
                assert!(
                    (g - w).abs() <= 1e-13 * want[0],
                    "{m}x{n}: {got:?} vs {want:?}"
                );
            }
        }
        // Exact zeros on the diagonal (a rank-deficient bidiagonal) deflate.
        let got = bidiagonal_singular_values(&[3.0, 0.0, 2.0, 1.0], &[1.0, 1.0, 0.5]).unwrap();
        let b = DMatrix::from_row_slice(
            4,
            4,
            &[
                3.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 2.0, 0.5, 0.0, 0.0, 0.0, 1.0,
            ],
        );
        let want = nalgebra::SVD::new(b, false, false).singular_values;
        let mut want: Vec<f64> = want.iter().copied().collect();
        want.sort_by(|p, q| q.total_cmp(p));
        for (g, w) in got.iter().zip(&want) {
            assert!((g - w).abs() <= 1e-14 * want[0], "{got:?} vs {want:?}");
        }
    }

    #[test]
    fn the_bidiagonal_path_gives_the_svd_solution_of_full_rank_systems() {
        for (seed, (m, n)) in [(20, 24), (24, 20), (12, 12)].into_iter().enumerate() {
            let a = graded(m, n, 100 + seed as u64, 4.0);
            let b = DVector::from_fn(m, |i, _| (i as f64 * 0.7).sin());
            let (x, sv, rank) = bidiagonal_solve(&a, &b, 1e-14).unwrap().unwrap();
            let (u, s, v_t) = checked_svd(&a).unwrap();
            let c = DVector::from_fn(s.len(), |k, _| u.column(k).dot(&b) / s[k]);
            let want = v_t.tr_mul(&c);
            assert_eq!(rank, m.min(n));
            assert!((x - &want).norm() <= 1e-10 * want.norm(), "{m}x{n}");
            assert!((sv[0] - s.max()).abs() <= 1e-13 * sv[0]);
        }
        // Rank-deficient (two equal rows): left to the SVD's truncation.
        let a = graded(6, 8, 7, 0.0);
        let rankdef = DMatrix::from_fn(6, 8, |i, j| if i == 5 { a[(4, j)] } else { a[(i, j)] });
        assert!(
            bidiagonal_solve(&rankdef, &DVector::from_element(6, 1.0), 1e-12)
                .unwrap()
                .is_none()
        );
    }

    #[test]
    fn options_are_checked_by_name() {
        let a = DMatrix::from_row_slice(1, 1, &[1.0]);
        for (opts, name) in [
            (
                Options {
                    rcond: Some(1.5),
                    ..Options::default()
                },
                "rcond",
            ),
            (
                Options {
                    damping: -1.0,
                    ..Options::default()
                },
                "damping",
            ),
            (
                Options {
                    max_strength: Some(0.0),
                    ..Options::default()
                },
                "max_strength",
            ),
        ] {
            let e = lstsq(&a, &[1.0], &opts).unwrap_err();
            assert!(e.to_string().starts_with(name), "{e}");
        }
    }
}
