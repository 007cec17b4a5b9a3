"""Poses ``(x, y, theta)`` of polygon parts seen from above (issue 27, docs/polygons.md).

Parts are found as round parts are (:func:`upm.vision.find_parts`, with the polygon's
circumradius): their centres are the centroids of their coverage in the rectified top view. The
angle then comes from the part's complex moments about that centroid,

    O_j = ∫ w(z) z^j dA,     z = (x - x_c) + i (y - y_c) on the plate,

with ``w`` the coverage (the colour difference from the plate projected on the part's own
colour). Turning a shape by ``theta`` multiplies its moments by ``e^{i j theta}``, so the angle
is where the rotational cross-correlation ``sum_j Re(O_j conj(T_j) e^{-i j theta})`` with the
outline's own moments ``T_j`` (exact, by quadrature over the triangles of the outline) is
largest, over the orders ``j = 2..12`` (order 1 vanishes about the centroid). A shape with
``k``-fold symmetry has ``T_j = 0`` unless ``k`` divides ``j``, so the angle is found modulo
``2 pi / k`` (a square's modulo 90°, a rectangle's modulo 180°), as it must be.

Given several shapes (parts of mixed shapes), each part is told by its moments too: the shape
whose moments correlate best with the part's after the best turn, normalised (1 for the same
shape), less the log of the ratio of the seen area to the shape's, names it (:attr:`Poses.kinds`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import as_float, integer
from .._errors import ParameterError
from ..physics.polygon import Polygon
from .parts import THESIS_PALETTE, Palette, Parts, Rectifier, seen_parts
from .table import Table

__all__ = ["Poses", "angle_error", "find_poses"]

FloatArray = NDArray[np.float64]

#: Complex moment orders used for the angle.
ORDERS = np.arange(2, 13)
#: Grid of the angle search [rad] before the parabolic refinement.
GRID = math.radians(0.25)


@dataclass(frozen=True)
class Poses:
    """Poses of polygon parts found in one frame, in the order of :attr:`parts`.

    Attributes
    ----------
    positions : (N, 2) ndarray
        Where the part's frame origin is on the plate [m]: with ``angles``, ``Polygon(vertices,
        position, angle)`` redraws the part (the pose :func:`upm.simulate` records).
    centroids : (N, 2) ndarray
        The parts' centroids on the plate [m].
    angles : (N,) ndarray
        Orientation of the part's frame [rad], in ``[0, 2 pi / symmetry)``.
    symmetry : int
        The outline's rotational symmetry: angles are known modulo ``2 pi / symmetry`` (the
        first shape's, given several: see :attr:`symmetries`).
    parts : Parts
        The detections (labels, contrast, visible area).
    kinds : (N,) ndarray of int
        Which of the shapes each part is (all 0 for one shape; -1 for a part too near the
        view's edge to tell among several, whose angle is NaN too).
    symmetries : (N,) ndarray of int
        Each part's symmetry (its shape's).
    """

    positions: FloatArray
    centroids: FloatArray
    angles: FloatArray
    symmetry: int
    parts: Parts
    kinds: NDArray[np.int64]
    symmetries: NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.angles)


def angle_error(measured: ArrayLike, true: ArrayLike, symmetry: int = 1) -> FloatArray:
    """The orientation error [deg] of ``measured`` against ``true`` angles [rad] for a shape with
    ``symmetry``-fold rotational symmetry: in ``(-180/k, 180/k]``."""
    k = integer("symmetry", symmetry, low=1)
    period = 2 * np.pi / k
    d = np.mod(as_float("measured", measured) - as_float("true", true) + period / 2, period) - period / 2
    out: FloatArray = np.degrees(d)
    return out


def _about_centroid(part: Polygon) -> FloatArray:
    out: FloatArray = np.asarray(part.vertices, np.float64) - part.centroid
    return out


def outline_moments(part: Polygon, orders: NDArray[np.int64] = ORDERS) -> NDArray[np.complex128]:
    """``T_j = ∫ z^j dA`` over the outline about its centroid, in the part's frame [m^(j+2)]:
    Gauss–Legendre (16 x 16, exact for these polynomial degrees) over the triangles that fan from
    the centroid."""
    v = _about_centroid(part)
    x, w = np.polynomial.legendre.leggauss(16)
    x, w = (x + 1) / 2, w / 2
    a = v[:, 0] + 1j * v[:, 1]
    b = np.roll(a, -1)
    jac = (a.real * b.imag - a.imag * b.real)[:, None, None]
    # the triangle (0, a, b) as s (a + t (b - a)), dA = s |a x b| ds dt
    z = x[None, :, None] * (a[:, None, None] + x[None, None, :] * (b - a)[:, None, None])
    dA = jac * (w[:, None] * x[:, None])[None] * w[None, None, :]
    out: NDArray[np.complex128] = np.array([(z**j * dA).sum() for j in orders])
    return out


def find_poses(
    frame: ArrayLike,
    table: Table,
    part: Polygon | Sequence[Polygon],
    *,
    palette: Palette | None = THESIS_PALETTE,
    min_contrast: float = 30.0,
    max_parts: int | None = None,
) -> Poses:
    """Find the parts of shape ``part`` (or of any of several shapes) on the plate and their
    poses (module docs).

    Parameters
    ----------
    frame : (H, W, 3) BGR or (H, W) grey uint8 ndarray
        A camera frame of the size ``table`` was found in.
    table : Table
        The plate.
    part : upm.Polygon or sequence of them
        The parts' shape (its vertices; its position and angle are ignored), or the shapes
        parts may have: each part is then told by its moments and area (:attr:`Poses.kinds`).
    palette, min_contrast, max_parts
        As :func:`upm.vision.find_parts`.
    """
    shapes = [part] if isinstance(part, Polygon) else list(part) if isinstance(part, (list, tuple)) else None
    if not shapes or not all(isinstance(p, Polygon) for p in shapes):
        raise ParameterError(f"part must be a upm.Polygon or a non-empty list of them; got {part!r}")
    reach = max(p.radius for p in shapes)
    parts, rect, top, background = seen_parts(frame, table, reach, palette, min_contrast, max_parts)
    symmetries = np.array([p.symmetry for p in shapes], dtype=np.int64)
    templates = [outline_moments(p) for p in shapes]
    diff = top.astype(np.float32) - background
    centres = rect.to_top(parts.positions) if len(parts) else np.zeros((0, 2))
    found = [_pose(diff, c, rect, shapes, templates, symmetries) for c in centres]
    kinds = np.array([k for k, _ in found], dtype=np.int64)
    angles = np.array([a for _, a in found], dtype=np.float64)
    offsets = [shapes[k].centroid_offset(a) for k, a in found]
    if len(shapes) > 1:
        kinds[np.isnan(angles)] = -1
    return Poses(
        positions=parts.positions - np.reshape(offsets, (-1, 2)),
        centroids=parts.positions,
        angles=angles,
        symmetry=int(symmetries[0]),
        parts=parts,
        kinds=kinds,
        symmetries=np.where(kinds >= 0, symmetries[np.maximum(kinds, 0)], 1),
    )


def _pose(
    diff: NDArray[np.float32],
    centre: FloatArray,
    rect: Rectifier,
    shapes: list[Polygon],
    templates: list[NDArray[np.complex128]],
    symmetries: NDArray[np.int64],
) -> tuple[int, float]:
    """Which of ``shapes`` the part centred at top-view pixel ``centre`` is, and its angle
    (module docs); ``(0, nan)`` when it is too near the view's edge to tell."""
    s = rect.scale
    radius = max(p.radius for p in shapes)
    reach = math.ceil(radius * s + 3)
    x0, y0 = (int(np.rint(v)) - reach for v in centre)
    h, w = diff.shape[:2]
    if x0 < 0 or y0 < 0 or x0 + 2 * reach + 1 > w or y0 + 2 * reach + 1 > h:
        return 0, math.nan
    patch = diff[y0 : y0 + 2 * reach + 1, x0 : x0 + 2 * reach + 1].astype(np.float64)
    ys, xs = np.mgrid[y0 : y0 + 2 * reach + 1, x0 : x0 + 2 * reach + 1].astype(np.float64)
    dx, dy = (xs - centre[0]) / s, -(ys - centre[1]) / s  # plate frame: the top view's y is down
    r2 = dx * dx + dy * dy
    # the part's colour: the mean difference well inside it (inside the smallest shape)
    inner = r2 < (0.3 * math.sqrt(min(p.area for p in shapes) / math.pi)) ** 2
    colour = patch[inner].mean(axis=0) if inner.any() else patch.reshape(-1, patch.shape[2]).mean(axis=0)
    norm2 = float(colour @ colour)
    if norm2 <= 0:
        return 0, math.nan
    cover = np.clip(patch @ colour / norm2, 0.0, 1.0)
    cover[r2 > (radius + 2.5 / s) ** 2] = 0.0  # keep neighbours out
    z = (dx + 1j * dy)[cover > 0]
    wts = cover[cover > 0] / (s * s)
    observed = np.array([(wts * z**j).sum() for j in ORDERS])
    seen_area = float(wts.sum())
    best: tuple[float, int, float] = (-math.inf, 0, math.nan)
    for kind, (part, moments) in enumerate(zip(shapes, templates, strict=True)):
        angle, fit = _angle(observed, radius, moments, int(symmetries[kind]))
        if len(shapes) > 1:
            fit -= abs(math.log(max(seen_area, 1e-300) / part.area))
        if fit > best[0]:
            best = (fit, kind, angle)
    return best[1], best[2]


def _angle(
    observed: NDArray[np.complex128], radius: float, templates: NDArray[np.complex128], k: int
) -> tuple[float, float]:
    """The angle of the part whose moments are ``observed`` as ``part`` (module docs), and the
    normalised correlation there (1 for the same shape): each order scaled by ``radius``."""
    scale = radius**ORDERS
    o, t = observed / scale, templates / scale
    weights = o * np.conj(t)
    period = 2 * math.pi / k
    grid = np.arange(0.0, period, GRID)
    score = (weights[None, :] * np.exp(-1j * np.outer(grid, ORDERS))).real.sum(axis=1)
    i = int(np.argmax(score))
    left, mid, right = score[i - 1], score[i], score[(i + 1) % len(grid)]
    curvature = left - 2 * mid + right
    shift = 0.5 * (left - right) / curvature if curvature < 0 else 0.0
    norm = math.sqrt(float(np.sum(np.abs(o) ** 2) * np.sum(np.abs(t) ** 2)))
    fit = float(mid) / norm if norm > 0 else 0.0
    return float(np.mod(grid[i] + shift * GRID, period)), fit
