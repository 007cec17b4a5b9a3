//! The bidiagonal path of an undamped full-rank least-squares solve: one Householder
//! bidiagonalisation, the bidiagonal's singular values by the implicit-shift QR of Golub and
//! Kahan (no singular vectors), and the minimum-norm solution from the factors.

use nalgebra::{DMatrix, DVector};

use crate::error::{Error, Result};

/// `sqrt(a^2 + b^2)`.
#[inline]
pub(crate) fn pyth(a: f64, b: f64) -> f64 {
    (a * a + b * b).sqrt()
}

/// Singular values of the upper bidiagonal matrix with diagonal `d` and superdiagonal `e`
/// (`e[i]` couples rows `i` and `i + 1`), descending: Golub–Kahan–Reinsch implicit-shift QR with
/// Wilkinson shifts and deflation, no singular vectors accumulated.
pub(super) fn bidiagonal_singular_values(d: &[f64], e: &[f64]) -> Result<Vec<f64>> {
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
pub(super) type Solved = (DVector<f64>, Vec<f64>, usize);

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
pub(super) fn bidiagonal_solve(
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    rcond: f64,
) -> Result<Option<Solved>> {
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
