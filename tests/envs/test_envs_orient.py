"""``upm/Orient-v0`` (issue 59): polygons to target poses. Each world's polygons start at their
own poses in one batched call, a step is the pulse simulated alone, the cost and completion follow
the poses' symmetry, and the pose planner as a policy orients a part where random actions do not."""

from __future__ import annotations

import math

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import upm  # noqa: E402
from upm.envs import PlannerPolicy, PlateEnv, RandomPolicy  # noqa: E402
from upm.envs.orient import OrientTask  # noqa: E402

RECT = upm.Polygon.rectangle(0.04, 0.02)


def test_simulate_batch_starts_each_worlds_polygons_at_their_own_poses():
    rng = np.random.default_rng(2)
    motions = [upm.Pulse.rotation(rng.uniform(-0.05, 0.05, 2), upm.Harmonics([1.0, 0.0], [0.0, -1.0], 35.0),
                                  0.05, 0.1, 0.05, 0.05).motion() for _ in range(3)]  # fmt: skip
    starts = np.stack(
        [np.column_stack([rng.uniform(-0.1, 0.1, (2, 2)), rng.uniform(-3, 3, 2)]) for _ in range(3)]
    )
    kw = {"duration": 0.25, "dt": 1 / 2800, "mu": 0.3, "plate_size": 0.4064, "record_every": 50}
    parts = [RECT.moved(tuple(p[:2]), p[2]) for p in starts[0]]
    batch = upm.simulate_batch(motions, parts, starts=starts, **kw)
    for w, m in enumerate(motions):
        alone = upm.simulate(m, [RECT.moved(tuple(p[:2]), p[2]) for p in starts[w]], **kw)
        np.testing.assert_array_equal(batch.positions[w], alone.positions)
        np.testing.assert_array_equal(batch.angles[w], alone.angles)
    assert np.all(np.abs(batch.angles[:, -1] - starts[..., 2]) > 1e-3)  # the rotations turned them
    with pytest.raises(upm.ShapeError, match="starts"):
        upm.simulate_batch(motions, parts, starts=np.zeros((3, 2, 4)), **kw)


def test_a_step_is_the_pulse_simulated_alone_until_the_part_stops():
    env = PlateEnv("orient", n_parts=1, polygon=RECT)
    obs, _ = env.reset(seed=4)
    start = env.positions[0]
    assert obs.shape == (9,) and np.isfinite(start).all()
    action = np.array([0.0, *(start[:2] / (1.5 * env._e.half)), 1.0, 1.0, 0.0, 0.0], np.float32)
    pulse = env.pulse(action)
    assert pulse.kind == "rotation"
    dt = 1 / (24 * 2 * pulse.frequency)
    coast = 1.05 * pulse.on_time + 1e-3  # every part stopped (mu_s = mu)
    motion = upm.PlateMotion.sequence([pulse.motion(rest=False), upm.PlateMotion.rest(coast + 1e-3)])
    run = upm.simulate(motion, [RECT.moved(tuple(start[:2]), start[2])], duration=pulse.on_time + coast,
                       dt=dt, mu=0.3, plate_size=env._e.limits.size, record_every=10**9)  # fmt: skip
    env.step(action)
    after = env.positions[0]
    np.testing.assert_allclose(after, [*run.positions[-1, 0], run.angles[-1, 0]], rtol=0, atol=1e-12)
    assert abs(after[2] - start[2]) > math.radians(1)  # a spin about the part turns it


def test_the_cost_and_completion_follow_the_outlines_symmetry():
    task = OrientTask(2, upm.DriveLimits(), RECT, tolerance=0.004, angle_tolerance=10.0)
    goals = np.array([[[0.05, 0.0, 0.3], [-0.05, 0.02, -1.0]]])
    turned = goals + np.array([[[0.001, 0.0, math.pi], [0.0, -0.001, -math.pi]]])  # a half turn
    assert task.done(turned, goals)[0] and task.cost(turned, goals)[0] == 0.0
    off = goals + np.array([[[0.01, 0.0, 0.0], [0.0, 0.0, math.radians(30)]]])
    weight = 0.004 / math.radians(10)
    want = (0.01 - 0.002) + weight * (math.radians(30) - math.radians(5))
    assert not task.done(off, goals)[0] and task.cost(off, goals)[0] == pytest.approx(want, rel=1e-12)
    lost = off.copy()
    lost[0, 1] = np.nan
    assert task.cost(lost, goals)[0] == pytest.approx(0.008 + 1.0, rel=1e-12)
    obs = task.observe(goals, goals)[0]
    assert obs.shape == (18,) and obs[2] == pytest.approx(math.cos(2 * 0.3))  # the angle's 2-fold view


def test_the_pose_planner_policy_orients_a_part_where_random_actions_do_not():
    results = {}
    for name in ("planner", "random"):
        env = gym.make("upm/Orient-v0", max_plate_time=20.0)
        obs, info = env.reset(seed=1)
        act = PlannerPolicy(env) if name == "planner" else RandomPolicy(env, seed=1)
        for _ in range(200):
            obs, _, term, trunc, info = env.step(act(obs))
            if term or trunc:
                break
        results[name] = info["is_success"]
    assert results == {"planner": True, "random": False}
    with pytest.raises(upm.ParameterError, match="planner"):
        PlannerPolicy(gym.make("upm/Orient-v0"), planner=upm.plan.PredictivePlanner(upm.DriveLimits()))


@pytest.mark.parametrize(
    "kw,name",
    [({"polygon": "circle"}, "polygon"), ({"polygon": 3}, "polygon"),
     ({"angle_tolerance": 0}, "angle_tolerance"),
     ({"contacts": True, "part_radius": 0.01}, "contacts"), ({"n_parts": 200}, "n_parts"),
     ({"polygon": upm.Polygon.regular(4, 0.15)}, "polygon")],
)  # fmt: skip
def test_bad_orient_options_name_the_parameter(kw, name):
    with pytest.raises(upm.ParameterError, match=name):
        PlateEnv("orient", **kw)
