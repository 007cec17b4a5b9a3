"""The loop on an imperfect machine (issue 60): sort8 and goto6 through the full loop (motors on
flexures, 10 mm stroke, colliding disks, virtual camera and vision, the predictive planner told
nothing of the faults) under each fault alone and all together, beside the perfect plant.

Faults (each seed draws its own):

* ``tilt``: the plate 0.5 degrees off level, downhill along a random direction
  (``SimulatedUPM(tilt=)``: gravity's in-plane part in the integrator);
* ``part_mu``: each part's friction within +-30 % of the planner's 0.3 (``mu`` per part);
* ``gain``: each motor's force within +-15 % of what is asked (``motor_gain``);
* ``phase``: each motor up to 10 degrees late (``motor_phase``);
* ``latency``: the camera 50 ms late (``camera_latency``: each frame shows the parts as they were);
* ``pixel``: each part seen off by 1 px of Gaussian jitter (``pixel_noise``);
* ``light``: the light's brightness drifting 3 % a frame, bounded to +-40 % (``lighting_drift``);
* ``mu_map``: the plate's friction varying over its surface, mu from 0.2 to 0.4 in a few smooth
  bumps (``friction_map``, factors 2/3 to 4/3 on the parts' 0.3, in the core integrator);
* ``stuck``: one part that sticks to the plate until it accelerates beyond 8.8 m/s^2 (three
  times a part's grip; ``stuck``), and again whenever it comes to rest;
* ``all``: all of them (``all7``: the seven before ``mu_map`` and ``stuck``, runs of earlier
  sessions).

Columns: done (of the seeds), plate time [s] median (max), parts lost, wall time [s] median, and
pulses the plant refused (``StrokeError``: motors stronger than the planner's model swing a corner
beyond the stroke; nothing plays, the loop sizes its pulses lower and goes on; a run the loop
gave up on counts as not done).
Every run is appended to ``docs/img/robustness.jsonl`` as it ends; runs already there are not run
again (``--stored``: tabulate them only).

Run: ``python bench/robustness.py [--tasks sort8,goto6] [--faults none,tilt,...] [--seeds 5]``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from control import cpu, planner, setup
from upm import control
from upm.experiments.demos import LIMITS
from upm.physics.surface import smooth_map
from upm.plate.drive import StrokeError
from upm.plate.plant import SimulatedUPM

FAULTS = ("none", "tilt", "part_mu", "gain", "phase", "latency", "pixel", "light", "mu_map", "stuck", "all")
STORE = Path("docs/img/robustness.jsonl")


def faults(name: str, n: int, seed: int) -> dict[str, Any]:
    """The plant's options for fault ``name`` with ``n`` parts (seeded)."""
    rng = np.random.default_rng(1000 + seed)
    way = rng.uniform(0, 2 * math.pi)
    slope = math.radians(0.5)
    each = {
        "tilt": {"tilt": (slope * math.cos(way), slope * math.sin(way))},
        "part_mu": {"mu": 0.3 * rng.uniform(0.7, 1.3, n)},
        "gain": {"motor_gain": rng.uniform(0.85, 1.15, 4)},
        "phase": {"motor_phase": np.radians(rng.uniform(0.0, 10.0, 4))},
        "latency": {"camera_latency": 0.05},
        "pixel": {"pixel_noise": 1.0},
        "light": {"lighting_drift": 0.03},
        "mu_map": {"friction_map": smooth_map(0.2 / 0.3, 0.4 / 0.3, seed=seed)},
        "stuck": {"stuck": {int(rng.integers(n)): 3 * 0.3 * 9.81}},
    }
    if name == "none":
        return {}
    if name == "all":
        return {k: v for d in each.values() for k, v in d.items()}
    return each[name]


def run(task: str, fault: str, seed: int, learn_tilt: bool = False) -> dict[str, float]:
    parts, labels, radius, job, cycles, _ = setup(task, seed)
    plant = SimulatedUPM(plate=LIMITS.plate, axes=LIMITS.axes, parts=parts, seed=seed, part_radius=radius,
                         **faults(fault, len(parts), seed))  # fmt: skip
    chooser = planner("predictive", radius)
    chooser.learn_tilt = learn_tilt
    loop = control.Loop(plant, plant.camera(labels, seed=seed), chooser, job, part_radius=radius)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        start = time.perf_counter()
        try:
            log = loop.run(4 * cycles)
        except StrokeError:  # refused again and again: the loop gave up
            return {"done": 0.0, "time": float("nan"), "lost": float(plant.fallen),
                    "wall": time.perf_counter() - start, "refused": float(loop_refusals(loop))}  # fmt: skip
        wall = time.perf_counter() - start
    refused = float(log.meta.get("refused", 0))
    return {"done": float(log.done and plant.fallen == 0), "time": float(log.meta["plate_time"]),
            "lost": float(plant.fallen), "wall": wall, "refused": refused}  # fmt: skip


def loop_refusals(loop: Any) -> int:
    """Refusals before the loop gave up (its planner's headroom fell 15 % for each)."""
    return 1 + round(math.log(max(loop.planner.headroom, 1e-9)) / math.log(0.85))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", default="sort8,goto6")
    ap.add_argument("--faults", default=",".join(FAULTS))
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--stored", action="store_true", help="tabulate the stored runs, run none")
    ap.add_argument("--learn-tilt", action="store_true",
                    help="the planner learns the slope on line (PredictivePlanner(learn_tilt=True)); "
                    "its rows are stored as FAULT+learnt")  # fmt: skip
    args = ap.parse_args()
    stored: dict[tuple[str, str, int], dict[str, Any]] = {}
    if STORE.exists():
        for line in STORE.read_text().splitlines():
            row = json.loads(line)
            stored[(row["task"], row["fault"], int(row["seed"]))] = row
    tasks, names = args.tasks.split(","), args.faults.split(",")
    for name in names:
        if name not in FAULTS:
            raise SystemExit(f"unknown fault {name!r}; one of {FAULTS}")
    suffix = "+learnt" if args.learn_tilt else ""
    for task in tasks:
        for name in names:
            for seed in range(1, args.seeds + 1):
                if (task, name + suffix, seed) in stored or args.stored:
                    continue
                row = {"task": task, "fault": name + suffix, "seed": seed, "cpu": cpu(),
                       **run(task, name, seed, args.learn_tilt)}  # fmt: skip
                stored[(task, name + suffix, seed)] = row
                with STORE.open("a") as f:
                    f.write(json.dumps(row) + "\n")
                print(f"{task} {name}{suffix} seed {seed}: done {row['done']:.0f}, {row['time']:.1f} s, "
                      f"{row['lost']:.0f} lost, {row['wall']:.0f} s wall", flush=True)  # fmt: skip
    print(f"\n{cpu()}: the predictive planner, told nothing of the faults; median (max)\n")
    print("| task | fault | done | plate time [s] | vs perfect | lost | wall time [s] | refused |")
    print("|---|---|---|---|---|---|---|---|")
    for task in tasks:
        base = [r["time"] for (t, f, _), r in stored.items() if (t, f) == (task, "none")]
        shown = [*names, *(["all7"] if "all" in names else []), *(n + "+learnt" for n in names)]
        for name in shown:
            rows = [r for (t, f, _), r in stored.items() if (t, f) == (task, name)]
            if not rows:
                continue
            t_ = np.array([r["time"] for r in rows if np.isfinite(r["time"])] or [np.nan])
            ratio = f"{np.median(t_) / np.median(base):.2f}x" if base else "–"
            lost = np.array([r["lost"] for r in rows])
            print(f"| {task} | {name} | {int(sum(r['done'] for r in rows))}/{len(rows)} | "
                  f"{np.median(t_):.1f} ({np.max(t_):.1f}) | {ratio} | "
                  f"{lost.sum():.0f} (max {lost.max():.0f}) | "
                  f"{np.median([r['wall'] for r in rows]):.0f} | "
                  f"{sum(r.get('refused', 0) for r in rows):.0f} |")  # fmt: skip


if __name__ == "__main__":
    main()
