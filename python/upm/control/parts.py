"""Goals given part by part, by tracker id, and changed while the loop runs (the desk's task).

Each command names a tracked part: send it to a point (:meth:`PartsTask.goto`) or along a path at
a speed (:meth:`PartsTask.follow`). Every commanded part is served at once by the planner; the
parts without a command are asked to stay where they are (steps of zero; :meth:`PartsTask.cost`
charges ``hold`` per metre they move). The commands end together, when every commanded part is
within ``tolerance`` of its goal (or of its path's end, the reference there): a part that arrives
first is held at its goal while the others travel. Ended commands are listed in
:attr:`PartsTask.finished`, and their parts stay *placed*: while later commands run, a placed part
is held at the point it was sent to, as firmly as a commanded part (steered back when pushed off,
and the later commands end only when it is back within ``tolerance``), until it gets a command of
its own or is cleared.
Thread-safe: commands may come from another thread while the loop reads the task.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import point, real
from .._errors import ParameterError
from ._steps import clip, points, positions_of
from .state import State

__all__ = ["PartsTask"]

FloatArray = NDArray[np.float64]


@dataclass
class _Command:
    path: FloatArray
    """(K, 2) [m]: the goal alone (K = 1) or the path's points."""
    arc: FloatArray
    """(K,) arc length at each point [m]."""
    speed: float
    progress: float = 0.0
    time: float | None = None
    """Plate time of the last cycle that advanced the reference [s]."""

    def reference(self, progress: float | FloatArray) -> FloatArray:
        if len(self.path) == 1:
            return np.broadcast_to(self.path[0], (*np.shape(progress), 2)).copy()
        at = np.clip(progress, 0.0, self.arc[-1])
        return np.stack(
            [np.interp(at, self.arc, self.path[:, 0]), np.interp(at, self.arc, self.path[:, 1])], -1
        )

    @property
    def end(self) -> float:
        return float(self.arc[-1])


class PartsTask:
    """Goals and paths for individual parts, by tracker id.

    Parameters
    ----------
    tolerance : float
        A command is done when its part is within this of its goal [m].
    max_step : float
        Longest step asked for per cycle [m].
    gain : float
        Fraction of the remaining error asked for per cycle.
    speed : float
        Default speed of a path's reference [m/s of plate time].
    hold : float
        Weight, per metre, of moving a part that has no command (in :meth:`cost`).
    lag : float
        A path's reference waits while its part lags it by more than this [m].
    """

    def __init__(
        self,
        *,
        tolerance: float = 0.003,
        max_step: float = 0.02,
        gain: float = 0.8,
        speed: float = 0.02,
        hold: float = 0.3,
        lag: float = 0.015,
    ) -> None:
        def positive(name: str, value: float) -> float:
            return real(name, value, low=0.0, low_open=True)

        self.tolerance, self.max_step, self.gain = (
            positive("tolerance", tolerance),
            positive("max_step", max_step),
            positive("gain", gain),
        )
        self.speed, self.lag, self.hold = (
            positive("speed", speed),
            positive("lag", lag),
            real("hold", hold, low=0.0),
        )
        self.commands: dict[int, _Command] = {}
        self.placed: dict[int, _Command] = {}
        """Parts whose command ended, held where they were sent while later commands run."""
        self.finished: list[int] = []
        """Ids whose command was done, in the order they finished."""
        self._lock = threading.Lock()

    # -- commands ----------------------------------------------------------------------------------
    def goto(self, part_id: int, goal: ArrayLike) -> None:
        """Send part ``part_id`` to ``goal`` (x, y) [m] (replacing its command)."""
        g = np.asarray(point("goal", goal), dtype=np.float64)
        i = self._id(part_id)
        with self._lock:
            self.commands[i] = _Command(g[None], np.zeros(1), self.speed)
            self.placed.pop(i, None)

    def follow(self, part_id: int, path: ArrayLike, speed: float | None = None) -> None:
        """Send part ``part_id`` along ``path`` ((K, 2) [m], K >= 2) at ``speed`` [m/s]."""
        p = points("path", path)
        if len(p) < 2:
            raise ParameterError(f"path needs at least 2 points; got {len(p)}")
        seg = np.hypot(*np.diff(p, axis=0).T)
        keep = np.concatenate([[True], seg > 1e-9])  # repeated points (a mouse that did not move)
        p = p[keep]
        if len(p) < 2:
            raise ParameterError("path has no length: all its points are the same")
        v = self.speed if speed is None else real("speed", speed, low=0.0, low_open=True)
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))])
        i = self._id(part_id)
        with self._lock:
            self.commands[i] = _Command(p, arc, v)
            self.placed.pop(i, None)

    def clear(self, part_id: int | None = None) -> None:
        """Drop the command and placement of ``part_id`` (every one when None)."""
        with self._lock:
            if part_id is None:
                self.commands.clear()
                self.placed.clear()
            else:
                self.commands.pop(self._id(part_id), None)
                self.placed.pop(self._id(part_id), None)

    @property
    def active(self) -> bool:
        """Whether any command is left."""
        return bool(self.commands)

    @staticmethod
    def _id(part_id: int) -> int:
        if isinstance(part_id, bool) or not isinstance(part_id, (int, np.integer)) or part_id < 0:
            raise ParameterError(f"part_id must be an integer >= 0 (a tracker id); got {part_id!r}")
        return int(part_id)

    # -- the task ----------------------------------------------------------------------------------
    def _mine(self, state: State) -> list[tuple[int, _Command | None]]:
        """Each part's command, or its placement while other commands run."""
        with self._lock:
            held = self.placed if self.commands else {}
            return [(k, self.commands.get(int(i)) or held.get(int(i))) for k, i in enumerate(state.ids)]

    def targets(self, state: State) -> FloatArray:
        """Where each commanded (or held placed) part's reference is now [m] (NaN: none)."""
        out = np.full_like(state.positions, np.nan)
        for k, c in self._mine(state):
            if c is not None:
                out[k] = c.reference(c.progress)
        return out

    def lines(self) -> list[FloatArray]:
        """The commanded paths [m]."""
        with self._lock:
            return [c.path.copy() for c in self.commands.values() if len(c.path) > 1]

    def errors(self, state: State) -> FloatArray:
        d = self.targets(state) - state.positions
        out: FloatArray = np.hypot(d[:, 0], d[:, 1])
        return out

    def steps(self, state: State) -> FloatArray:
        """Commanded parts: toward their reference, fed forward along a path; the rest: zero."""
        out = np.zeros_like(state.positions)
        for k, c in self._mine(state):
            if c is None or not np.all(np.isfinite(state.positions[k])):
                continue
            self._advance(c, state, k)
            ahead = c.reference(min(c.progress + c.speed * (state.last_cycle or 0.0), c.end))
            here = c.reference(c.progress)
            e = here - state.positions[k]
            out[k] = (ahead - here) + (self.gain * e if len(c.path) == 1 or c.progress >= c.end else e)
            if np.hypot(*e) <= self.tolerance / 2 and len(c.path) == 1:
                out[k] = 0.0
        return clip(out, self.max_step)

    def _advance(self, c: _Command, state: State, k: int) -> None:
        """Move a path's reference on by the plate time since its last cycle, unless its part lags."""
        if c.time is not None and len(c.path) > 1:
            lagging = np.hypot(*(c.reference(c.progress) - state.positions[k])) > self.lag
            if not lagging:
                c.progress = min(c.progress + c.speed * max(state.time - c.time, 0.0), c.end)
        c.time = state.time

    def cost(self, state: State, positions: FloatArray | None = None, elapsed: ArrayLike = 0.0) -> FloatArray:
        """Sum of the commanded parts' distances [m] to where their references will be after
        ``elapsed`` more seconds (less half the tolerance), plus ``hold`` times how far the other
        parts moved; a lost commanded part counts 1 m."""
        q = positions_of(state, positions)
        el = np.asarray(elapsed, dtype=np.float64)
        total = np.zeros(q.shape[:-2]) + np.zeros(el.shape)
        for k, c in self._mine(state):
            if c is None:
                if self.hold and np.all(np.isfinite(state.positions[k])):
                    d = q[..., k, :] - state.positions[k]
                    moved = np.hypot(d[..., 0], d[..., 1])
                    total = total + self.hold * np.where(np.isfinite(moved), moved, 0.0)
                continue
            ref = c.reference(np.minimum(c.progress + c.speed * el, c.end)) if len(c.path) > 1 else c.path[0]
            d = q[..., k, :] - ref
            r = np.hypot(d[..., 0], d[..., 1])
            total = total + np.where(np.isfinite(r), np.maximum(r - 0.5 * self.tolerance, 0.0), 1.0)
        out: FloatArray = total
        return out

    def done(self, state: State) -> bool:
        """True when every commanded part has arrived and every placed part seen is at its place
        (the commands then end and their parts become placed); a commanded part that is not seen
        now has not arrived."""
        seen = {int(i): k for k, i in enumerate(state.ids) if np.all(np.isfinite(state.positions[k]))}
        with self._lock:
            for i, c in self.commands.items():
                k = seen.get(i)
                if k is None or (len(c.path) > 1 and c.progress < c.end):
                    return False
                if np.hypot(*(c.reference(c.end) - state.positions[k])) > self.tolerance:
                    return False
            for i, c in self.placed.items():
                k = seen.get(i)
                if self.commands and k is not None:
                    if np.hypot(*(c.path[0] - state.positions[k])) > self.tolerance:
                        return False
            self.finished.extend(self.commands)
            for i, c in self.commands.items():
                self.placed[i] = _Command(c.reference(c.end)[None], np.zeros(1), c.speed)
            self.commands.clear()
            return True

    def describe(self) -> dict[int, dict[str, Any]]:
        """The commands as plain data: ``{id: {"goal": (x, y)} or {"path": [...], "progress": s}}``."""
        with self._lock:
            return {
                i: (
                    {"goal": c.path[0].tolist()}
                    if len(c.path) == 1
                    else {"path": c.path.tolist(), "progress": c.progress, "length": c.end}
                )
                for i, c in self.commands.items()
            }
