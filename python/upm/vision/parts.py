"""Parts on the plate: matched-filter detection, subpixel centres, colour labels (docs/spec.md §8).

The plate is first rectified (``cv2.warpPerspective``) to a top view in which every part of
radius ``r`` is a disk of known pixel radius, whatever the camera's perspective. The plate's own
colour, lit unevenly, is modelled by a robust cubic polynomial per channel; the contrast of a
pixel is its colour distance from that model, which shows pennies (dark) and red/blue chips
(as bright as the plate in grey) alike. A box filter of the part's size on the contrast finds
the candidates (local maxima, non-maximum suppression at one radius, so touching parts stay
apart). Each centre is then refined by the centroid of the part's coverage (the colour
difference projected on the part's own colour, so noise does not bias it) inside a window of
radius ``r + 2`` px, split between touching parts along the perpendicular bisector of their
centres.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from .._arrays import as_float, check_range, instance, integer, real
from .._errors import VisionError
from .table import Table, check_frame

__all__ = ["Palette", "Parts", "find_parts"]

FloatArray = NDArray[np.float64]
F32 = NDArray[np.float32]
Refined = tuple[FloatArray, FloatArray, FloatArray, FloatArray]  # centres, colours, areas, rings

#: Mean coverage round a candidate above which it is inside something larger than a part.
BLOB_RING = 0.75
#: Coverage (relative to the part's disk) above which a candidate is larger than a part.
BLOB_AREA = 1.25


#: Two references closer than this (distance of log colour ratios, about 5 % a channel) cannot be
#: told apart by a camera: a palette that has them is refused.
SAME_COLOUR = 0.05


@dataclass(frozen=True)
class Palette:
    """Reference colours of the part kinds, relative to the plate's colour (so that a lighting
    change that scales every channel does not change the labels).

    Parameters
    ----------
    colors : mapping of label to BGR
        Each kind's colour as the camera sees it where the plate looks like ``plate``.
    plate : BGR
        The plate's colour in the same light.
    tolerance : float
        Largest distance (in log colour ratio) to the nearest reference for a label; beyond it
        the label is ``"unknown"``.
    """

    colors: Mapping[str, Sequence[float]]
    plate: Sequence[float] = (150.0, 150.0, 150.0)
    tolerance: float = 0.35

    def __post_init__(self) -> None:
        if not self.colors:
            raise VisionError("a Palette needs at least one colour")
        for name, c in {**self.colors, "plate": self.plate}.items():
            v = as_float(f"colors[{name!r}]", c)
            if v.shape != (3,) or np.any(v <= 0) or np.any(v > 255):
                raise VisionError(f"colour {name!r} must be 3 BGR levels in (0, 255]; got {c!r}")
        if not (
            isinstance(self.tolerance, (int, float)) and math.isfinite(self.tolerance) and self.tolerance > 0
        ):
            raise VisionError(f"tolerance must be finite and > 0; got {self.tolerance!r}")
        refs, names = self.ratios(), self.labels
        for i in range(len(refs)):
            for j in range(i):
                if np.linalg.norm(refs[i] - refs[j]) < SAME_COLOUR:
                    raise VisionError(
                        f"colors {names[j]!r} and {names[i]!r} are the same colour to a camera (log ratio "
                        f"{np.linalg.norm(refs[i] - refs[j]):.3g} apart, under {SAME_COLOUR:g}): one label "
                        "would never be assigned; give each kind a colour of its own"
                    )

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(self.colors)

    def ratios(self) -> FloatArray:
        """Log colour ratios ``(K, 3)`` of the references to the plate."""
        plate = np.asarray(self.plate, dtype=np.float64)
        return np.log(np.array([np.asarray(c, dtype=np.float64) for c in self.colors.values()]) / plate)

    def classify(self, ratios: FloatArray) -> tuple[str, ...]:
        """Labels for measured colour ratios ``(N, 3)`` (part colour / plate colour, BGR)."""
        if not len(ratios):
            return ()
        logs = np.log(np.clip(ratios, 1e-3, None))
        dist = np.linalg.norm(logs[:, None, :] - self.ratios()[None], axis=2)
        best = np.argmin(dist, axis=1)
        names = self.labels
        return tuple(names[b] if dist[i, b] <= self.tolerance else "unknown" for i, b in enumerate(best))


#: The thesis's parts: copper pennies, red and blue poker chips on a light grey plate.
THESIS_PALETTE = Palette(
    {"penny": (45.0, 85.0, 140.0), "red": (110.0, 125.0, 220.0), "blue": (235.0, 165.0, 80.0)},
    plate=(150.0, 150.0, 150.0),
)


@dataclass(frozen=True)
class Parts:
    """Parts found in one frame, in reading order (top row of the image first).

    Attributes
    ----------
    positions : (N, 2) ndarray
        Centres on the plate [m].
    pixels : (N, 2) ndarray
        Centres in the camera image [px].
    labels : tuple of N str
        Palette labels (``"unknown"`` when no reference is close; ``""`` for grey frames).
    contrast : (N,) ndarray
        Colour distance between part and plate [grey levels].
    area : (N,) ndarray
        Visible area relative to a disk of the given radius (about 1 for a whole disk, less
        when occluded or cut by the image border).
    colors : (N, 3) ndarray
        Part colour relative to the plate (BGR ratios); NaN for grey frames.
    """

    positions: FloatArray
    pixels: FloatArray
    labels: tuple[str, ...]
    contrast: FloatArray
    area: FloatArray
    colors: FloatArray

    def __len__(self) -> int:
        return len(self.positions)


class Rectifier:
    """The top view of a table used by detection and tracking: scale, padding, homographies and
    the plate's lighting model."""

    def __init__(self, table: Table, part_radius: float) -> None:
        check_range("part_radius", as_float("part_radius", part_radius), low=0.0, low_open=True)
        self.table = table
        w, h = table.plate_size
        c = table.corners
        sides = np.linalg.norm(np.roll(c, -1, axis=0) - c, axis=1) / np.array([w, h, w, h])
        self.scale = float(sides.max())  # px/m: no coarser than the camera anywhere on the plate
        self.radius = part_radius * self.scale  # the part's radius in the top view [px]
        if self.radius < 2.0:
            raise VisionError(
                f"part_radius {part_radius} m is {self.radius:.2f} px in this camera; "
                "parts need at least 2 px"
            )
        if self.radius > 0.25 * min(w, h) * self.scale:
            raise VisionError(f"part_radius {part_radius} m is larger than a quarter of the plate")
        self.pad = math.ceil(self.radius + 3.5) + 5  # holds refine's windows for parts on the edge
        self.size = (
            math.ceil(w * self.scale) + 2 * self.pad,
            math.ceil(h * self.scale) + 2 * self.pad,
        )
        s, p = self.scale, self.pad
        self.top_from_plate = np.array([[s, 0.0, w / 2 * s + p], [0.0, -s, h / 2 * s + p], [0.0, 0.0, 1.0]])
        self.top_from_camera = self.top_from_plate @ table.plate_from_camera
        self.plate_box = (p, p, p + round(w * s), p + round(h * s))  # x0, y0, x1, y1
        self.background: F32 | None = None

    def warp(self, frame: NDArray[np.uint8]) -> NDArray[np.uint8]:
        """The top view (H, W, C) of a camera frame (through the lens of a calibrated table)."""
        if self.table.lens is not None:
            mx, my = self._camera_maps()
            img = cv2.remap(frame, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        else:
            img = cv2.warpPerspective(frame, self.top_from_camera, self.size, flags=cv2.INTER_LINEAR,
                                      borderMode=cv2.BORDER_REPLICATE)  # fmt: skip
        return np.asarray(img if img.ndim == 3 else img[..., None], np.uint8)

    def _camera_maps(self) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        """The camera pixel (x, y) of every top-view pixel (computed once)."""
        if not hasattr(self, "_maps"):
            w, h = self.size
            ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
            top = np.stack([xs, ys], axis=-1).reshape(-1, 2)
            cam = self.table.to_camera(self.to_plate(top)).reshape(h, w, 2)
            self._maps = (cam[..., 0].astype(np.float32), cam[..., 1].astype(np.float32))
        return self._maps

    def patches(self, frame: NDArray[np.uint8], origins: NDArray[np.intp], n: int) -> F32:
        """``n x n`` windows (N, n, n, C) of the top view whose top-left pixels are ``origins``,
        sampled in one ``cv2.remap`` call from the camera frame."""
        mx, my = self._camera_maps()
        sx = np.concatenate([mx[oy : oy + n, ox : ox + n] for ox, oy in origins])
        sy = np.concatenate([my[oy : oy + n, ox : ox + n] for ox, oy in origins])
        out = cv2.remap(frame, sx, sy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return out.reshape(len(origins), n, n, -1).astype(np.float32)

    def plate_mask(self) -> NDArray[np.bool_]:
        """Top-view pixels at least 1.5 px inside the plate's edge."""
        x0, y0, x1, y1 = self.plate_box
        mask = np.zeros((self.size[1], self.size[0]), bool)
        mask[y0 + 2 : y1 - 1, x0 + 2 : x1 - 1] = True
        return mask

    def _lighting_bases(
        self,
    ) -> tuple[NDArray[np.intp], NDArray[np.intp], FloatArray, FloatArray, tuple[int, int]]:
        if not hasattr(self, "_bases"):
            x0, y0, x1, y1 = self.plate_box
            ys = np.linspace(y0 + 3, y1 - 3, 48).round().astype(np.intp)
            xs = np.linspace(x0 + 3, x1 - 3, 48).round().astype(np.intp)
            gy, gx = np.meshgrid(ys, xs, indexing="ij")
            w, h = self.size
            fit = _cubic((gx.ravel() - w / 2) / w, (gy.ravel() - h / 2) / h)
            cw, ch = w // 8 + 2, h // 8 + 2
            # node i of the coarse grid sits where cv2.resize puts it: (i + 0.5) * w / cw - 0.5
            cy, cx = np.meshgrid((np.arange(ch) + 0.5) * h / ch - 0.5, (np.arange(cw) + 0.5) * w / cw - 0.5,
                                 indexing="ij")  # fmt: skip
            coarse = _cubic((cx.ravel() - w / 2) / w, (cy.ravel() - h / 2) / h)
            self._bases = (gy, gx, fit, coarse, (cw, ch))
        return self._bases

    def fit_background(self, top: NDArray[np.uint8]) -> F32:
        """The plate's colour everywhere in the top view: a cubic per channel, fitted robustly
        (parts and occluders are outliers) on a 48 x 48 grid of plate pixels."""
        gy, gx, basis, coarse, (cw, ch) = self._lighting_bases()
        samples = top[gy, gx].reshape(-1, top.shape[2]).astype(np.float64)
        keep = np.ones(len(samples), bool)
        coef = np.zeros((basis.shape[1], top.shape[2]))
        for _ in range(5):
            b = basis[keep]
            coef = np.asarray(np.linalg.solve(b.T @ b, b.T @ samples[keep]), dtype=np.float64)
            res = np.linalg.norm(samples - basis @ coef, axis=1)
            sigma = 1.4826 * float(np.median(res[keep])) + 0.5
            new = res < 3.0 * sigma + 2.0
            if new.sum() < 0.3 * len(keep):
                raise VisionError("the plate is mostly covered: cannot estimate its colour (too many parts?)")
            if np.array_equal(new, keep):
                break
            keep = new
        # evaluated on a grid of 8 px and interpolated up (the cubic is smooth at that scale)
        coarse_img = (coarse @ coef).reshape(ch, cw, -1).astype(np.float32)
        full = cv2.resize(coarse_img, self.size, interpolation=cv2.INTER_LINEAR)
        background = np.asarray(full if full.ndim == 3 else full[..., None], np.float32)
        self.background = background
        return background

    def light_gain(self, frame: NDArray[np.uint8]) -> float:
        """How much brighter ``frame`` is than when :meth:`fit_background` last ran: the median over
        the lighting grid's plate pixels (sampled straight from the camera frame) of their
        brightness over the background's there (parts on a few of them do not move the median)."""
        if self.background is None:
            return 1.0
        gy, gx, _, _, _ = self._lighting_bases()
        mx, my = self._camera_maps()
        sx, sy = mx[gy, gx].reshape(1, -1), my[gy, gx].reshape(1, -1)
        seen = cv2.remap(frame, sx, sy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        seen = np.asarray(seen, np.float64).reshape(sx.size, -1).sum(axis=1)
        then = np.asarray(self.background[gy, gx], np.float64).reshape(sx.size, -1).sum(axis=1)
        ratio = seen / np.maximum(then, 1.0)
        return float(np.clip(np.median(ratio), 0.2, 5.0))

    def to_plate(self, top: FloatArray) -> FloatArray:
        w, h = self.table.plate_size
        s, p = self.scale, self.pad
        return np.column_stack([(top[:, 0] - p) / s - w / 2, h / 2 - (top[:, 1] - p) / s])

    def to_top(self, plate: FloatArray) -> FloatArray:
        w, h = self.table.plate_size
        s, p = self.scale, self.pad
        return np.column_stack([(plate[:, 0] + w / 2) * s + p, (h / 2 - plate[:, 1]) * s + p])


def _cubic(x: FloatArray, y: FloatArray) -> FloatArray:
    return np.column_stack([np.ones_like(x), x, y, x * x, x * y, y * y, x**3, x * x * y, x * y * y, y**3])


def refine(diff: F32, centres: FloatArray, origins: FloatArray, radius: float,
           direction: FloatArray | None = None, iterations: int = 3) -> Refined:  # fmt: skip
    """Coverage-centroid refinement of part centres, all parts together.

    ``diff`` (N, P, P, C) holds each part's window of (frame - plate colour), the window of part
    i starting at top-view pixel ``origins[i]``; ``centres`` (N, 2) are the starting centres in
    top-view pixels. The coverage (the difference projected on the part's colour ``direction``,
    measured in the inner 60% of the radius when not given; clipped below at 0, since a touching
    part of another colour projects negatively) is averaged over a disk of radius ``r + 2`` px
    centred on the pixel nearest the current centre, split from touching neighbours along the
    perpendicular bisector of the current centres. Returns the refined centres (top view), the
    colour differences, the coverage areas [px^2] and the mean coverage of the ring from
    ``r + 1.5`` to ``r + 3.5`` px around each centre (near 0 round a part with plate around it, at
    most about 0.6 in a packed cluster, near 1 inside anything larger than a part).
    """
    n, size = diff.shape[0], diff.shape[1]
    if direction is None:
        reach = math.ceil(radius + 3.5)
        off = np.arange(-reach, reach + 1, dtype=np.float32)
        inner = (off[None, :] ** 2 + off[:, None] ** 2 < np.float32((0.6 * radius) ** 2)).astype(np.float32)
        at = np.clip(np.rint(centres - origins).astype(np.intp), reach, size - 1 - reach)
        w = 2 * reach + 1
        patches = np.stack(
            [diff[i, y - reach : y - reach + w, x - reach : x - reach + w] for i, (x, y) in enumerate(at)]
        )
        direction = np.einsum("nyxc,yx->nc", patches, inner) / max(float(inner.sum()), 1.0)
    d = np.asarray(direction, np.float32)
    norm2 = np.maximum((d * d).sum(axis=1), 1e-6)
    flat = diff.reshape(n, size * size, diff.shape[3])
    cover = np.maximum(np.matmul(flat, (d / norm2[:, None])[:, :, None]), np.float32(0)).reshape(
        n, size, size
    )
    # the centroid iterations: upm_core::centroid (the per-pixel loop, once per part and frame)
    c, area, around = _core.coverage_centroids(
        np.ascontiguousarray(cover), np.ascontiguousarray(origins, dtype=np.float64),
        np.ascontiguousarray(centres, dtype=np.float64), float(radius), int(iterations),
    )  # fmt: skip
    return c, d.astype(np.float64), area, around


def detect(top: NDArray[np.uint8], background: F32, rect: Rectifier, min_contrast: float,
           max_parts: int | None) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:  # fmt: skip
    """Candidates and refined centres in the top view: centres (N, 2), colour differences
    (N, C), coverage areas (N,), box-filter contrast (N,)."""
    r = rect.radius
    diff = np.asarray(cv2.subtract(top, background, dtype=cv2.CV_32F), np.float32)
    if diff.ndim == 2:
        diff = diff[..., None]
    mask = rect.plate_mask()
    # candidates on a coarser grid (the box filter needs only a few pixels per radius)
    q = max(1, int(r / 4))
    small = (
        diff
        if q == 1
        else cv2.resize(diff, (diff.shape[1] // q, diff.shape[0] // q), interpolation=cv2.INTER_AREA)
    )
    if small.ndim == 2:
        small = small[..., None]
    mag = np.sqrt(np.einsum("yxc,yxc->yx", small, small))
    inside = mask if q == 1 else cv2.resize(mask.astype(np.uint8), (mag.shape[1], mag.shape[0]),
                                            interpolation=cv2.INTER_NEAREST).astype(bool)  # fmt: skip
    mag[~inside] = 0.0
    rq = r / q
    side = max(round(rq), 3) | 1  # a box well inside the disk: little cross-talk between touching parts
    resp = cv2.blur(mag, (side, side))
    near = max(round(0.5 * rq), 1)
    kernel = np.ones((2 * near + 1, 2 * near + 1), np.uint8)
    peaks = (resp >= cv2.dilate(resp, kernel)) & (resp > min_contrast) & inside
    ys, xs = np.nonzero(peaks)
    if not len(xs):
        return np.zeros((0, 2)), np.zeros((0, top.shape[2])), np.zeros(0), np.zeros(0)
    order = np.argsort(-resp[ys, xs], kind="stable")
    # non-maximum suppression (plateaus give several equal maxima): strongest first, each kept
    # peak suppressing every weaker one within a radius
    peak_at = np.stack([xs[order], ys[order]], axis=1).astype(np.int64)
    gone = np.zeros(len(peak_at), dtype=bool)
    kept: list[int] = []
    for k in range(len(peak_at)):
        if gone[k]:
            continue
        kept.append(k)
        if max_parts is not None and len(kept) >= max_parts:
            break
        gone |= np.sum((peak_at - peak_at[k]) ** 2, axis=1) <= rq * rq
    coarse = peak_at[kept].astype(np.float64)
    strength = resp[coarse[:, 1].astype(int), coarse[:, 0].astype(int)].astype(np.float64)
    centres = (coarse + 0.5) * q - 0.5
    refined, colour, area, around = refine_in(diff, centres, rect)
    for _ in range(3):
        # drop candidates inside or at the edge of something larger than a part (an arm, a
        # hand: its colour all round the part's outline, or more of it than a part holds), and
        # of candidates that converged within half a radius of each other (one started between
        # two parts) keep the strongest
        keep: list[int] = []
        taken = np.zeros(len(refined), dtype=bool)  # within half a radius of one kept (or NaN)
        part_like = (area < BLOB_AREA * math.pi * r * r) & (around < BLOB_RING)
        for i in np.nonzero(part_like)[0]:
            if not taken[i]:
                keep.append(int(i))
                taken |= ~(np.hypot(*(refined - refined[i]).T) > 0.5 * r)
        if len(keep) == len(refined):
            break
        strength = strength[keep]
        if not keep:
            return np.zeros((0, 2)), np.zeros((0, top.shape[2])), np.zeros(0), np.zeros(0)
        refined, colour, area, around = refine_in(diff, refined[keep], rect)
    return refined, colour, area, strength


def refine_in(
    diff: F32, centres: FloatArray, rect: Rectifier, direction: FloatArray | None = None
) -> Refined:
    """:func:`refine` on windows cut from a whole top-view difference image; the windows are cut
    again around the first pass's centres (a window must hold the part whole)."""
    r = rect.radius
    half = math.ceil(r + 3.5) + 4  # refine's reach, and room for its centre to move
    size = 2 * half + 1
    # the top view's padding holds every window of a centre on the plate
    high = np.array([diff.shape[1] - size, diff.shape[0] - size])
    out = (centres, np.zeros((len(centres), diff.shape[2])), np.zeros(len(centres)), np.zeros(len(centres)))
    for _ in range(2):
        origins = np.clip(np.floor(out[0]).astype(int) - half, 0, high)
        windows = np.stack([diff[oy : oy + size, ox : ox + size] for ox, oy in origins])
        out = refine(windows, out[0], origins.astype(np.float64), r, direction)
    return out


def find_parts(
    frame: ArrayLike,
    table: Table,
    part_radius: float,
    *,
    palette: Palette | None = THESIS_PALETTE,
    min_contrast: float = 30.0,
    max_parts: int | None = None,
) -> Parts:
    """Find the parts on the plate (docs/spec.md §8).

    Parameters
    ----------
    frame : (H, W, 3) BGR or (H, W) grey uint8 ndarray
        A camera frame of the same size as the one ``table`` was found in.
    table : Table
        The plate (from :func:`find_table` or :meth:`Table.from_corners`).
    part_radius : float
        Radius of the parts [m] (for other shapes, their circumradius).
    palette : Palette or None
        Reference colours for the labels (default: pennies, red and blue chips); ``None``: no
        labels (``"unknown"``).
    min_contrast : float
        Smallest mean colour distance from the plate [grey levels] for a part.
    max_parts : int, optional
        Keep at most this many, the most contrasted first.

    Returns
    -------
    Parts
        Centres on the plate [m] and in the image [px], labels, contrast, visible area.
    """
    return seen_parts(frame, table, part_radius, palette, min_contrast, max_parts)[0]


def seen_parts(
    frame: ArrayLike,
    table: Table,
    part_radius: float,
    palette: Palette | None,
    min_contrast: float,
    max_parts: int | None,
) -> tuple[Parts, Rectifier, NDArray[np.uint8], F32]:
    """:func:`find_parts` (its arguments checked) with the top view it worked in: the parts, the
    :class:`Rectifier`, the rectified frame and the plate's fitted colour."""
    img = check_frame(frame)
    instance("table", table, Table, "a upm.vision.Table (from find_table)")
    if palette is not None:
        instance("palette", palette, Palette, "a upm.vision.Palette or None")
    real("part_radius", part_radius, low=0.0, low_open=True)
    min_contrast = real("min_contrast", min_contrast, low=0.0, low_open=True)
    if max_parts is not None:
        max_parts = integer("max_parts", max_parts, low=1)
    if (img.shape[1], img.shape[0]) != tuple(table.image_size):
        raise VisionError(f"frame is {img.shape[1]} x {img.shape[0]} px but the table was found in "
                          f"{table.image_size[0]} x {table.image_size[1]} px frames")  # fmt: skip
    rect = Rectifier(table, part_radius)
    top = rect.warp(img)
    background = rect.fit_background(top)
    return parts_from_top(top, background, rect, palette, min_contrast, max_parts), rect, top, background


def parts_from_top(top: NDArray[np.uint8], background: F32, rect: Rectifier, palette: Palette | None,
                   min_contrast: float, max_parts: int | None) -> Parts:  # fmt: skip
    centres, colour, area, strength = detect(top, background, rect, min_contrast, max_parts)
    plate = rect.to_plate(centres) if len(centres) else np.zeros((0, 2))
    on = rect.table.contains(plate) if len(plate) else np.zeros(0, bool)
    centres, colour, area, strength, plate = centres[on], colour[on], area[on], strength[on], plate[on]
    order = np.lexsort((plate[:, 0], -plate[:, 1])) if len(plate) else np.zeros(0, int)
    centres, colour, area, strength, plate = (a[order] for a in (centres, colour, area, strength, plate))
    labels, ratios = label_parts(centres, colour, background, palette)
    return Parts(
        positions=plate,
        pixels=rect.table.to_camera(plate) if len(plate) else np.zeros((0, 2)),
        labels=labels,
        contrast=np.linalg.norm(colour, axis=1) if len(colour) else np.zeros(0),
        area=area / (math.pi * rect.radius**2),
        colors=ratios,
    )


def label_parts(centres: FloatArray, colour: FloatArray, background: F32,
                palette: Palette | None) -> tuple[tuple[str, ...], FloatArray]:  # fmt: skip
    """Labels and colour ratios (part / plate) for parts at top-view ``centres``."""
    n = len(centres)
    if background.shape[2] != 3:
        return ("",) * n, np.full((n, 3), np.nan)
    if not n:
        return (), np.zeros((0, 3))
    ix = np.clip(np.round(centres).astype(int), 0, [background.shape[1] - 1, background.shape[0] - 1])
    plate = background[ix[:, 1], ix[:, 0]].astype(np.float64)
    ratios = (plate + colour) / np.maximum(plate, 1.0)
    labels = palette.classify(ratios) if palette is not None else ("unknown",) * n
    return labels, ratios
