"""A grid of cells over a polygon's footprint, shared by the polygon tests' brute-force sums."""

from __future__ import annotations

import numpy as np

import upm


def cells(part: upm.Polygon, h: float = 2.5e-4) -> np.ndarray:
    """Centres of a grid of cells of side ``h`` over the footprint, in the part's frame about its
    centroid."""
    v = np.asarray(part.vertices) - part.centroid
    lo, hi = v.min(axis=0), v.max(axis=0)
    x, y = np.meshgrid(np.arange(lo[0], hi[0], h) + h / 2, np.arange(lo[1], hi[1], h) + h / 2)
    inside = np.ones_like(x, bool)
    for a, b in zip(v, np.roll(v, -1, axis=0), strict=True):
        inside &= (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]) >= 0
    return np.stack([x[inside], y[inside]], axis=1)
