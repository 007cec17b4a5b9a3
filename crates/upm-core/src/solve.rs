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
//! The systems are solved by [`crate::linalg`] (SVD, damping, bounds); its [`Options`],
//! [`Solution`] and [`lstsq`] are re-exported here.

use nalgebra::DMatrix;

use crate::error::{finite, Error, Result};
use crate::linalg::{condition, pyth};
pub use crate::linalg::{lstsq, Options, Solution};

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
}
