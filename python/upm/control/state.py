"""What a task sees and what the loop asks of it: the tracked parts at the start of a cycle
(:class:`State`), the :class:`Task` protocol, and the binding of parts to a task's slots
(:class:`Slots`: goals or paths, by minimum total distance on the first cycle they are seen)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["Slots", "State", "Task"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class State:
    """The loop's view of the plate at the start of a cycle."""

    cycle: int
    time: float
    """Plate time elapsed [s] (the pulses played so far)."""
    ids: NDArray[np.int64]
    positions: FloatArray
    """(M, 2) [m], NaN for parts lost in this frame."""
    labels: tuple[str, ...]
    last_cycle: float
    """Plate time of the previous cycle [s] (0 on the first)."""


@runtime_checkable
class Task(Protocol):
    """What the loop asks of a task. ``cost(state, positions, elapsed)`` is the task's own
    measure of what is left to do [m] for the parts of ``state`` at ``positions (..., M, 2)``
    (default: where they are) after ``elapsed`` [s] of plate time (scalar or the batch's shape):
    zero when done, growing with distance; predictive planners minimise it."""

    def steps(self, state: State) -> FloatArray: ...

    def done(self, state: State) -> bool: ...

    def errors(self, state: State) -> FloatArray: ...

    def cost(
        self, state: State, positions: FloatArray | None = None, elapsed: ArrayLike = 0.0
    ) -> FloatArray: ...


class Slots:
    """Binding of tracked part ids to a task's slots, made once on the first cycle they are seen."""

    def __init__(self, anchors: FloatArray) -> None:
        self.anchors = anchors
        self.of: dict[int, int] = {}

    def bind(self, state: State) -> NDArray[np.int64]:
        """Slot of every tracked part (-1: none). A slot whose part has left the tracker's view
        for good (its id is gone) is free for a part that appears."""
        present = {int(i) for i in state.ids}
        self.of = {i: s for i, s in self.of.items() if i in present}
        new = [
            k
            for k, i in enumerate(state.ids)
            if int(i) not in self.of and np.all(np.isfinite(state.positions[k]))
        ]
        free = [s for s in range(len(self.anchors)) if s not in self.of.values()]
        if new and free:
            from scipy.optimize import linear_sum_assignment

            cost = np.linalg.norm(state.positions[new][:, None] - self.anchors[free][None], axis=2)
            rows, cols = linear_sum_assignment(cost)
            for r, c in zip(rows, cols, strict=True):
                self.of[int(state.ids[new[r]])] = free[c]
        return np.array([self.of.get(int(i), -1) for i in state.ids], dtype=np.int64)
