"""Polygon parts turned and placed through the closed loop (issue 27, docs/polygons.md).

``upm demo orient``: four 40 x 20 mm brackets (rectangles: an L-shaped bracket's convex hull
feeds like one) at random poses on the simulated plate (motors on flexures, the plate's stroke,
contacts between the parts) brought to four given poses, seen by the virtual camera
(:func:`upm.vision.find_poses`), each pulse chosen by :class:`upm.plan.orient.PosePlanner`; over
several seeds, medians and maxima of plate time and final errors.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ._experiments import run_named
from .polygon import Polygon

__all__ = ["DEMOS", "TARGETS", "run_orient"]

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
    from .control import PoseLoop, PosePlanner, PoseTask, SimulatedDevice
    from .plant import SimulatedUPM

    rng = np.random.default_rng(seed)
    t = np.asarray(targets, dtype=np.float64)
    corners = np.array([[-0.08, 0.07], [0.08, 0.07], [-0.08, -0.07], [0.08, -0.07]])[: len(t)]
    starts = corners + rng.uniform(-0.01, 0.01, (len(t), 2))
    plant = SimulatedUPM(parts=starts, part_shape=part, angles=rng.uniform(0, 2 * math.pi, len(t)), seed=seed)
    device = SimulatedDevice(plant)
    loop = PoseLoop(device, plant.camera("red", seed=seed), PosePlanner(part, device.limits), PoseTask(t))
    log = loop.run(cycles=cycles)
    errors = log.errors[-1]
    return {
        "seed": seed,
        "done": log.done,
        "stopped": log.stopped,
        "plate_time_s": log.plate_time,
        "cycles": len(log.pulses),
        "position_error_mm": (1e3 * errors[:, 0]).tolist(),
        "angle_error_deg": errors[:, 1].tolist(),
        "start_angle_error_deg": log.errors[0][:, 1].tolist(),
        "fallen": plant.fallen,
    }


def _orient(quick: bool, out: Path) -> dict[str, Any]:
    seeds = [1] if quick else [1, 2, 3]
    runs = [run_orient(s) for s in seeds]
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


DEMOS: dict[str, tuple[str, Callable[[bool, Path], dict[str, Any]]]] = {
    "orient": ("four brackets turned and placed to given poses through the closed loop", _orient),
}


def run_orient_demo(out: Path | str = "out", quick: bool = False, verbose: bool = True) -> dict[str, Any]:
    """Run ``upm demo orient``; write ``out/orient/metrics.json`` and return the metrics."""
    return run_named(DEMOS, "orient", out, quick, verbose)
