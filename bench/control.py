"""The three planners on the same task, through the same loop: 4 chips (2 red, 2 blue) sorted to
opposite sides of the simulated plate (motors, flexures, virtual camera, vision).

Reports, per planner: whether the sort finished, plate time to sort, cycles, the step tracking
error (|achieved - desired| per part and cycle, median and 90th percentile) and the cross-talk
(median sideways motion: the part of each achieved step across the step asked for). Seeds are fixed; the
table in README.md comes from this script. Run: ``python bench/control.py [--seeds N]``.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import upm
from upm import control
from upm.demos import _MOTORS, CHIP, PLATE, _scatter
from upm.drive import flexures
from upm.plant import SimulatedUPM


def planners() -> dict[str, object]:
    centers = upm.ring_centers(12, 0.25)
    return {
        "RotationsPlanner (ch. 4, 12 centres, SVD, damped)": control.RotationsPlanner(
            centers, cycle=2.0, damping=1.0
        ),
        "DisplacementPlanner (ch. 5, same centres)": control.DisplacementPlanner(centers, mu=0.3, **_MOTORS),
        "JetPlanner (ch. 6)": control.JetPlanner(mu=0.3, amplitude=0.1, rho=0.03, **_MOTORS),
    }


def run(name: str, planner: object, seed: int) -> dict[str, float]:
    rng = np.random.default_rng(seed)
    parts = _scatter(rng, 4, 0.07, 0.055)
    labels = ["red", "red", "blue", "blue"]
    plant = SimulatedUPM(plate=PLATE, axes=flexures(PLATE.mass, PLATE.inertia), parts=parts, seed=seed)
    task = control.SortTask({"red": -1, "blue": 1}, line=0.09, margin=0.08, spacing=0.046, max_step=0.02)
    loop = control.Loop(plant, plant.camera(labels, seed=seed), planner, task, part_radius=CHIP)
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        log = loop.run(60)
    wall = time.perf_counter() - start
    d, a = log.desired, log.achieved
    asked = np.hypot(d[..., 0], d[..., 1])
    across = np.abs(a[..., 0] * d[..., 1] - a[..., 1] * d[..., 0]) / np.where(asked > 1e-3, asked, np.nan)
    track = log.tracking_error()
    return {
        "done": float(log.done),
        "plate_time": float(log.meta["plate_time"]),
        "cycles": float(len(log.rows) - 1),
        "track_median": float(np.nanmedian(track)),
        "track_p90": float(np.nanpercentile(track, 90)),
        "crosstalk": float(np.nanmedian(across)),
        "fallen": float(plant.fallen),
        "wall": wall,
        "planning_ms": 1000 * float(np.mean(log.planning)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args()
    print(f"upm {upm.__version__}: 4 chips sorted, {args.seeds} seeds each (medians over seeds)\n")
    print(
        "| planner | sorted | plate time to sort [s] | cycles | step error median / p90 [mm] "
        "| cross-talk [mm] | planning [ms/cycle] |"
    )
    print("|---|---|---|---|---|---|---|")
    for name, planner in planners().items():
        rows = [run(name, planner, seed) for seed in range(args.seeds)]
        med = {k: float(np.median([r[k] for r in rows])) for k in rows[0]}
        done = sum(int(r["done"]) for r in rows)
        track = f"{1000 * med['track_median']:.1f} / {1000 * med['track_p90']:.1f}"
        print(
            f"| {name} | {done}/{len(rows)} | {med['plate_time']:.0f} | {med['cycles']:.0f} | {track} | "
            f"{1000 * med['crosstalk']:.1f} | {med['planning_ms']:.0f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
