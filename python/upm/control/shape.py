"""Many parts into a shape: N parts to N target points, the assignment solved again every cycle.

:class:`ShapeTask` is the task of the Chladni-plate assembly line (Kopitca, Latifi & Zhou, *Sci.
Adv.* 7:eabi7716, 2021): each cycle the parts are matched to the target points by minimum total
squared distance (``scipy.optimize.linear_sum_assignment``); optionally the whole shape may turn
and shift to where the parts already are (the best rigid alignment: the assignment and the
orthogonal Procrustes fit, Kabsch's, taken in turn from ``angles`` starting turns). Done when a
matching exists that puts every target's part within ``tolerance`` of it (a bottleneck test, exact:
the assignment on the indicator ``distance > tolerance`` costs 0).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import integer, real
from .._errors import ParameterError
from ..plate.drive import PLATE_SIZE
from ._steps import PointTargets, clip, points
from .state import State

__all__ = ["ShapeTask", "assign", "kabsch"]

FloatArray = NDArray[np.float64]


def assign(positions: FloatArray, targets: FloatArray) -> NDArray[np.int64]:
    """The target of each part ``(M,)`` (-1: none) minimising the total squared distance; parts
    with NaN positions get none. ``scipy.optimize.linear_sum_assignment``."""
    from scipy.optimize import linear_sum_assignment

    out = np.full(len(positions), -1, dtype=np.int64)
    seen = np.nonzero(np.all(np.isfinite(positions), axis=1))[0]
    if not len(seen) or not len(targets):
        return out
    d = positions[seen][:, None, :] - targets[None, :, :]
    rows, cols = linear_sum_assignment(np.einsum("ijk,ijk->ij", d, d))
    out[seen[rows]] = cols
    return out


def _angle(a: FloatArray, b: FloatArray) -> float:
    """The turn [rad] about the origin taking the points ``a (K, 2)`` closest to ``b``."""
    return math.atan2(float(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])), float(np.sum(a * b)))


def kabsch(source: FloatArray, target: FloatArray) -> tuple[float, FloatArray]:
    """The rigid motion ``x -> R(angle) x + shift`` taking ``source (K, 2)`` closest to
    ``target`` in total squared distance (the orthogonal Procrustes problem, no reflection)."""
    cs, ct = source.mean(axis=0), target.mean(axis=0)
    angle = _angle(source - cs, target - ct)
    c, s = math.cos(angle), math.sin(angle)
    return angle, ct - np.array([[c, -s], [s, c]]) @ cs


def _turn(p: FloatArray, angle: float, about: FloatArray) -> FloatArray:
    c, s = math.cos(angle), math.sin(angle)
    out: FloatArray = (p - about) @ np.array([[c, s], [-s, c]]) + about
    return out


class ShapeTask(PointTargets):
    """N parts to N target points, any part to any point (see the module docstring).

    Parameters
    ----------
    targets : (N, 2) array_like
        The shape [m] (:mod:`upm.shapes` makes them).
    tolerance : float, optional
        Done when every target has a part within this [m] (default 0.9 % of ``plate_size``: 3.7 mm
        on the 16 in plate, the Chladni line's accuracy).
    rotate, translate : bool
        The shape may turn about its centroid / shift, to wherever fits the parts best each cycle
        (kept within ``edge`` of the plate's edges).
    plate_size : float
        Side of the plate [m].
    part_radius : float, optional
        When given, targets closer than two radii (disks that cannot both sit on their points) are
        refused with a :class:`upm.ParameterError`.
    gain, max_step : float
        :meth:`steps` asks for ``gain`` of each part's way to its point, at most ``max_step`` [m].
    angles : int
        Starting turns tried for the alignment (``rotate``), evenly round the circle.
    edge : float
        A moved shape keeps this far from the plate's edges [m].
    """

    def __init__(
        self,
        targets: ArrayLike,
        *,
        tolerance: float | None = None,
        rotate: bool = False,
        translate: bool = False,
        plate_size: float = PLATE_SIZE,
        part_radius: float | None = None,
        gain: float = 0.8,
        max_step: float = 0.02,
        angles: int = 16,
        edge: float = 0.04,
    ) -> None:
        self.shape = points("targets", targets)
        if not len(self.shape):
            raise ParameterError("targets must hold at least one point")
        self.plate_size = real("plate_size", plate_size, low=0.0, low_open=True)
        half = self.plate_size / 2
        self.tolerance = (
            0.009 * self.plate_size
            if tolerance is None
            else real("tolerance", tolerance, low=0.0, low_open=True)
        )
        self.gain = real("gain", gain, low=0.0, low_open=True)
        self.max_step = real("max_step", max_step, low=0.0, low_open=True)
        self.edge = real("edge", edge, low=0.0, high=half, high_open=True)
        self.angles = integer("angles", angles, low=1)
        self.rotate, self.translate = bool(rotate), bool(translate)
        if np.any(np.abs(self.shape) > half):
            raise ParameterError(f"targets must lie on the plate (|x|, |y| <= {half:.4g} m)")
        self.part_radius = (
            None if part_radius is None else real("part_radius", part_radius, low=0.0, low_open=True)
        )
        if self.part_radius is not None and len(self.shape) > 1:
            from .shapes import min_spacing

            gap = min_spacing(self.shape)
            if gap < 2 * self.part_radius:
                raise ParameterError(
                    f"targets: two points are {1000 * gap:.1f} mm apart, closer than two parts of radius "
                    f"{1000 * self.part_radius:.1f} mm can sit; spread the shape (larger, or fewer points)"
                )
        self.pose = (0.0, np.zeros(2))  # the shape's turn about its centroid [rad] and shift [m]
        self._cache: tuple[bytes, FloatArray, NDArray[np.int64]] | None = None

    # -- the shape where it is now, and the parts' points ---------------------------------------------
    def placed(self, pose: tuple[float, FloatArray] | None = None) -> FloatArray:
        """The target points at ``pose`` (default: the current one) [m]."""
        angle, shift = self.pose if pose is None else pose
        c = self.shape.mean(axis=0)
        out: FloatArray = _turn(self.shape, angle, c) + shift
        return out

    def _fit(self, pos: FloatArray) -> tuple[float, FloatArray]:
        """The pose that brings the shape closest to the parts ``pos`` (seen ones), from the
        current pose and from ``angles`` starting turns: the assignment and the best rigid fit
        (Kabsch) in turn, the shape kept ``edge`` inside the plate."""
        seen = pos[np.all(np.isfinite(pos), axis=1)]
        if not len(seen) or not (self.rotate or self.translate):
            return self.pose
        c = self.shape.mean(axis=0)
        half = self.plate_size / 2 - self.edge
        starts = [self.pose]
        if self.rotate:
            starts += [(2 * math.pi * k / self.angles, self.pose[1]) for k in range(self.angles)]
        best, best_cost = self.pose, math.inf
        for angle, shift in starts:
            for _ in range(4):
                slot = assign(seen, self.placed((angle, shift)))
                has = slot >= 0
                src, dst = self.shape[slot[has]] - c, seen[has] - c
                if self.rotate and self.translate:
                    angle, shift = kabsch(src, dst)
                elif self.rotate:  # about the shape's centre, where it is
                    angle = _angle(src, dst - shift)
                else:
                    shift = np.mean(dst - _turn(src, angle, np.zeros(2)), axis=0)
                turned = _turn(self.shape, angle, c)
                lo, hi = turned.min(axis=0) + shift, turned.max(axis=0) + shift
                shift = shift - np.maximum(hi - half, 0.0) + np.maximum(-half - lo, 0.0)
            placed = self.placed((angle, shift))
            slot = assign(seen, placed)
            d = seen[slot >= 0] - placed[slot[slot >= 0]]
            cost = float(np.einsum("ij,ij->", d, d))
            if cost < best_cost * (1 - 1e-3):  # the current pose wins near-ties: no flip-flopping
                best, best_cost = (float(angle), np.asarray(shift, dtype=np.float64)), cost
        return best

    def _slots(self, state: State) -> tuple[FloatArray, NDArray[np.int64]]:
        """This cycle's target points and each part's (-1: none), solved once per layout."""
        pos = np.asarray(state.positions, dtype=np.float64)
        key = pos.tobytes()
        if self._cache is None or self._cache[0] != key:
            self.pose = self._fit(pos)
            placed = self.placed()
            self._cache = (key, placed, assign(pos, placed))
        return self._cache[1], self._cache[2]

    def targets(self, state: State) -> FloatArray:
        """Each part's assigned point [m] (NaN: none)."""
        placed, slot = self._slots(state)
        out = np.full_like(np.asarray(state.positions, dtype=np.float64), np.nan)
        out[slot >= 0] = placed[slot[slot >= 0]]
        return out

    def steps(self, state: State) -> FloatArray:
        d = self.targets(state) - state.positions
        d = np.where(np.isfinite(d), d, 0.0)
        d[np.hypot(d[:, 0], d[:, 1]) <= self.tolerance / 2] = 0.0
        return clip(self.gain * d, self.max_step)

    def done(self, state: State) -> bool:
        """Every target point has its own part within ``tolerance`` (whatever the assignment that
        minimises the squared distances says: the test is exact)."""
        from scipy.optimize import linear_sum_assignment

        pos = np.asarray(state.positions, dtype=np.float64)
        seen = pos[np.all(np.isfinite(pos), axis=1)]
        placed, _ = self._slots(state)
        if len(seen) < len(placed):
            return False
        far = (np.hypot(*(seen[:, None] - placed[None]).transpose(2, 0, 1)) > self.tolerance).astype(float)
        rows, cols = linear_sum_assignment(far)
        return bool(far[rows, cols].sum() == 0)

    def __repr__(self) -> str:
        return (
            f"ShapeTask({len(self.shape)} points, tolerance={1000 * self.tolerance:.1f} mm, "
            f"rotate={self.rotate}, translate={self.translate})"
        )
