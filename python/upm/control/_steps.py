"""Shared arithmetic of the tasks: parts' positions under a candidate layout, distances to targets,
steps clipped to a longest length."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import as_float
from .._errors import ShapeError

__all__ = ["PointTargets", "clip", "distance_sum", "points", "positions_of"]

FloatArray = NDArray[np.float64]


def positions_of(state: Any, positions: FloatArray | None) -> FloatArray:
    """The parts of ``state`` at ``positions (..., M, 2)`` (default: where they are)."""
    q = state.positions if positions is None else np.asarray(positions, dtype=np.float64)
    if q.shape[-2:] != state.positions.shape:
        raise ShapeError(f"positions must have shape (..., {len(state.positions)}, 2); got {q.shape}")
    return q


def distance_sum(q: FloatArray, targets: FloatArray, slack: float = 0.0) -> FloatArray:
    """Sum over parts of ``|q - target|`` less ``slack`` (0 within it), parts without a target
    (NaN) left out; a lost part (NaN in ``q``) counts 1 m (it is not done)."""
    d = q - targets
    r = np.hypot(d[..., 0], d[..., 1])
    has = np.all(np.isfinite(targets), axis=-1)
    r = np.where(has, np.where(np.isfinite(r), np.maximum(r - slack, 0.0), 1.0), 0.0)
    out: FloatArray = np.sum(r, axis=-1)
    return out


def points(name: str, value: ArrayLike) -> FloatArray:
    p = as_float(name, value)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ShapeError(f"{name} must have shape (M, 2) [m]; got {p.shape}")
    return np.array(p, dtype=np.float64)


def clip(steps: FloatArray, longest: float) -> FloatArray:
    n = np.hypot(steps[:, 0], steps[:, 1])
    scale = np.where(n > longest, longest / np.maximum(n, 1e-300), 1.0)
    out: FloatArray = steps * scale[:, None]
    return out


class PointTargets(ABC):
    """What tasks of point targets share (:class:`~upm.control.GotoTask`,
    :class:`~upm.control.ShapeTask`): errors and cost from ``targets(state)`` (each part's point,
    NaN: none) and ``tolerance`` [m]."""

    tolerance: float

    @abstractmethod
    def targets(self, state: Any) -> FloatArray:
        """Each part's point [m] (NaN: none), ``(M, 2)``."""

    def lines(self) -> list[FloatArray]:
        """Lines to draw the task with [m] (none: the targets are points)."""
        return []

    def errors(self, state: Any) -> FloatArray:
        """Each part's distance to its point [m] (NaN: none)."""
        d = self.targets(state) - state.positions
        out: FloatArray = np.hypot(d[:, 0], d[:, 1])
        return out

    def cost(self, state: Any, positions: FloatArray | None = None, elapsed: Any = 0.0) -> FloatArray:
        """Sum of the parts' distances to their points [m], each less half the tolerance (0 within
        it); a lost part counts 1 m."""
        return distance_sum(positions_of(state, positions), self.targets(state), 0.5 * self.tolerance)
