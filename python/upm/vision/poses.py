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
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import as_float, instance, integer
from ..polygon import Polygon
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
        The outline's rotational symmetry: angles are known modulo ``2 pi / symmetry``.
    parts : Parts
        The detections (labels, contrast, visible area).
    """

    positions: FloatArray
    centroids: FloatArray
    angles: FloatArray
    symmetry: int
    parts: Parts

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
    part: Polygon,
    *,
    palette: Palette | None = THESIS_PALETTE,
    min_contrast: float = 30.0,
    max_parts: int | None = None,
) -> Poses:
    """Find the parts of shape ``part`` on the plate and their poses (module docs).

    Parameters
    ----------
    frame : (H, W, 3) BGR or (H, W) grey uint8 ndarray
        A camera frame of the size ``table`` was found in.
    table : Table
        The plate.
    part : upm.Polygon
        The parts' shape (its vertices; its position and angle are ignored).
    palette, min_contrast, max_parts
        As :func:`upm.vision.find_parts`.
    """
    instance("part", part, Polygon, "a upm.Polygon")
    parts, rect, top, background = seen_parts(frame, table, part.radius, palette, min_contrast, max_parts)
    k = part.symmetry
    templates = outline_moments(part)
    diff = top.astype(np.float32) - background
    centres = rect.to_top(parts.positions) if len(parts) else np.zeros((0, 2))
    angles = np.array([_angle(diff, c, rect, part, templates, k) for c in centres])
    return Poses(
        positions=parts.positions - part.centroid_offset(angles).reshape(-1, 2),
        centroids=parts.positions,
        angles=angles,
        symmetry=k,
        parts=parts,
    )


def _angle(
    diff: NDArray[np.float32],
    centre: FloatArray,
    rect: Rectifier,
    part: Polygon,
    templates: NDArray[np.complex128],
    k: int,
) -> float:
    """The angle of the part centred at top-view pixel ``centre`` (module docs)."""
    s = rect.scale
    reach = math.ceil(part.radius * s + 3)
    x0, y0 = (int(np.rint(v)) - reach for v in centre)
    h, w = diff.shape[:2]
    if x0 < 0 or y0 < 0 or x0 + 2 * reach + 1 > w or y0 + 2 * reach + 1 > h:
        return math.nan
    patch = diff[y0 : y0 + 2 * reach + 1, x0 : x0 + 2 * reach + 1].astype(np.float64)
    ys, xs = np.mgrid[y0 : y0 + 2 * reach + 1, x0 : x0 + 2 * reach + 1].astype(np.float64)
    dx, dy = (xs - centre[0]) / s, -(ys - centre[1]) / s  # plate frame: the top view's y is down
    r2 = dx * dx + dy * dy
    # the part's colour: the mean difference well inside it
    inner = r2 < (0.3 * math.sqrt(part.area / math.pi)) ** 2
    colour = patch[inner].mean(axis=0) if inner.any() else patch.reshape(-1, patch.shape[2]).mean(axis=0)
    norm2 = float(colour @ colour)
    if norm2 <= 0:
        return math.nan
    cover = np.clip(patch @ colour / norm2, 0.0, 1.0)
    cover[r2 > (part.radius + 2.5 / s) ** 2] = 0.0  # keep neighbours out
    z = (dx + 1j * dy)[cover > 0]
    wts = cover[cover > 0] / (s * s)
    observed = np.array([(wts * z**j).sum() for j in ORDERS])
    scale = part.radius ** (2 * ORDERS) * part.area**2
    weights = observed * np.conj(templates) / scale
    period = 2 * math.pi / k
    grid = np.arange(0.0, period, GRID)
    score = (weights[None, :] * np.exp(-1j * np.outer(grid, ORDERS))).real.sum(axis=1)
    i = int(np.argmax(score))
    left, mid, right = score[i - 1], score[i], score[(i + 1) % len(grid)]
    curvature = left - 2 * mid + right
    shift = 0.5 * (left - right) / curvature if curvature < 0 else 0.0
    return float(np.mod(grid[i] + shift * GRID, period))
