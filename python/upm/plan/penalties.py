"""What the predictive planner charges a predicted layout besides the task's cost: parts near or
over the plate's edge (scored at each part's worst case) and parts overlapping one another. The
sums run in the core (``upm_core::plan::edge_penalty``, ``overlap_penalty``)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .. import _core

__all__ = ["in_band", "penalty"]

FloatArray = NDArray[np.float64]


def penalty(
    q: FloatArray,
    *,
    half: float,
    edge: float,
    edge_weight: float,
    lost_cost: float,
    guard: float,
    spread: float = 0.0,
    part_radius: float | None = None,
    start: FloatArray | None = None,
) -> FloatArray:
    """Edge and overlap penalties ``(K,)`` [m of cost] for predicted positions ``(K, M, 2)`` on a
    plate of half-side ``half`` [m].

    ``lost_cost`` per part off the plate (or NaN), half of it per part within ``guard`` of an
    edge; inside the edge band (``edge`` wide) ``edge_weight`` per metre, and five times more in
    its outer half. Parts that were at ``start`` (``(M, 2)``, or ``(S, M, 2)`` with ``S``
    dividing ``K``: each start for ``K / S`` consecutive layouts) are scored at their worst case,
    ``spread`` times their way further out. With ``part_radius``, half the depth of every overlap
    of two parts (a sweep along x in the core, not all pairs)."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    begin = None
    if start is not None and spread > 0:
        begin = np.ascontiguousarray(np.asarray(start, dtype=np.float64).reshape(-1, *q.shape[1:]))
    out: FloatArray = _core.edge_penalty(q, half, edge, edge_weight, lost_cost, guard, begin, spread)
    if part_radius is not None and q.shape[1] > 1:
        out = out + 0.5 * _core.overlap_penalty(q, 2.05 * part_radius)
    return out


def in_band(q: FloatArray, half: float, edge: float) -> NDArray[np.bool_]:
    """Whether any part of each layout ``(K, M, 2)`` lies in the edge band (``edge`` wide, on a
    plate of half-side ``half``) or beyond."""
    out: NDArray[np.bool_] = np.any(np.abs(np.nan_to_num(q)) > half - edge, axis=(1, 2))
    return out
