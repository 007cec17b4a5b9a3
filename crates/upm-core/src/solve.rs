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
//! solution; singular values below `rcond * s_max` are truncated and `damping` adds Tikhonov
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

/// Filtered SVD solve of `A x = b`: `x = V diag(phi(s)) U^T b` with `phi(s) = s / (s^2 + lambda^2)`
/// above `cutoff` and 0 below. Returns `(x, singular values, rank)`.
fn svd_solve(
    a: DMatrix<f64>,
    b: &DVector<f64>,
    rcond: Option<f64>,
    damping: f64,
) -> Result<(DVector<f64>, Vec<f64>, usize)> {
    let (m, n) = a.shape();
    let rcond = rcond.unwrap_or(f64::EPSILON * m.max(n) as f64);
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

/// Length scale of a layout: below `1e-12` of it two points count as the same.
fn coincidence_tol(sets: &[&[[f64; 2]]]) -> f64 {
    let scale = sets
        .iter()
        .flat_map(|s| s.iter())
        .map(|p| p[0].abs().max(p[1].abs()))
        .fold(0.0, f64::max);
    1e-12 * scale.max(f64::MIN_POSITIVE)
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
    let tol = coincidence_tol(&[parts, centers, others]);
    for (j, c) in centers.iter().enumerate() {
        for (l, d) in centers.iter().enumerate().skip(j + 1) {
            if (c[0] - d[0]).hypot(c[1] - d[1]) <= tol {
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
                if (p[0] - c[0]).hypot(p[1] - c[1]) <= tol {
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
    let q = curl_points.len();
    DMatrix::from_fn(2 * m + q, centers.len(), |row, j| {
        let c = centers[j];
        if row < 2 * m {
            let p = parts[row % m];
            let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
            let r = dx.hypot(dy);
            if row < m {
                -dy / r
            } else {
                dx / r
            }
        } else {
            let p = curl_points[row - 2 * m];
            1.0 / (p[0] - c[0]).hypot(p[1] - c[1])
        }
    })
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
                .map(|p| (p[0] - c[0]).hypot(p[1] - c[1]))
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
    let r = dx.hypot(dy);
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
                let angle = strengths[j] / dx.hypot(dy);
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
