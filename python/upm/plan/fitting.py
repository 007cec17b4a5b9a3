"""The predictive planner's online friction fit: the factor on its friction estimate that best
explains the last pulse, from a handful of predictions (:class:`~upm.plan.PredictivePlanner`)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["FACTORS", "best_factor"]

FACTORS = np.array([0.7, 0.8, 0.9, 1.0, 1.1, 1.25, 1.4])
"""Factors on the friction estimate the last pulse is predicted again with."""


def best_factor(factors: NDArray[np.float64], err: NDArray[np.float64]) -> float:
    """The factor of least ``err`` (one value per factor), refined between its neighbours by the
    vertex of the parabola through the three in log factor (kept within them)."""
    best = int(np.argmin(err))
    f = float(factors[best])
    if 0 < best < len(factors) - 1:
        y0, y1, y2 = err[best - 1], err[best], err[best + 1]
        x0, x1, x2 = np.log(factors[best - 1 : best + 2])
        den = (x0 - x1) * (x0 - x2) * (x1 - x2)
        if den != 0:
            aa = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / den
            bb = (x2**2 * (y0 - y1) + x1**2 * (y2 - y0) + x0**2 * (y1 - y2)) / den
            if aa > 0:
                f = float(np.exp(np.clip(-bb / (2 * aa), x0, x2)))
    return f
