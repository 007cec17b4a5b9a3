"""Every planner on the closed-loop tasks, through the full loop: motors on flexures (10 mm stroke,
200 N motors), colliding disks (rapier2d), the virtual camera and vision.

Tasks (each over ``--seeds`` seeds; medians and maxima):

* ``sort8``: 8 chips sorted by colour (thesis Fig. 6.6: about 30 s on the hardware);
* ``sort10``: 10 chips (Fig. 4.9);
* ``goto6``: 6 pennies to random goals, all within 3 mm;
* ``bowtie``: 3 pennies equidistant around the figure-eight (Figs. 6.4-6.5: about a minute a loop);
* ``mu0.21``, ``mu0.39``: sort8 on plates whose friction is 0.21 and 0.39, the planner told 0.3;
* ``gather8``: 8 pennies into a pile of 4 cm radius off the centre (not in the default list).

Planner ``fields`` (:class:`upm.control.FieldPlanner`, docs/ppod.md) plays velocity fields on the
six-actuator plate (:class:`upm.control.SimulatedDevice6`: each actuator's force and stroke
checked, 5 % gain errors); its parts are points, since contacts with lift-off are not modelled.

Columns: done (of the seeds), plate time to finish [s], parts lost, largest plate-corner excursion
[mm], median predicted-vs-achieved step error [mm] (predictive planner), median planning time per
cycle [ms], and the share of progress later undone. Also ``--scaling``: sorts and the letter L of
8 to 100 parts, the predictive planner beside the greedy library peer (the published Chladni
controller, :class:`upm.control.GreedyLibraryPlanner`): done, plate and wall time, lost, final
max error, planning time, parts per minute; plotted to ``docs/img/scaling.png`` (``--stored``:
from the runs already in ``docs/img/scaling.jsonl``).

Run: ``python bench/control.py [--tasks sort8,goto6] [--planners predictive,jets] [--seeds 5]``.
"""

from __future__ import annotations

import argparse
import platform
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

import upm
from upm import control
from upm.experiments.demos import CHIP, LIMITS, PENNY, figure_eight, scatter
from upm.plan import PredictivePlanner
from upm.plate.plant import SimulatedUPM


def cpu() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def planner(name: str, radius: float) -> Any:
    if name == "predictive":
        return PredictivePlanner(LIMITS, mu=0.3, part_radius=radius)
    if name == "jets":
        return control.JetPlanner(mu=0.3, amplitude=0.1, rho=0.03, limits=LIMITS)
    if name == "fields":  # a 6-DOF plate: velocity fields, no stroke model (docs/ppod.md)
        return control.FieldPlanner(mu=0.3)
    if name == "rotations":
        centers = np.vstack([upm.ring_centers(8, 0.07), upm.ring_centers(16, 0.18, phase=0.2)])
        return control.RotationsPlanner(centers, cycle=4.0, limits=LIMITS)
    raise SystemExit(f"unknown planner {name!r}")


def setup(task: str, seed: int) -> tuple[np.ndarray, list[str], float, Any, int, float]:
    """Parts, labels, radius, task, cycles for the thesis planners, and the plant's friction."""
    rng = np.random.default_rng(seed)
    mu = 0.3
    if task.startswith("mu"):
        mu, task = float(task[2:]), "sort8"
    if task.startswith("sort"):
        n = int(task[4:])
        parts = scatter(rng, n, 0.12 if n <= 8 else 0.13 if n <= 10 else 0.16, 0.052 if n <= 16 else 0.042)
        labels = ["red"] * (n // 2) + ["blue"] * (n - n // 2)
        job = control.SortTask({"red": -1, "blue": 1}, margin=0.08, spacing=0.046, max_step=0.025)
        return parts, labels, CHIP, job, 60 * max(1, n // 8), mu
    if task == "gather8":  # into a pile of 4 cm radius off the centre
        parts = scatter(rng, 8, 0.12, 0.04)
        return parts, ["penny"] * 8, PENNY, control.GatherTask((0.04, -0.03), radius=0.04), 60, mu
    if task == "goto6":
        parts = scatter(rng, 6, 0.12, 0.04)
        goals = scatter(rng, 6, 0.12, 0.04)
        return parts, ["penny"] * 6, PENNY, control.GotoTask(goals, tolerance=0.003), 60, mu
    if task == "bowtie":
        path = figure_eight()
        job = control.TrajectoryTask([path], speed=0.012, closed=True, equidistant=True, count=3,
                                     kp=0.8, kd=0.1, max_step=0.015, hold=0.012, tolerance=0.006)  # fmt: skip
        parts = np.array([job.reference(k, 0.0) for k in range(3)]) + 0.003
        return parts, ["penny"] * 3, PENNY, job, 400, mu
    raise SystemExit(f"unknown task {task!r}")


def run(task: str, name: str, seed: int) -> dict[str, float]:
    parts, labels, radius, job, cycles, mu = setup(task, seed)
    # Fields need a plate that moves out of its plane: the six-actuator plate (force and stroke
    # limits, 5 % actuator gain errors) and point parts (contacts with lift-off are not modelled).
    spatial = name == "fields"
    plant = SimulatedUPM(
        plate=LIMITS.plate,
        axes=LIMITS.axes,
        parts=parts,
        seed=seed,
        part_radius=None if spatial else radius,
        mu=mu,
    )
    plan = planner(name, radius)
    if name in ("predictive", "fields"):
        cycles *= 4  # one pulse a cycle
    device = control.SimulatedDevice6(plant, seed=seed) if spatial else plant
    loop = control.Loop(device, plant.camera(labels, seed=seed), plan, job, part_radius=radius)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        start = time.perf_counter()
        log = loop.run(cycles)
        wall = time.perf_counter() - start
    errs = getattr(plan, "step_errors", [])
    e = log.errors
    de = np.diff(e, axis=0)
    de = de[np.isfinite(de)]
    gained = float(np.sum(np.maximum(-de, 0)))
    return {
        "done": float(log.done and plant.fallen == 0),
        "time": float(log.meta["plate_time"]),
        "lost": float(plant.fallen),
        "stroke": float("nan") if spatial else 1000 * plant.max_excursion,
        "step_error": 1000 * float(np.median(errs)) if errs else float("nan"),
        "planning": 1000 * float(np.median(log.planning)),
        "undone": float(np.sum(np.maximum(de, 0))) / gained if gained else float("nan"),
        "path_error": 1000 * float(np.nanmedian(e)),
        "wall": wall,
    }


def cell(rows: list[dict[str, float]], key: str, digits: int) -> str:
    """Median (max) over the seeds."""
    v = np.array([r[key] for r in rows])
    if not np.any(np.isfinite(v)):
        return "–"
    return f"{np.nanmedian(v):.{digits}f} ({np.nanmax(v):.{digits}f})"


def table(tasks: list[str], planners: list[str], seeds: int) -> None:
    print(f"upm {upm.__version__} on {cpu()}, {seeds} seeds each: median (max)\n")
    print("| task | planner | done | plate time [s] | lost | stroke [mm] | step error [mm] | planning [ms] "
          "| undone | path error [mm] |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|")
    for task in tasks:
        for name in planners:
            rows = [run(task, name, seed) for seed in range(1, seeds + 1)]

            done = int(sum(r["done"] for r in rows))
            keys = (("time", 1), ("lost", 0), ("stroke", 1), ("step_error", 1), ("planning", 0),
                    ("undone", 2), ("path_error", 1))  # fmt: skip
            cells = " | ".join(cell(rows, k, d) for k, d in keys)
            print(f"| {task} | {name} | {done}/{seeds} | {cells} |", flush=True)


def scale_run(task: str, n: int, name: str, seed: int) -> dict[str, float]:
    """One run of the scaling table through the full loop as ``upm demo`` runs it (the scale
    demos' set-ups: sorts of poker chips up to 32, of 20 mm chips beyond; the letter L of 10 mm
    washers; the predictive planner plans while the plate plays)."""
    from upm.experiments.scale_demos import CHIP, SMALL_CHIP, shape_setup, sort_setup

    if task == "sort":
        setup = sort_setup(False, seed, n, CHIP if n <= 32 else SMALL_CHIP, name)
    else:
        setup = shape_setup(False, seed, n, "L", name)
    plant = SimulatedUPM(plate=LIMITS.plate, axes=LIMITS.axes, stroke=LIMITS.stroke, parts=setup.parts,
                         seed=seed, part_radius=setup.radius)  # fmt: skip
    camera = plant.camera(setup.labels, seed=seed, **setup.view)
    loop = control.Loop(plant, camera, setup.planner, setup.task, part_radius=setup.radius,
                        pipeline=setup.pipeline, keep_frames=setup.keep_frames)  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        start = time.perf_counter()
        log = loop.run(setup.cycles, timeout=600.0)
        wall = time.perf_counter() - start
    final = log.errors[-1] if len(log.errors) else np.zeros(0)
    return {
        "done": float(log.done and plant.fallen == 0),
        "time": float(log.meta["plate_time"]),
        "wall": wall,
        "dead": float(np.sum(log.vision) + np.sum(log.planning)),
        "lost": float(plant.fallen),
        "error": 1000 * float(np.nanmax(final)) if np.any(np.isfinite(final)) else float("nan"),
        "planning": 1000 * float(np.median(log.planning)),
    }


def scaling(planners: list[str], seeds: int, counts: list[int], tasks: list[str], out: Path,
            stored: bool = False) -> None:  # fmt: skip
    """Sorts and shapes of ``counts`` parts by each planner over ``seeds`` seeds through the full
    loop: done, plate and wall time, parts lost, the farthest part's final error, planning time
    and parts per minute. Every run is appended to ``out`` with the suffix ``.jsonl`` as it ends,
    and runs already there are not run again (an interrupted sweep resumes); ``stored``: tabulate
    and plot the stored runs only."""
    import json

    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    store = out.with_suffix(".jsonl")
    store.parent.mkdir(parents=True, exist_ok=True)
    done: dict[tuple[str, str, int, int], dict[str, float]] = {}
    if store.exists():
        for line in store.read_text().splitlines():
            row = json.loads(line)
            done[(row["task"], row["planner"], int(row["parts"]), int(row["seed"]))] = row
    for task in tasks:
        for n in counts:
            for name in planners:
                for seed in range(1, seeds + 1):
                    if (task, name, n, seed) in done or stored:
                        continue
                    row = {"task": task, "planner": name, "parts": n, "seed": seed, "cpu": cpu(),
                           **scale_run(task, n, name, seed)}  # fmt: skip
                    done[(task, name, n, seed)] = row
                    with store.open("a") as f:
                        f.write(json.dumps(row) + "\n")
                    print(f"{task}{n} {name} seed {seed}: {row['time']:.1f} s, done {row['done']:.0f}, "
                          f"{row['lost']:.0f} lost, {row['wall']:.0f} s wall", flush=True)  # fmt: skip
    fig, axes = plt.subplots(1, len(tasks), figsize=(5.5 * len(tasks), 3.8), squeeze=False)
    print(f"\n{cpu()}: median (max) over the seeds run\n")
    print("| task | parts | planner | done | plate time [s] | wall time [s] | lost | final max error [mm] "
          "| planning [ms] | parts per minute |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|")
    for ax, task in zip(axes[0], tasks, strict=True):
        for name in planners:
            xs, med, full = [], [], []
            for n in counts:
                rows = [r for (t, p, k, _), r in done.items() if (t, p, k) == (task, name, n)]
                if not rows:
                    continue
                ok = int(sum(r["done"] for r in rows))
                t_ = np.array([r["time"] for r in rows])
                keys = (("wall", 0), ("lost", 0), ("error", 1), ("planning", 0))
                columns = [(t_, 1)] + [(np.array([r[k] for r in rows]), d) for k, d in keys]
                cells = " | ".join(f"{np.nanmedian(v):.{d}f} ({np.nanmax(v):.{d}f})" for v, d in columns)
                rate = f"{60.0 * n / np.median(t_):.0f}" if ok == len(rows) else "– (not all done)"
                print(f"| {task} | {n} | {name} | {ok}/{len(rows)} | {cells} | {rate} |")
                xs.append(n)
                med.append(float(np.median(t_)))
                full.append(ok == len(rows))
            if xs:
                (line,) = ax.plot(xs, med, "-", label=name)
                for x, m, f in zip(xs, med, full, strict=True):  # hollow: not every seed done
                    ax.plot([x], [m], "o", color=line.get_color(), mfc=line.get_color() if f else "white")
        ax.set(
            xlabel="parts",
            ylabel="plate time [s] (median; hollow: not all done)",
            xscale="log",
            yscale="log",
            title=f"{task} (letter L of 10 mm washers)" if task == "shape" else "sort by colour",
        )
        ax.set_xticks(counts, [str(n) for n in counts])
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.legend(fontsize=8)
    fig.suptitle(f"many parts through the full loop, 10 mm stroke ({cpu()})", fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"\nwrote {out} and {store}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", default="sort8,sort10,goto6,bowtie,mu0.21,mu0.39")
    parser.add_argument("--planners", default="predictive,jets")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--scaling", action="store_true", help="sorts and shapes against the number of parts")
    parser.add_argument("--counts", default="8,16,32,64,100", help="part counts for --scaling")
    parser.add_argument("--scale-tasks", default="sort,shape", help="--scaling: sort, shape or both")
    parser.add_argument("--stored", action="store_true", help="--scaling: tabulate the stored runs, run none")
    args = parser.parse_args()
    planners = args.planners.split(",")
    if args.scaling:
        counts = [int(n) for n in args.counts.split(",")]
        names = planners if args.planners != "predictive,jets" else ["predictive", "greedy"]
        scaling(names, args.seeds, counts, args.scale_tasks.split(","), Path("docs/img/scaling.png"),
                stored=args.stored)  # fmt: skip
    else:
        table(args.tasks.split(","), planners, args.seeds)


if __name__ == "__main__":
    main()
