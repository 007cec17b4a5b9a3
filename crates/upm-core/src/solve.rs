//! The parallel-manipulation solvers: sequencing rotations (4.10, 4.12) and displacement fields
//! (5.3), their ordering heuristic (4.2.4) and the second-order error of executing them in
//! sequence (5.28–5.30).
//!
//! Frames and units: parts and centres in the plate frame [m]. Columns of the system are the unit
//! tangential fields `R90(P - C_j) / |P - C_j|` of each centre, `x` rows first, then `y` rows, then
//! curl rows `1 / |Q - C_j|`. Rotation strengths `k_j` are dimensionless: the plan's average force
//! on a part is `(mu m g / N) sum_j k_j R90(P - C_j)/|P - C_j|` (4.9). Displacement strengths `d_j`
//! are arc lengths [m] along the tangential flow of `C_j` (5.1–5.3).
//!
//! Solutions come from the singular value decomposition of the system (nalgebra): square systems
//! are solved exactly, redundant ones (more centres than constraints) give the minimum-norm
//! solution (undamped full-rank systems reach the same solution through one Householder
//! bidiagonalisation and the bidiagonal's singular values, without the SVD's vectors); singular values below `rcond * s_max` are truncated and `damping` adds Tikhonov
//! regularisation. `max_strength` bounds every `|k_j|` by an active-set bounded least-squares
//! solve (Lawson–Hanson, extended to two-sided bounds) and reports the residual it costs.

use nalgebra::{DMatrix, DVector};

use crate::error::{finite, Error, Result};

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
    fn check(&self) -> Result<()> {
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
fn condition(singular_values: &[f64]) -> f64 {
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
#[inline]
fn pyth(a: f64, b: f64) -> f64 {
    (a * a + b * b).sqrt()
}

/// Singular values of the upper bidiagonal matrix with diagonal `d` and superdiagonal `e`
/// (`e[i]` couples rows `i` and `i + 1`), descending: Golub–Kahan–Reinsch implicit-shift QR with
/// Wilkinson shifts and deflation, no singular vectors accumulated.
fn bidiagonal_singular_values(d: &[f64], e: &[f64]) -> Result<Vec<f64>> {
    let n = d.len();
    let mut w = d.to_vec();
    // rv[i] couples i - 1 and i; rv[0] = 0.
    let mut rv = vec![0.0; n];
    rv[1..n].copy_from_slice(&e[..n.saturating_sub(1)]);
    let anorm = (0..n).map(|i| w[i].abs() + rv[i].abs()).fold(0.0, f64::max);
    let negligible = |x: f64| x.abs() <= f64::EPSILON * anorm;
    for k in (0..n).rev() {
        let mut its = 0;
        loop {
            // Split: find l with rv[l] negligible, or w[l - 1] negligible (then cancel rv[l]).
            let mut l = k;
            let mut cancel = false;
            while l > 0 {
                if negligible(rv[l]) {
                    break;
                }
                if negligible(w[l - 1]) {
                    cancel = true;
                    break;
                }
                l -= 1;
            }
            if cancel {
                let (mut c, mut s) = (0.0, 1.0);
                for i in l..=k {
                    let f = s * rv[i];
                    rv[i] *= c;
                    if negligible(f) {
                        break;
                    }
                    let g = w[i];
                    let h = pyth(f, g);
                    w[i] = h;
                    (c, s) = (g / h, -f / h);
                }
            }
            let z = w[k];
            if l == k {
                w[k] = z.abs();
                break;
            }
            its += 1;
            if its > 75 {
                return Err(Error::Convergence(
                    "the singular values did not converge in 75 QR sweeps".into(),
                ));
            }
            // Wilkinson shift from the trailing 2 x 2 block, then one chase from l to k.
            let mut x = w[l];
            let y = w[k - 1];
            let (g, h) = (rv[k - 1], rv[k]);
            let mut f = ((y - z) * (y + z) + (g - h) * (g + h)) / (2.0 * h * y);
            let r = pyth(f, 1.0);
            f = ((x - z) * (x + z) + h * ((y / (f + r.copysign(f))) - h)) / x;
            let (mut c, mut s) = (1.0, 1.0);
            for j in l..k {
                let i = j + 1;
                let mut g = rv[i];
                let mut y = w[i];
                let mut h = s * g;
                g *= c;
                let mut z = pyth(f, h);
                rv[j] = z;
                // One division per rotation (the divider is the chase's bottleneck).
                let inv = 1.0 / z;
                c = f * inv;
                s = h * inv;
                f = x * c + g * s;
                g = g * c - x * s;
                h = y * s;
                y *= c;
                z = pyth(f, h);
                w[j] = z;
                if z != 0.0 {
                    let inv = 1.0 / z;
                    c = f * inv;
                    s = h * inv;
                }
                f = c * g + s * y;
                x = c * y - s * g;
            }
            rv[l] = 0.0;
            rv[k] = f;
            w[k] = x;
        }
    }
    w.sort_by(|p, q| q.total_cmp(p));
    Ok(w)
}

#[inline]
fn dot(x: &[f64], y: &[f64]) -> f64 {
    x.iter().zip(y).map(|(a, b)| a * b).sum()
}

/// `y += alpha x`.
#[inline]
fn axpy(alpha: f64, x: &[f64], y: &mut [f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += alpha * xi;
    }
}

/// A solve's `(x, singular values descending, rank)`.
type Solved = (DVector<f64>, Vec<f64>, usize);

/// A Householder reflector `H = I - tau v v^T` (`v[0] = 1`) mapping `x` to `beta e_1`: returns
/// `(beta, tau)` and leaves `v[1..]` in `x[1..]`; `x` holds the vector's `len` entries `stride`
/// apart.
fn householder(x: &mut [f64], stride: usize, len: usize) -> (f64, f64) {
    let alpha = x[0];
    let sigma: f64 = (1..len).map(|i| x[i * stride] * x[i * stride]).sum();
    if sigma == 0.0 {
        return (alpha, 0.0);
    }
    let norm = (alpha * alpha + sigma).sqrt();
    let beta = if alpha > 0.0 { -norm } else { norm };
    let scale = 1.0 / (alpha - beta);
    for i in 1..len {
        x[i * stride] *= scale;
    }
    (beta, (beta - alpha) / beta)
}

/// Householder bidiagonalisation `A = Q B P^T` of a tall `rows x cols` column-major matrix, in
/// place: the diagonal `d` and superdiagonal `e` of `B`, the left reflectors' vectors below the
/// diagonal (scales `tau_q`) and the right ones' right of the superdiagonal (scales `tau_p`).
struct Bidiagonal {
    a: Vec<f64>,
    rows: usize,
    cols: usize,
    d: Vec<f64>,
    e: Vec<f64>,
    tau_q: Vec<f64>,
    tau_p: Vec<f64>,
}

impl Bidiagonal {
    fn new(mut a: Vec<f64>, rows: usize, cols: usize) -> Self {
        let (m, n) = (rows, cols);
        let (mut d, mut e) = (vec![0.0; n], vec![0.0; n.saturating_sub(1)]);
        let (mut tau_q, mut tau_p) = (vec![0.0; n], vec![0.0; n.saturating_sub(1)]);
        let mut w = vec![0.0; m];
        for k in 0..n {
            let (beta, tau) = householder(&mut a[k + k * m..(k + 1) * m], 1, m - k);
            d[k] = beta;
            tau_q[k] = tau;
            if tau != 0.0 {
                // Columns k+1.. get H = I - tau v v^T, v = (1, a[k+1..m, k]).
                let (head, tail) = a.split_at_mut((k + 1) * m);
                let v = &head[k * m + k + 1..(k + 1) * m];
                for col in tail.chunks_exact_mut(m) {
                    let (top, below) = col[k..].split_at_mut(1);
                    let s = tau * (top[0] + dot(v, below));
                    top[0] -= s;
                    axpy(-s, v, below);
                }
            }
            if k + 1 < n {
                let start = k + (k + 1) * m;
                let (beta, tau) = householder(&mut a[start..], m, n - k - 1);
                e[k] = beta;
                tau_p[k] = tau;
                if tau != 0.0 {
                    // Rows k+1.. of columns k+1.. get G = I - tau u u^T from the right,
                    // u = (1, a[k, k+2..n]): w = A u, then A -= tau w u^T, column by column.
                    let lo = k + 1;
                    let w = &mut w[..m - lo];
                    w.copy_from_slice(&a[lo + lo * m..(lo + 1) * m]);
                    for j in lo + 1..n {
                        let uj = a[k + j * m];
                        axpy(uj, &a[lo + j * m..(j + 1) * m], w);
                    }
                    axpy(-tau, w, &mut a[lo + lo * m..(lo + 1) * m]);
                    for j in lo + 1..n {
                        let uj = a[k + j * m];
                        axpy(-tau * uj, w, &mut a[lo + j * m..(j + 1) * m]);
                    }
                }
            }
        }
        Bidiagonal {
            a,
            rows,
            cols,
            d,
            e,
            tau_q,
            tau_p,
        }
    }

    /// `x <- H_k x` for the k-th left reflector (`x` of length `rows`).
    fn left(&self, k: usize, x: &mut [f64]) {
        let (m, tau) = (self.rows, self.tau_q[k]);
        if tau == 0.0 {
            return;
        }
        let v = &self.a[k + k * m + 1..(k + 1) * m];
        let (top, below) = x[k..].split_at_mut(1);
        let s = tau * (top[0] + dot(v, below));
        top[0] -= s;
        axpy(-s, v, below);
    }

    /// `x <- G_k x` for the k-th right reflector (`x` of length `cols`; it acts on `k + 1..`).
    fn right(&self, k: usize, x: &mut [f64]) {
        let (m, n, tau) = (self.rows, self.cols, self.tau_p[k]);
        if tau == 0.0 {
            return;
        }
        // v_{k+1} = 1 implicit; v_j for j >= k + 2 stored in row k.
        let v = |j: usize| self.a[k + j * m];
        let (top, rest) = x[k + 1..n].split_at_mut(1);
        let s = tau
            * (top[0]
                + rest
                    .iter()
                    .zip(k + 2..)
                    .map(|(xj, j)| v(j) * xj)
                    .sum::<f64>());
        top[0] -= s;
        for (xj, j) in rest.iter_mut().zip(k + 2..) {
            *xj -= s * v(j);
        }
    }
}

/// The undamped solve of a full-rank `A x = b` through one Householder bidiagonalisation (of `A`
/// or, when `A` is wide, of `A^T`): `x = Q B^-T P^T b` (minimum norm) for a wide `A = P B^T Q^T`,
/// `x = P B^-1 Q^T b` (least squares) for a tall `A = Q B P^T`, with the singular values of `B`
/// (those of `A`). `None` when `A` is rank-deficient at `rcond` (the SVD solve then truncates).
/// About half the time of the checked SVD for the 20 x 24 systems of the solvers.
fn bidiagonal_solve(a: &DMatrix<f64>, b: &DVector<f64>, rcond: f64) -> Result<Option<Solved>> {
    let (m, n) = a.shape();
    let wide = m < n;
    let (rows, cols) = if wide { (n, m) } else { (m, n) };
    let data: Vec<f64> = if wide {
        a.transpose().data.into()
    } else {
        a.as_slice().to_vec()
    };
    let bd = Bidiagonal::new(data, rows, cols);
    let sv = bidiagonal_singular_values(&bd.d, &bd.e)?;
    let s_max = sv.first().copied().unwrap_or(0.0);
    let s_min = sv.last().copied().unwrap_or(0.0);
    // NaN singular values (non-finite input) also take the SVD road, which reports them.
    if s_min.is_nan() || s_min <= rcond * s_max {
        return Ok(None);
    }
    let (d, e) = (&bd.d, &bd.e);
    let x = if wide {
        // c = P^T b, B^T y = c (lower bidiagonal), x = Q [y; 0].
        let mut c: Vec<f64> = b.iter().copied().collect();
        for k in 0..cols.saturating_sub(1) {
            bd.right(k, &mut c);
        }
        let mut y = vec![0.0; rows];
        for k in 0..cols {
            let carry = if k > 0 { e[k - 1] * y[k - 1] } else { 0.0 };
            y[k] = (c[k] - carry) / d[k];
        }
        for k in (0..cols).rev() {
            bd.left(k, &mut y);
        }
        y
    } else {
        // c = Q^T b, B y = c (upper bidiagonal), x = P y.
        let mut c: Vec<f64> = b.iter().copied().collect();
        for k in 0..cols {
            bd.left(k, &mut c);
        }
        let mut y = vec![0.0; cols];
        for k in (0..cols).rev() {
            let carry = if k + 1 < cols { e[k] * y[k + 1] } else { 0.0 };
            y[k] = (c[k] - carry) / d[k];
        }
        for k in (0..cols.saturating_sub(1)).rev() {
            bd.right(k, &mut y);
        }
        y
    };
    if !x.iter().all(|v| v.is_finite()) {
        return Ok(None);
    }
    Ok(Some((DVector::from_vec(x), sv, cols)))
}

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

fn check_points(name: &str, points: &[[f64; 2]]) -> Result<()> {
    for (i, p) in points.iter().enumerate() {
        if !(p[0].is_finite() && p[1].is_finite()) {
            return Err(Error::parameter(
                name,
                format!("must be finite; got ({}, {}) at index {i}", p[0], p[1]),
            ));
        }
    }
    Ok(())
}

/// Whether `a` and `b` count as the same point: closer than `1e-12` of their own size, so a part
/// far away does not make nearby centres coincide.
fn coincide(a: [f64; 2], b: [f64; 2]) -> bool {
    let size = a[0].abs().max(a[1].abs()).max(b[0].abs()).max(b[1].abs());
    let tol = 1e-12 * size.max(f64::MIN_POSITIVE);
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) <= tol * tol
}

/// Validates centres (finite, distinct) and the points the system is evaluated at (finite, on no
/// centre).
fn check_layout(parts: &[[f64; 2]], centers: &[[f64; 2]], others: &[[f64; 2]]) -> Result<()> {
    check_points("parts", parts)?;
    check_points("centers", centers)?;
    check_points("curl_points", others)?;
    if centers.is_empty() {
        return Err(Error::parameter("centers", "must hold at least one centre"));
    }
    for (j, c) in centers.iter().enumerate() {
        for (l, d) in centers.iter().enumerate().skip(j + 1) {
            if coincide(*c, *d) {
                return Err(Error::parameter(
                    "centers",
                    format!(
                        "must be distinct; centres {j} and {l} are both at ({}, {}): their fields are identical",
                        c[0], c[1]
                    ),
                ));
            }
        }
    }
    for (name, set) in [("parts", parts), ("curl_points", others)] {
        for (i, p) in set.iter().enumerate() {
            for (j, c) in centers.iter().enumerate() {
                if coincide(*p, *c) {
                    return Err(Error::parameter(
                        name,
                        format!(
                            "must not lie on a centre of rotation; {name}[{i}] = ({}, {}) is on centers[{j}] (its field is undefined there)",
                            p[0], p[1]
                        ),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// The unit tangential field of every centre at every part (4.10, 5.3): `2M x N`, `x` rows first,
/// then curl rows `1/|Q - C_j|` (4.12). Inputs must be valid (see [`check_layout`]).
fn system_matrix(
    parts: &[[f64; 2]],
    centers: &[[f64; 2]],
    curl_points: &[[f64; 2]],
) -> DMatrix<f64> {
    let m = parts.len();
    let rows = 2 * m + curl_points.len();
    let mut data = Vec::with_capacity(rows * centers.len());
    for c in centers {
        // Column j, column-major: x rows, y rows, curl rows.
        let start = data.len();
        data.resize(start + rows, 0.0);
        let col = &mut data[start..];
        for (i, p) in parts.iter().enumerate() {
            let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
            let inv = 1.0 / pyth(dx, dy);
            (col[i], col[m + i]) = (-dy * inv, dx * inv);
        }
        for (k, p) in curl_points.iter().enumerate() {
            col[2 * m + k] = 1.0 / pyth(p[0] - c[0], p[1] - c[1]);
        }
    }
    DMatrix::from_vec(rows, centers.len(), data)
}

/// A solved plan: strengths per centre, the order to execute them in, and what it achieves.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// `k_j` (rotations, dimensionless) or `d_j` (displacements, m), one per centre.
    pub strengths: Vec<f64>,
    /// Execution order by the priority rule of 4.2.4 (indices into `strengths`).
    pub order: Vec<usize>,
    /// What the plan gives at each part: force [N] or step [m].
    pub predicted: Vec<[f64; 2]>,
    /// The curl the plan gives at each curl point [N/m] (rotations only).
    pub predicted_curls: Vec<f64>,
    /// Euclidean norm of (predicted - requested) over every force (or step) and curl, in the
    /// caller's units.
    pub residual: f64,
    /// How much `max_strength` raised `residual` (0 when unbounded or not binding).
    pub bound_cost: f64,
    /// Singular values of the system, descending.
    pub singular_values: Vec<f64>,
    /// Numerical rank of the system; full rank is the number of constraints.
    pub rank: usize,
}

impl Plan {
    /// `s_max / s_min` of the system (4.2.5).
    pub fn condition_number(&self) -> f64 {
        condition(&self.singular_values)
    }
}

/// Curl constraints: the curl the plan must produce at each point [N/m].
#[derive(Debug, Clone, Copy, Default)]
pub struct Curls<'a> {
    /// Where [m].
    pub points: &'a [[f64; 2]],
    /// Desired curl of the average force field [N/m].
    pub values: &'a [f64],
}

fn enough_centres(constraints: usize, centres: usize, what: &str) -> Result<()> {
    if centres < constraints {
        return Err(Error::parameter(
            "centers",
            format!(
                "must number at least {constraints} ({what}); got {centres}: the system would be over-determined"
            ),
        ));
    }
    Ok(())
}

fn pairs(flat: &[f64], m: usize) -> Vec<[f64; 2]> {
    (0..m).map(|i| [flat[i], flat[m + i]]).collect()
}

/// Rotation strengths `k_j` about `centers` that give the average `forces` [N] at `parts` and
/// the curls `curls` (4.10, 4.12); `mu_m_g` [N] is the friction scale.
pub fn solve_rotations(
    parts: &[[f64; 2]],
    forces: &[[f64; 2]],
    centers: &[[f64; 2]],
    curls: Curls<'_>,
    mu_m_g: f64,
    opts: &Options,
) -> Result<Plan> {
    if forces.len() != parts.len() {
        return Err(Error::Shape(format!(
            "forces has {} rows; parts has {}",
            forces.len(),
            parts.len()
        )));
    }
    if curls.values.len() != curls.points.len() {
        return Err(Error::Shape(format!(
            "curls has {} entries; curl_points has {}",
            curls.values.len(),
            curls.points.len()
        )));
    }
    crate::error::positive("mu_m_g", mu_m_g)?;
    check_points("forces", forces)?;
    for &c in curls.values {
        finite("curls", c)?;
    }
    check_layout(parts, centers, curls.points)?;
    let (m, q, n) = (parts.len(), curls.points.len(), centers.len());
    enough_centres(2 * m + q, n, "two per part plus one per curl constraint")?;
    let a = system_matrix(parts, centers, curls.points);
    let scale = n as f64 / mu_m_g;
    let mut b: Vec<f64> = Vec::with_capacity(2 * m + q);
    b.extend(forces.iter().map(|f| f[0] * scale));
    b.extend(forces.iter().map(|f| f[1] * scale));
    b.extend(curls.values.iter().map(|c| c * scale));
    let sol = lstsq(&a, &b, opts)?;
    let predicted_all: Vec<f64> = sol.ax.iter().map(|v| v / scale).collect();
    Ok(Plan {
        order: priority_order(&priorities(&sol.x, parts, centers)),
        predicted: pairs(&predicted_all, m),
        predicted_curls: predicted_all[2 * m..].to_vec(),
        residual: sol.residual / scale,
        bound_cost: sol.bound_cost / scale,
        singular_values: sol.singular_values,
        rank: sol.rank,
        strengths: sol.x,
    })
}

/// Arc lengths `d_j` [m] of rotation about each centre that move `parts` by `steps` [m] to first
/// order (5.3).
pub fn solve_displacements(
    parts: &[[f64; 2]],
    steps: &[[f64; 2]],
    centers: &[[f64; 2]],
    opts: &Options,
) -> Result<Plan> {
    if steps.len() != parts.len() {
        return Err(Error::Shape(format!(
            "steps has {} rows; parts has {}",
            steps.len(),
            parts.len()
        )));
    }
    check_points("steps", steps)?;
    check_layout(parts, centers, &[])?;
    let m = parts.len();
    enough_centres(2 * m, centers.len(), "two per part")?;
    let a = system_matrix(parts, centers, &[]);
    let mut b: Vec<f64> = steps.iter().map(|s| s[0]).collect();
    b.extend(steps.iter().map(|s| s[1]));
    let sol = lstsq(&a, &b, opts)?;
    Ok(Plan {
        order: priority_order(&priorities(&sol.x, parts, centers)),
        predicted: pairs(&sol.ax, m),
        predicted_curls: Vec::new(),
        residual: sol.residual,
        bound_cost: sol.bound_cost,
        singular_values: sol.singular_values,
        rank: sol.rank,
        strengths: sol.x,
    })
}

/// Priorities of 4.2.4: `rho_j = |k_j| / min_i |P_i - C_j|` (erratum E4: the thesis's printed
/// values do not follow from this formula; the formula is implemented).
pub fn priorities(strengths: &[f64], parts: &[[f64; 2]], centers: &[[f64; 2]]) -> Vec<f64> {
    centers
        .iter()
        .zip(strengths)
        .map(|(c, k)| {
            let r = parts
                .iter()
                .map(|p| pyth(p[0] - c[0], p[1] - c[1]))
                .fold(f64::INFINITY, f64::min);
            k.abs() / r
        })
        .collect()
}

/// Indices sorted by descending priority; ties keep their index order.
pub fn priority_order(priorities: &[f64]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..priorities.len()).collect();
    order.sort_by(|&i, &j| priorities[j].total_cmp(&priorities[i]));
    order
}

fn check_order(order: &[usize], n: usize) -> Result<()> {
    let mut seen = vec![false; n];
    for &j in order {
        if j >= n || seen[j] {
            return Err(Error::parameter(
                "order",
                format!("must be a permutation of 0..{n}; got {order:?}"),
            ));
        }
        seen[j] = true;
    }
    if order.len() != n {
        return Err(Error::parameter(
            "order",
            format!("must be a permutation of 0..{n}; got {order:?}"),
        ));
    }
    Ok(())
}

/// `(X, DX)` of the unit tangential field of `c` at `p`: `X = R90 n`, `DX v = R90 (v - n (n.v)) / r`.
fn tangential(p: [f64; 2], c: [f64; 2]) -> ([f64; 2], impl Fn([f64; 2]) -> [f64; 2]) {
    let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
    let r = pyth(dx, dy);
    let n = [dx / r, dy / r];
    let jac = move |v: [f64; 2]| {
        let s = n[0] * v[0] + n[1] * v[1];
        let w = [(v[0] - n[0] * s) / r, (v[1] - n[1] * s) / r];
        [-w[1], w[0]]
    };
    ([-n[1], n[0]], jac)
}

fn check_flows(
    strengths: &[f64],
    parts: &[[f64; 2]],
    centers: &[[f64; 2]],
    order: &[usize],
) -> Result<()> {
    if strengths.len() != centers.len() {
        return Err(Error::Shape(format!(
            "strengths has {} entries; centers has {}",
            strengths.len(),
            centers.len()
        )));
    }
    for &d in strengths {
        finite("strengths", d)?;
    }
    check_layout(parts, centers, &[])?;
    check_order(order, centers.len())
}

/// Second-order error of moving each part along the tangential flows of `centers` for arc
/// lengths `strengths`, one after another in `order`, instead of along their sum (5.28–5.30):
/// `sum_j d_j^2/2 DX_j X_j + sum_{a<b} d_a d_b DX_b X_a` (flows `a` before `b`), at each part [m].
pub fn flow_error(
    strengths: &[f64],
    parts: &[[f64; 2]],
    centers: &[[f64; 2]],
    order: &[usize],
) -> Result<Vec<[f64; 2]>> {
    check_flows(strengths, parts, centers, order)?;
    Ok(parts
        .iter()
        .map(|&p| {
            // Running sum of d_a X_a over the flows already executed.
            let mut before = [0.0; 2];
            let mut e = [0.0; 2];
            for &j in order {
                let d = strengths[j];
                let (x, jac) = tangential(p, centers[j]);
                let arg = [before[0] + 0.5 * d * x[0], before[1] + 0.5 * d * x[1]];
                let term = jac(arg);
                e[0] += d * term[0];
                e[1] += d * term[1];
                before[0] += d * x[0];
                before[1] += d * x[1];
            }
            e
        })
        .collect())
}

/// Where each part ends after the exact flows in `order`: the tangential flow of `C_j` for arc
/// length `d_j` is the rotation about `C_j` by `d_j / |P - C_j|` [m].
pub fn flow_exact(
    strengths: &[f64],
    parts: &[[f64; 2]],
    centers: &[[f64; 2]],
    order: &[usize],
) -> Result<Vec<[f64; 2]>> {
    check_flows(strengths, parts, centers, order)?;
    Ok(parts
        .iter()
        .map(|&p0| {
            let mut p = p0;
            for &j in order {
                let c = centers[j];
                let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
                let angle = strengths[j] / pyth(dx, dy);
                let (s, co) = angle.sin_cos();
                p = [c[0] + co * dx - s * dy, c[1] + s * dx + co * dy];
            }
            p
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_parts_need_no_rotation() {
        let centers = [[-1.0, -0.5], [1.0, -0.5], [1.0, 0.5], [-1.0, 0.5]];
        let plan = solve_rotations(
            &[],
            &[],
            &centers,
            Curls::default(),
            1.0,
            &Options::default(),
        )
        .unwrap();
        assert_eq!(plan.strengths, vec![0.0; 4]);
        assert_eq!(plan.rank, 0);
    }

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
