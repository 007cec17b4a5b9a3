"""Benchmark: vision, upm versus the usual OpenCV recipes, on the same synthetic frames.

Run with ``make bench`` (or ``python bench/vision.py [--quick]``). Frames are 640 x 480 with
noise sigma 5 grey levels, a lighting gradient and lens blur; ground truth comes from
``upm.vision.synthetic``. Printed, per case:

* full detection (``find_table`` + ``find_parts``): milliseconds per frame (target: at most 10),
  centre error [px RMS], parts found; beside it ``cv2.HoughCircles`` on the grey frame (the usual
  recipe, with the table already known), its time, error and parts found;
* tracking 10 parts (``Tracker.update``, local search): milliseconds per frame (target: at most
  0.5), beside it ``cv2.TrackerMIL`` (one OpenCV tracker per part) and re-running ``find_parts``
  on every frame; the ratios are printed.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import cv2
import numpy as np

from upm.vision import Tracker, find_parts, find_table
from upm.vision.synthetic import RADII, Camera, render


def layout(n: int, r: float, rng: np.random.Generator, packed: bool) -> np.ndarray:
    if packed:  # a touching hexagonal cluster
        d = 2 * r + 0.0002
        grid = np.array([[(c + 0.5 * (row % 2)) * d, row * d * 0.866] for row in range(4) for c in range(3)])
        return grid[:n] - grid[:n].mean(axis=0)
    pts: list[np.ndarray] = []
    while len(pts) < n:
        p = rng.uniform(-0.17, 0.17, 2)
        if all(np.linalg.norm(p - q) > 2 * r + 0.004 for q in pts):
            pts.append(p)
    return np.array(pts)


def per_call(fn: Callable[[int], object], n: int) -> float:
    fn(0)
    start = time.perf_counter()
    for k in range(n):
        fn(k)
    return (time.perf_counter() - start) / n


def rms_error(found: np.ndarray, truth: np.ndarray) -> tuple[float, int]:
    """RMS distance [px] of each truth to its nearest detection (within 3 px), and the count."""
    if not len(found):
        return float("nan"), 0
    d = np.linalg.norm(truth[:, None] - found[None], axis=2)
    near = d.min(axis=1)
    hit = near < 3.0
    return float(np.sqrt(np.mean(near[hit] ** 2))) if hit.any() else float("nan"), int(hit.sum())


def hough(grey: np.ndarray, radius_px: float) -> np.ndarray:
    circles = cv2.HoughCircles(
        cv2.GaussianBlur(grey, (5, 5), 1.0),
        cv2.HOUGH_GRADIENT,
        dp=1,
        minDist=1.5 * radius_px,
        param1=80,
        param2=12,
        minRadius=int(0.8 * radius_px),
        maxRadius=int(1.2 * radius_px) + 1,
    )
    return np.zeros((0, 2)) if circles is None else circles[0, :, :2].astype(np.float64)


def detection(kind: str, frames: int, rng: np.random.Generator) -> None:
    labels = ["penny"] * 10 if kind == "pennies" else ["red", "blue"] * 5
    r = RADII[labels[0]]
    cam = Camera()
    shots = [render(cam, layout(10, r, rng, packed=False), labels, rng=k) for k in range(frames)]
    table = find_table(shots[0].image)
    radius_px = r * table.pixels_per_metre

    found = [find_parts(s.image, find_table(s.image), r) for s in shots]
    ours = [rms_error(f.pixels, s.truth.centers) for f, s in zip(found, shots, strict=True)]
    t_ours = per_call(lambda k: find_parts(shots[k].image, find_table(shots[k].image), r), frames)
    greys = [cv2.cvtColor(s.image, cv2.COLOR_BGR2GRAY) for s in shots]
    peer = [rms_error(hough(g, radius_px), s.truth.centers) for g, s in zip(greys, shots, strict=True)]
    t_peer = per_call(lambda k: hough(greys[k], radius_px), frames)
    err_ours = np.sqrt(np.nanmean([e**2 for e, _ in ours]))
    err_peer = np.sqrt(np.nanmean([e**2 for e, _ in peer])) if any(n for _, n in peer) else float("nan")
    print(
        f"detect {kind:8s}  upm: {t_ours * 1e3:6.2f} ms/frame (table + parts), {err_ours:.3f} px RMS, "
        f"{sum(n for _, n in ours)}/{10 * frames} found | HoughCircles (grey, table given): "
        f"{t_peer * 1e3:6.2f} ms, {err_peer:.3f} px RMS, {sum(n for _, n in peer)}/{10 * frames} found"
    )


def tracking(packed: bool, frames: int, rng: np.random.Generator) -> None:
    labels = ["red", "blue"] * 5
    r = RADII["red"]
    cam = Camera()
    start = layout(10, r, rng, packed)
    drift = np.array([0.0003, 0.0001])
    shots = [render(cam, start + k * drift, labels, rng=k) for k in range(frames + 1)]
    table = find_table(shots[0].image)

    tracker = Tracker(table, r, detect_every=0)
    tracker.update(shots[0].image)
    t_ours = per_call(lambda k: tracker.update(shots[1 + k % frames].image), frames)
    tracker = Tracker(table, r, detect_every=0)
    tracks = [tracker.update(s.image) for s in shots]
    owner = np.argmin(
        np.linalg.norm(tracks[0].pixels[:, None] - shots[0].truth.centers[None], axis=2), axis=1
    )
    err = np.sqrt(
        np.mean(
            [
                np.sum((t.pixels - s.truth.centers[owner]) ** 2, axis=1)
                for t, s in zip(tracks, shots, strict=True)
            ]
        )
    )

    t_detect = per_call(lambda k: find_parts(shots[1 + k % frames].image, table, r), frames)

    px = shots[0].truth.centers
    size = int(2.4 * r * table.pixels_per_metre)
    mil = []
    for x, y in px:
        t = cv2.TrackerMIL.create()
        t.init(shots[0].image, (int(x - size / 2), int(y - size / 2), size, size))
        mil.append(t)
    mil_frames = min(frames, 20)

    def run_mil(k: int) -> None:
        for t in mil:
            t.update(shots[1 + k % mil_frames].image)

    t_mil = per_call(run_mil, mil_frames)
    name = "packed   " if packed else "scattered"
    print(
        f"track 10 chips {name}  upm Tracker: {t_ours * 1e3:5.2f} ms/frame ({err:.3f} px RMS) | "
        f"find_parts every frame: {t_detect * 1e3:5.2f} ms ({t_detect / t_ours:4.1f}x) | "
        f"10 x cv2.TrackerMIL: {t_mil * 1e3:6.1f} ms ({t_mil / t_ours:5.0f}x)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="fewer frames (for smoke tests)")
    args = parser.parse_args()
    frames = 10 if args.quick else 100
    rng = np.random.default_rng(0)
    print(f"OpenCV {cv2.__version__}, {cv2.getNumThreads()} threads; 640 x 480 frames, noise sigma 5")
    for kind in ("pennies", "chips"):
        detection(kind, frames, rng)
    for packed in (False, True):
        tracking(packed, frames, rng)


if __name__ == "__main__":
    main()
