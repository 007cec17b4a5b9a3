"""Solvers (SPEC §4, §5): known answers of the thesis, and independent NumPy references."""

import warnings

import numpy as np
import pytest

import upm

CENTERS = [(-1, -0.5), (1, -0.5), (1, 0.5), (-1, 0.5)]
PARTS = [(0.5, 0), (-0.75, 0.25)]
FORCES = [(0.01, 0.01), (-0.01, 0)]


def tangential_matrix(parts, centers):
    """(4.10) written out from the SPEC formula: x rows, then y rows."""
    p = np.asarray(parts, float)[:, None, :]
    c = np.asarray(centers, float)[None, :, :]
    d = p - c
    r = np.hypot(d[..., 0], d[..., 1])
    return np.vstack([-d[..., 1] / r, d[..., 0] / r])


def test_section_4_2_1():
    plan = upm.solve_rotations(PARTS, FORCES, CENTERS, mu_m_g=0.1)
    np.testing.assert_allclose(plan.strengths, [0.584, -0.389, 0.480, -0.095], atol=6e-4)
    np.testing.assert_allclose(plan.predicted_forces, FORCES, atol=1e-15)
    assert plan.rank == 4 and plan.residual < 1e-14 and plan.bound_cost == 0.0
    # The reference: numpy's dense solve of the same square system.
    k = np.linalg.solve(tangential_matrix(PARTS, CENTERS), [0.4, -0.4, 0.4, 0.0])
    np.testing.assert_allclose(plan.strengths, k, rtol=1e-12)
    np.testing.assert_allclose(plan.condition_number, np.linalg.cond(tangential_matrix(PARTS, CENTERS)))
    # Erratum E4: the formula's priorities (0.739, 0.550, 0.679, 0.268) give this order.
    assert plan.order.tolist() == [0, 2, 1, 3]


def test_section_4_2_3_curl():
    plan = upm.solve_rotations(PARTS[:1], [(0, 0)], CENTERS[:3], curls=[-0.05], mu_m_g=0.1)
    np.testing.assert_allclose(plan.strengths, [-0.593, -0.265, -0.530], atol=6e-4)
    np.testing.assert_allclose(plan.predicted_curls, [-0.05], atol=1e-15)


def redundant(seed=0, m=3, n=9):
    rng = np.random.default_rng(seed)
    parts = rng.uniform(-0.05, 0.05, (m, 2))
    return parts, rng.normal(0, 1e-3, (m, 2)), upm.ring_centers(n, 0.2)


def test_redundant_centres_give_the_pinv_minimum_norm_solution():
    parts, steps, centers = redundant()
    plan = upm.solve_displacements(parts, steps, centers)
    a = tangential_matrix(parts, centers)
    b = np.concatenate([steps[:, 0], steps[:, 1]])
    np.testing.assert_allclose(plan.strengths, np.linalg.pinv(a) @ b, atol=1e-15, rtol=1e-12)
    np.testing.assert_allclose(plan.predicted_steps, steps, atol=1e-15)
    np.testing.assert_allclose(plan.singular_values, np.linalg.svd(a, compute_uv=False), rtol=1e-12)


def test_damping_and_rcond():
    parts, steps, centers = redundant(1)
    a = tangential_matrix(parts, centers)
    b = np.concatenate([steps[:, 0], steps[:, 1]])
    lam = 0.4
    plan = upm.solve_displacements(parts, steps, centers, damping=lam)
    want = np.linalg.solve(a.T @ a + lam**2 * np.eye(a.shape[1]), a.T @ b)
    np.testing.assert_allclose(plan.strengths, want, rtol=1e-10)
    s = np.linalg.svd(a, compute_uv=False)
    with pytest.warns(upm.RankWarning):
        cut = upm.solve_displacements(parts, steps, centers, rcond=float(s[2] / s[0]) * 1.0001)
    assert cut.rank == 2
    np.testing.assert_allclose(
        cut.strengths, np.linalg.pinv(a, rcond=float(s[2] / s[0]) * 1.0001) @ b, atol=1e-14
    )


def test_max_strength_bounds_and_reports_its_cost():
    plan = upm.solve_rotations(PARTS, FORCES, CENTERS, mu_m_g=0.1, max_strength=0.3)
    assert np.all(np.abs(plan.strengths) <= 0.3 + 1e-12)
    assert plan.bound_cost > 0
    np.testing.assert_allclose(plan.residual, np.linalg.norm(plan.predicted_forces - FORCES), rtol=1e-9)
    # Optimality (KKT) of the box-constrained least squares, checked on the system directly.
    a = tangential_matrix(PARTS, CENTERS)
    gradient = a.T @ (np.array([0.4, -0.4, 0.4, 0.0]) - a @ plan.strengths)
    for k, g in zip(plan.strengths, gradient, strict=True):
        if abs(k) < 0.3 - 1e-9:
            assert abs(g) < 1e-9
        else:
            assert g * np.sign(k) >= -1e-9  # held at the bound it pushes against


def test_batch_matches_single_calls_exactly():
    rng = np.random.default_rng(2)
    parts = rng.uniform(-0.1, 0.1, (50, 3, 2))
    forces = rng.normal(0, 0.01, (50, 3, 2))
    centers = upm.ring_centers(7, 0.25)
    batch = upm.solve_rotations_batch(parts, forces, centers, mu_m_g=0.2, damping=0.01)
    assert batch.strengths.shape == (50, 7) and batch.predicted_forces.shape == (50, 3, 2)
    for i in (0, 17, 49):
        one = upm.solve_rotations(parts[i], forces[i], centers, mu_m_g=0.2, damping=0.01)
        assert np.array_equal(one.strengths, batch.strengths[i])
        assert np.array_equal(one.order, batch.order[i])
        assert one.residual == batch.residual[i]
    per = upm.solve_rotations_batch(
        parts, forces, np.broadcast_to(centers, (50, 7, 2)), mu_m_g=0.2, damping=0.01
    )
    assert np.array_equal(per.strengths, batch.strengths)


def test_undamped_batch_of_redundant_systems_matches_numpy_pinv_and_svd():
    # The bidiagonalisation road (undamped, full rank) against LAPACK through NumPy: minimum-norm
    # strengths, singular values and condition numbers of 20 x 24 systems, random layouts.
    rng = np.random.default_rng(11)
    parts = rng.uniform(-0.1, 0.1, (200, 10, 2))
    forces = rng.normal(0.0, 0.01, (200, 10, 2))
    centers = upm.ring_centers(24, 0.25)
    plans = upm.solve_rotations_batch(parts, forces, centers, mu_m_g=0.1)
    for i in range(200):
        a = tangential_matrix(parts[i], centers)
        rhs = (24 / 0.1) * np.concatenate([forces[i, :, 0], forces[i, :, 1]])
        sv = np.linalg.svd(a, compute_uv=False)
        cond = sv[0] / sv[-1]
        want = np.linalg.pinv(a, rcond=1e-15) @ rhs
        scale = np.abs(want).max()
        assert np.abs(plans.strengths[i] - want).max() <= (1e-14 * cond + 1e-12) * scale
        np.testing.assert_allclose(plans.singular_values[i], sv, rtol=0, atol=1e-13 * sv[0])
        assert plans.rank[i] == 20
        np.testing.assert_allclose(plans.condition_number[i], cond, rtol=1e-13 * cond)


def test_bad_input_is_a_parameter_error_naming_it():
    with pytest.raises(upm.ParameterError, match=r"parts\[0\].*centers\[2\]"):
        upm.solve_rotations([(1, 0.5)], [(0, 0)], CENTERS)
    with pytest.raises(upm.ParameterError, match="centers must be distinct"):
        upm.solve_rotations([(0, 0)], [(0, 0)], [(0, 1), (1, 0), (0, 1)])
    with pytest.raises(upm.ParameterError, match="centers must number at least 4"):
        upm.solve_rotations(PARTS, FORCES, CENTERS[:3])
    with pytest.raises(upm.ParameterError, match="parts must be finite"):
        upm.solve_rotations([(np.nan, 0)], [(0, 0)], CENTERS)
    with pytest.raises(upm.ParameterError, match="forces must be finite"):
        upm.solve_rotations([(0, 0)], [(np.inf, 0)], CENTERS)
    with pytest.raises(upm.ParameterError, match="damping"):
        upm.solve_displacements([(0, 0)], [(0, 0)], CENTERS, damping=-1)
    with pytest.raises(upm.ShapeError, match=r"forces must have shape \(K, 2\)"):
        upm.solve_rotations(PARTS, [1, 2], CENTERS)
    with pytest.raises(upm.ShapeError, match="forces has 1 rows; parts has 2"):
        upm.solve_rotations(PARTS, FORCES[:1], CENTERS)


def test_rank_deficiency_warns_and_reports_the_rank():
    # Two parts at one place asking for different forces: no exact solution exists.
    with pytest.warns(upm.RankWarning, match="rank 2 < 4"):
        plan = upm.solve_displacements([(0.1, 0), (0.1, 0)], [(0, 1e-3), (0, 3e-3)], CENTERS)
    assert plan.rank == 2 and plan.condition_number > 1e12
    np.testing.assert_allclose(plan.predicted_steps, [(0, 2e-3), (0, 2e-3)], atol=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        upm.solve_rotations(PARTS, FORCES, CENTERS)


def test_rotation_order_rules():
    k = np.array([0.584, -0.389, 0.480, -0.095])
    assert upm.rotation_order(k, PARTS, CENTERS).tolist() == [0, 2, 1, 3]
    assert upm.rotation_order(k, PARTS, CENTERS, rule="magnitude").tolist() == [0, 2, 1, 3]
    assert upm.rotation_order(k, PARTS, CENTERS, rule="given").tolist() == [0, 1, 2, 3]
    assert upm.rotation_order(k, PARTS, CENTERS, rule=lambda k, p, c: -np.abs(k)).tolist() == [3, 1, 2, 0]
    plan = upm.solve_rotations(PARTS, FORCES, CENTERS, mu_m_g=0.1, order="given")
    assert plan.order.tolist() == [0, 1, 2, 3]
    with pytest.raises(upm.ParameterError, match="rule must be"):
        upm.rotation_order(k, PARTS, CENTERS, rule="random")


def test_flow_error_is_the_exact_sequencing_error_to_third_order():
    parts, steps, centers = redundant(3)
    plan = upm.solve_displacements(parts, steps, centers)
    rest = []
    for scale in (1.0, 0.5):
        d = plan.strengths * scale
        estimate = upm.flow_error(d, parts, centers, plan.order)
        exact = upm.flow_error(d, parts, centers, plan.order, exact=True)
        assert np.linalg.norm(exact - estimate) < 0.2 * np.linalg.norm(exact)
        rest.append(np.linalg.norm(exact - estimate))
    assert 6 < rest[0] / rest[1] < 10  # third order
    np.testing.assert_array_equal(
        upm.flow_error(plan), upm.flow_error(plan.strengths, parts, centers, plan.order)
    )
    # The error depends on the order of the rotations.
    assert not np.allclose(upm.flow_error(plan), upm.flow_error(plan, order=plan.order[::-1]))
    with pytest.raises(upm.ParameterError, match="DisplacementPlan"):
        upm.flow_error(upm.solve_rotations(PARTS, FORCES, CENTERS))


def test_layouts():
    np.testing.assert_array_equal(upm.corner_centers((-1, -0.5, 1, 0.5)), CENTERS)
    ring = upm.ring_centers(6, 2.0, center=(1, 1))
    np.testing.assert_allclose(np.hypot(*(ring - 1).T), 2.0)
    grid = upm.grid_centers((3, 2), (0, 0, 1, 1))
    np.testing.assert_array_equal(grid, [[0, 0], [0.5, 0], [1, 0], [0, 1], [0.5, 1], [1, 1]])
    with pytest.raises(upm.ParameterError, match="count"):
        upm.ring_centers(0, 1.0)
