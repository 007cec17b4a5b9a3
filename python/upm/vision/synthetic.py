"""Synthetic camera frames of a plate with parts on it, with exact ground truth.

A pinhole camera above the plate (:class:`Camera`) sees a dark background, the light plate and
the parts through a perspective homography. :func:`render` draws them with 4 x 4 supersampling
(edges are area-weighted, so centres are unbiased to about 0.01 px), then applies a smooth
lighting gradient with vignetting, a Gaussian lens blur, optional occluders (an arm reaching in)
and Gaussian noise in grey levels. The returned :class:`Truth` holds the plate corners and the part
centres in camera pixels (the projection of each part's centre), their labels and the fraction
of each part left visible.

:class:`VirtualCamera` reads frames of a :class:`upm.plant.SimulatedUPM` (or of any object with
``parts``) like an OpenCV ``VideoCapture``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import as_float, check_range
from .._errors import ParameterError, ShapeError
from .table import PLATE_SIZE, plate_corners, project

if TYPE_CHECKING:
    from .calibration import CharucoBoard

__all__ = ["COLORS", "Camera", "Frame", "Truth", "VirtualCamera", "render", "render_board", "through_lens"]

FloatArray = NDArray[np.float64]

#: Nominal colours (BGR, 0–255) under uniform light: the chips are as bright as the plate in grey
#: (``0.299 R + 0.587 G + 0.114 B``), so only their colour sets them apart.
COLORS: dict[str, tuple[float, float, float]] = {
    "background": (25.0, 25.0, 25.0),
    "plate": (150.0, 150.0, 150.0),
    "penny": (45.0, 85.0, 140.0),
    "red": (110.0, 125.0, 220.0),
    "blue": (235.0, 165.0, 80.0),
    "occluder": (60.0, 55.0, 50.0),
}

#: Part radii [m]: a US penny (19.05 mm across) and a poker chip (39 mm).
RADII: dict[str, float] = {"penny": 0.009525, "red": 0.0195, "blue": 0.0195}

_SS = 4  # supersampling factor per axis
_SHIFT = 4  # fractional bits of cv2.fillPoly's coordinates


@dataclass(frozen=True)
class Camera:
    """A pinhole camera looking down at a square plate.

    Parameters
    ----------
    size : (int, int)
        Image width and height [px].
    plate_size : float
        Side of the plate [m] (default 16 in, the thesis's plate).
    fill : float
        Fraction of the image height the plate spans when seen straight down.
    tilt, yaw : float
        Rotation of the camera about the plate's x axis and about its optical axis [rad]; keep
        ``|yaw| < pi/4`` so the plate's x axis stays the image's rightward side.
    shift : (float, float)
        Offset of the plate's image from the image centre [px].
    height : float
        Height of the camera above the plate [m] (perspective strength).
    distortion : float
        Radial lens distortion: the fraction by which a point at the image's corner is pushed out
        (> 0, pincushion) or pulled in (< 0, barrel) from where a pinhole would see it; OpenCV's
        ``k1`` only (:attr:`dist_coeffs`). 0: a pinhole.
    """

    size: tuple[int, int] = (640, 480)
    plate_size: float = PLATE_SIZE
    fill: float = 0.8
    tilt: float = 0.08
    yaw: float = 0.03
    shift: tuple[float, float] = (0.0, 0.0)
    height: float = 1.2
    distortion: float = 0.0

    def __post_init__(self) -> None:
        w, h = self.size
        if not (isinstance(w, int) and isinstance(h, int) and w >= 32 and h >= 32):
            raise ParameterError(f"size must be two integers >= 32 (width, height) [px]; got {self.size}")
        for name in ("plate_size", "fill", "height"):
            check_range(name, as_float(name, getattr(self, name)), low=0.0, low_open=True)
        check_range("tilt", as_float("tilt", self.tilt), low=-1.0, high=1.0)
        check_range("yaw", as_float("yaw", self.yaw), low=-math.pi / 4, high=math.pi / 4, low_open=True,
                    high_open=True)  # fmt: skip
        check_range("distortion", as_float("distortion", self.distortion), low=-0.2, high=0.2)

    @property
    def intrinsics(self) -> FloatArray:
        """The camera matrix ``(3, 3)`` [px]."""
        w, h = self.size
        f = self.fill * h * self.height / self.plate_size
        return np.array([[f, 0.0, w / 2 + self.shift[0]], [0.0, f, h / 2 + self.shift[1]], [0.0, 0.0, 1.0]])

    @property
    def dist_coeffs(self) -> FloatArray:
        """OpenCV's distortion ``(k1, k2, p1, p2, k3)`` of :attr:`distortion`."""
        w, h = self.size
        corner = math.hypot(w / 2, h / 2) / self.intrinsics[0, 0]  # the corner's normalised radius
        return np.array([self.distortion / corner**2, 0.0, 0.0, 0.0, 0.0])

    @property
    def pose(self) -> tuple[FloatArray, FloatArray]:
        """The plate's pose in the camera: rotation ``(3, 3)`` and translation ``(3,)`` [m]
        (``camera = rotation @ plate + translation``)."""
        # camera axes seen from above: x along the plate's x, y along the plate's -y, z down
        down = np.diag([1.0, -1.0, -1.0])
        ct, st, cy, sy = math.cos(self.tilt), math.sin(self.tilt), math.cos(self.yaw), math.sin(self.yaw)
        tilt = np.array([[1.0, 0.0, 0.0], [0.0, ct, -st], [0.0, st, ct]])
        yaw = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
        return yaw @ tilt @ down, np.array([0.0, 0.0, self.height])

    @property
    def camera_from_plate(self) -> FloatArray:
        """The homography ``(3, 3)`` from plate coordinates [m] to camera pixels of a pinhole
        (before the lens's :attr:`distortion`, which :meth:`distort` adds)."""
        r, t = self.pose
        m = self.intrinsics @ np.column_stack([r[:, 0], r[:, 1], t])
        return np.asarray(m / m[2, 2], dtype=np.float64)

    def distort(self, pixels: ArrayLike) -> FloatArray:
        """Where the lens moves pinhole pixels ``(..., 2)`` to."""
        p = np.asarray(pixels, dtype=np.float64)
        if self.distortion == 0:
            return p.copy()
        k = self.intrinsics
        c, f = k[:2, 2], k[0, 0]
        n = (p - c) / f
        return np.asarray(c + f * n * (1 + self.dist_coeffs[0] * np.sum(n * n, axis=-1, keepdims=True)))


@functools.lru_cache(maxsize=8)
def _lens_maps(camera: Camera) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """For every pixel of a distorted frame, the pinhole pixel it shows (the inverse of
    :meth:`Camera.distort`, by fixed-point iteration: ``|k1| r^2 <= 0.2`` converges fast)."""
    w, h = camera.size
    k = camera.intrinsics
    c, f, k1 = k[:2, 2], k[0, 0], camera.dist_coeffs[0]
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    seen = (np.stack([xs, ys], axis=-1) - c) / f
    ideal = seen.copy()
    for _ in range(30):
        ideal = seen / (1 + k1 * np.sum(ideal * ideal, axis=-1, keepdims=True))
    px = c + f * ideal
    return px[..., 0].astype(np.float32), px[..., 1].astype(np.float32)


def through_lens(camera: Camera, image: NDArray[np.float32]) -> NDArray[np.float32]:
    """A pinhole frame as the camera's lens shows it (unchanged without :attr:`Camera.distortion`)."""
    if camera.distortion == 0:
        return image
    mx, my = _lens_maps(camera)
    return np.asarray(cv2.remap(image, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE), np.float32)


@dataclass(frozen=True)
class Truth:
    """Ground truth of a rendered frame (camera pixels: x right, y down, pixel centres at integers)."""

    corners: FloatArray
    """Plate corners ``(4, 2)`` [px], in the order of :func:`upm.vision.plate_corners`."""
    centers: FloatArray
    """Part centres ``(M, 2)`` [px]: the projections of the parts' centres."""
    positions: FloatArray
    """Part centres ``(M, 2)`` on the plate [m]."""
    labels: tuple[str, ...]
    visible: FloatArray
    """Fraction ``(M,)`` of each part's image not hidden by an occluder or the image border."""


@dataclass(frozen=True)
class Frame:
    """A rendered frame: ``image`` (H, W, 3) BGR uint8 (or (H, W) grey) and its :class:`Truth`."""

    image: NDArray[np.uint8]
    truth: Truth


def _circle(radius: float, n: int = 96) -> FloatArray:
    a = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    return radius * np.column_stack([np.cos(a), np.sin(a)])


def _signed_area(polygon: FloatArray) -> float:
    """Shoelace area [px^2], positive for counter-clockwise vertices (x right, y up)."""
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _inset(polygon: FloatArray, delta: float) -> FloatArray:
    """The convex ``polygon`` with every side moved inwards by ``delta``."""
    edges = np.roll(polygon, -1, axis=0) - polygon
    lengths = np.linalg.norm(edges, axis=1)
    keep = lengths > 1e-9
    p, e = polygon[keep], edges[keep] / lengths[keep, None]
    orientation = np.sign(_signed_area(polygon)) or 1.0
    inward = orientation * np.column_stack([-e[:, 1], e[:, 0]])
    q = p + delta * inward  # a point on each moved side
    prev_q, prev_e = np.roll(q, 1, axis=0), np.roll(e, 1, axis=0)
    # vertex i = intersection of moved side i - 1 and moved side i
    cross = prev_e[:, 0] * e[:, 1] - prev_e[:, 1] * e[:, 0]
    d = q - prev_q
    t = np.where(
        np.abs(cross) > 1e-12, (d[:, 0] * e[:, 1] - d[:, 1] * e[:, 0]) / np.where(cross == 0, 1, cross), 0
    )
    moved = prev_q + t[:, None] * prev_e + np.where(np.abs(cross) > 1e-12, 0, 1)[:, None] * (q - prev_q)
    return np.asarray(moved, dtype=np.float64)


def _coverage(shape: tuple[int, int], polygon: FloatArray) -> tuple[tuple[int, int], NDArray[np.float32]]:
    """Area coverage in [0, 1] of the convex ``polygon`` [px] over the pixels of its bounding box
    (clipped to an image of ``shape``); returns the box's top-left corner and the coverage.

    ``cv2.fillPoly`` sets every subpixel whose centre lies within half a subpixel of the polygon
    (rounded ends), so the polygon is first moved inwards by that half subpixel."""
    polygon = _inset(polygon, 0.5 / _SS)
    h, w = shape
    x0 = max(math.floor(polygon[:, 0].min()) - 1, 0)
    y0 = max(math.floor(polygon[:, 1].min()) - 1, 0)
    x1 = min(math.ceil(polygon[:, 0].max()) + 2, w)
    y1 = min(math.ceil(polygon[:, 1].max()) + 2, h)
    if x1 <= x0 or y1 <= y0:
        return (0, 0), np.zeros((0, 0), np.float32)
    mask = np.zeros(((y1 - y0) * _SS, (x1 - x0) * _SS), np.uint8)
    # pixel (i, j) of the supersampled box has its centre at ((i + 0.5) / SS - 0.5) + origin
    fine = ((polygon - (x0, y0) + 0.5) * _SS - 0.5) * (1 << _SHIFT)
    cv2.fillPoly(mask, [np.round(fine).astype(np.int32)], 255, cv2.LINE_8, _SHIFT)
    small = cv2.resize(mask, (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA)
    return (x0, y0), small.astype(np.float32) / 255.0


def _blend(image: NDArray[np.float32], origin: tuple[int, int], cover: NDArray[np.float32],
           color: Sequence[float]) -> None:  # fmt: skip
    x0, y0 = origin
    h, w = cover.shape
    if h == 0:
        return
    roi = image[y0 : y0 + h, x0 : x0 + w]
    roi += cover[..., None] * (np.asarray(color, np.float32) - roi)


@functools.lru_cache(maxsize=8)
def _lighting(size: tuple[int, int], gradient: float, vignette: float) -> NDArray[np.float32]:
    w, h = size
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    u, v = (x - w / 2) / (w / 2), (y - h / 2) / (h / 2)
    gain = (1.0 + gradient * (0.8 * u + 0.6 * v) / 2 - vignette * (u * u + v * v) / 2).astype(np.float32)
    gain.flags.writeable = False
    return np.asarray(gain[..., None], dtype=np.float32)


@functools.lru_cache(maxsize=8)
def _empty_plate(
    camera: Camera, background: tuple[float, ...], plate: tuple[float, ...]
) -> NDArray[np.float32]:
    """The frame without parts (cached: it is the same for every frame of a camera)."""
    w, h = camera.size
    image = np.empty((h, w, 3), np.float32)
    image[:] = np.asarray(background, np.float32)
    corners = project(camera.camera_from_plate, plate_corners(camera.plate_size))
    _blend(image, *_coverage((h, w), corners), plate)
    image.flags.writeable = False
    return image


def _develop(camera: Camera, image: NDArray[np.float32], gradient: float, vignette: float, blur: float,
             noise: float, gen: np.random.Generator, grey: bool = False) -> NDArray[np.uint8]:  # fmt: skip
    """A drawn pinhole frame as the camera delivers it: through the lens, uneven light, lens blur,
    grey if asked, pixel noise, rounded to 8 bits."""
    image = through_lens(camera, image)
    image *= _lighting(camera.size, float(gradient), float(vignette))
    if blur > 0:
        image = np.asarray(cv2.GaussianBlur(image, (0, 0), blur), np.float32)
    if grey:
        image = np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), np.float32)
    if noise > 0:
        # OpenCV's generator, seeded from ``gen`` (deterministic, and a third of numpy's time on
        # a megapixel frame)
        cv2.setRNGSeed(int(gen.integers(1 << 31)))
        grain = np.empty_like(image)
        cv2.randn(grain, 0.0, float(noise))  # type: ignore[call-overload]
        image += grain
    np.maximum(image, np.float32(0), out=image)
    return np.asarray(cv2.convertScaleAbs(image))  # rounded to nearest, saturated at 255


def render(
    camera: Camera,
    positions: ArrayLike,
    labels: Sequence[str] | str = "penny",
    *,
    radius: float | ArrayLike | None = None,
    angles: ArrayLike | None = None,
    shapes: Mapping[str, ArrayLike] | Sequence[ArrayLike | None] | None = None,
    colors: Mapping[str, Sequence[float]] | None = None,
    noise: float = 5.0,
    blur: float = 0.7,
    gradient: float = 0.25,
    vignette: float = 0.15,
    occluders: Sequence[ArrayLike] = (),
    grey: bool = False,
    rng: np.random.Generator | int | None = 0,
) -> Frame:
    """Render one camera frame of the plate with parts at ``positions``.

    Parameters
    ----------
    camera : Camera
        The camera and the plate's size.
    positions : (M, 2) array_like
        Part centres on the plate [m].
    labels : str or sequence of M str
        Part kinds: ``"penny"``, ``"red"``, ``"blue"`` (chips) or any key of ``colors``.
    radius : float or (M,) array_like, optional
        Part radii [m]; default from the kind (penny 9.5 mm, chip 19.5 mm).
    angles : (M,) array_like, optional
        Part orientations [rad] (for ``shapes``).
    shapes : mapping of label to (K, 2) array_like, or sequence of M of them (or None), optional
        Convex outlines [m] in the part's frame (centroid at the origin) for labels (or for
        parts, in a sequence; None: a disk) drawn as polygons instead of disks.
    colors : mapping of name to BGR, optional
        Overrides of :data:`COLORS` (also ``"plate"``, ``"background"``, ``"occluder"``).
    noise : float
        Standard deviation of the Gaussian pixel noise [grey levels].
    blur : float
        Standard deviation of the Gaussian lens blur [px] (0: none).
    gradient, vignette : float
        Relative brightness change across the image and darkening towards its corners.
    occluders : sequence of (K, 2) array_like
        Polygons in camera pixels drawn over everything (an arm, a hand).
    grey : bool
        Return a single-channel grey frame.
    rng : numpy.random.Generator or int or None
        Source of the noise.
    """
    pos = as_float("positions", positions)
    if pos.ndim != 2 or pos.shape[1] != 2:
        raise ShapeError(f"positions must have shape (M, 2) [m]; got {pos.shape}")
    m = len(pos)
    kinds = (labels,) * m if isinstance(labels, str) else tuple(labels)
    if len(kinds) != m:
        raise ShapeError(f"labels must hold one label per part ({m}); got {len(kinds)}")
    palette = {**COLORS, **(colors or {})}
    unknown = sorted({k for k in kinds if k not in palette})
    if unknown:
        raise ParameterError(f"labels {unknown} have no colour; known: {sorted(palette)} (or pass colors=)")
    if shapes is not None and not isinstance(shapes, Mapping):
        per_part = list(shapes)
        if len(per_part) != m:
            raise ShapeError(f"shapes must hold one outline (or None) per part ({m}); got {len(per_part)}")
        outlines = [None if o is None else as_float(f"shapes[{k}]", o) for k, o in enumerate(per_part)]
    else:
        outlines = [as_float(f"shapes[{k!r}]", shapes[k]) if shapes and k in shapes else None for k in kinds]
    if radius is None:
        missing = sorted({k for k, o in zip(kinds, outlines, strict=True) if k not in RADII and o is None})
        if missing:
            raise ParameterError(f"radius is needed for labels {missing}")
        radii = np.array([RADII.get(k, 0.0) for k in kinds])
    else:
        radii = np.broadcast_to(as_float("radius", radius), (m,)).copy()
        check_range("radius", radii, low=0.0, low_open=True)
    ang = np.zeros(m) if angles is None else np.broadcast_to(as_float("angles", angles), (m,))
    check_range("noise", as_float("noise", noise), low=0.0)
    check_range("blur", as_float("blur", blur), low=0.0)
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)

    w, h = camera.size
    hom = camera.camera_from_plate
    corners = project(hom, plate_corners(camera.plate_size))
    image = _empty_plate(camera, tuple(palette["background"]), tuple(palette["plate"])).copy()

    covers = []
    for k in range(m):
        local = outlines[k]
        if local is None:
            local = _circle(float(radii[k]))
        elif local.ndim != 2 or local.shape[1] != 2 or len(local) < 3:
            raise ShapeError(f"the outline of part {k} must have shape (K >= 3, 2) [m]; got {local.shape}")
        c, s = math.cos(ang[k]), math.sin(ang[k])
        outline = project(hom, local @ np.array([[c, s], [-s, c]]) + pos[k])
        origin, cover = _coverage((h, w), outline)
        covers.append((origin, cover, abs(_signed_area(outline))))
        _blend(image, origin, cover, palette[kinds[k]])

    occl = np.zeros((h, w), np.float32) if len(occluders) else None
    for i, poly in enumerate(occluders):
        p = as_float(f"occluders[{i}]", poly)
        if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3:
            raise ShapeError(f"occluders[{i}] must have shape (K >= 3, 2) [px]; got {p.shape}")
        (x0, y0), cov = _coverage((h, w), p)
        if cov.size and occl is not None:
            view = occl[y0 : y0 + cov.shape[0], x0 : x0 + cov.shape[1]]
            np.maximum(view, cov, out=view)
    if occl is not None:
        image += occl[..., None] * (np.asarray(palette["occluder"], np.float32) - image)

    visible = np.zeros(m)
    for k, ((x0, y0), cov, area) in enumerate(covers):
        if cov.size and area > 0:
            seen = cov if occl is None else cov * (1.0 - occl[y0 : y0 + cov.shape[0], x0 : x0 + cov.shape[1]])
            visible[k] = min(float(seen.sum()) / area, 1.0)

    out = _develop(camera, image, gradient, vignette, blur, noise, gen, grey)
    truth = Truth(
        corners=camera.distort(corners),
        centers=camera.distort(project(hom, pos)) if m else np.zeros((0, 2)),
        positions=pos.copy(),
        labels=kinds,
        visible=visible,
    )
    return Frame(out, truth)


def render_board(
    camera: Camera,
    board: CharucoBoard,
    pose: ArrayLike | None = None,
    *,
    noise: float = 2.0,
    blur: float = 0.7,
    rng: np.random.Generator | int | None = 0,
) -> NDArray[np.uint8]:
    """A frame of a ChArUco ``board`` (:class:`upm.vision.CharucoBoard`) over the empty plate,
    through the camera's lens: lying flat at its centre (``pose`` None) or held at ``pose``
    ``(rx, ry, rz, x, y, z)`` (a rotation vector [rad] and the board's centre [m], plate frame).
    The board is drawn 4 x 4 supersampled (area-weighted edges, as parts are)."""
    check_range("noise", as_float("noise", noise), low=0.0)
    check_range("blur", as_float("blur", blur), low=0.0)
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    w, h = camera.size
    r_pb, t_pb = board.plate_from_board(pose)
    r_cp, t_cp = camera.pose
    r_cb, t_cb = r_cp @ r_pb, r_cp @ t_pb + t_cp
    k = camera.intrinsics
    depth = float(np.linalg.norm(t_cb))
    texture = board.image(float(np.clip(1.5 * _SS * k[0, 0] / depth, 1000.0, 1e5)))
    bw, bh = board.size
    sx, sy = texture.shape[1] / bw, texture.shape[0] / bh
    metres = np.array([[1 / sx, 0.0, 0.5 / sx], [0.0, 1 / sy, 0.5 / sy], [0.0, 0.0, 1.0]])
    fine = np.array([[_SS, 0.0, (_SS - 1) / 2], [0.0, _SS, (_SS - 1) / 2], [0.0, 0.0, 1.0]])
    m = fine @ k @ np.column_stack([r_cb[:, 0], r_cb[:, 1], t_cb]) @ metres
    big = (w * _SS, h * _SS)
    warped = [cv2.warpPerspective(t, m, big, flags=cv2.INTER_LINEAR, borderValue=0)
              for t in (texture, np.full_like(texture, 255))]  # fmt: skip
    shade, cover = (cv2.resize(t.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA) for t in warped)
    cover = np.asarray(cover, np.float32) / np.float32(255.0)
    image = _empty_plate(camera, tuple(COLORS["background"]), tuple(COLORS["plate"])).copy()
    ink = (20.0 + shade * (215.0 / 255.0))[..., None]  # black squares 20, white 235 grey levels
    image += cover[..., None] * (ink - image)
    return _develop(camera, image, 0.1, 0.05, blur, noise, gen)


class _HasParts(Protocol):
    parts: Any


@dataclass
class VirtualCamera:
    """Frames of a simulated plate, read like an OpenCV ``VideoCapture``.

    ``read()`` renders the current ``source.parts`` (e.g. a :class:`upm.plant.SimulatedUPM`) and
    returns ``(True, image)``; :attr:`last` keeps the latest :class:`Frame` with its truth.
    """

    source: _HasParts
    camera: Camera = field(default_factory=Camera)
    labels: Sequence[str] | str = "penny"
    options: dict[str, Any] = field(default_factory=dict)
    seed: int = 0
    last: Frame | None = None

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        self._light = 1.0  # the brightness's drift so far (a source's ``lighting_drift``)

    def read(self) -> tuple[bool, NDArray[np.uint8]]:
        source: Any = self.source
        lag = float(getattr(source, "camera_latency", 0.0))
        # a camera that lags shows the parts as they were (a source's ``parts_at``)
        seen = source.parts_at(source.clock - lag) if lag > 0 else source.parts
        parts = np.asarray(seen, dtype=np.float64).reshape(-1, 2)
        here = np.all(np.isfinite(parts), axis=1)  # NaN rows: parts that fell off the plate
        labels = (
            self.labels
            if isinstance(self.labels, str)
            else [k for k, h in zip(self.labels, here, strict=True) if h]
        )
        options = dict(self.options)
        shapes = getattr(source, "shapes", None)
        if shapes is not None:  # polygons: drawn at their centroids, turned by their angles
            parts = np.asarray(source.centroids(), dtype=np.float64).reshape(-1, 2)
            outlines = [np.asarray(p.vertices) - p.centroid for p in shapes]
            options["shapes"] = [o for o, h in zip(outlines, here, strict=True) if h]
            options["angles"] = np.asarray(source.angles)[here]
        jitter = float(getattr(source, "pixel_noise", 0.0))
        if jitter > 0:  # each part seen off by a Gaussian jitter of that many pixels
            ends = project(self.camera.camera_from_plate, np.array([[0.0, 0.0], [0.01, 0.0]]))
            per_metre = 100.0 * float(np.hypot(*(ends[1] - ends[0])))
            parts = parts + self._rng.normal(0.0, jitter / per_metre, parts.shape)
        self.last = render(self.camera, parts[here], labels, rng=self._rng, **options)
        drift = float(getattr(source, "lighting_drift", 0.0))
        if drift > 0:  # the light brightens and dims as a bounded random walk
            self._light = float(np.clip(self._light * math.exp(self._rng.normal(0.0, drift)), 0.6, 1.4))
            lit = np.asarray(cv2.convertScaleAbs(self.last.image, alpha=self._light), dtype=np.uint8)
            self.last = Frame(lit, self.last.truth)
        return True, self.last.image

    def isOpened(self) -> bool:
        return True

    def release(self) -> None:
        """Nothing to release (the VideoCapture interface)."""
