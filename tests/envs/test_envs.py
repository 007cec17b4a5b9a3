"""The Gymnasium environments (issue 59): the checker, semantics, determinism, the vector env
against single envs bit for bit, actions within the drive's limits, bad options."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import upm  # noqa: E402
from upm.envs import IDS, PlateEnv, PlateVectorEnv, PulseActions  # noqa: E402
from upm.envs.actions import FREQUENCIES, ON_TIMES  # noqa: E402

SMALL = {"n_parts": 3, "max_plate_time": 3.0}


@pytest.mark.parametrize("env_id", sorted(IDS))
@pytest.mark.parametrize("action_space", ["pulse", "library"])
def test_every_registered_env_passes_the_checker_without_warnings(env_id, action_space):
    from gymnasium.utils.env_checker import check_env

    env = gym.make(env_id, action_space=action_space, **SMALL)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, skip_render_check=False)


def test_a_pulse_moves_the_parts_as_the_simulator_does_and_the_reward_is_the_cost_rate():
    # independent of the env's batching: the action's upm.Pulse simulated alone, then slid to rest
    env = PlateEnv("goto", n_parts=4)
    obs, _ = env.reset(seed=3)
    start = env.positions
    action = np.array([-1.0, 0.0, 0.0, 0.25, 0.6, 0.0, 0.0], np.float32)  # translation at 45 degrees
    pulse = env.pulse(action)
    assert (
        pulse.kind == "translation"
        and pulse.frequency == FREQUENCIES[1]
        and pulse.on_time == pytest.approx(ON_TIMES[1])
    )
    dt = 1 / (24 * 2 * pulse.frequency)
    run = upm.simulate(pulse.motion(rest=False), start, duration=pulse.on_time, dt=dt,
                       mu=0.3, plate_size=env.unwrapped._e.limits.size)  # fmt: skip
    v = run.velocities[-1]
    speed = np.hypot(v[:, 0], v[:, 1])
    expect = run.positions[-1] + v * (speed / (2 * 0.3 * 9.81))[:, None]
    _, reward, terminated, truncated, info2 = env.step(action)
    np.testing.assert_allclose(env.positions, expect, rtol=0, atol=1e-12)
    moved = env.positions - start
    assert np.all(np.hypot(moved[:, 0], moved[:, 1]) > 1e-3)
    assert np.allclose(moved, moved[0], atol=1e-9)  # a translation moves every part alike
    goals = env.unwrapped._e.goals[0]
    np.testing.assert_allclose(
        obs[8:16].reshape(4, 2) * env.unwrapped._e.half, goals, atol=1e-7
    )  # as observed
    tol = 0.0037

    def cost(q):
        d = np.hypot(*(q - goals).T)
        return np.sum(np.maximum(d - tol / 2, 0.0))

    duration = pulse.on_time + np.max(speed / (0.3 * 9.81))
    assert info2["duration"] == pytest.approx(duration, rel=1e-12)
    assert reward == pytest.approx((cost(start) - cost(env.positions)) / duration, rel=1e-9)
    assert info2["plate_time"] == pytest.approx(duration)
    assert not terminated and not truncated


def test_every_action_stays_within_force_and_stroke_even_far_outside_the_box():
    limits = upm.DriveLimits()
    actions = PulseActions(limits)
    rng = np.random.default_rng(5)
    batch = rng.uniform(-3, 3, (160, 7))
    batch[:, 4] = rng.choice([1.0, 5.0, 1e9], 160)  # full amplitude and beyond
    batch[:5] = np.array([np.nan, 1e300, -1e300, np.inf, -np.inf])[:, None]
    for a in batch:
        pulse = actions.pulse(a)
        if pulse.kind != "rest":
            limits.check(pulse)  # StrokeError / ParameterError beyond the limits
            assert limits.headroom(pulse) >= 1.0
    # and the kinds, frequencies and on-times all occur
    d = actions.decode(batch)
    assert set(d.kind) == {0, 1, 2} and set(d.frequency) == {0, 1, 2} and set(d.on) == {0, 1, 2}


def test_the_batched_motions_are_the_pulses_own():
    actions = PulseActions(upm.DriveLimits())
    rng = np.random.default_rng(2)
    batch = rng.uniform(-1, 1, (12, 7))
    batch[3, 4] = -1.0  # amplitude 0: a rest
    d = actions.decode(batch)
    t = np.linspace(0, 0.6, 997)
    for i, core in enumerate(actions.motions(d)):
        own = actions.pulse(batch[i]).motion(rest=False)
        np.testing.assert_array_equal(upm.PlateMotion(core).velocity(t), own.velocity(t))


def test_the_same_seed_gives_the_same_episode_bit_for_bit():
    def episode(seed):
        env = gym.make("upm/Sort-v0", n_parts=4)
        env.action_space.seed(seed)
        obs, _ = env.reset(seed=seed)
        out = [obs]
        for _ in range(4):
            obs, r, *_ = env.step(env.action_space.sample())
            out += [obs, np.array([r])]
        return np.concatenate([o.ravel().astype(np.float64) for o in out])

    a, b, c = episode(7), episode(7), episode(8)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


@pytest.mark.parametrize("env_id,parts", [("upm/Goto-v0", 3), ("upm/Shape-v0", 4), ("upm/Orient-v0", 2)])
def test_the_vector_env_equals_single_envs_bit_for_bit_through_autoresets(env_id, parts):
    n, kw = 6, {"n_parts": parts, "max_plate_time": 1.2}
    vec = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kw)
    assert isinstance(vec.unwrapped, PlateVectorEnv)
    sync = gym.make_vec(env_id, num_envs=n, vectorization_mode="sync", **kw)
    o1, _ = vec.reset(seed=11)
    o2, _ = sync.reset(seed=11)
    np.testing.assert_array_equal(o1, o2)
    rng = np.random.default_rng(0)
    resets = 0
    for _ in range(12):
        a = rng.uniform(-1, 1, (n, 7)).astype(np.float32)
        r1 = vec.step(a)
        r2 = sync.step(a)
        for x, y in zip(r1[:4], r2[:4], strict=True):
            np.testing.assert_array_equal(x, y)
        resets += int(np.sum(r1[3]))
    assert resets > 0  # the plate-time limit truncated episodes, and both autoreset them alike


def test_next_step_autoreset_and_disabled_autoreset_with_a_mask():
    vec = PlateVectorEnv(3, "goto", n_parts=2, max_plate_time=0.2)
    assert vec.metadata["autoreset_mode"] == gym.vector.AutoresetMode.NEXT_STEP
    vec.reset(seed=0)
    a = np.zeros((3, 7), np.float32)
    _, _, term, trunc, info = vec.step(a)
    assert np.all(trunc) and np.all(info["plate_time"] >= 0.2)
    _, reward, term, trunc, _ = vec.step(a)  # the reset step: reward 0, a fresh layout
    assert np.all(reward == 0) and not np.any(term | trunc)
    assert np.all(vec._e.time == 0.0)

    off = PlateVectorEnv(3, "goto", n_parts=2, max_plate_time=0.2, autoreset_mode="disabled")
    off.reset(seed=0)
    off.step(a)
    before = off.positions
    off.reset(options={"reset_mask": np.array([True, False, False])})
    after = off.positions
    assert not np.array_equal(before[0], after[0])
    np.testing.assert_array_equal(before[1:], after[1:])
    assert off._e.time[0] == 0.0 and np.all(off._e.time[1:] > 0)


def test_a_library_action_plays_its_pulse_and_a_lost_part_is_penalised():
    env = PlateEnv("goto", n_parts=2, action_space="library", lost_penalty=5.0)
    env.reset(seed=1)
    assert env.action_space.n == len(upm.envs.library()) == 188
    pulse = env.pulse(12)  # the library's translation along +x at the middle on-time
    assert pulse.kind == "translation" and pulse.direction == pytest.approx((1.0, 0.0))
    env.unwrapped._e.positions[0] = [[0.17, 0.0], [-0.1, 0.0]]
    for _ in range(20):
        before = float(env.unwrapped._e.cost[0])
        _, reward, terminated, _, info = env.step(12)
        if info["lost"]:
            break
    assert info["lost"] == 1 and np.isnan(env.positions[0]).all() and np.isfinite(env.positions[1]).all()
    # the cost counts the lost part 1 m, and the penalty comes on top
    assert reward == pytest.approx((before - info["cost"]) / info["duration"] - 5.0, rel=1e-12)
    assert not terminated


@pytest.mark.parametrize(
    "kw,name",
    [({"n_parts": 0}, "n_parts"), ({"n_parts": 2.5}, "n_parts"), ({"part_radius": -1}, "part_radius"),
     ({"mu": float("nan")}, "mu"), ({"action_space": "joystick"}, "action_space"),
     ({"contacts": True}, "part_radius"), ({"max_plate_time": 0}, "max_plate_time"),
     ({"shape": "star"}, "shape"), ({"task": "juggle"}, "task"), ({"render_mode": "human"}, "render_mode")],
)  # fmt: skip
def test_bad_options_name_the_parameter(kw, name):
    task = kw.pop("task", "shape" if "shape" in kw else "goto")
    with pytest.raises(upm.ParameterError, match=name):
        PlateEnv(task, **kw)


def test_contacts_keep_disks_apart_and_render_gives_the_camera_frame():
    env = PlateEnv("sort", n_parts=4, part_radius=0.0195, contacts=True, render_mode="rgb_array")
    env.reset(seed=2)
    env.step(np.array([0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 1.0], np.float32))  # a rotation about the centre
    q = env.positions
    gaps = [np.hypot(*(q[i] - q[j])) for i in range(4) for j in range(i) if np.isfinite(q[[i, j]]).all()]
    assert min(gaps) > 2 * 0.0195 - 1e-3
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3


@pytest.mark.parametrize("contacts", [False, True])
def test_simulate_batch_starts_each_world_from_its_own_layout(contacts):
    # the vector env's physics: each world equals that world simulated alone from its start
    rng = np.random.default_rng(4)
    motions = [upm.Pulse.jet(rng.uniform(-0.05, 0.05, 2), (1.0, 0.0), 0.04, 0.1, 35.0, 0.1, 0.1, 0.1).motion()
               for _ in range(5)]  # fmt: skip
    starts = np.stack([rng.uniform(-0.1, 0.1, 2) + np.array([[0.0, 0.0], [0.05, 0.0], [0.0, 0.05]])
                       for _ in range(5)])  # fmt: skip
    kw = {"duration": 0.3, "dt": 1 / 1680, "mu": 0.3, "plate_size": 0.4064, "record_every": 20}
    parts = [upm.Disk(tuple(p), 0.01) for p in starts[0]] if contacts else starts[0]
    batch = upm.simulate_batch(motions, parts, starts=starts, contacts=contacts, **kw)
    for w, m in enumerate(motions):
        own = [upm.Disk(tuple(p), 0.01) for p in starts[w]] if contacts else starts[w]
        alone = upm.simulate(m, own, contacts=contacts, **kw)
        np.testing.assert_array_equal(batch.positions[w], alone.positions)
    assert not np.allclose(batch.positions[0, -1], batch.positions[1, -1])
    with pytest.raises(upm.ShapeError, match="starts"):
        upm.simulate_batch(motions, starts[0], starts=starts[:2], **kw)


@pytest.mark.slow
def test_the_planner_policy_assembles_a_small_shape_where_random_actions_do_not():
    from upm.envs import PlannerPolicy, RandomPolicy

    results = {}
    for name in ("planner", "random"):
        env = gym.make("upm/Shape-v0", n_parts=3, max_plate_time=40.0)
        obs, info = env.reset(seed=0)
        start = info["cost"]
        act = PlannerPolicy(env) if name == "planner" else RandomPolicy(env, seed=0)
        for _ in range(400):
            obs, _, term, trunc, info = env.step(act(obs))
            if term or trunc:
                break
        results[name] = (info["is_success"], info["cost"], start)
    assert results["planner"][0] and results["planner"][1] < 0.1 * results["planner"][2]
    assert not results["random"][0]
    with pytest.raises(upm.ParameterError, match="action_space"):
        PlannerPolicy(gym.make("upm/Goto-v0", action_space="library"))


@pytest.mark.slow
def test_the_planner_policy_brings_parts_to_their_goals():
    # its planner looks ahead through no long pulse the env cannot play: with the look-ahead of
    # 1 s rotations it played small short jets for the whole 40 s of this episode
    from upm.envs import PlannerPolicy

    env = gym.make("upm/Goto-v0", n_parts=3, max_plate_time=40.0)
    obs, info = env.reset(seed=0)
    act = PlannerPolicy(env)
    assert act.planner.macros is None
    for _ in range(400):
        obs, _, term, trunc, info = env.step(act(obs))
        if term or trunc:
            break
    assert term and info["is_success"] and info["lost"] == 0
    assert info["plate_time"] < 40.0
