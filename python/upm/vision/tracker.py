"""Tracking parts from frame to frame with persistent IDs (docs/spec.md §8, thesis 5.2.4).

Each frame, every tracked part is looked for only in a small window around its predicted
position (last position plus last step), cut from the camera frame straight into the plate's
top view; its centre is refined by the same coverage centroid as in detection, with the part's
own colour. A part whose window no longer holds it (too little of its colour, or it moved
farther than ``search`` pixels) is reported lost, never guessed. When a part is lost, and every
``detect_every`` frames, the whole plate is searched again: lost parts are re-acquired by label
and distance, new parts get new IDs, and parts lost for more than ``max_missed`` frames are
dropped as having left.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import as_float, as_int, check_range
from .._errors import ShapeError, VisionError
from .parts import BLOB_AREA, BLOB_RING, THESIS_PALETTE, Palette, Rectifier, detect, label_parts, refine
from .table import Table, check_frame

__all__ = ["Tracker", "Tracks"]

FloatArray = NDArray[np.float64]


#: The first local search looks this many part radii around each part's guess (the full
#: ``search`` only for the parts not found there).
NEAR = 0.75


@dataclass(frozen=True)
class Tracks:
    """The tracked parts after one frame.

    Attributes
    ----------
    frame : int
        Index of the frame (0 for the first).
    ids : (N,) int ndarray
        Persistent IDs of every part known now (tracked or lost), ascending.
    positions : (N, 2) ndarray
        Centres on the plate [m]; NaN for parts lost in this frame.
    pixels : (N, 2) ndarray
        Centres in the camera image [px]; NaN when lost.
    labels : tuple of N str
        Colour labels (fixed when a part is first seen).
    lost : (N,) bool ndarray
        Parts not found in this frame.
    entered, left : tuple of int
        IDs that appeared in this frame, and IDs dropped in it (lost for too long).
    redetected : bool
        Whether the whole plate was searched in this frame.
    seconds : float
        Time spent on this frame.
    """

    frame: int
    ids: NDArray[np.int64]
    positions: FloatArray
    pixels: FloatArray
    labels: tuple[str, ...]
    lost: NDArray[np.bool_]
    entered: tuple[int, ...]
    left: tuple[int, ...]
    redetected: bool
    seconds: float

    def __len__(self) -> int:
        return len(self.ids)

    def position(self, part_id: int) -> FloatArray:
        """Centre [m] of part ``part_id`` (NaN if it is lost in this frame)."""
        where = np.nonzero(self.ids == part_id)[0]
        if not len(where):
            raise VisionError(f"no part with id {part_id}; known ids: {self.ids.tolist()}")
        return np.asarray(self.positions[where[0]], dtype=np.float64)


class _Source(Protocol):
    def read(self) -> tuple[bool, Any]: ...


class Tracker:
    """Persistent part IDs over a sequence of frames.

    Parameters
    ----------
    table : Table
        The plate (the camera is assumed fixed).
    part_radius : float
        Part radius [m].
    palette : Palette or None
        Colour references for labels (default: pennies, red and blue chips).
    search : float
        Farthest a part may move from its predicted position between two frames [px of the
        top view, about camera px]; beyond it the part is lost and found again by re-detection.
    min_area : float
        Smallest visible fraction of a part's area (in its own colour) that counts as found.
    min_contrast : float
        Detection threshold [grey levels] (see :func:`find_parts`).
    detect_every : int
        Search the whole plate every this many frames (for parts that entered); 0: only when a
        part is lost.
    max_missed : int
        Frames a part may stay lost before it is dropped as having left.
    reacquire : float
        Farthest [m] from its last position at which a lost part is recognised again
        (default: 10 part radii); farther away a detection becomes a new part.
    """

    def __init__(
        self,
        table: Table,
        part_radius: float,
        *,
        palette: Palette | None = THESIS_PALETTE,
        search: float = 4.0,
        min_area: float = 0.6,
        min_contrast: float = 30.0,
        detect_every: int = 30,
        max_missed: int = 15,
        reacquire: float | None = None,
    ) -> None:
        self.rect = Rectifier(table, part_radius)
        self.palette = palette
        for name, value in (("search", search), ("min_contrast", min_contrast)):
            check_range(name, as_float(name, value), low=0.0, low_open=True)
        check_range("min_area", as_float("min_area", min_area), low=0.0, high=1.0, low_open=True)
        self.search = float(search)
        self.min_area = float(min_area)
        self.min_contrast = float(min_contrast)
        self.detect_every = as_int("detect_every", detect_every)
        self.max_missed = as_int("max_missed", max_missed)
        if self.detect_every < 0 or self.max_missed < 0:
            raise VisionError("detect_every and max_missed must be >= 0")
        self.reacquire = 10 * part_radius if reacquire is None else float(reacquire)
        self._next_id = 0
        self._frame = -1
        self._ids = np.zeros(0, np.int64)
        self._pos = np.zeros((0, 2))  # top view [px]
        self._vel = np.zeros((0, 2))
        self._colour = np.zeros((0, 0))
        self._labels: list[str] = []
        self._missed = np.zeros(0, np.int64)
        self._gain = 1.0  # this frame's brightness over the stored plate colour's

    # -- public -------------------------------------------------------------------------------

    def update(self, frame: ArrayLike) -> Tracks:
        """Track the parts in the next frame."""
        start = time.perf_counter()
        img = check_frame(frame)
        size = tuple(self.rect.table.image_size)
        if (img.shape[1], img.shape[0]) != size:
            raise VisionError(
                f"frame is {img.shape[1]} x {img.shape[0]} px; the table was found in {size[0]} x {size[1]}"
            )
        self._frame += 1
        entered: list[int] = []
        if self.rect.background is None:
            top = self.rect.warp(img)
            self.rect.fit_background(top)
            entered = self._redetect(top)
            redetected = True
        else:
            still = self._missed > 0  # lost before this frame: one more frame missed unless found again
            self._missed[still] += 1
            # the light drifts (auto-exposure, clouds): the plate's stored colour scaled to this frame
            self._gain = self.rect.light_gain(img)
            self._follow(img)
            lost_now = self._missed > 0
            periodic = self.detect_every > 0 and self._frame % self.detect_every == 0
            redetected = bool(np.any(lost_now) or periodic)
            if redetected:
                entered = self._redetect(self.rect.warp(img))
        left = self._drop()
        return self._report(entered, left, redetected, time.perf_counter() - start)

    def expect(self, ids: ArrayLike, positions: ArrayLike) -> None:
        """Where parts ``ids`` should be in the next frame, ``positions (n, 2)`` [m, plate frame]
        (a planner's prediction of the pulse it played): the next local search starts there
        instead of at the constant-velocity guess, so parts that moved further than ``search``
        are still followed. Unknown ids and non-finite positions are ignored."""
        want = np.asarray(ids, dtype=np.int64).reshape(-1)
        at = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
        if len(want) != len(at):
            raise ShapeError(f"ids and positions must match; got {len(want)} ids and {len(at)} positions")
        index = {int(i): k for k, i in enumerate(self._ids)}
        for i, p in zip(want, at, strict=True):
            k = index.get(int(i))
            if k is not None and np.all(np.isfinite(p)) and self._missed[k] == 0:
                self._vel[k] = self.rect.to_top(p[None])[0] - self._pos[k]

    def run(self, source: _Source, frames: int | None = None) -> Iterator[Tracks]:
        """Track every frame of ``source`` (an OpenCV ``VideoCapture``, a
        :class:`~upm.vision.synthetic.VirtualCamera`, ...) until it ends or ``frames`` were read."""
        n = 0
        while frames is None or n < frames:
            ok, frame = source.read()
            if not ok:
                return
            yield self.update(frame)
            n += 1

    # -- steps --------------------------------------------------------------------------------

    def _follow(self, img: NDArray[np.uint8]) -> None:
        """Local search around every tracked part's predicted position: first in a window of
        :data:`NEAR` part radii (a told or steady part is within a few pixels of its guess), then
        in the full ``search`` window for the parts not found there. The windows' pixels are most
        of a frame's cost, so the near pass makes a frame of many parts several times cheaper."""
        active = np.nonzero(self._missed == 0)[0]
        if not len(active):
            return
        predicted = self._pos[active] + self._vel[active]
        near = min(self.search, NEAR * self.rect.radius)
        centres, found, area = self._look(img, active, predicted, near)
        if near < self.search and not np.all(found):
            again = ~found
            centres[again], found[again], area[again] = self._look(
                img, active[again], predicted[again], self.search
            )
        # two tracks on one part: the weaker one is lost
        dist = np.linalg.norm(centres[:, None] - centres[None], axis=2)
        for a, b in np.argwhere(np.triu(dist < self.rect.radius, 1)):
            if found[a] and found[b]:
                found[b if area[b] < area[a] else a] = False
        idx = active[found]
        self._vel[idx] = centres[found] - self._pos[idx]
        self._pos[idx] = centres[found]
        gone = active[~found]
        self._missed[gone] += 1
        self._vel[gone] = 0.0

    def _look(
        self, img: NDArray[np.uint8], which: NDArray[np.intp], predicted: FloatArray, search: float
    ) -> tuple[FloatArray, NDArray[np.bool_], FloatArray]:
        """Refined centres of parts ``which`` searched for within ``search`` [px] of ``predicted``,
        whether each was found there, and its coverage area [px^2]."""
        bg = self.rect.background
        assert bg is not None
        half = math.ceil(self.rect.radius + 3.5 + search) + 1  # refine's reach plus the search
        size = 2 * half + 1
        high = np.array([bg.shape[1] - size, bg.shape[0] - size])
        origins = np.clip(np.floor(predicted).astype(int) - half, 0, high)
        windows = self.rect.patches(img, origins, size)
        gain = np.float32(self._gain)
        for k, (ox, oy) in enumerate(origins):
            windows[k] -= gain * bg[oy : oy + size, ox : ox + size]
        centres, _, area, around = refine(windows, predicted, origins.astype(np.float64), self.rect.radius,
                                          self._colour[which] * self._gain, iterations=4)  # fmt: skip
        covered = area / (math.pi * self.rect.radius**2)
        found = (
            (covered >= self.min_area)
            & (covered < BLOB_AREA)
            & (np.linalg.norm(centres - predicted, axis=1) <= search)
            & (around < BLOB_RING)  # not under an arm or hand of a similar colour
        )
        return centres, found, area

    def _redetect(self, top: NDArray[np.uint8]) -> list[int]:
        """Search the whole plate; re-acquire lost parts, add new ones."""
        bg = self.rect.background
        assert bg is not None
        if self._gain != 1.0:
            bg = np.asarray(bg * np.float32(self._gain), np.float32)
        centres, colour, area, _ = detect(top, bg, self.rect, self.min_contrast, None)
        plate = self.rect.to_plate(centres) if len(centres) else np.zeros((0, 2))
        keep = self.rect.table.contains(plate) & (area / (math.pi * self.rect.radius**2) >= self.min_area)
        centres, colour = centres[keep], colour[keep]
        labels, _ = label_parts(centres, colour, bg, self.palette)
        colour = colour / self._gain  # kept as under the stored plate colour's light
        r = self.rect.radius
        active = self._missed == 0
        unused = []
        for k in range(len(centres)):
            if len(self._pos) and np.any(active):
                d = np.linalg.norm(self._pos[active] - centres[k], axis=1)
                if d.min() < r:  # already tracked
                    continue
            unused.append(k)
        # lost parts: nearest unused detection of the same label within reach, closest pairs first
        lost = np.nonzero(~active)[0]
        reach = self.reacquire * self.rect.scale
        pairs = sorted(
            (float(np.hypot(*(self._pos[i] - centres[k]))), int(i), k)
            for i in lost
            for k in unused
            if self._labels[i] == labels[k]
        )
        taken_tracks: set[int] = set()
        taken_dets: set[int] = set()
        for dist, i, k in pairs:
            if dist > reach or i in taken_tracks or k in taken_dets:
                continue
            taken_tracks.add(i)
            taken_dets.add(k)
            self._pos[i], self._vel[i], self._missed[i] = centres[k], 0.0, 0
            self._colour[i] = colour[k]
        entered = []
        for k in unused:
            if k in taken_dets:
                continue
            entered.append(self._add(centres[k], colour[k], labels[k]))
        return entered

    def _add(self, centre: FloatArray, colour: FloatArray, label: str) -> int:
        new_id = self._next_id
        self._next_id += 1
        self._ids = np.append(self._ids, new_id)
        self._pos = np.vstack([self._pos, centre[None]])
        self._vel = np.vstack([self._vel, np.zeros((1, 2))])
        self._colour = (
            colour[None].copy() if self._colour.size == 0 else np.vstack([self._colour, colour[None]])
        )
        self._labels.append(label)
        self._missed = np.append(self._missed, 0)
        return new_id

    def _drop(self) -> list[int]:
        gone = self._missed > self.max_missed
        if not np.any(gone):
            return []
        left = [int(i) for i in self._ids[gone]]
        keep = ~gone
        self._ids, self._pos, self._vel = self._ids[keep], self._pos[keep], self._vel[keep]
        self._colour, self._missed = self._colour[keep], self._missed[keep]
        self._labels = [lab for lab, k in zip(self._labels, keep, strict=True) if k]
        return left

    def _report(self, entered: list[int], left: list[int], redetected: bool, seconds: float) -> Tracks:
        lost = self._missed > 0
        plate = self.rect.to_plate(self._pos) if len(self._pos) else np.zeros((0, 2))
        plate[lost] = np.nan
        pixels = self.rect.table.to_camera(plate) if len(plate) else np.zeros((0, 2))
        return Tracks(
            frame=self._frame,
            ids=self._ids.copy(),
            positions=plate,
            pixels=pixels,
            labels=tuple(self._labels),
            lost=lost,
            entered=tuple(entered),
            left=tuple(left),
            redetected=redetected,
            seconds=seconds,
        )
