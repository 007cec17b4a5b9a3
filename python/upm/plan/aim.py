"""Where a cycle's pulses aim: each part's direction of steepest cost descent, and the parts
with the most to gain (:class:`~upm.plan.PredictivePlanner`'s ``focus``)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["aimed", "descent"]

FloatArray = NDArray[np.float64]


def descent(task: Any, state: Any, pos: FloatArray, h: float = 1e-3) -> FloatArray:
    """Each part's direction of steepest cost descent ``(M, 2)`` (central differences)."""
    m = len(pos)
    probe = np.repeat(pos[None], 4 * m, axis=0)
    for i in range(m):
        for j in range(2):
            probe[4 * i + 2 * j, i, j] += h
            probe[4 * i + 2 * j + 1, i, j] -= h
    c = np.asarray(task.cost(state, probe, 0.0), dtype=float).reshape(m, 2, 2)
    out: FloatArray = -(c[:, :, 0] - c[:, :, 1]) / (2 * h)
    return out


def aimed(
    task: Any, state: Any, pos: FloatArray, toward: FloatArray, focus: int | None
) -> list[tuple[FloatArray, FloatArray]]:
    """The parts to aim pulses at, and their descent directions: all of them, or (``focus``) first
    the ``focus`` parts with the most to gain (the steepest descent of the cost; ties, as a
    distance cost's far parts all are, broken by the task's error, the farthest first), then all
    of them when none of those pulses gains (the parts with the most to gain may be jammed)."""
    if focus is None:
        return [(pos, toward)]
    slope = np.round(np.hypot(toward[:, 0], toward[:, 1]), 9)
    far = np.zeros(len(pos))
    errors = getattr(task, "errors", None)
    if errors is not None:
        e = np.asarray(errors(state), dtype=float).reshape(-1)
        if len(e) == len(pos):
            far = np.nan_to_num(e, nan=0.0)
    keep = np.sort(np.lexsort((-far, -slope))[:focus])
    return [(pos[keep], toward[keep]), (pos, toward)]
