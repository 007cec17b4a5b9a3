"""Shared arithmetic of the tasks: parts' positions under a candidate layout, distances to targets,
steps clipped to a longest length."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
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


def distance_sum(q: FloatArray, targets: FloatArray, slack: float = 0.0, bend: float = 0.0) -> FloatArray:
    """Sum over parts of ``|q - target|`` less ``slack`` (0 within it), parts without a target
    (NaN) left out; a lost part (NaN in ``q``) counts 1 m (it is not done). With ``bend`` [m], an
    excess ``e`` below it counts ``e^2 / (2 bend)`` and one beyond it ``e - bend / 2`` (a Huber
    loss: the same slope far out, a vanishing one near the target).

    ``q (..., M, 2)`` and ``targets (..., M, 2)`` broadcast against each other. One pass in the core
    (``upm_core::plan::distance_sum``); with the same targets for every layout, a leading axis
    along which ``q`` is broadcast (a layout repeated, as resting layouts are) is summed once."""
    # either side may carry the leading axes (a trajectory's references over elapsed times
    # against one layout, or candidate layouts against one set of points)
    q, t = np.broadcast_arrays(np.asarray(q, dtype=np.float64), np.asarray(targets, dtype=np.float64))
    lead, m = q.shape[:-2], q.shape[-2]
    shape = lead
    if all(stride == 0 for stride in t.strides[: len(lead)]):  # one set of targets for all
        repeats = [stride == 0 for stride in q.strides[: len(lead)]]
        q = q[tuple(0 if r else slice(None) for r in repeats)]
        t = t[(0,) * len(lead)]
        shape = tuple(1 if r else n for r, n in zip(repeats, lead, strict=True))
    sums = _core.distance_sum(
        np.ascontiguousarray(q.reshape(-1, m, 2)),
        np.ascontiguousarray(t.reshape(-1, m, 2)),
        float(slack),
        float(bend),
    )
    out: FloatArray = np.array(np.broadcast_to(sums.reshape(shape), lead))
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
        it) and bent into a square over the first tolerance beyond that (:func:`distance_sum`); a
        lost part counts 1 m.

        The bend is what lets the last parts in: a pulse that brings one far part in moves its
        neighbours too, and a straight sum charges each neighbour's millimetre as much as the far
        part's. Squared near the target, a millimetre at a part already close costs little, so
        the planner spends the placed parts' slack on the part still out (a 12-part ring: 14 of
        14 seeds assembled, against 4 of 6 with the straight sum at half or 0.8 of the tolerance
        of slack, which stalled on one part 4-9 mm out)."""
        return distance_sum(
            positions_of(state, positions), self.targets(state), 0.5 * self.tolerance, self.tolerance
        )
