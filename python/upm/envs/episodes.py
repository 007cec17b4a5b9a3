"""``B`` episodes stepped together: what :class:`~upm.envs.PlateEnv` (``B = 1``) and
:class:`~upm.envs.PlateVectorEnv` share, so that their numbers agree bit for bit."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._arrays import integer, real
from .._errors import ParameterError
from ..plate.drive import DriveLimits
from .actions import ACTION_SIZE, library
from .orient import OrientTask, polygon_of
from .world import TASKS, Plates, Task

__all__ = ["Episodes", "options"]

FloatArray = NDArray[np.float64]
ACTIONS = ("pulse", "library")


def options(
    task: str = "goto",
    *,
    n_parts: int = 8,
    part_radius: float | None = None,
    mu: float = 0.3,
    mu_s: float | None = None,
    limits: DriveLimits | None = None,
    action_space: str = "pulse",
    contacts: bool = False,
    max_plate_time: float = 60.0,
    tolerance: float = 0.0037,
    lost_penalty: float = 1.0,
    shape: str = "ring",
    polygon: Any = "rectangle",
    angle_tolerance: float = 5.0,
) -> dict[str, Any]:
    """The environments' keyword arguments, checked (`ParameterError` naming the first bad one)."""
    if task not in TASKS:
        raise ParameterError(f"task must be one of {TASKS}; got {task!r}")
    n_parts = integer("n_parts", n_parts, low=1, high=256)
    outline = polygon_of(polygon) if task == "orient" else None
    if task == "orient" and contacts:
        raise ParameterError(
            "contacts=True is not available for task 'orient' (polygons slide without contacts)"
        )
    if task == "sort" and n_parts < 2:
        raise ParameterError(f"n_parts must be >= 2 for a sort (a part of each colour); got {n_parts}")
    radius = (
        None if part_radius is None else real("part_radius", part_radius, low=0.0, high=0.05, low_open=True)
    )
    if contacts not in (True, False):
        raise ParameterError(f"contacts must be True or False; got {contacts!r}")
    if contacts and radius is None:
        raise ParameterError("part_radius must be given with contacts=True (points have no size to collide)")
    if limits is None:
        limits = DriveLimits()
    if not isinstance(limits, DriveLimits):
        raise ParameterError(f"limits must be a upm.DriveLimits; got {type(limits).__name__}")
    if action_space not in ACTIONS:
        raise ParameterError(f"action_space must be one of {ACTIONS}; got {action_space!r}")
    friction = real("mu", mu, low=0.0, high=2.0, low_open=True)
    static = None if mu_s is None else real("mu_s", mu_s, low=friction, high=2.0)
    return {
        "task": task, "n_parts": n_parts, "part_radius": radius, "mu": friction, "mu_s": static,
        "limits": limits, "action_space": action_space, "contacts": bool(contacts),
        "max_plate_time": real("max_plate_time", max_plate_time, low=0.0, high=1e6, low_open=True),
        "tolerance": real("tolerance", tolerance, low=0.0, high=0.1, low_open=True),
        "lost_penalty": real("lost_penalty", lost_penalty, low=0.0, high=1e6), "shape": shape,
        "polygon": outline,
        "angle_tolerance": real("angle_tolerance", angle_tolerance, low=0.0, high=180.0, low_open=True),
    }  # fmt: skip


class Episodes:
    """``n`` episodes of one environment family (``options``' keywords)."""

    def __init__(self, n: int, **kwargs: Any) -> None:
        o = options(**kwargs)
        self.o = o
        self.n, self.m = n, o["n_parts"]
        self.limits: DriveLimits = o["limits"]
        self.half = self.limits.size / 2
        self.task: Task | OrientTask
        if o["task"] == "orient":
            self.task = OrientTask(self.m, self.limits, o["polygon"], o["tolerance"], o["angle_tolerance"])
        else:
            self.task = Task(o["task"], self.m, self.limits, o["part_radius"], o["tolerance"], o["shape"])
        self.plates = Plates(self.limits, o["mu"], o["mu_s"], o["part_radius"], o["contacts"], o["polygon"])
        self.library = library() if o["action_space"] == "library" else None
        dim = 3 if o["polygon"] is not None else 2  # polygons' poses: x, y and the angle
        self.positions = np.zeros((n, self.m, dim))
        self.goals = np.zeros((n, self.m, dim))
        self.time = np.zeros(n)
        self.cost = np.zeros(n)
        self.obs_size = (9 if dim == 3 else 5) * self.m

    def reset(self, rows: NDArray[np.int64], rngs: list[np.random.Generator]) -> None:
        """New layouts for ``rows``, each drawn from its own generator."""
        for r in rows:
            self.positions[r], self.goals[r] = self.task.layout(rngs[r])
        self.time[rows] = 0.0
        self.cost[rows] = self.task.cost(self.positions[rows], self.goals[rows])

    def actions(self, action: Any) -> FloatArray:
        """Pulse actions ``(n, 7)`` from the env's actions (library indices are looked up)."""
        if self.library is None:
            return np.asarray(action, dtype=np.float64).reshape(self.n, ACTION_SIZE)
        k = np.asarray(action).reshape(self.n)
        if not np.issubdtype(k.dtype, np.integer) or np.any((k < 0) | (k >= len(self.library))):
            raise ParameterError(
                f"action must be library indices in [0, {len(self.library)}); got {action!r}"
            )
        out: FloatArray = self.library[k]
        return out

    def step(self, action: Any, rows: NDArray[np.int64]) -> dict[str, FloatArray]:
        """Play ``rows``' actions: rewards, terminations, truncations and infos of those rows."""
        pulses = self.plates.actions.decode(self.actions(action)[rows])
        before = self.positions[rows]
        after, duration = self.plates.play(before, pulses)
        lost = np.sum(np.all(np.isfinite(before), axis=2) & ~np.all(np.isfinite(after), axis=2), axis=1)
        cost = self.task.cost(after, self.goals[rows])
        reward = (self.cost[rows] - cost) / duration - self.o["lost_penalty"] * lost
        self.positions[rows], self.cost[rows] = after, cost
        self.time[rows] += duration
        fallen = np.sum(~np.all(np.isfinite(after), axis=2), axis=1)
        done = self.task.done(after, self.goals[rows])
        # every part lost: nothing left to do (terminated, unsolved)
        over = done | (fallen == self.m)
        return {
            "reward": reward, "terminated": over,
            "truncated": ~over & (self.time[rows] >= self.o["max_plate_time"]),
            "plate_time": self.time[rows].copy(), "duration": duration, "cost": cost, "lost": fallen,
            "is_success": done,
        }  # fmt: skip

    def observe(self) -> NDArray[np.float32]:
        """Observations ``(n, 5 M)``: positions and targets over half the plate's side (a lost
        part's 0), then 1 for each part on the plate and 0 for a lost one (polygons' ``(n, 9
        M)``: :meth:`upm.envs.orient.OrientTask.observe`)."""
        q = self.positions
        if isinstance(self.task, OrientTask):
            poses = np.clip(self.task.observe(q, self.goals), -2.0, 2.0)
            return poses.astype(np.float32)
        here = np.all(np.isfinite(q), axis=2)
        targets = self.task.targets(q, self.goals)
        scale = 1.0 if self.task.name == "sort" else 1.0 / self.half
        obs = np.concatenate(
            [np.nan_to_num(q / self.half).reshape(self.n, -1),
             np.nan_to_num(targets * scale).reshape(self.n, -1), here.astype(np.float64)], axis=1,
        )  # fmt: skip
        out: NDArray[np.float32] = np.clip(obs, -2.0, 2.0).astype(np.float32)
        return out
