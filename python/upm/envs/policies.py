"""Baseline policies in the environments' own action space: uniformly random actions, and the
predictive planner choosing among the actions (:class:`PlannerPolicy`)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._errors import ParameterError
from ..control._steps import PointTargets
from ..control.shape import ShapeTask
from ..control.state import State
from ..plan import PredictivePlanner
from ..plan.orient import PosePlanner
from .actions import ACTION_SIZE, library
from .env import PlateEnv
from .world import Task

__all__ = ["PlannerPolicy", "RandomPolicy"]

FloatArray = NDArray[np.float64]


class RandomPolicy:
    """Uniformly random actions of ``env``'s action space (seeded)."""

    def __init__(self, env: Any, seed: int | None = None) -> None:
        self.space = env.action_space
        self.space.seed(seed)

    def __call__(self, obs: Any) -> Any:
        return self.space.sample()


class _Goals(PointTargets):
    """Each part to its own fixed goal (the Goto env's task as the planner scores it)."""

    def __init__(self, goals: FloatArray, tolerance: float) -> None:
        self.goals, self.tolerance = goals, tolerance

    def targets(self, state: Any) -> FloatArray:
        return self.goals

    def steps(self, state: Any) -> FloatArray:
        out: FloatArray = self.goals - state.positions
        return out

    def done(self, state: Any) -> bool:
        e = self.errors(state)
        return bool(np.all(e <= self.tolerance))


class PlannerPolicy:
    """:class:`upm.plan.PredictivePlanner` as a policy of a :class:`PlateEnv`: each step, it
    predicts every candidate action (the motion library, and pulse actions at each part: jets
    toward its target and rotations about it, at two amplitudes) with the planner's model and
    plays the one with the best predicted gain per second of plate time (pairs of actions
    included; no look-ahead through the long pulses the env cannot play). It reads the env's
    exact state, not the float32 observation.

    For ``upm/Orient-v0`` the planner is :class:`upm.plan.orient.PosePlanner` (its rollouts of
    the polygons' exact friction and its pose score), over the same candidate actions."""

    def __init__(self, env: Any, planner: PredictivePlanner | PosePlanner | None = None) -> None:
        plate = getattr(env, "unwrapped", env)
        if not isinstance(plate, PlateEnv):
            raise ParameterError(f"env must be a upm.envs.PlateEnv (or wrap one); got {type(plate).__name__}")
        self.env = plate
        e = plate._e
        if e.library is not None:
            raise ParameterError("PlannerPolicy plays pulse actions: make the env with action_space='pulse'")
        o = e.o
        self.planner: Any = planner
        if planner is None and o["polygon"] is not None:
            self.planner = PosePlanner(o["polygon"], e.limits, mu=o["mu"], mu_s=o["mu_s"])
        elif planner is None:
            radius = o["part_radius"]
            # no look-ahead through long pulses: the env's actions last at most 0.5 s, and a first
            # pulse scored as if a 1 s rotation followed (one it can never play) favours small
            # short jets forever (upm/Goto-v0, 4 parts: 1 of 5 done in 60 s with it, 5 of 5 without)
            self.planner = PredictivePlanner(
                e.limits, mu=o["mu"], mu_s=o["mu_s"], part_radius=radius, lookahead=None
            )
        want = PosePlanner if o["polygon"] is not None else PredictivePlanner
        if not isinstance(self.planner, want):
            raise ParameterError(f"planner must be a upm.plan.{want.__name__} for this env; got {planner!r}")
        self.library = library()
        self._shape: ShapeTask | None = None

    def _task(self) -> tuple[Any, State]:
        e = self.env._e
        task = e.task
        assert isinstance(task, Task)  # (point parts: orientations go through _poses)
        q = e.positions[0]
        ids = np.nonzero(np.all(np.isfinite(q), axis=1))[0]
        labels = tuple(task.state.labels[i] for i in ids) if task.sort is not None else ("penny",) * len(ids)
        state = State(0, float(e.time[0]), ids.astype(np.int64), q[ids], labels, 0.0)
        if task.sort is not None:
            return task.sort, state
        if task.name == "goto":
            return _Goals(e.goals[0][ids], task.tolerance), state
        if self._shape is None:
            assert task.shape_points is not None
            self._shape = ShapeTask(task.shape_points, tolerance=task.tolerance)
        return self._shape, state

    def candidates(self, state: State, task: Any) -> FloatArray:
        """Candidate actions ``(K, 7)``: the library, then at each part jets toward where the
        task wants it (and 35 degrees either side) and rotations about it, full and half
        amplitude, short and middle on-time."""
        half = self.env._e.half
        out = [self.library]
        want = np.asarray(task.steps(state), dtype=float)
        for p, w in zip(state.positions, want, strict=True):
            centre = p / half  # a jet's centre spans the plate
            angle = np.arctan2(w[1], w[0]) if np.all(np.isfinite(w)) and np.hypot(*w) > 0 else 0.0
            for amp in (1.0, 0.0):  # full and half amplitude
                for on in (-1.0, 0.0):
                    for turn in (0.0, -0.61, 0.61):
                        out.append(np.array([[1.0, *centre, (angle + turn) / np.pi, amp, 1.0, on]]))
                    for sense in (1.0, -1.0):
                        out.append(np.array([[0.0, *(p / (1.5 * half)), sense, amp, 0.0, on]]))
        acts = np.concatenate(out)
        acts[:, 3] = (acts[:, 3] + 1) % 2 - 1  # angles into [-1, 1)
        return np.clip(acts, -1, 1)

    def _poses(self) -> tuple[Any, State]:
        """The orientation's state as the candidates read it: each part's target as its step."""
        e = self.env._e
        q = e.positions[0]
        ids = np.nonzero(np.all(np.isfinite(q), axis=1))[0]
        state = State(0, float(e.time[0]), ids.astype(np.int64), q[ids, :2], ("part",) * len(ids), 0.0)
        return _Goals(e.goals[0][ids, :2], e.task.tolerance), state

    def __call__(self, obs: Any = None) -> NDArray[np.float32]:
        orient = isinstance(self.planner, PosePlanner)
        task, state = self._poses() if orient else self._task()
        acts = self.candidates(state, task)
        decode = self.env._e.plates.actions.pulse
        pulses = [decode(a) for a in acts]
        moving = [k for k, p in enumerate(pulses) if p.kind != "rest"]
        if orient:
            best = self._best_pose([pulses[k] for k in moving], state.ids)
        else:
            best, _, _ = self.planner.choose(task, state, [pulses[k] for k in moving], state.ids)
        if best is None:  # nothing gains: the weakest short pulse (a near rest)
            return np.array([-1, 0, 0, 0, -1, 0, -1], dtype=np.float32)
        out: NDArray[np.float32] = acts[moving[best]].astype(np.float32).reshape(ACTION_SIZE)
        return out

    def _best_pose(self, pulses: list[Any], ids: NDArray[np.int64]) -> int | None:
        """The pulse whose predicted poses score best per second of plate time, or None when
        none lowers the pose score."""
        if not pulses or not len(ids):
            return None
        e = self.env._e
        poses, targets = e.positions[0][ids], e.goals[0][ids]
        now = float(self.planner.score(poses, targets))
        after = self.planner.score(self.planner.predict(poses, pulses), targets)
        gain = (now - after) / np.array([p.duration for p in pulses])
        best = int(np.argmax(gain))
        return best if gain[best] > 0 else None
