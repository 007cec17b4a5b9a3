"""Target sets for many parts: shapes a user can name or draw (for :class:`upm.control.ShapeTask`).

Every function returns an ``(n, 2)`` array of points [m] in the plate frame (x right, y up),
centred on ``center``:

* :func:`ring`: ``n`` points evenly round a circle;
* :func:`grid`: ``n`` points on a square lattice, row by row (a short last row centred);
* :func:`letter`: ``n`` points spread evenly over a capital letter drawn with a stroke font;
* :func:`from_mask`: ``n`` points spread evenly over any binary image (a drawn shape): the
  centroids of a k-means partition of its pixels (``scipy.cluster.vq.kmeans2``, a centroidal
  Voronoi tessellation), each pulled onto the mask if it fell outside.

>>> import upm
>>> upm.shapes.ring(12, 0.08).shape
(12, 2)
>>> upm.shapes.letter("L", 100, 0.26).shape  # doctest: +SKIP
(100, 2)

:func:`letter` and :func:`from_mask` need SciPy (``pip install 'upm[control]'``).
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import integer, point, real
from .._errors import ParameterError, ShapeError
from .._extras import need

__all__ = ["LETTERS", "from_mask", "grid", "letter", "min_spacing", "ring", "scatter"]

FloatArray = NDArray[np.float64]


def _center(center: ArrayLike) -> FloatArray:
    return np.asarray(point("center", center), dtype=np.float64)


def ring(n: int, radius: float, *, center: ArrayLike = (0.0, 0.0), phase: float = 0.0) -> FloatArray:
    """``n`` points evenly round a circle of ``radius`` [m], the first at angle ``phase`` [rad]."""
    n = integer("n", n, low=1)
    radius = real("radius", radius, low=0.0, low_open=True)
    phase = real("phase", phase)
    a = phase + 2 * np.pi * np.arange(n) / n
    out: FloatArray = _center(center) + radius * np.stack([np.cos(a), np.sin(a)], axis=1)
    return out


def grid(n: int, spacing: float, *, center: ArrayLike = (0.0, 0.0), columns: int | None = None) -> FloatArray:
    """``n`` points on a square lattice ``spacing`` [m] apart: ``columns`` a row (default
    ``ceil(sqrt(n))``), rows from the top, the last row centred when short."""
    n = integer("n", n, low=1)
    spacing = real("spacing", spacing, low=0.0, low_open=True)
    cols = math.ceil(math.sqrt(n)) if columns is None else integer("columns", columns, low=1)
    rows = math.ceil(n / cols)
    pts = []
    for r in range(rows):
        k = min(cols, n - r * cols)
        x = (np.arange(k) - (k - 1) / 2) * spacing
        y = np.full(k, ((rows - 1) / 2 - r) * spacing)
        pts.append(np.stack([x, y], axis=1))
    out: FloatArray = _center(center) + np.vstack(pts)
    return out


def _arc(
    cx: float, cy: float, rx: float, ry: float, a0: float, a1: float, k: int = 24
) -> list[tuple[float, float]]:
    t = np.radians(np.linspace(a0, a1, k))
    return [(cx + rx * math.cos(v), cy + ry * math.sin(v)) for v in t]


_W = 0.72  # a letter's width in units of its height
_O = _arc(0.36, 0.5, 0.36, 0.5, 0.0, 360.0, 40)
_P = [(0.0, 0.0), (0.0, 1.0), (0.5, 1.0), (0.7, 0.88), (0.7, 0.62), (0.5, 0.5), (0.0, 0.5)]

#: The stroke font of :func:`letter`: each capital a list of polylines in a box ``0.72`` wide
#: and ``1`` high (x right, y up).
LETTERS: dict[str, list[list[tuple[float, float]]]] = {
    "A": [[(0.0, 0.0), (0.36, 1.0), (0.72, 0.0)], [(0.14, 0.38), (0.58, 0.38)]],
    "B": [
        [(0.0, 0.0), (0.0, 1.0), (0.5, 1.0), (0.66, 0.9), (0.66, 0.62), (0.5, 0.52), (0.0, 0.52)],
        [(0.5, 0.52), (0.72, 0.42), (0.72, 0.1), (0.54, 0.0), (0.0, 0.0)],
    ],
    "C": [_arc(0.4, 0.5, 0.38, 0.5, 45.0, 315.0)],
    "D": [
        [(0.0, 0.0), (0.0, 1.0), (0.4, 1.0), (0.66, 0.8), (0.72, 0.5), (0.66, 0.2), (0.4, 0.0), (0.0, 0.0)]
    ],
    "E": [[(0.72, 1.0), (0.0, 1.0), (0.0, 0.0), (0.72, 0.0)], [(0.0, 0.52), (0.56, 0.52)]],
    "F": [[(0.72, 1.0), (0.0, 1.0), (0.0, 0.0)], [(0.0, 0.52), (0.56, 0.52)]],
    "G": [_arc(0.38, 0.5, 0.36, 0.5, 40.0, 360.0), [(0.74, 0.5), (0.42, 0.5)]],
    "H": [[(0.0, 0.0), (0.0, 1.0)], [(0.72, 0.0), (0.72, 1.0)], [(0.0, 0.5), (0.72, 0.5)]],
    "I": [[(0.36, 0.0), (0.36, 1.0)], [(0.1, 1.0), (0.62, 1.0)], [(0.1, 0.0), (0.62, 0.0)]],
    "J": [[(0.72, 1.0), (0.72, 0.3), *_arc(0.36, 0.3, 0.36, 0.3, 0.0, -180.0)]],
    "K": [[(0.0, 0.0), (0.0, 1.0)], [(0.72, 1.0), (0.0, 0.4)], [(0.24, 0.6), (0.72, 0.0)]],
    "L": [[(0.0, 1.0), (0.0, 0.0), (0.66, 0.0)]],
    "M": [[(0.0, 0.0), (0.0, 1.0), (0.36, 0.45), (0.72, 1.0), (0.72, 0.0)]],
    "N": [[(0.0, 0.0), (0.0, 1.0), (0.72, 0.0), (0.72, 1.0)]],
    "O": [_O],
    "P": [_P],
    "Q": [_O, [(0.45, 0.3), (0.76, 0.0)]],
    "R": [_P, [(0.35, 0.5), (0.72, 0.0)]],
    "S": [
        [
            (0.7, 0.9),
            (0.55, 1.0),
            (0.15, 1.0),
            (0.0, 0.88),
            (0.0, 0.62),
            (0.15, 0.52),
            (0.57, 0.48),
            (0.72, 0.38),
            (0.72, 0.12),
            (0.55, 0.0),
            (0.15, 0.0),
            (0.0, 0.1),
        ],
    ],
    "T": [[(0.0, 1.0), (0.72, 1.0)], [(0.36, 1.0), (0.36, 0.0)]],
    "U": [[(0.0, 1.0), (0.0, 0.3), *_arc(0.36, 0.3, 0.36, 0.3, 180.0, 360.0), (0.72, 1.0)]],
    "V": [[(0.0, 1.0), (0.36, 0.0), (0.72, 1.0)]],
    "W": [[(0.0, 1.0), (0.18, 0.0), (0.36, 0.6), (0.54, 0.0), (0.72, 1.0)]],
    "X": [[(0.0, 0.0), (0.72, 1.0)], [(0.0, 1.0), (0.72, 0.0)]],
    "Y": [[(0.0, 1.0), (0.36, 0.5), (0.72, 1.0)], [(0.36, 0.5), (0.36, 0.0)]],
    "Z": [[(0.0, 1.0), (0.72, 1.0), (0.0, 0.0), (0.72, 0.0)]],
}


def _segment_distance(p: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """Distance of each point ``p (P, 2)`` to the segment ``a``-``b``."""
    ab = b - a
    t = np.clip(((p - a) @ ab) / max(float(ab @ ab), 1e-300), 0.0, 1.0)
    d = p - (a + t[:, None] * ab)
    out: FloatArray = np.hypot(d[:, 0], d[:, 1])
    return out


def letter(
    ch: str,
    n: int,
    height: float,
    *,
    center: ArrayLike = (0.0, 0.0),
    stroke: float | None = None,
    seed: int = 0,
) -> FloatArray:
    """``n`` points spread evenly over the capital letter ``ch``, ``height`` [m] tall, drawn with
    strokes ``stroke`` [m] wide (default ``0.18 * height``; a wider stroke holds more parts), the
    letter's bounding box centred on ``center``.

    Raises :class:`upm.ParameterError` for a character the font does not have (:data:`LETTERS`).
    """
    if not isinstance(ch, str) or ch.upper() not in LETTERS:
        raise ParameterError(f"ch must be one letter A-Z; got {ch!r}")
    n = integer("n", n, low=1)
    height = real("height", height, low=0.0, low_open=True)
    width = 0.18 * height if stroke is None else real("stroke", stroke, low=0.0, low_open=True)
    lines = [np.asarray(line, dtype=np.float64) * height for line in LETTERS[ch.upper()]]
    lo = np.min(np.vstack(lines), axis=0) - width / 2
    hi = np.max(np.vstack(lines), axis=0) + width / 2
    # a raster of about 300 pixels a point (at least 200 along the height): fine enough that the
    # spread does not feel the pixels
    area = width * sum(float(np.sum(np.hypot(*np.diff(line, axis=0).T))) for line in lines)
    pixel = min(height / 200, math.sqrt(area / (300 * n)))
    xs = np.arange(lo[0] + pixel / 2, hi[0], pixel)
    ys = np.arange(lo[1] + pixel / 2, hi[1], pixel)
    px = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    near = np.full(len(px), np.inf)
    for line in lines:
        for a, b in itertools.pairwise(line):
            near = np.minimum(near, _segment_distance(px, a, b))
    inside = px[near <= width / 2]
    mid = (lo + hi) / 2
    return _spread(inside - mid, n, seed, pixel) + _center(center)


def from_mask(
    image: ArrayLike | str | Path,
    n: int,
    size: float,
    *,
    center: ArrayLike = (0.0, 0.0),
    invert: bool = False,
    seed: int = 0,
) -> FloatArray:
    """``n`` points spread evenly over the shape drawn in ``image``.

    Parameters
    ----------
    image : (H, W) or (H, W, C) array_like, or a path to an image file
        The shape: pixels that are nonzero (an array of bools or numbers), or brighter than mid
        grey (an image file, or an array of ``uint8`` with channels), are inside; ``invert`` for
        dark ink on a light background. Row 0 is the top of the shape (as an image is shown).
    n : int
        How many points (the mask must hold at least ``n`` pixels).
    size : float
        The image's longer side spans this on the plate [m]; the image is centred on ``center``.
    seed : int
        Seed of the k-means start (the same seed gives the same points).
    """
    n = integer("n", n, low=1)
    size = real("size", size, low=0.0, low_open=True)
    mask = _mask(image, invert)
    h, w = mask.shape
    pixel = size / max(h, w)
    rows, cols = np.nonzero(mask)
    if len(rows) < n:
        raise ParameterError(f"image: the shape holds {len(rows)} pixels, fewer than n = {n} points")
    xy = np.stack([(cols - (w - 1) / 2) * pixel, ((h - 1) / 2 - rows) * pixel], axis=1)
    return _spread(xy, n, seed, pixel) + _center(center)


def _mask(image: ArrayLike | str | Path, invert: bool) -> NDArray[np.bool_]:
    """The inside of ``image`` as an ``(H, W)`` boolean array."""
    if isinstance(image, (str, Path)):
        path = Path(image)
        if not path.is_file():
            raise ParameterError(f"image: no such file {str(path)!r}")
        iio = need("imageio.v3", "control", "reading a mask image", "imageio")
        try:
            pixels = np.asarray(iio.imread(path))
        except Exception as error:  # imageio raises a different error for every format
            raise ParameterError(f"image: cannot read {str(path)!r} as an image: {error}") from None
        grey = pixels[..., :3].mean(axis=-1) if pixels.ndim == 3 else pixels.astype(np.float64)
        top = 65535.0 if pixels.dtype == np.uint16 else 255.0 if pixels.dtype.kind in "ui" else 1.0
        inside = grey > top / 2
    else:
        a = np.asarray(image)
        if a.dtype == object or a.dtype.kind not in "biuf":
            raise ParameterError(
                f"image must be an array of bools or numbers, or a path; got dtype {a.dtype}"
            )
        if a.ndim == 3 and a.shape[2] in (1, 3, 4):
            top = 255.0 if a.dtype.kind in "ui" else 1.0
            inside = a[..., : min(3, a.shape[2])].astype(np.float64).mean(axis=-1) > top / 2
        elif a.ndim == 2:
            if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
                raise ParameterError("image must be finite")
            inside = a != 0
        else:
            raise ShapeError(f"image must have shape (H, W) or (H, W, 1|3|4); got {a.shape}")
    out: NDArray[np.bool_] = ~inside if invert else inside
    if out.shape[0] < 1 or out.shape[1] < 1:
        raise ShapeError(f"image must not be empty; got shape {out.shape}")
    return out


def _spread(xy: FloatArray, n: int, seed: int, pixel: float) -> FloatArray:
    """``n`` points spread evenly over the pixel centres ``xy (P, 2)``: a centroidal Voronoi
    tessellation by k-means, each centroid then pulled onto its nearest pixel (a centroid of a
    curved region may lie outside it)."""
    vq = need("scipy.cluster.vq", "control", "spreading points over a shape", "scipy")
    if len(xy) < n:
        raise ParameterError(f"the shape holds {len(xy)} pixels, fewer than n = {n} points: make it larger")
    if n == len(xy):
        return np.array(xy, dtype=np.float64)
    stride = max(1, len(xy) // (400 * n))  # enough pixels a point; no more than needed
    data = np.ascontiguousarray(xy[::stride], dtype=np.float64)
    if len(data) < n:
        data = np.ascontiguousarray(xy, dtype=np.float64)
    rng = np.random.default_rng(integer("seed", seed, low=0))
    centres, _ = vq.kmeans2(data, n, iter=60, minit="++", seed=rng, missing="raise")
    # onto the shape: the nearest pixel centre of any centroid farther than half a pixel from all
    spatial = need("scipy.spatial", "control", "spreading points over a shape", "scipy")
    dist, nearest = spatial.cKDTree(data).query(centres)
    off = dist > 0.75 * pixel * stride
    centres[off] = data[nearest[off]]
    out: FloatArray = np.asarray(centres, dtype=np.float64)
    return out


def min_spacing(points: ArrayLike) -> float:
    """The smallest distance between two of ``points (n, 2)`` [m] (``inf`` for fewer than two)."""
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ShapeError(f"points must have shape (n, 2); got {p.shape}")
    if len(p) < 2:
        return math.inf
    d = np.hypot(*(p[:, None] - p[None]).transpose(2, 0, 1))
    d[np.diag_indices(len(p))] = np.inf
    return float(d.min())


def scatter(rng: np.random.Generator, count: int, reach: float, gap: float) -> NDArray[np.float64]:
    """``count`` random points in the square of half-side ``reach`` [m], at least ``gap`` [m]
    apart (a starting layout of parts), drawn from ``rng``.

    Points are drawn one at a time, a draw too close to an earlier point drawn again. When
    ``200 count + 1000`` draws do not place them all (random sequential placement jams near half
    the square covered), the points are ``count`` random cells of the coarsest square lattice of
    cells at least ``gap`` wide, each point jittered within its cell's slack. `ParameterError`
    when that lattice has fewer than ``count`` cells."""
    pts: list[tuple[float, float]] = []  # (Python floats: a reset of an environment draws here)
    for _ in range(200 * count + 1000):
        if len(pts) == count:
            return np.array(pts, dtype=np.float64).reshape(-1, 2)
        px, py = rng.uniform(-reach, reach, 2).tolist()
        if all(math.hypot(px - qx, py - qy) > gap for qx, qy in pts):
            pts.append((px, py))
    if len(pts) == count:
        return np.array(pts, dtype=np.float64).reshape(-1, 2)
    k = int(2 * reach // gap) if gap > 0 else count
    if k * k < count:
        raise ParameterError(
            f"{count} points {gap:g} m apart do not fit a square of half-side {reach:g} m "
            f"(at most {k * k}); use fewer, or a larger square"
        )
    cell = 2 * reach / k
    cells = rng.choice(k * k, size=count, replace=False)
    centre = (np.stack([cells % k, cells // k], axis=1) + 0.5) * cell - reach
    slack = (cell - gap) / 2
    return np.asarray(centre + rng.uniform(-slack, slack, (count, 2)), dtype=np.float64)
