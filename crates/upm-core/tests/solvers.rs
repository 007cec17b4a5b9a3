//! Known answers of docs/spec.md §4 and independent slow references for the solvers.

use upm_core::solve::{self, Curls, Options};

const CENTERS: [[f64; 2]; 4] = [[-1.0, -0.5], [1.0, -0.5], [1.0, 0.5], [-1.0, 0.5]];
const PARTS: [[f64; 2]; 2] = [[0.5, 0.0], [-0.75, 0.25]];

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

/// Gaussian elimination with partial pivoting (the reference: no SVD involved).
fn gauss(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let n = b.len();
    for k in 0..n {
        let p = (k..n)
            .max_by(|&i, &j| a[i][k].abs().total_cmp(&a[j][k].abs()))
            .unwrap();
        a.swap(k, p);
        b.swap(k, p);
        let (top, rest) = a.split_at_mut(k + 1);
        let pivot = &top[k];
        for (i, row) in rest.iter_mut().enumerate() {
            let f = row[k] / pivot[k];
            for (x, p) in row[k..].iter_mut().zip(&pivot[k..]) {
                *x -= f * p;
            }
            b[k + 1 + i] -= f * b[k];
        }
    }
    let mut x = vec![0.0; n];
    for k in (0..n).rev() {
        let s: f64 = (k + 1..n).map(|j| a[k][j] * x[j]).sum();
        x[k] = (b[k] - s) / a[k][k];
    }
    x
}

/// Rows of (4.10) written out directly from the docs/spec.md formula.
fn rows(parts: &[[f64; 2]], centers: &[[f64; 2]]) -> Vec<Vec<f64>> {
    let r = |p: [f64; 2], c: [f64; 2]| ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2)).sqrt();
    let mut out = Vec::new();
    for p in parts {
        out.push(centers.iter().map(|&c| -(p[1] - c[1]) / r(*p, c)).collect());
    }
    for p in parts {
        out.push(centers.iter().map(|&c| (p[0] - c[0]) / r(*p, c)).collect());
    }
    out
}

#[test]
fn section_4_2_1_square_system() {
    // docs/spec.md §4 known answer 4.2.1.
    let forces = [[0.01, 0.01], [-0.01, 0.0]];
    let plan = solve::solve_rotations(
        &PARTS,
        &forces,
        &CENTERS,
        Curls::default(),
        0.1,
        &Options::default(),
    )
    .unwrap();
    let want = [0.584, -0.389, 0.480, -0.095];
    for (k, w) in plan.strengths.iter().zip(want) {
        assert!(close(*k, w, 6e-4), "{:?}", plan.strengths);
    }
    assert_eq!(plan.rank, 4);
    assert!(plan.residual < 1e-14);
    for (f, p) in forces.iter().zip(&plan.predicted) {
        assert!(close(f[0], p[0], 1e-15) && close(f[1], p[1], 1e-15));
    }
    // Printed rows of A (three decimals).
    let printed = [
        [-0.316, -0.707, 0.707, 0.316],
        [-0.949, -0.394, 0.141, 0.707],
        [0.949, -0.707, -0.707, 0.949],
        [0.316, -0.919, -0.990, 0.707],
    ];
    for (row, want) in rows(&PARTS, &CENTERS).iter().zip(printed) {
        for (a, w) in row.iter().zip(want) {
            assert!(close(*a, w, 6e-4));
        }
    }
    // The reference: the same square system by Gaussian elimination.
    let b = vec![0.4, -0.4, 0.4, 0.0];
    let x = gauss(rows(&PARTS, &CENTERS), b);
    for (k, r) in plan.strengths.iter().zip(x) {
        assert!(close(*k, r, 1e-12));
    }
    // Erratum E4: the priority formula gives these, not the printed (.16, .031, .43, .34).
    let rho = solve::priorities(&plan.strengths, &PARTS, &CENTERS);
    for (r, w) in rho.iter().zip([0.739, 0.550, 0.679, 0.268]) {
        assert!(close(*r, w, 6e-4), "{rho:?}");
    }
    assert_eq!(plan.order, vec![0, 2, 1, 3]);
}

#[test]
fn section_4_2_3_curl_constraint() {
    let plan = solve::solve_rotations(
        &PARTS[..1],
        &[[0.0, 0.0]],
        &CENTERS[..3],
        Curls {
            points: &PARTS[..1],
            values: &[-0.05],
        },
        0.1,
        &Options::default(),
    )
    .unwrap();
    for (k, w) in plan.strengths.iter().zip([-0.593, -0.265, -0.530]) {
        assert!(close(*k, w, 6e-4), "{:?}", plan.strengths);
    }
    assert!(close(plan.predicted_curls[0], -0.05, 1e-15));
}

type Points = Vec<[f64; 2]>;

fn redundant() -> (Points, Points, Points) {
    let parts = vec![[0.1, 0.05], [-0.08, 0.02], [0.03, -0.09]];
    let steps = vec![[1e-3, -2e-3], [0.5e-3, 1e-3], [-1.5e-3, 0.2e-3]];
    let centers: Vec<[f64; 2]> = (0..9)
        .map(|j| {
            let a = j as f64 * std::f64::consts::TAU / 9.0;
            [0.2 * a.cos(), 0.2 * a.sin()]
        })
        .collect();
    (parts, steps, centers)
}

#[test]
fn redundant_centres_give_the_minimum_norm_solution() {
    let (parts, steps, centers) = redundant();
    let plan = solve::solve_displacements(&parts, &steps, &centers, &Options::default()).unwrap();
    // Reference: x = A^T (A A^T)^-1 b by elimination on the (well-conditioned) Gram matrix.
    let a = rows(&parts, &centers);
    let b: Vec<f64> = steps
        .iter()
        .map(|s| s[0])
        .chain(steps.iter().map(|s| s[1]))
        .collect();
    let gram: Vec<Vec<f64>> = a
        .iter()
        .map(|ri| {
            a.iter()
                .map(|rj| ri.iter().zip(rj).map(|(x, y)| x * y).sum())
                .collect()
        })
        .collect();
    let y = gauss(gram, b);
    for j in 0..centers.len() {
        let x: f64 = (0..a.len()).map(|i| a[i][j] * y[i]).sum();
        assert!(close(plan.strengths[j], x, 1e-13), "{j}");
    }
    assert_eq!(plan.rank, 6);
    assert!(plan.residual < 1e-15);
}

#[test]
fn damping_is_tikhonov() {
    let (parts, steps, centers) = redundant();
    let lambda = 0.3;
    let opts = Options {
        damping: lambda,
        ..Options::default()
    };
    let plan = solve::solve_displacements(&parts, &steps, &centers, &opts).unwrap();
    // Reference: (A^T A + lambda^2 I) x = A^T b.
    let a = rows(&parts, &centers);
    let b: Vec<f64> = steps
        .iter()
        .map(|s| s[0])
        .chain(steps.iter().map(|s| s[1]))
        .collect();
    let n = centers.len();
    let mut normal = vec![vec![0.0; n]; n];
    let mut rhs = vec![0.0; n];
    for j in 0..n {
        for l in 0..n {
            normal[j][l] = (0..a.len()).map(|i| a[i][j] * a[i][l]).sum::<f64>();
        }
        normal[j][j] += lambda * lambda;
        rhs[j] = (0..a.len()).map(|i| a[i][j] * b[i]).sum();
    }
    let x = gauss(normal, rhs);
    for (k, r) in plan.strengths.iter().zip(x) {
        assert!(close(*k, r, 1e-15), "{k} {r}");
    }
    assert!(plan.residual > 0.0);
}

#[test]
fn rcond_truncates_and_reports_the_rank() {
    // Two parts at the same place ask for different steps: rank 2 of 4, least-squares average.
    let parts = [[0.1, 0.0], [0.1, 0.0]];
    let steps = [[0.0, 1e-3], [0.0, 3e-3]];
    let plan = solve::solve_displacements(&parts, &steps, &CENTERS, &Options::default()).unwrap();
    assert_eq!(plan.rank, 2);
    assert!(plan.condition_number() > 1e12);
    for p in &plan.predicted {
        assert!(close(p[1], 2e-3, 1e-12) && close(p[0], 0.0, 1e-12), "{p:?}");
    }
    let cut = Options {
        rcond: Some(0.9),
        ..Options::default()
    };
    let plan = solve::solve_displacements(&parts[..1], &steps[..1], &CENTERS, &cut).unwrap();
    assert_eq!(plan.rank, 1);
}

/// Projected gradient with a tiny fixed step, run to convergence (slow, independent).
fn projected_gradient(a: &[Vec<f64>], b: &[f64], bound: f64, lambda: f64) -> Vec<f64> {
    let n = a[0].len();
    let mut x = vec![0.0; n];
    let lip: f64 = a.iter().flat_map(|r| r.iter()).map(|v| v * v).sum::<f64>() + lambda * lambda;
    for _ in 0..200_000 {
        let r: Vec<f64> = a
            .iter()
            .zip(b)
            .map(|(row, bi)| row.iter().zip(&x).map(|(p, q)| p * q).sum::<f64>() - bi)
            .collect();
        for j in 0..n {
            let g: f64 = (0..a.len()).map(|i| a[i][j] * r[i]).sum::<f64>() + lambda * lambda * x[j];
            x[j] = (x[j] - g / lip).clamp(-bound, bound);
        }
    }
    x
}

#[test]
fn max_strength_matches_a_projected_gradient_reference() {
    let forces = [[0.01, 0.01], [-0.01, 0.0]];
    let a = rows(&PARTS, &CENTERS);
    let b = [0.4, -0.4, 0.4, 0.0];
    for (bound, lambda) in [(0.4, 0.0), (0.3, 0.05), (0.1, 0.0)] {
        let opts = Options {
            max_strength: Some(bound),
            damping: lambda,
            ..Options::default()
        };
        let plan = solve::solve_rotations(&PARTS, &forces, &CENTERS, Curls::default(), 0.1, &opts)
            .unwrap();
        assert!(
            plan.strengths
                .iter()
                .all(|k| k.abs() <= bound * (1.0 + 1e-12)),
            "{:?}",
            plan.strengths
        );
        let x = projected_gradient(&a, &b, bound, lambda);
        let objective = |k: &[f64]| {
            let r: f64 = a
                .iter()
                .zip(&b)
                .map(|(row, bi)| (row.iter().zip(k).map(|(p, q)| p * q).sum::<f64>() - bi).powi(2))
                .sum();
            r + lambda * lambda * k.iter().map(|v| v * v).sum::<f64>()
        };
        assert!(
            objective(&plan.strengths) <= objective(&x) + 1e-10,
            "{bound}: {:?} vs {x:?}",
            plan.strengths
        );
        for (k, r) in plan.strengths.iter().zip(&x) {
            assert!(
                close(*k, *r, 1e-5),
                "{bound}: {:?} vs {x:?}",
                plan.strengths
            );
        }
        // The bound binds (0.584 > 0.4), so it costs force error.
        assert!(plan.bound_cost > 0.0);
        assert!(close(plan.bound_cost, plan.residual, 1e-15) || lambda > 0.0);
    }
}

#[test]
fn second_order_flow_error_is_the_exact_error_to_third_order() {
    let (parts, steps, centers) = redundant();
    let plan = solve::solve_displacements(&parts, &steps, &centers, &Options::default()).unwrap();
    let mut previous = f64::NAN;
    for scale in [1.0, 0.5, 0.25] {
        let d: Vec<f64> = plan.strengths.iter().map(|v| v * scale).collect();
        let exact = solve::flow_exact(&d, &parts, &centers, &plan.order).unwrap();
        let est = solve::flow_error(&d, &parts, &centers, &plan.order).unwrap();
        let mut worst: f64 = 0.0;
        for (i, p) in parts.iter().enumerate() {
            let linear = [p[0] + scale * steps[i][0], p[1] + scale * steps[i][1]];
            let err = [exact[i][0] - linear[0], exact[i][1] - linear[1]];
            // The estimate captures most of the error...
            let rest = (err[0] - est[i][0]).hypot(err[1] - est[i][1]);
            assert!(rest < 0.2 * err[0].hypot(err[1]), "{scale} {i}");
            worst = worst.max(rest);
        }
        // ...and what it misses is third order: halving the steps divides it by about 8.
        if previous.is_finite() {
            let ratio = previous / worst;
            assert!((6.0..10.0).contains(&ratio), "{ratio}");
        }
        previous = worst;
    }
}

#[test]
fn bad_layouts_are_parameter_errors() {
    let o = Options::default();
    let e = solve::solve_displacements(&[[1.0, 0.5]], &[[0.0, 0.0]], &CENTERS, &o).unwrap_err();
    assert!(
        e.to_string().contains("parts[0]") && e.to_string().contains("centers[2]"),
        "{e}"
    );
    let dup = [CENTERS[0], CENTERS[1], CENTERS[0]];
    let e = solve::solve_displacements(&[[0.0, 0.0]], &[[0.0, 0.0]], &dup, &o).unwrap_err();
    assert!(e.to_string().starts_with("centers must be distinct"), "{e}");
    let e = solve::solve_displacements(&PARTS, &[[0.0, 0.0]; 2], &CENTERS[..3], &o).unwrap_err();
    assert!(
        e.to_string().starts_with("centers must number at least 4"),
        "{e}"
    );
    let e =
        solve::solve_displacements(&[[f64::NAN, 0.0]], &[[0.0, 0.0]], &CENTERS, &o).unwrap_err();
    assert!(e.to_string().starts_with("parts must be finite"), "{e}");
    let e = solve::flow_error(&[1.0; 4], &PARTS, &CENTERS, &[0, 1, 1, 2]).unwrap_err();
    assert!(
        e.to_string().starts_with("order must be a permutation"),
        "{e}"
    );
}
