"""Parts along paths: :class:`TrajectoryTask`, a PD controller per part on a reference that
moves along a polyline (thesis 4.3.1, 6.3)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._errors import ParameterError, ShapeError
from ._steps import clip, distance_sum, points, positions_of
from .state import Slots, State

__all__ = ["TrajectoryTask"]

FloatArray = NDArray[np.float64]


def _polyline(name: str, path: ArrayLike, closed: bool) -> tuple[FloatArray, FloatArray]:
    p = points(name, path)
    if closed and np.any(p[0] != p[-1]):
        p = np.vstack([p, p[:1]])
    if len(p) < 2:
        raise ShapeError(f"{name} needs at least 2 points")
    seg = np.hypot(*np.diff(p, axis=0).T)
    if np.any(seg <= 0):
        raise ParameterError(f"{name} has repeated consecutive points")
    return p, np.concatenate([[0.0], np.cumsum(seg)])


def _along(p: FloatArray, s: FloatArray, at: FloatArray) -> FloatArray:
    return np.stack([np.interp(at, s, p[:, 0]), np.interp(at, s, p[:, 1])], axis=-1)


class TrajectoryTask:
    """Parts follow polylines at a given speed, each under a PD controller (thesis 4.3.1, 6.3).

    Parameters
    ----------
    paths : sequence of (K, 2) array_like
        One polyline per part [m]; or a single path shared by ``count`` parts spaced equally
        along it (``equidistant``; the figure-eight of the bow-tie experiment).
    speed : float
        Speed of the references along the paths [m/s of plate time].
    kp, kd : float
        Proportional and derivative gains of each part's controller (per cycle).
    closed : bool
        The paths are loops; run ``laps`` times around.
    equidistant : bool
        Parts share ``paths[0]``, ``count`` of them, kept ``L / count`` apart along it.
    hold : float
        When a part lags its reference by more than this [m], every reference waits (the parts keep
        their spacing and nobody is left behind).
    max_step : float
        Longest step asked for [m].
    tolerance : float
        Done when the references have finished and every part is within this of its end [m].
    """

    def __init__(
        self,
        paths: Sequence[ArrayLike],
        speed: float,
        *,
        kp: float = 0.7,
        kd: float = 0.2,
        closed: bool = False,
        laps: float = 1.0,
        equidistant: bool = False,
        count: int | None = None,
        hold: float = 0.015,
        max_step: float = 0.02,
        tolerance: float = 0.005,
    ) -> None:
        if not (math.isfinite(speed) and speed > 0):
            raise ParameterError(f"speed must be finite and > 0 [m/s]; got {speed!r}")
        self.speed, self.kp, self.kd, self.closed, self.laps = (
            float(speed),
            float(kp),
            float(kd),
            closed,
            float(laps),
        )
        self.hold, self.max_step, self.tolerance = float(hold), float(max_step), float(tolerance)
        if equidistant:
            if count is None or count < 1:
                raise ParameterError("equidistant needs count >= 1 (how many parts share the path)")
            p, s = _polyline("paths[0]", paths[0], closed)
            self.paths = [(p, s)] * count
            self.offsets = -np.arange(count) * s[-1] / count
        else:
            self.paths = [_polyline(f"paths[{k}]", q, closed) for k, q in enumerate(paths)]
            self.offsets = np.zeros(len(self.paths))
        if not self.paths:
            raise ParameterError("paths must hold at least one path")
        self.length = float(self.paths[0][1][-1])
        self.progress = 0.0  # arc length covered by the references [m]
        self.slots = Slots(np.array([self.reference(k, 0.0) for k in range(len(self.paths))]))
        self._previous: dict[int, FloatArray] = {}
        self._time = 0.0
        self.waited = 0.0

    def reference(self, k: int, progress: float) -> FloatArray:
        """Where the reference of slot ``k`` is after ``progress`` [m] along its path."""
        p, s = self.paths[k]
        at = progress + self.offsets[k]
        at = at % s[-1] if self.closed else min(max(at, 0.0), s[-1])
        return _along(p, s, np.array(at))

    @property
    def end(self) -> float:
        return self.laps * self.length if self.closed else self.length

    def _refs(self, state: State, progress: float) -> FloatArray:
        slot = self.slots.bind(state)
        out = np.full_like(state.positions, np.nan)
        for k, j in enumerate(slot):
            if j >= 0:
                out[k] = self.reference(int(j), progress)
        return out

    def targets(self, state: State) -> FloatArray:
        """Where each tracked part's reference is now [m] (NaN: not bound to a path)."""
        return self._refs(state, self.progress)

    def lines(self) -> list[FloatArray]:
        """The paths [m]."""
        unique = {id(p): p for p, _ in self.paths}
        return list(unique.values())

    def errors(self, state: State) -> FloatArray:
        d = self._refs(state, self.progress) - state.positions
        out: FloatArray = np.hypot(d[:, 0], d[:, 1])
        return out

    def cost(self, state: State, positions: FloatArray | None = None, elapsed: ArrayLike = 0.0) -> FloatArray:
        """Sum of the parts' distances [m] to where their references will be after ``elapsed``
        more seconds (the references wait while a part lags more than ``hold``)."""
        q = positions_of(state, positions)
        el = np.asarray(elapsed, dtype=np.float64)
        lag = self.errors(state)
        wait = bool(np.nanmax(lag, initial=0.0) > self.hold)
        ahead = np.minimum(self.progress + (0.0 if wait else self.speed) * el, self.end)
        slot = self.slots.bind(state)
        flat = ahead.reshape(-1)
        refs = np.full((len(flat), len(slot), 2), np.nan)
        for k, j in enumerate(slot):
            if j >= 0:
                p, s_ = self.paths[int(j)]
                at = flat + self.offsets[int(j)]
                at = at % s_[-1] if self.closed else np.clip(at, 0.0, s_[-1])
                refs[:, k] = _along(p, s_, at)
        refs = refs.reshape(*ahead.shape, len(slot), 2) if ahead.ndim else refs[0]
        return distance_sum(q, refs)

    def steps(self, state: State) -> FloatArray:
        dt = state.time - self._time
        self._time = state.time
        lag = self.errors(state)
        holding = bool(np.nanmax(lag, initial=0.0) > self.hold)
        if state.cycle > 0:
            if holding:
                self.waited += dt
            else:
                self.progress = min(self.progress + self.speed * dt, self.end)
        # feed forward: where the reference will be after a cycle like the last one (none while
        # the references wait for a lagging part)
        ahead = (
            self.progress
            if holding
            else min(self.progress + self.speed * (state.last_cycle or 0.0), self.end)
        )
        e = self._refs(state, self.progress) - state.positions
        forward = self._refs(state, ahead) - self._refs(state, self.progress)
        out = np.zeros_like(state.positions)
        for k, i in enumerate(state.ids):
            if not np.all(np.isfinite(e[k])):
                continue
            prev = self._previous.get(int(i), e[k])
            out[k] = forward[k] + self.kp * e[k] + self.kd * (e[k] - prev)
            self._previous[int(i)] = e[k]
        return clip(out, self.max_step)

    def done(self, state: State) -> bool:
        if self.progress < self.end:
            return False
        e = self.errors(state)
        return bool(np.all(e[np.isfinite(e)] <= self.tolerance))
