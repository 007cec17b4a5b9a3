"""Benchmark: upm's Gymnasium environments (issue 59), their speed beside two peers in one run, and
the random policy's results as a baseline.

Run with ``python bench/envs.py [--quick] [--envs N] [--seconds S]`` (needs ``upm[bench]``:
gymnasium and mujoco). Throughput is measured by ``gymnasium.utils.performance.
benchmark_vector_step`` (env-steps per second) with random pulse actions on ``upm/Goto-v0``,
8 point parts:

* ours: the native vector env (``vectorization_mode="vector_entry_point"``), every plate of one
  drive frequency and on-time in one batched simulator call on every core;
* peer 1: ``gymnasium.vector.SyncVectorEnv`` over the same single env (how a user vectorises an
  env that has no vector entry point);
* peer 2: the same task in MuJoCo (``bench/mujoco_plate.py``'s driven plate, 8 boxes): each step
  plays the same pulse by prescribing the plate's velocity every step at the same ``dt``, then
  lets the parts come to rest as long as upm's step says they slide (``benchmark_step``).

Memory per env: the vector env's arrays (its episodes' state) over ``num_envs``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

import gymnasium as gym
from gymnasium.utils.performance import benchmark_step, benchmark_vector_step

import upm
import upm.envs
from upm.envs.world import DT_FACTOR


class MujocoGoto(gym.Env[np.ndarray, np.ndarray]):
    """The engine peer: Goto with 8 parts on MuJoCo's driven plate, the same pulse actions."""

    def __init__(self, n_parts: int = 8) -> None:
        from mujoco_plate import plate_world

        self.n = n_parts
        self.actions = upm.envs.PulseActions(upm.DriveLimits())
        self.half = upm.DriveLimits().size / 2
        boxes = "".join(
            f'<body pos="{0.02 * i - 0.07} 0 0.016"><freejoint/><geom type="box" size="0.005 0.005 0.005" '
            'mass="0.005"/></body>'
            for i in range(n_parts)
        )
        self.dt = 1 / (DT_FACTOR * 2 * 35.0)
        self.model, self.data = plate_world(boxes, half=self.half, dt=self.dt, mu=0.3, g=9.81, settle=50)
        self.observation_space = gym.spaces.Box(-2, 2, (2 * n_parts,), np.float32)
        self.action_space = gym.spaces.Box(-1, 1, (7,), np.float32)

    def _obs(self) -> np.ndarray:
        return (self.data.qpos[3:].reshape(self.n, 7)[:, :2] / self.half).astype(np.float32).ravel()

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        return self._obs(), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        from mujoco_plate import drive

        pulse = self.actions.pulse(action)
        on = pulse.on_time
        t = np.arange(int(on / self.dt)) * self.dt
        u = pulse.motion(rest=False).velocity(t) if pulse.kind != "rest" else np.zeros((len(t), 3))
        coast = np.zeros((int(1.05 * on / self.dt), 3))  # the parts slide to rest on the still plate
        drive(self.model, self.data, np.vstack([u, coast]))
        return self._obs(), 0.0, False, False, {}


def baseline(policy: str, env_id: str, episodes: int, seed: int, **kw: Any) -> tuple[float, float]:
    """Success rate and median plate time [s] of ``policy`` (``random``: uniformly random pulse
    actions; ``planner``: :class:`upm.envs.PlannerPolicy`) over ``episodes`` seeds."""
    from upm.envs.policies import PlannerPolicy, RandomPolicy

    env = gym.make(env_id, **kw)
    act = RandomPolicy(env, seed) if policy == "random" else PlannerPolicy(env)
    wins, times = 0, []
    for k in range(episodes):
        obs, _ = env.reset(seed=seed + k)
        while True:
            obs, _, term, trunc, info = env.step(act(obs))
            if term or trunc:
                wins += int(info["is_success"])
                times.append(info["plate_time"])
                break
    return wins / episodes, float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="short runs (a smoke test)")
    ap.add_argument("--envs", type=int, default=1024, help="environments in the vector env")
    ap.add_argument("--seconds", type=float, default=5.0, help="seconds per throughput measurement")
    args = ap.parse_args()
    secs = 1 if args.quick else args.seconds
    n = 64 if args.quick else args.envs
    build = upm.build_info()
    print(f"CPU: {build['cpu']}; upm {upm.__version__}, step build {build['simd']}; "
          f"gymnasium {gym.__version__}")  # fmt: skip
    kw = {"n_parts": 8, "max_plate_time": 60.0}
    ours = gym.make_vec("upm/Goto-v0", num_envs=n, vectorization_mode="vector_entry_point", **kw)
    ours_rate = benchmark_vector_step(ours, target_duration=int(max(secs, 1)), seed=0)
    state = ours.unwrapped._e
    per_env = sum(a.nbytes for a in (state.positions, state.goals, state.time, state.cost)) / n
    sync_n = min(n, 64)
    sync = gym.make_vec("upm/Goto-v0", num_envs=sync_n, vectorization_mode="sync", **kw)
    sync_rate = benchmark_vector_step(sync, target_duration=int(max(secs, 1)), seed=0)
    print(f"upm/Goto-v0, 8 points, random pulse actions ({n} envs; SyncVectorEnv {sync_n}):")
    print(f"  ours (vector entry point)  {ours_rate:12,.0f} env-steps/s   ({per_env:.0f} B of state an env "
          f"beside the parts' {16 * 8} B)")  # fmt: skip
    print(
        f"  SyncVectorEnv (peer)       {sync_rate:12,.0f} env-steps/s   "
        f"ours / peer = {ours_rate / sync_rate:.1f}x"
    )
    try:
        import mujoco  # noqa: F401
    except ImportError:
        print("  MuJoCo peer: not installed (pip install 'upm[bench]')")
    else:
        peer = MujocoGoto()
        peer.action_space.seed(0)
        mj_rate = benchmark_step(peer, target_duration=int(max(secs, 1)), seed=0)
        print(
            f"  MuJoCo Goto (engine peer)  {mj_rate:12,.1f} env-steps/s   "
            f"ours / peer = {ours_rate / mj_rate:,.0f}x"
        )
    episodes = 1 if args.quick else 5
    print(f"baselines, {episodes} seeds, 60 s of plate time at most:")
    tasks = (
        ("upm/Goto-v0", {"n_parts": 4}),
        ("upm/Sort-v0", {"n_parts": 8}),
        ("upm/Shape-v0", {"n_parts": 6}),
        ("upm/Orient-v0", {"n_parts": 1}),
        ("upm/Orient-v0", {"n_parts": 3}),
    )
    for policy in ("random", "planner"):
        for env_id, extra in tasks:
            t0 = time.perf_counter()
            win, plate = baseline(policy, env_id, episodes, 0, **{**kw, **extra})
            wall = time.perf_counter() - t0
            print(f"  {policy:8s} {env_id:14s} {extra['n_parts']} parts: success {win:4.0%}, "
                  f"median plate time {plate:5.1f} s ({wall:.0f} s of wall time)")  # fmt: skip


if __name__ == "__main__":
    main()
