"""Fields (SPEC §4, §7) and executing plans in the integrator (SPEC §5): independent checks."""

import numpy as np
import pytest

import upm

F0 = 0.23856  # force at rest of cos t - cos(2t)/2, SPEC §5


def test_jet_known_answers_and_shapes():
    # SPEC §7: d = (0, 1), rho = 1, C = 0.
    points = [(0, 0), (0.25, 0), (0.5, 0), (1, 0), (2, 0), (4, 0), (0, 0.5), (0, 1), (0, 2), (0.7, 0.7)]
    want_y = [0.3333, 0.1869, 0.0813, -0.0559, 0.0138, 0.0036, 0.1442, 0.0821, 0.0434, 0.0425]
    f = upm.jet_field(points, (0, 0), (0, 1), 1.0)
    np.testing.assert_allclose(f[:, 1], want_y, atol=6e-5)
    np.testing.assert_allclose(f[-1, 0], 0.0443, atol=6e-5)
    grid = np.zeros((3, 4, 2))
    assert upm.jet_field(grid, (0, 0), (1, 0), 0.5).shape == (3, 4, 2)
    with pytest.raises(upm.ParameterError, match="rho"):
        upm.jet_field(points, (0, 0), (0, 1), 0.0)


def test_rotation_field_and_curl():
    f = upm.rotation_field([(3, 4), (0, 0)], (0, 0))
    np.testing.assert_allclose(f, [(-0.8, 0.6), (0, 0)])
    assert upm.rotation_curl((3, 4), (0, 0)) == pytest.approx(0.2)


def test_average_field_agrees_with_closed_forms():
    rotation = upm.PlateMotion.rotation((0.02, -0.01), upm.Harmonics([3.0, -1.5], [0, 0], 35.0))
    points = np.array([(0.1, 0.0), (-0.05, 0.08), (0.0, -0.2)])
    np.testing.assert_allclose(
        upm.average_field(rotation, points), F0 * upm.rotation_field(points, (0.02, -0.01)), atol=1e-5
    )
    jet = upm.PlateMotion.jet((0.0, 0.0), (0, 1), 0.05, 0.2, 50.0)
    np.testing.assert_allclose(
        upm.average_field(jet, points / 2), upm.jet_field(points / 2, (0, 0), (0, 1), 0.05), atol=1e-8
    )
    # A part sliding along with the plate feels the 1-D force at its relative velocity (3.4).
    drive = upm.TwoHarmonic(0.5, np.pi / 2, amplitude=0.3, frequency=20.0)
    slide = upm.PlateMotion.translation((0, 1), drive)
    f = upm.average_field(slide, (0.1, 0.1), part_velocity=(0, 0.04))
    np.testing.assert_allclose(f, [0, upm.mean_force(drive, 0.04)], atol=1e-9)


def test_average_field_agrees_with_the_integrator():
    # Over one period of a fast plate a part barely moves: the change of its velocity divided by
    # mu g T is the average force / (mu m g), evaluated at the part's mean velocity over the period.
    def check(motion, points, period, steps, atol):
        run = upm.simulate(motion, points, duration=period, dt=period / steps, mu=0.3, record_every=steps)
        measured = run.velocities[-1] / (0.3 * 9.81 * period)
        mean_velocity = (run.positions[-1] - points) / period
        np.testing.assert_allclose(measured, upm.average_field(motion, points, mean_velocity), atol=atol)

    rotation = upm.PlateMotion.rotation((0.0, 0.0), upm.Harmonics([30.0, -15.0], [0, 0], 10.0))
    check(rotation, np.array([(1.0, 0.0), (0.5, 0.4), (-0.8, 2.0)]), 0.1, 20000, 5e-4)
    # The jet's feeding term touches zero tangentially (cos t - cos 2t at t = 0), so its force
    # falls steeply with part speed and the one-period average is only good to about 1e-2.
    jet = upm.PlateMotion.jet((0.0, 0.0), (1, 1), 2.0, 20.0, 10.0)
    check(jet, np.array([(0.0, 0.0), (1.2, 0.4), (-0.8, 2.0)]), 0.3, 60000, 1e-2)


def test_force_plan_gives_its_forces_on_average():
    plan = upm.solve_rotations(
        [(0.5, 0), (-0.75, 0.25)], [(0.004, 0.004), (-0.004, 0)],
        [(-1, -0.5), (1, -0.5), (1, 0.5), (-1, 0.5)], mu_m_g=0.1,
    )  # fmt: skip
    wave = upm.Harmonics([2.0, -1.0], [0, 0], 35.0)
    motion = upm.plan_to_motion(plan, wave, duration=2.0)
    assert motion.is_closed(1e-9)
    # Independent expectation: each rotation j runs a whole number of periods n_j, so the average
    # is sum_j sign(k_j) n_j T f0 / duration times its unit field.
    periods = np.rint(np.abs(plan.strengths) / (4 * F0) * 2.0 * 35.0)
    weights = np.sign(plan.strengths) * periods / 35.0 * upm.mean_force(wave) / 2.0
    fields = np.stack([upm.rotation_field(plan.parts, c) for c in plan.centers], axis=1)
    want = np.einsum("mnk,n->mk", fields, weights)
    got = upm.average_field(motion, plan.parts, tol=1e-9)
    np.testing.assert_allclose(got, want, atol=1e-7)
    # ... and within one period per rotation of the plan's forces.
    np.testing.assert_allclose(got, plan.predicted_forces / 0.1, atol=4 * F0 / 70)
    strong = upm.solve_rotations(plan.parts, [(0.01, 0.01), (-0.01, 0)], plan.centers, mu_m_g=0.1)
    with pytest.raises(upm.ParameterError, match="max_strength"):
        upm.plan_to_motion(strong)
    with pytest.raises(upm.ParameterError, match="intensity must be 'duration'"):
        upm.plan_to_motion(plan, intensity="amplitude")


def grid_layout(m, g, seed):
    """Centres on a g x g grid over a 0.3 m square; parts at distinct cell centres (away from
    every centre)."""
    rng = np.random.default_rng(seed)
    centers = upm.grid_centers((g, g), (-0.15, -0.15, 0.15, 0.15))
    s = 0.3 / (g - 1)
    cells = np.array([(x, y) for x in range(g - 1) for y in range(g - 1)]) * s - 0.15 + s / 2
    return cells[rng.choice(len(cells), m, replace=False)], centers


def run(motion, parts, mu=0.3):
    dt = 1 / (200 * motion.max_frequency)
    result = upm.simulate(motion, parts, duration=motion.duration, dt=dt, mu=mu, record_every=10**9)
    return result.positions[-1] - parts


@pytest.mark.parametrize(("m", "g", "tolerance"), [(2, 4, 0.03), (5, 6, 0.10), (10, 7, 0.10)])
def test_displacement_plans_move_the_parts_by_their_steps(m, g, tolerance):
    parts, centers = grid_layout(m, g, seed=3)
    steps = np.random.default_rng(m).normal(0, 4e-4, (m, 2))
    plan = upm.solve_displacements(parts, steps, centers)
    motion = upm.plan_to_motion(plan, mu=0.3, amplitude=5.0, frequency=100.0)
    moved = run(motion, parts)
    assert np.linalg.norm(moved - steps) <= tolerance * np.linalg.norm(steps)


def test_errors_grow_near_the_centres_and_redundancy_bounds_them():
    rng = np.random.default_rng(7)
    centers = upm.grid_centers((4, 4), (-0.15, -0.15, 0.15, 0.15))
    steps = rng.normal(0, 4e-4, (3, 2))
    away = np.array([(-0.1, -0.1), (0.0, 0.1), (0.1, 0.0)])
    near = centers[[5, 6, 9]] + 0.004
    plans = {name: upm.solve_displacements(p, steps, centers) for name, p in (("away", away), ("near", near))}
    errors = {name: np.linalg.norm(upm.flow_error(plan, exact=True)) for name, plan in plans.items()}
    assert plans["near"].condition_number > 2 * plans["away"].condition_number
    assert errors["near"] > 10 * errors["away"]
    # Redundancy: with all 16 centres the minimum-norm strengths and the sequencing error are
    # smaller than with six of them (a square system).
    few = upm.solve_displacements(away, steps, centers[[0, 3, 12, 15, 1, 14]])
    assert np.abs(plans["away"].strengths).sum() < np.abs(few.strengths).sum()
    assert errors["away"] < 0.5 * np.linalg.norm(upm.flow_error(few, exact=True))


def test_pulse_planning_rejects_what_it_cannot_do():
    parts, centers = grid_layout(2, 4, seed=1)
    plan = upm.solve_displacements(parts, [(1e-6, 0), (0, 1e-6)], centers)
    with pytest.raises(upm.ParameterError, match="too small for pulses at 35 Hz"):
        upm.plan_to_motion(plan, mu=0.3)
    with pytest.raises(upm.ParameterError, match="mu is required"):
        upm.plan_to_motion(plan)


def test_jets_move_one_part_at_a_time():
    parts = np.array([[0.0, 0.0], [0.06, 0.02], [-0.04, 0.05]])
    steps = np.array([[1e-3, 0.5e-3], [0, 0], [0, 0]])
    motion = upm.jet_plan(parts, steps, mu=0.3, frequency=300.0, amplitude=0.5)
    moved = run(motion, parts)
    np.testing.assert_allclose(moved[0], steps[0], rtol=0.01)
    cross_talk = np.hypot(*moved[1:].T).max() / np.hypot(*moved[0])
    assert cross_talk < 0.25
    both = upm.jet_plan(parts, [[1e-3, 0], [0, -1e-3], [0, 0]], mu=0.3, frequency=300.0, amplitude=0.5)
    assert both.duration > motion.duration  # two jets, one after the other


def test_field_plot_draws_the_fields():
    plot = pytest.importorskip("upm.plot")
    fig = plot.field("jet", (-2, -2, 2, 2), rho=1.0, resolution=5, parts=[(0, 0)])
    quiver = fig.axes[0].collections[0]
    gx, gy = np.meshgrid(np.linspace(-2, 2, 5), np.linspace(-2, 2, 5))
    want = upm.jet_field(np.stack([gx, gy], axis=-1), (0, 0), (0, 1), 1.0)
    np.testing.assert_allclose(np.asarray(quiver.U).reshape(5, 5), want[..., 0], atol=1e-6)
    np.testing.assert_allclose(np.asarray(quiver.V).reshape(5, 5), want[..., 1], atol=1e-6)
    plan = upm.solve_rotations(
        [(0.5, 0), (-0.75, 0.25)], [(0.01, 0.01), (-0.01, 0)], upm.corner_centers((-1, -0.5, 1, 0.5))
    )
    fig = plot.field(
        "plan", (-1.2, -0.8, 1.2, 0.8), strengths=plan.strengths, centers=plan.centers, parts=plan.parts
    )
    assert len(fig.axes[0].lines) == 2  # centres and parts marked
    with pytest.raises(ValueError, match="kind must be"):
        plot.field("vortex", (0, 0, 1, 1))
