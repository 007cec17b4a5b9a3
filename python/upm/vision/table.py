"""The plate in the camera image: edges, Hough lines, four sides, corners, homography (docs/spec.md §8).

Frames: camera pixels have x to the right, y down and pixel centres at integer coordinates; the
plate frame has its origin at the plate's centre, metres, x along the plate side that appears
rightward in the image and y along the side that appears upward (right-handed, z towards the
camera). Corners are listed in the order ``(-w/2, -h/2), (w/2, -h/2), (w/2, h/2), (-w/2, h/2)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import as_float, check_range
from .._errors import ShapeError, VisionError
from ..plate.drive import PLATE_SIZE  # the side of the thesis's plate [m] (16 in), re-exported here


class Lens(Protocol):
    """What a :class:`Table` asks of a calibrated camera (:class:`upm.vision.Calibration`): pixels
    to plate coordinates and back through the lens model."""

    def to_plate(self, pixels: ArrayLike) -> NDArray[np.float64]: ...

    def to_camera(self, points: ArrayLike) -> NDArray[np.float64]: ...


__all__ = ["PLATE_SIZE", "Table", "check_frame", "find_table", "plate_corners", "project"]

FloatArray = NDArray[np.float64]


def plate_corners(plate_size: float | tuple[float, float]) -> FloatArray:
    """The plate's corners ``(4, 2)`` [m] in the plate frame, in the library's order."""
    w, h = _sides(plate_size)
    return np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]])


def _sides(plate_size: float | tuple[float, float] | ArrayLike) -> tuple[float, float]:
    given = as_float("plate_size", plate_size)
    if given.shape not in ((), (1,), (2,)):
        raise ShapeError(f"plate_size must be one side or (width, height) [m]; got shape {given.shape}")
    s = np.broadcast_to(given, (2,))
    check_range("plate_size", s, low=0.0, low_open=True)
    return float(s[0]), float(s[1])


def project(homography: FloatArray, points: ArrayLike) -> FloatArray:
    """Apply a ``(3, 3)`` homography to points ``(..., 2)``."""
    p = np.asarray(points, dtype=np.float64)
    q = p @ homography[:, :2].T + homography[:, 2]
    return q[..., :2] / q[..., 2:]


def homography(src: FloatArray, dst: FloatArray) -> FloatArray:
    """The homography taking 4 points ``src`` to ``dst`` exactly (float64 DLT):
    ``cv2.getPerspectiveTransform`` takes float32 points and ``cv2.findHomography`` leaves
    ~1e-5 px at the corners; the frames' round trips here are exact to 1e-12."""
    a = np.zeros((8, 8))
    b = np.zeros(8)
    for i, ((x, y), (u, v)) in enumerate(zip(src, dst, strict=True)):
        a[2 * i] = [x, y, 1, 0, 0, 0, -u * x, -u * y]
        a[2 * i + 1] = [0, 0, 0, x, y, 1, -v * x, -v * y]
        b[2 * i], b[2 * i + 1] = u, v
    return np.append(np.linalg.solve(a, b), 1.0).reshape(3, 3)


def check_frame(frame: object, name: str = "frame") -> NDArray[np.uint8]:
    """``frame`` as a (H, W) or (H, W, 3) uint8 image; `VisionError` saying what is wrong."""
    if not isinstance(frame, np.ndarray):
        raise VisionError(
            f"{name} must be a numpy array (H, W) or (H, W, 3) of uint8; got {type(frame).__name__}"
        )
    if frame.dtype != np.uint8:
        raise VisionError(f"{name} must have dtype uint8 (8-bit camera frames); got {frame.dtype}")
    if not (frame.ndim == 2 or (frame.ndim == 3 and frame.shape[2] in (1, 3))):
        raise VisionError(f"{name} must have shape (H, W) grey or (H, W, 3) BGR; got {frame.shape}")
    if frame.shape[0] < 32 or frame.shape[1] < 32:
        raise VisionError(
            f"{name} is too small to hold a plate: {frame.shape[:2]} (need at least 32 x 32 px)"
        )
    return frame[..., 0] if frame.ndim == 3 and frame.shape[2] == 1 else frame


def grey_of(frame: NDArray[np.uint8]) -> NDArray[np.uint8]:
    return frame if frame.ndim == 2 else np.asarray(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), np.uint8)


@dataclass(frozen=True)
class Table:
    """The plate as seen by the camera.

    Attributes
    ----------
    corners : (4, 2) ndarray
        Corners [px] in the order of :func:`plate_corners`.
    plate_size : (float, float)
        Plate width and height [m].
    plate_from_camera, camera_from_plate : (3, 3) ndarray
        Homographies between camera pixels and plate coordinates [m].
    image_size : (int, int)
        Width and height of the frames it was found in [px].
    residual : float
        RMS distance [px] of the edge points from the four fitted sides (a calibrated table:
        the calibration's reprojection error).
    lens : Calibration or None
        A calibrated camera (:meth:`upm.vision.Calibration.table`): pixels map to the plate
        through its lens model, and the homographies are only its best straight approximation.
    """

    corners: FloatArray
    plate_size: tuple[float, float]
    plate_from_camera: FloatArray
    camera_from_plate: FloatArray
    image_size: tuple[int, int]
    residual: float = 0.0
    lens: Lens | None = None

    @classmethod
    def from_corners(cls, corners: ArrayLike, plate_size: float | tuple[float, float] = PLATE_SIZE,
                     image_size: tuple[int, int] = (640, 480)) -> Table:  # fmt: skip
        """A table from known corner pixels (e.g. clicked by hand, or from a calibration)."""
        c = as_float("corners", corners)
        if c.shape != (4, 2):
            raise VisionError(f"corners must have shape (4, 2) [px]; got {c.shape}")
        sides = _sides(plate_size)
        plate = plate_corners(sides)
        try:
            cam = homography(plate, c)
            back = homography(c, plate)
        except np.linalg.LinAlgError as error:
            raise VisionError(f"corners {c.tolist()} are degenerate (three on a line)") from error
        return cls(c, sides, back, cam, image_size)

    @property
    def pixels_per_metre(self) -> float:
        """Mean image scale over the plate [px/m]."""
        c = self.corners
        sides = np.linalg.norm(np.roll(c, -1, axis=0) - c, axis=1)
        return float(np.mean(sides / np.array(self.plate_size * 2)))

    def to_plate(self, pixels: ArrayLike) -> FloatArray:
        """Camera pixels ``(..., 2)`` to plate coordinates [m]."""
        if self.lens is not None:
            return self.lens.to_plate(pixels)
        return project(self.plate_from_camera, pixels)

    def to_camera(self, points: ArrayLike) -> FloatArray:
        """Plate coordinates [m] ``(..., 2)`` to camera pixels."""
        if self.lens is not None:
            return self.lens.to_camera(points)
        return project(self.camera_from_plate, points)

    def contains(self, points: ArrayLike, margin: float = 0.0) -> NDArray[np.bool_]:
        """Whether plate points [m] lie on the plate (shrunk by ``margin`` [m])."""
        p = np.asarray(points, dtype=np.float64)
        w, h = self.plate_size
        return (np.abs(p[..., 0]) <= w / 2 - margin) & (np.abs(p[..., 1]) <= h / 2 - margin)


def _hough_sides(edges: NDArray[np.uint8], size: tuple[int, int]) -> NDArray[np.float64]:
    """The four strongest distinct Hough lines ``(rho, theta)``, or `VisionError`."""
    w, h = size
    lines = cv2.HoughLines(edges, 1, math.pi / 360, threshold=max(min(w, h) // 8, 10))
    if lines is None:
        raise VisionError("no table found: no straight edges in the frame")
    chosen: list[tuple[float, float]] = []
    for rho, theta in lines[:, 0, :]:
        duplicate = False
        for r0, t0 in chosen:
            dt = abs(theta - t0)
            same = dt < math.radians(8) and abs(rho - r0) < 0.06 * max(w, h)
            flipped = math.pi - dt < math.radians(8) and abs(rho + r0) < 0.06 * max(w, h)
            duplicate |= same or flipped
        if not duplicate:
            chosen.append((float(rho), float(theta)))
        if len(chosen) == 4:
            break
    if len(chosen) < 4:
        raise VisionError(f"no table found: only {len(chosen)} distinct straight edges (need 4 sides)")
    return np.array(chosen)


def _intersect(a: FloatArray, b: FloatArray) -> FloatArray:
    """Intersection of two lines given as ``(nx, ny, c)`` with ``nx x + ny y = c``."""
    m = np.array([a[:2], b[:2]])
    return np.linalg.solve(m, np.array([a[2], b[2]]))


def _quad(lines: FloatArray) -> FloatArray:
    """Corners of the quadrilateral formed by four lines ``(nx, ny, c)``: opposite sides are the
    pairing whose lines are closest to parallel."""
    best = None
    for pair in ([(0, 1), (2, 3)], [(0, 2), (1, 3)], [(0, 3), (1, 2)]):
        skew = sum(abs(float(lines[i, 0] * lines[j, 1] - lines[i, 1] * lines[j, 0])) for i, j in pair)
        if best is None or skew < best[0]:
            best = (skew, pair)
    assert best is not None
    (a, b), (c, d) = best[1]
    try:
        pts = np.array([_intersect(lines[i], lines[j]) for i, j in ((a, c), (c, b), (b, d), (d, a))])
    except np.linalg.LinAlgError as error:
        raise VisionError(
            "no table found: two of the four sides are parallel lines that never meet"
        ) from error
    return pts


def _order(corners: FloatArray) -> FloatArray:
    """Corners sorted into the plate frame's order: plate x rightward, plate y upward in the image."""
    centre = corners.mean(axis=0)
    angle = np.arctan2(-(corners[:, 1] - centre[1]), corners[:, 0] - centre[0])  # y up
    ccw = corners[np.argsort(angle)]  # counter-clockwise as seen with y up
    start = int(np.argmin([abs(math.remainder(a + 3 * math.pi / 4, 2 * math.pi)) for a in np.sort(angle)]))
    return np.roll(ccw, -start, axis=0)


def _refine_side(grey: NDArray[np.float32], p: FloatArray, q: FloatArray, reach: float) -> FloatArray | None:
    """Subpixel edge points along the side from ``p`` to ``q``: on each normal profile, where the
    intensity crosses halfway between the plate's and the background's levels."""
    length = float(np.linalg.norm(q - p))
    if length < 8:
        return None
    d = (q - p) / length
    n = np.array([-d[1], d[0]])
    s = np.linspace(0.08, 0.92, max(int(length / 3), 8))[:, None]
    base = p + s * (q - p)
    offsets = np.arange(-reach, reach + 0.25, 0.25)
    pts = base[:, None, :] + offsets[None, :, None] * n
    prof = cv2.remap(grey, pts[..., 0].astype(np.float32), pts[..., 1].astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE)  # fmt: skip
    k = max(len(offsets) // 6, 2)
    lo, hi = prof[:, :k].mean(axis=1), prof[:, -k:].mean(axis=1)
    contrast = hi - lo
    good = np.abs(contrast) > max(0.25 * float(np.median(np.abs(contrast))), 10.0)
    z = (prof - ((lo + hi) / 2)[:, None]) * np.sign(contrast)[:, None]
    up = (z[:, :-1] < 0) & (z[:, 1:] >= 0)
    good &= up.sum(axis=1) == 1  # clutter (a part at the edge, an occluder): skip this profile
    rows = np.nonzero(good)[0]
    if len(rows) < 6:
        return None
    j = np.argmax(up[rows], axis=1)
    z0, z1 = z[rows, j], z[rows, j + 1]
    t = offsets[j] + (offsets[1] - offsets[0]) * (-z0) / (z1 - z0)
    return np.asarray(base[rows] + t[:, None] * n, dtype=np.float64)


def _fit_line(points: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Total-least-squares line ``(nx, ny, c)`` through ``points``, with outliers (> 3 robust
    sigma) removed twice; returns the line and the residuals of the kept points."""
    keep = np.ones(len(points), bool)
    for _ in range(3):
        pts = points[keep]
        centre = pts.mean(axis=0)
        _, _, vt = np.linalg.svd(pts - centre, full_matrices=False)
        normal = vt[1]
        res = (points - centre) @ normal
        sigma = 1.4826 * float(np.median(np.abs(res[keep]))) + 0.02
        keep = np.abs(res) < 3 * sigma
        if keep.sum() < 4:
            break
    return np.append(normal, normal @ centre), res[keep]


#: The least share of its convex hull the plate's bright region fills (a plate: 0.99 clear, lower
#: with parts or an arm over its edge).
MIN_SOLIDITY = 0.8


def find_table(frame: ArrayLike, plate_size: float | tuple[float, float] = PLATE_SIZE) -> Table:
    """Find the plate in a camera frame (docs/spec.md §8).

    Canny edges, Hough votes ``(rho, theta)``, the four strongest distinct lines, consecutive
    intersections; then each side is refitted by total least squares to subpixel edge points
    (where the intensity profile across the side crosses halfway between plate and background,
    robust to parts and occluders touching the edge), and the corners are the refitted sides'
    intersections.

    Parameters
    ----------
    frame : (H, W) or (H, W, 3) uint8 ndarray
        A camera frame: a light plate on a dark background.
    plate_size : float or (float, float)
        Plate side(s) [m].

    Returns
    -------
    Table
        Corners [px], homographies and the plate's size.

    Raises
    ------
    VisionError
        If the frame is not an 8-bit image, is blank, or holds no quadrilateral plate.
    """
    img = check_frame(frame)
    sides = _sides(plate_size)
    grey = grey_of(img)
    h, w = grey.shape
    if float(grey.std()) < 3.0:
        raise VisionError(
            f"no table found: the frame is blank (grey level {float(grey.mean()):.0f} everywhere)"
        )
    smooth = cv2.GaussianBlur(grey, (5, 5), 1.2)
    _, bright = cv2.threshold(smooth, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
    contours, _ = cv2.findContours(bright, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        raise VisionError("no table found: nothing bright in the frame")
    region = max(contours, key=cv2.contourArea)
    if cv2.contourArea(region) < 0.05 * w * h:
        raise VisionError(
            f"no table found: the largest bright region covers {cv2.contourArea(region) / (w * h):.1%} "
            "of the frame (a plate needs 5%)"
        )
    hull = cv2.convexHull(region)
    solidity = cv2.contourArea(region) / max(cv2.contourArea(hull), 1.0)
    if solidity < MIN_SOLIDITY:
        # a plate is a convex quadrilateral, parts and arms cut into its outline only at its edge;
        # noise or texture gives a ragged bright region (seen: 0.43-0.61 on random frames)
        raise VisionError(
            f"no table found: the largest bright region is ragged (it fills {solidity:.0%} of its convex "
            f"hull; a plate fills at least {MIN_SOLIDITY:.0%}): noise, texture or no plate in view"
        )
    # the edge of the plate region's convex hull: parts and arms cutting into the plate are bridged
    edges = np.zeros_like(grey)
    cv2.polylines(edges, [hull], True, 255, 1)
    hough = _hough_sides(edges, (w, h))
    lines = np.column_stack([np.cos(hough[:, 1]), np.sin(hough[:, 1]), hough[:, 0]])
    corners = _order(_quad(lines))
    span = np.ptp(corners, axis=0)
    if (
        span.min() < 0.1 * min(w, h)
        or np.any(corners < -0.5 * max(w, h))
        or np.any(corners > 1.5 * max(w, h))
    ):
        raise VisionError(
            "no table found: the four strongest edges do not bound a plate "
            f"(corners {corners.round(1).tolist()})"
        )
    fine = grey.astype(np.float32)
    refined, residuals = [], []
    for i in range(4):
        pts = _refine_side(fine, corners[i], corners[(i + 1) % 4], reach=6.0)
        if pts is None:
            raise VisionError(f"no table found: side {i} of the plate has no clear edge")
        line, res = _fit_line(pts)
        refined.append(line)
        residuals.append(res)
    quad = np.array([_intersect(refined[i - 1], refined[i]) for i in range(4)])
    quad = _order(quad)
    rms = float(np.sqrt(np.mean(np.concatenate(residuals) ** 2)))
    table = Table.from_corners(quad, sides, (w, h))
    return Table(table.corners, sides, table.plate_from_camera, table.camera_from_plate, (w, h), rms)
