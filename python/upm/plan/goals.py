"""Plain steps as a task: what a planner with a task's cost minimises when it is given
``plan(positions, steps)`` instead (the :class:`~upm.plan.Planner` protocol)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["PositionsView", "StepsGoal"]

FloatArray = NDArray[np.float64]


class StepsGoal:
    """The cost of plain steps: the sum of the parts' distances [m] to ``goal (M, 2)`` over its
    finite components (a NaN component is free)."""

    def __init__(self, goal: FloatArray) -> None:
        self.goal = goal

    def cost(self, state: Any, positions: FloatArray | None = None, elapsed: Any = 0.0) -> Any:
        q = state.positions if positions is None else positions
        d = np.where(np.isfinite(self.goal), q - self.goal, 0.0)
        return np.sum(np.hypot(d[..., 0], d[..., 1]), axis=-1)


class PositionsView:
    """A minimal state: the parts' positions ``(M, 2)`` [m], numbered from 0."""

    def __init__(self, positions: FloatArray) -> None:
        self.positions = positions
        self.ids = np.arange(len(positions))
