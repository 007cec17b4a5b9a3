"""Polygon parts turned and placed through the closed loop (issue 27, docs/polygons.md).

``upm demo orient``: four 40 x 20 mm brackets (rectangles: an L-shaped bracket's convex hull
feeds like one) at random poses on the simulated plate (motors on flexures, the plate's stroke,
contacts between the parts) brought to four given poses, seen by the virtual camera
(:func:`upm.vision.find_poses`), each pulse chosen by :class:`upm.plan.orient.PosePlanner`; over
several seeds, medians and maxima of plate time and final errors.

``upm demo sort-shapes``: parts of mixed shapes sorted by shape: two brackets and two right
triangles start in one row across the plate in a random order, and the loop brings the brackets
to the row above and the triangles to the row below, each to a given pose; the camera tells the
shapes apart by their moments (:attr:`upm.vision.Poses.kinds`).

``upm demo orient-ppod``: sensorless orienting on the simulated 6-DOF plate: the test polygons
(a right triangle, a 2:1 rectangle, an irregular pentagon) started 45 degrees either side of the
orientation :func:`upm.orientation_equilibria` predicts for the PPOD's line sink (a linear
squeeze field), and where the simulation brings them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..physics.polygon import Polygon
from .runner import run_named

__all__ = [
    "DEMOS",
    "SORT_TARGETS",
    "TARGETS",
    "TEST_POLYGONS",
    "line_sink_orienting",
    "run_orient",
    "run_sort",
]

#: The brackets' targets: frame origin [m] and angle [rad].
TARGETS = np.array(
    [
        [-0.06, 0.05, 0.0],
        [0.06, 0.05, math.pi / 4],
        [-0.06, -0.05, math.pi / 2],
        [0.06, -0.05, 3 * math.pi / 4],
    ]
)
BRACKET = Polygon.rectangle(0.04, 0.02)


def run_orient(
    seed: int, part: Polygon = BRACKET, targets: Any = TARGETS, cycles: int = 200
) -> dict[str, Any]:
    """One run of the orienting task from a layout drawn with ``seed``: the loop's outcome."""
    from ..control import PoseLoop, PosePlanner, PoseTask, SimulatedDevice
    from ..plate.plant import SimulatedUPM

    rng = np.random.default_rng(seed)
    t = np.asarray(targets, dtype=np.float64)
    corners = np.array([[-0.08, 0.07], [0.08, 0.07], [-0.08, -0.07], [0.08, -0.07]])[: len(t)]
    starts = corners + rng.uniform(-0.01, 0.01, (len(t), 2))
    plant = SimulatedUPM(parts=starts, part_shape=part, angles=rng.uniform(0, 2 * math.pi, len(t)), seed=seed)
    device = SimulatedDevice(plant)
    loop = PoseLoop(device, plant.camera("red", seed=seed), PosePlanner(part, device.limits), PoseTask(t))
    log = loop.run(cycles=cycles)
    return {**_outcome(seed, log, plant), "start_angle_error_deg": log.errors[0][:, 1].tolist()}


def _outcome(seed: int, log: Any, plant: Any) -> dict[str, Any]:
    """What a pose loop's run ended with: done, why it stopped, plate time, pulses, the final
    errors per part and the parts that fell off."""
    errors = log.errors[-1]
    return {
        "seed": seed,
        "done": log.done,
        "stopped": log.stopped,
        "plate_time_s": log.plate_time,
        "cycles": len(log.pulses),
        "position_error_mm": (1e3 * errors[:, 0]).tolist(),
        "angle_error_deg": errors[:, 1].tolist(),
        "fallen": plant.fallen,
    }


#: The shapes sorted by ``upm demo sort-shapes``: a 40 x 20 mm bracket and a 40 x 25 mm right
#: triangle.
SORT_SHAPES = [Polygon.rectangle(0.04, 0.02), Polygon([(0.0, 0.0), (0.04, 0.0), (0.0, 0.025)])]
#: Their targets (frame origin [m], angle [rad]) and the shape each is for: brackets to the row
#: above, triangles to the row below.
SORT_TARGETS = np.array(
    [[-0.05, 0.06, 0.0], [0.05, 0.06, 0.0], [-0.06, -0.07, math.pi / 2], [0.04, -0.07, math.pi / 2]]
)
SORT_KINDS = np.array([0, 0, 1, 1])


def run_sort(seed: int, cycles: int = 200) -> dict[str, Any]:
    """One run of ``upm demo sort-shapes`` from a layout drawn with ``seed``: the loop's outcome,
    and how many parts the camera took for the wrong shape in the first frame."""
    from ..control import PoseLoop, PosePlanner, PoseTask, SimulatedDevice
    from ..plate.plant import SimulatedUPM
    from ..vision import find_poses, find_table

    rng = np.random.default_rng(seed)
    # one row across the middle, 6 cm apart, the shapes in a random order
    row = np.column_stack([[-0.09, -0.03, 0.03, 0.09], np.zeros(4)]) + rng.uniform(-0.005, 0.005, (4, 2))
    starts = row[rng.permutation(4)]
    shapes = [SORT_SHAPES[k] for k in SORT_KINDS]
    plant = SimulatedUPM(parts=starts, part_shape=shapes, angles=rng.uniform(0, 2 * math.pi, 4), seed=seed)
    device = SimulatedDevice(plant)
    camera = plant.camera("red", seed=seed)
    _, frame = camera.read()
    seen = find_poses(frame, find_table(frame), SORT_SHAPES)
    truth = plant.centroids()
    nearest = [int(np.argmin(np.hypot(*(truth - c).T))) for c in seen.centroids]
    mistaken = int(np.sum(seen.kinds != SORT_KINDS[nearest]))
    planner = PosePlanner(SORT_SHAPES, device.limits)
    loop = PoseLoop(device, camera, planner, PoseTask(SORT_TARGETS, kinds=SORT_KINDS))
    log = loop.run(cycles=cycles)
    # where each part really ended (its frame's origin), against the targets of its own shape
    right = [bool(np.min(np.hypot(*(SORT_TARGETS[SORT_KINDS == k, :2] - p).T)) < 0.01)
             for k, p in zip(SORT_KINDS, plant.parts, strict=True)]  # fmt: skip
    return {**_outcome(seed, log, plant), "mistaken_shapes": mistaken, "sorted": int(sum(right))}


def _summary(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """Medians and maxima over the seeds of a loop demo's runs (plate time, worst final errors)."""
    times = [r["plate_time_s"] for r in runs]
    pos = [max(r["position_error_mm"]) for r in runs]
    ang = [max(abs(a) for a in r["angle_error_deg"]) for r in runs]
    return {
        "runs": runs,
        "done": f"{sum(r['done'] for r in runs)}/{len(runs)}",
        "plate_time_s_median_max": [float(np.median(times)), max(times)],
        "position_error_mm_median_max": [float(np.median(pos)), max(pos)],
        "angle_error_deg_median_max": [float(np.median(ang)), max(ang)],
        "fallen": sum(r["fallen"] for r in runs),
    }


def _sort(quick: bool, out: Path) -> dict[str, Any]:
    runs = [run_sort(s) for s in ([1] if quick else [1, 2, 3])]
    return {
        **_summary(runs),
        "sorted": f"{sum(r['sorted'] for r in runs)}/{4 * len(runs)}",
        "mistaken_shapes": sum(r["mistaken_shapes"] for r in runs),
    }


def _orient(quick: bool, out: Path) -> dict[str, Any]:
    return _summary([run_orient(s) for s in ([1] if quick else [1, 2, 3])])


#: The test polygons of sensorless orienting: a right triangle, a 2:1 rectangle and an irregular
#: pentagon [m].
TEST_POLYGONS = {
    "triangle": [[0.0, 0.0], [0.03, 0.0], [0.0, 0.015]],
    "rectangle 2:1": [[0.0, 0.0], [0.03, 0.0], [0.03, 0.015], [0.0, 0.015]],
    "pentagon": [[0.0, 0.0], [0.030, -0.004], [0.041, 0.016], [0.022, 0.031], [-0.006, 0.019]],
}


def line_sink_orienting(
    vertices: Any, offset: float, duration: float = 60.0, seed: int = 0
) -> dict[str, Any]:
    """One part on the simulated 6-DOF plate under the PPOD's ``LineSinkX`` (a line sink along y
    through the origin), started ``offset`` [rad] from the orientation that
    :func:`upm.orientation_equilibria` predicts for the linear squeeze field, at a position drawn
    with ``seed``: its angle error [deg] over time, and when it came within 3 degrees."""
    from ..physics.motion import PlateMotion
    from ..physics.orienting import SqueezeField, orientation_equilibria
    from ..physics.sim import simulate

    part = Polygon(vertices)
    (want,) = orientation_equilibria(part, SqueezeField(angle=math.pi / 2, profile="linear")).stable
    at = np.random.default_rng(seed).uniform(-0.02, 0.02, 2)
    every = 2000  # steps of 1/8000 s: a record every 0.25 s
    run = simulate(
        PlateMotion.ppod("LineSinkX"),
        [Polygon(part.vertices, position=(float(at[0]), float(at[1])), angle=want + offset)],
        duration=duration,
        dt=1 / 8000,
        mu=0.3,
        record_every=every,
    )
    err = np.degrees((run.angles[:, 0] - want + math.pi / 2) % math.pi - math.pi / 2)
    outside = np.flatnonzero(np.abs(err) >= 3.0)
    within = float(run.t[outside[-1] + 1]) if outside.size and outside[-1] + 1 < len(err) else None
    return {
        "predicted_deg": math.degrees(want) % 180.0,
        "start_error_deg": float(err[0]),
        "final_error_deg": float(err[-1]),
        "within_3_deg_after_s": 0.0 if not outside.size else within,
    }


def _orient_ppod(quick: bool, out: Path) -> dict[str, Any]:
    offsets = [math.radians(45.0)] if quick else [math.radians(-45.0), math.radians(45.0)]
    duration = 45.0 if quick else 90.0
    runs = {
        name: [line_sink_orienting(v, o, duration, seed=i) for i, o in enumerate(offsets)]
        for name, v in TEST_POLYGONS.items()
    }
    finals = [abs(r["final_error_deg"]) for rs in runs.values() for r in rs]
    return {
        "field": "PPOD LineSinkX, 20 Hz, mu 0.3; prediction: linear squeeze field along x = 0",
        "duration_s": duration,
        "runs": runs,
        "final_error_deg_median_max": [float(np.median(finals)), max(finals)],
        "within_3_deg": f"{sum(f < 3.0 for f in finals)}/{len(finals)}",
    }


DEMOS: dict[str, tuple[str, Callable[[bool, Path], dict[str, Any]]]] = {
    "orient": ("four brackets turned and placed to given poses through the closed loop", _orient),
    "sort-shapes": ("two brackets and two triangles sorted by shape to given poses through the loop", _sort),
    "orient-ppod": (
        "a triangle, a 2:1 rectangle and a pentagon turned by the PPOD's line sink, against the prediction",
        _orient_ppod,
    ),
}


def run_orient_demo(out: Path | str = "out", quick: bool = False, verbose: bool = True) -> dict[str, Any]:
    """Run ``upm demo orient``; write ``out/orient/metrics.json`` and return the metrics."""
    return run_named(DEMOS, "orient", out, quick, verbose)
