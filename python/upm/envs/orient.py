"""The ``orient`` task of the environments (``upm/Orient-v0``): convex polygon parts to target
poses ``(x, y, theta)``, the angle modulo the outline's symmetry, as
:class:`upm.control.PoseTask` scores them in the closed loop.

A pose is the part's frame origin and angle (:meth:`upm.Polygon.moved`); each world plays its
pulse on its own parts with the exact polygon friction wrench (docs/polygons.md), all the worlds of
one drive frequency and on-time in one batched call, each from its own poses
(:func:`upm.simulate_batch` ``starts (B, M, 3)``), then on the plate at rest until every part has
stopped (:class:`upm.envs.world.Plates`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._arrays import real
from .._errors import ParameterError
from ..control.shapes import scatter
from ..physics.polygon import Polygon
from ..plan.orient import pose_errors
from ..plate.drive import DriveLimits

__all__ = ["POLYGONS", "OrientTask", "polygon_of"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: The outlines ``polygon=`` may name (sizes of the thesis's parts: a few centimetres).
POLYGONS = {
    "triangle": lambda: Polygon.regular(3, 0.02),
    "square": lambda: Polygon.regular(4, 0.016),
    "rectangle": lambda: Polygon.rectangle(0.04, 0.02),
    "hexagon": lambda: Polygon.regular(6, 0.015),
}


def polygon_of(value: Any) -> Polygon:
    """A :class:`upm.Polygon` from ``polygon=``: one, or the name of one of :data:`POLYGONS`."""
    if isinstance(value, Polygon):
        return value
    if isinstance(value, str) and value in POLYGONS:
        return POLYGONS[value]()
    raise ParameterError(f"polygon must be a upm.Polygon or one of {sorted(POLYGONS)}; got {value!r}")


class OrientTask:
    """Polygons to target poses: the layouts, cost and completion of ``B`` worlds at once.

    Cost [m]: each part's distance to its target less half ``tolerance``, plus its angle error
    less half ``angle_tolerance``, weighed ``tolerance / angle_tolerance`` metres a radian (a part
    at both tolerances weighs as much in each); a lost part 1 m. Done when every part is within
    both tolerances."""

    name = "orient"

    def __init__(
        self, n_parts: int, limits: DriveLimits, polygon: Polygon, tolerance: float, angle_tolerance: float
    ) -> None:
        self.m, self.polygon, self.tolerance = n_parts, polygon, tolerance
        self.angle_tolerance = math.radians(real("angle_tolerance", angle_tolerance, low=0.0, high=180.0,
                                                  low_open=True))  # fmt: skip
        self.symmetry = polygon.symmetry
        self.half = limits.size / 2
        self.gap = 2.2 * polygon.radius
        if self.half - 0.6 * self.half < 1.5 * polygon.radius:
            raise ParameterError(f"polygon of radius {polygon.radius:g} m is too large for the plate")
        self.layout(np.random.default_rng(0))  # n_parts that cannot fit are refused now, not at reset

    def layout(self, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        """A new episode's poses ``(M, 3)`` and target poses ``(M, 3)``."""
        out = []
        for extent in (0.7 * self.half, 0.6 * self.half):
            try:
                xy = scatter(rng, self.m, extent, self.gap)
            except ParameterError:
                raise ParameterError(
                    f"n_parts = {self.m} polygons of radius {self.polygon.radius:g} m do not fit the "
                    "plate's middle; use fewer or a smaller polygon"
                ) from None
            out.append(np.column_stack([xy, rng.uniform(-math.pi, math.pi, self.m)]))
        return out[0], out[1]

    def errors(self, q: FloatArray, goals: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Distances [m] and absolute angle errors [rad] ``(B, M)`` (NaN for a lost part)."""
        d, a = pose_errors(q.reshape(-1, 3), goals.reshape(-1, 3), self.symmetry)
        return d.reshape(q.shape[:2]), np.abs(a).reshape(q.shape[:2])

    def cost(self, q: FloatArray, goals: FloatArray) -> FloatArray:
        """Each world's cost ``(B,)`` [m] (class docs)."""
        d, a = self.errors(q, goals)
        weight = self.tolerance / self.angle_tolerance
        with np.errstate(invalid="ignore"):
            terms = np.maximum(d - self.tolerance / 2, 0.0)
            terms = terms + weight * np.maximum(a - self.angle_tolerance / 2, 0.0)
        out: FloatArray = np.sum(np.where(np.isfinite(terms), terms, 1.0), axis=1)
        return out

    def done(self, q: FloatArray, goals: FloatArray) -> BoolArray:
        """Whether every part of each world is within both tolerances ``(B,)``."""
        d, a = self.errors(q, goals)
        with np.errstate(invalid="ignore"):
            out: BoolArray = np.all((d <= self.tolerance) & (a <= self.angle_tolerance), axis=1)
        return out

    def observe(self, q: FloatArray, goals: FloatArray) -> FloatArray:
        """Per world ``(B, 9 M)``: positions over half the plate's side and ``(cos k theta, sin k
        theta)`` (``k`` the symmetry: a pose's angle is known modulo ``2 pi / k``), the targets
        likewise, then 1 for each part on the plate (a lost part's numbers 0)."""
        here = np.all(np.isfinite(q), axis=2)

        def pose(p: FloatArray) -> FloatArray:
            k = self.symmetry * p[..., 2]
            both = np.concatenate([p[..., :2] / self.half, np.stack([np.cos(k), np.sin(k)], -1)], -1)
            flat: FloatArray = np.nan_to_num(both).reshape(len(p), -1)
            return flat

        out: FloatArray = np.concatenate([pose(q), pose(goals), here.astype(np.float64)], axis=1)
        return out
