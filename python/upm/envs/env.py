"""The Gymnasium environments: one plate (:class:`PlateEnv`) and ``N`` plates stepped in one batched
simulator call (:class:`PlateVectorEnv`). See docs/envs.md."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from .._arrays import integer
from .._errors import ParameterError
from .actions import ACTION_SIZE
from .episodes import Episodes
from .world import Task

__all__ = ["PlateEnv", "PlateVectorEnv"]

RENDER_MODES = ["rgb_array"]


def _spaces(e: Episodes) -> tuple[spaces.Box, spaces.Space[Any]]:
    obs = spaces.Box(-2.0, 2.0, (e.obs_size,), np.float32)
    if e.library is None:
        return obs, spaces.Box(-1.0, 1.0, (ACTION_SIZE,), np.float32)
    return obs, spaces.Discrete(len(e.library))


def _render_mode(mode: str | None) -> str | None:
    if mode is not None and mode not in RENDER_MODES:
        raise ParameterError(f"render_mode must be None or one of {RENDER_MODES}; got {mode!r}")
    return mode


def _frame(e: Episodes, row: int) -> NDArray[np.uint8]:
    """The synthetic camera's frame of plate ``row`` (RGB): red and blue chips for a sort,
    polygons for an orientation, pennies otherwise; lost parts are not drawn."""
    from ..vision.synthetic import Camera, render

    q = e.positions[row]
    here = np.all(np.isfinite(q), axis=1)
    camera = Camera(plate_size=e.limits.size)
    polygon = e.o["polygon"]
    if polygon is not None:  # drawn about their centroids
        centres = q[here, :2] + polygon.centroid_offset(q[here, 2])
        outline = polygon.vertices - polygon.centroid
        frame = render(camera, centres, "part", angles=q[here, 2], shapes={"part": outline},
                       colors={"part": (40, 160, 230)}, rng=0)  # fmt: skip
    else:
        task = e.task
        labels = ["penny"] * e.m
        if isinstance(task, Task) and task.name == "sort":
            labels = ["red" if s < 0 else "blue" for s in task.sides]
        radius = e.o["part_radius"] or 0.0095
        seen = [lab for lab, h in zip(labels, here, strict=True) if h]
        frame = render(camera, q[here], seen, radius=radius, rng=0)
    out: NDArray[np.uint8] = np.ascontiguousarray(frame.image[..., ::-1])
    return out


class PlateEnv(gym.Env[NDArray[np.float32], Any]):
    """One vibrating plate and its parts (``upm/Goto-v0``, ``upm/Sort-v0``, ``upm/Shape-v0``,
    ``upm/Orient-v0``).

    Keywords (all checked; `ParameterError` naming a bad one): ``task`` (``goto``, ``sort``,
    ``shape``, ``orient``), ``n_parts`` (8; Orient-v0 1), ``part_radius`` [m] (None: points),
    ``mu`` (0.3), ``mu_s``,
    ``limits`` (a :class:`upm.DriveLimits`), ``action_space`` (``"pulse"``: a ``Box`` of 7 numbers,
    :mod:`upm.envs.actions`; ``"library"``: ``Discrete`` over a fixed motion library),
    ``contacts`` (rapier; needs ``part_radius``), ``max_plate_time`` [s] (60: truncated after it),
    ``tolerance`` [m] (3.7 mm), ``lost_penalty`` (1 per part lost), ``shape`` (``ring``, ``grid``);
    for ``orient``, ``polygon`` (a :class:`upm.Polygon` or ``"triangle"``, ``"square"``,
    ``"rectangle"`` (default), ``"hexagon"``) and ``angle_tolerance`` [deg] (5).

    Reward: the decrease of the task's cost [m] per second of plate time, less ``lost_penalty``
    per part lost. Terminated when the task is done (or every part is lost).
    """

    metadata: dict[str, Any] = {"render_modes": RENDER_MODES, "render_fps": 4}  # noqa: RUF012 (gymnasium declares it an instance attribute)

    def __init__(self, task: str = "goto", render_mode: str | None = None, **kwargs: Any) -> None:
        self._e = Episodes(1, task=task, **kwargs)
        self.observation_space, self.action_space = _spaces(self._e)  # type: ignore[assignment]
        self.render_mode = _render_mode(render_mode)
        self._rows = np.zeros(1, dtype=np.int64)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        self._e.reset(self._rows, [self.np_random])
        return self._e.observe()[0], {"plate_time": 0.0, "cost": float(self._e.cost[0])}

    def step(self, action: Any) -> tuple[NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        out = self._e.step(np.asarray(action)[None], self._rows)
        info = {k: (v[0].item() if hasattr(v[0], "item") else v[0]) for k, v in out.items()
                if k not in ("reward", "terminated", "truncated")}  # fmt: skip
        obs = self._e.observe()[0]
        return obs, float(out["reward"][0]), bool(out["terminated"][0]), bool(out["truncated"][0]), info

    def render(self) -> NDArray[np.uint8] | None:
        return None if self.render_mode is None else _frame(self._e, 0)

    @property
    def positions(self) -> NDArray[np.float64]:
        """The parts [m], ``(M, 2)`` (polygons' poses ``(M, 3)``, the angle [rad]; NaN: lost)."""
        out: NDArray[np.float64] = self._e.positions[0].copy()
        return out

    @property
    def plate_time(self) -> float:
        """Plate time of the episode so far [s]."""
        return float(self._e.time[0])

    def pulse(self, action: Any) -> Any:
        """What ``action`` plays, as a :class:`upm.Pulse` (library indices looked up)."""
        a = self._e.actions(np.asarray(action)[None])[0]
        return self._e.plates.actions.pulse(a)


class PlateVectorEnv(gym.vector.VectorEnv[NDArray[np.float32], Any, Any]):
    """``num_envs`` plates stepped together: every pulse of one frequency and on-time in one
    batched simulator call, with the GIL released (``gymnasium.make_vec(id, num_envs=N,
    vectorization_mode="vector_entry_point")``). The same numbers as ``num_envs``
    :class:`PlateEnv` seeded ``seed + i``. ``autoreset_mode``: ``NEXT_STEP`` (default) or
    ``DISABLED`` (then ``reset(options={"reset_mask": mask})``)."""

    metadata: dict[str, Any] = {  # noqa: RUF012 (gymnasium declares it an instance attribute)
        "render_modes": RENDER_MODES,
        "render_fps": 4,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs: int = 1,
        task: str = "goto",
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **kwargs: Any,
    ) -> None:
        names = {"nextstep": AutoresetMode.NEXT_STEP, "disabled": AutoresetMode.DISABLED}
        key = autoreset_mode.value if isinstance(autoreset_mode, AutoresetMode) else autoreset_mode
        mode = names.get(str(key).replace("_", "").lower()) if isinstance(key, str) else None
        if mode is None:
            raise ParameterError(f"autoreset_mode must be NEXT_STEP or DISABLED; got {autoreset_mode!r}")
        self.metadata = {**self.metadata, "autoreset_mode": mode}
        self.num_envs = integer("num_envs", num_envs, low=1, high=2**20)
        self._e = Episodes(self.num_envs, task=task, **kwargs)
        self.single_observation_space, self.single_action_space = _spaces(self._e)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.render_mode = _render_mode(render_mode)
        self._rngs: list[np.random.Generator] = []
        self._pending = np.zeros(self.num_envs, dtype=bool)  # to reset on the next step

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(n)]
        elif isinstance(seed, (list, tuple)) and len(seed) == n:
            seeds = list(seed)
        else:
            raise ParameterError(f"seed must be None, an int or a list of {n} seeds; got {seed!r}")
        mask = np.ones(n, dtype=bool)
        if options and "reset_mask" in options:
            mask = np.asarray(options["reset_mask"], dtype=bool)
            if mask.shape != (n,):
                raise ParameterError(f"reset_mask must have shape ({n},); got {mask.shape}")
        if not self._rngs:
            self._rngs = [seeding.np_random(s)[0] for s in seeds]
        else:
            for i in np.nonzero(mask)[0]:
                if seeds[i] is not None:
                    self._rngs[i] = seeding.np_random(seeds[i])[0]
        rows = np.nonzero(mask)[0]
        self._e.reset(rows, self._rngs)
        self._pending[rows] = False
        info = {"plate_time": self._e.time.copy(), "_plate_time": mask.copy()}
        return self._e.observe(), info

    def step(
        self, actions: Any
    ) -> tuple[
        NDArray[np.float32], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]
    ]:
        if not self._rngs:
            raise ParameterError("reset the environments before the first step")
        n = self.num_envs
        reward = np.zeros(n)
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        info: dict[str, Any] = {}
        restart = np.nonzero(self._pending)[0]
        if len(restart):
            self._e.reset(restart, self._rngs)
        rows = np.nonzero(~self._pending)[0]
        if len(rows):
            out = self._e.step(actions, rows)
            reward[rows], terminated[rows], truncated[rows] = (
                out["reward"],
                out["terminated"],
                out["truncated"],
            )
            stepped = ~self._pending
            for k, v in out.items():
                if k in ("reward", "terminated", "truncated"):
                    continue
                full = np.zeros(n, dtype=np.asarray(v).dtype)
                full[rows] = v
                info[k], info[f"_{k}"] = full, stepped.copy()
        if self.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP:
            self._pending = terminated | truncated
        return self._e.observe(), reward, terminated, truncated, info

    def render(self) -> tuple[NDArray[np.uint8], ...] | None:
        if self.render_mode is None:
            return None
        return tuple(_frame(self._e, i) for i in range(self.num_envs))

    @property
    def positions(self) -> NDArray[np.float64]:
        """Every plate's parts [m], ``(N, M, 2)`` (NaN: lost)."""
        return self._e.positions.copy()
