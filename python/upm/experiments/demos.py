"""The thesis's experiments, reproduced in simulation through the closed loop (``upm demo NAME``).

Each demo builds a simulated plate with parts on it, runs :class:`upm.control.Loop` (virtual
camera → vision → task → planner → plate), and writes to ``out/NAME/``: ``animation.gif`` (the
camera's frames with the tracks drawn in), ``paths.png`` (the parts' paths on the plate with their
references), ``errors.png`` (each part's error and the step tracking error per cycle),
``metrics.json`` and ``log.npz`` (:func:`upm.control.load_log`). ``board=True`` (``sort8`` in
``make demo``) runs the plate in an emulator process reached over the board protocol on a
pseudo-terminal, and reads the camera it serves.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._errors import ParameterError
from ..control import (
    DisplacementPlanner,
    FixedPlanner,
    GotoTask,
    GreedyLibraryPlanner,
    JetPlanner,
    Log,
    Loop,
    RotationsPlanner,
    SimulatedDevice,
    SortTask,
    TrajectoryTask,
    WatchTask,
)
from ..control.shapes import scatter
from ..physics.waveforms import Harmonics
from ..plan import PredictivePlanner
from ..plan.solvers import corner_centers, ring_centers
from ..plate.actuation import Plate
from ..plate.drive import DriveLimits
from ..plate.plant import SimulatedUPM
from ..plate.pulses import Pulse
from .demo_outputs import demo_metrics, write_outputs

__all__ = ["DEMOS", "Demo", "run_demo"]

FloatArray = NDArray[np.float64]

PENNY = 0.009525
CHIP = 0.0195
#: The demos' plate: a 16 in honeycomb plate of 1 kg on flexures (3 Hz, damping ratio 0.2).
PLATE: Plate = DriveLimits().plate
#: Its drive limits: four 200 N motors, 10 mm stroke.
LIMITS = DriveLimits.of(PLATE)
#: The planners ``--planner`` chooses from.
PLANNERS = ("predictive", "jets", "rotations", "displacement", "greedy")
_MOTORS: dict[str, Any] = {"limits": LIMITS}


@dataclass
class Setup:
    """What a demo runs: the parts, and the planner and task for the loop."""

    parts: FloatArray
    labels: list[str]
    radius: float
    planner: Any
    task: Any
    cycles: int
    references: list[FloatArray] = field(default_factory=list)
    centers: FloatArray | None = None
    view: dict[str, Any] = field(default_factory=dict)
    """Options of the plant's camera (``SimulatedUPM.camera``): a finer camera, the parts' radius."""
    pipeline: float | None = None
    """The loop plans while the plate plays, keeping plans whose prediction holds to this [m]."""
    keep_frames: int = 1
    """The log keeps every this-many-th camera frame (for the animation)."""


@dataclass(frozen=True)
class Demo:
    name: str
    figure: str
    summary: str
    build: Callable[[bool, int], Setup]
    report: Callable[[Log, Setup, dict[str, Any]], list[str]]


def _rectangle(cx: float, cy: float, w: float, h: float) -> FloatArray:
    return np.array(
        [
            [cx - w / 2, cy - h / 2],
            [cx + w / 2, cy - h / 2],
            [cx + w / 2, cy + h / 2],
            [cx - w / 2, cy + h / 2],
            [cx - w / 2, cy - h / 2],
        ]
    )


# -- the experiments --------------------------------------------------------------------------------


def _trajectory2(quick: bool, seed: int) -> Setup:
    paths = [_rectangle(-0.06, 0.0, 0.08, 0.1), _rectangle(0.06, 0.0, 0.08, 0.1)]
    if quick:
        paths = [p[:2] for p in paths]
    centers = ring_centers(9, 0.17, phase=0.2)
    task = TrajectoryTask(paths, speed=0.006, kp=0.8, kd=0.2, max_step=0.015, tolerance=0.004)
    planner = RotationsPlanner(centers, cycle=2.0, amplitude=1.0)
    starts = np.array([p[0] for p in paths]) + np.array([[0.004, -0.003], [-0.003, 0.004]])
    return Setup(starts, ["penny", "penny"], PENNY, planner, task, 40 if quick else 160, paths, centers)


def _trajectory2_report(log: Log, setup: Setup, m: dict[str, Any]) -> list[str]:
    return [
        f"two pennies followed rectangles with {0 if setup.centers is None else len(setup.centers)} "
        "rotations per plate motion "
        f"(4 constraints, 5 redundant): median path error {1000 * m['median_error']:.1f} mm, "
        f"max {1000 * m['max_error']:.1f} mm (thesis Fig. 4.8: shown qualitatively, point parts, ideal plate)"
    ]


def _sort(quick: bool, seed: int, count: int, planner: Any, max_step: float, free_y: bool = False) -> Setup:
    rng = np.random.default_rng(seed)
    parts = scatter(rng, count, 0.12 if count <= 8 else 0.13, 0.052)
    labels = ["red"] * (count // 2) + ["blue"] * (count - count // 2)
    task = SortTask({"red": -1, "blue": 1}, margin=0.08, spacing=0.046, max_step=max_step, free_y=free_y)
    return Setup(parts, labels, CHIP, planner, task, 8 if quick else 60)


def _sort10(quick: bool, seed: int) -> Setup:
    # 24 centres on two rings through the workspace: centres far from the parts (a ring round the
    # plate) give nearly parallel fields, and the 20 x 24 system needs 100 times the cycle's time.
    # The task constrains x only (y free), as the thesis's sort pushes along x (4.3.2).
    centers = np.vstack([ring_centers(8, 0.07), ring_centers(16, 0.18, phase=0.2)])
    setup = _sort(quick, seed, 10, RotationsPlanner(centers, cycle=4.0, amplitude=1.0), 0.02, free_y=True)
    setup.cycles = 8 if quick else 400
    setup.centers = centers
    return setup


def _sort8(quick: bool, seed: int) -> Setup:
    planner = JetPlanner(mu=0.3, amplitude=0.1, rho=0.03, **_MOTORS)
    return _sort(quick, seed, 8, planner, 0.025)


def _sort_report(thesis: str) -> Callable[[Log, Setup, dict[str, Any]], list[str]]:
    def report(log: Log, setup: Setup, m: dict[str, Any]) -> list[str]:
        state = "sorted" if log.done else "NOT sorted"
        return [
            f"{len(setup.parts)} chips {state} in {m['plate_time']:.1f} s of plate time, "
            f"{m['cycles']} cycles; "
            f"{m['fallen']} lost over the edge ({thesis})"
        ]

    return report


def _racetrack(quick: bool, seed: int) -> Setup:
    c = np.array([-0.17, -0.17])
    radii = np.array([0.08, 0.14, 0.2])
    parts = c + np.stack([radii, np.zeros(3)], axis=1)
    wave = Harmonics([1.5, -0.75], [0.0, 0.0], 35.0)
    pulse = Pulse.rotation(c, wave, 3 / 35, 0.5, 3 / 35, rest=0.3)
    return Setup(
        parts, ["penny"] * 3, PENNY, FixedPlanner([pulse]), WatchTask(3 if quick else 10), 50, centers=c[None]
    )


def _racetrack_report(log: Log, setup: Setup, m: dict[str, Any]) -> list[str]:
    return [
        "three pennies raced along the rotation field about the lower-left corner: arc lengths "
        + ", ".join(f"{1000 * a:.0f}" for a in m["arc_lengths"])
        + " mm, angles "
        + ", ".join(f"{math.degrees(a):.0f}" for a in m["angles"])
        + " deg (inner first; thesis Fig. 5.2: the inner parts advance more rapidly than the outer ones)"
    ]


def _corners(quick: bool, seed: int) -> Setup:
    starts = np.array([[-0.06, -0.05], [0.05, -0.06]])
    goals = np.array([[0.02, 0.06], [-0.06, 0.03]])
    centers = corner_centers((-0.15, -0.15, 0.15, 0.15))
    planner = DisplacementPlanner(centers, mu=0.3, max_arc=0.1, sustain=0.3, refine=2, **_MOTORS)
    task = GotoTask(goals, starts=starts, gain=0.6, max_step=0.015, first_step=0.15, tolerance=0.004)
    return Setup(
        starts,
        ["penny", "penny"],
        PENNY,
        planner,
        task,
        4 if quick else 40,
        [np.stack([s, g]) for s, g in zip(starts, goals, strict=True)],
        centers,
    )


def _corners_report(log: Log, setup: Setup, m: dict[str, Any]) -> list[str]:
    first = m["errors_by_cycle"][1] if len(m["errors_by_cycle"]) > 1 else [float("nan")]
    return [
        "two parts, 4 corner centres, one large step each: after the first cycle they miss their goals by "
        + ", ".join(f"{1000 * e:.0f}" for e in first)
        + " mm (thesis Fig. 5.3(d): the error of large steps, made large on purpose); closed loop: "
        + f"within {1000 * m['final_error']:.1f} mm after {m['cycles']} cycles"
    ]


def _plus(quick: bool, seed: int) -> Setup:
    arm = 0.07
    o = np.zeros(2)
    path = np.array([o, [arm, 0], o, [0, arm], o, [-arm, 0], o, [0, -arm], o])
    if quick:
        path = path[:3]
    centers = corner_centers((-0.15, -0.15, 0.15, 0.15))
    planner = DisplacementPlanner(centers, mu=0.3, max_arc=0.03, refine=1, **_MOTORS)
    task = TrajectoryTask([path], speed=0.01, kp=0.8, kd=0.1, max_step=0.02, hold=0.01, tolerance=0.004)
    return Setup(
        np.array([[0.045, -0.035]]), ["penny"], PENNY, planner, task, 40 if quick else 120, [path], centers
    )


def _plus_report(log: Log, setup: Setup, m: dict[str, Any]) -> list[str]:
    return [
        f"one penny centred, then driven along the plus sign's branches: median path error "
        f"{1000 * m['median_error']:.1f} mm, max {1000 * m['max_error']:.1f} mm over {m['plate_time']:.0f} s "
        "(thesis 5.3.2)"
    ]


def figure_eight(scale: float = 0.09, points: int = 48) -> FloatArray:
    """The bow-tie experiment's closed path (Figs. 6.4-6.5) [m]."""
    t = np.linspace(0, 2 * np.pi, points, endpoint=False)
    return np.stack([scale * np.sin(t), scale * 0.6 * np.sin(2 * t)], axis=1)


def _bowtie(quick: bool, seed: int) -> Setup:
    path = figure_eight()
    task = TrajectoryTask(
        [path],
        speed=0.008,
        closed=True,
        laps=0.25 if quick else 1.0,
        equidistant=True,
        count=3,
        kp=0.8,
        kd=0.1,
        max_step=0.015,
        hold=0.012,
        tolerance=0.006,
    )
    starts = np.array([task.reference(k, 0.0) for k in range(3)]) + 0.003
    planner = JetPlanner(mu=0.3, amplitude=0.08, rho=0.025, **_MOTORS)
    return Setup(
        starts, ["penny"] * 3, PENNY, planner, task, 60 if quick else 400, [np.vstack([path, path[:1]])]
    )


def _bowtie_report(log: Log, setup: Setup, m: dict[str, Any]) -> list[str]:
    return [
        "three pennies kept equidistant around the figure-eight with jets: one loop in "
        f"{m['plate_time']:.0f} s "
        f"of plate time (thesis Figs. 6.4-6.5: about one minute); median path error "
        f"{1000 * m['median_error']:.1f} mm"
    ]


DEMOS: dict[str, Demo] = {
    d.name: d
    for d in (
        Demo(
            "trajectory2",
            "Fig. 4.8",
            "two parts follow rectangles, 9 rotations per motion (ch. 4)",
            _trajectory2,
            _trajectory2_report,
        ),
        Demo(
            "sort10",
            "Fig. 4.9",
            "5 + 5 parts sorted to opposite edges, 24 centres and SVD (ch. 4)",
            _sort10,
            _sort_report("thesis Fig. 4.9: simulation, point parts, ideal plate"),
        ),
        Demo(
            "racetrack",
            "Fig. 5.2",
            "three parts race along one rotation field (ch. 5)",
            _racetrack,
            _racetrack_report,
        ),
        Demo(
            "corners",
            "Fig. 5.3",
            "two parts, four corner centres, large steps (ch. 5)",
            _corners,
            _corners_report,
        ),
        Demo(
            "plus",
            "5.3.2",
            "one penny centred, then along the branches of a plus sign (ch. 5)",
            _plus,
            _plus_report,
        ),
        Demo(
            "bowtie",
            "Figs. 6.4-6.5",
            "three pennies equidistant along a figure-eight with jets (ch. 6)",
            _bowtie,
            _bowtie_report,
        ),
        Demo(
            "sort8",
            "Fig. 6.6",
            "8 chips sorted by colour with jets (ch. 6)",
            _sort8,
            _sort_report("thesis Fig. 6.6: about 30 s on the real UPM, one chip fell off the edge"),
        ),
    )
}


# -- running ----------------------------------------------------------------------------------------


def _planner(kind: str, setup: Setup, contacts: bool) -> Any:
    """The demo's planner replaced by one of :data:`PLANNERS`, all on :data:`LIMITS`."""
    if kind == "predictive":
        return PredictivePlanner(LIMITS, mu=0.3, part_radius=setup.radius if contacts else None)
    if kind == "jets":
        return JetPlanner(mu=0.3, amplitude=0.1, rho=0.03, limits=LIMITS)
    if kind == "greedy":
        return GreedyLibraryPlanner(LIMITS, mu=0.3)
    if kind == "rotations":
        centers = np.vstack([ring_centers(8, 0.07), ring_centers(16, 0.18, phase=0.2)])
        setup.centers = centers
        return RotationsPlanner(centers, cycle=4.0, amplitude=1.0, limits=LIMITS)
    if kind == "displacement":
        centers = corner_centers((-0.15, -0.15, 0.15, 0.15))
        setup.centers = centers
        return DisplacementPlanner(centers, mu=0.3, max_arc=0.03, refine=1, limits=LIMITS)
    raise ParameterError(f"planner must be one of {PLANNERS}; got {kind!r}")


def _plant(setup: Setup, seed: int, contacts: bool = False) -> SimulatedUPM:
    return SimulatedUPM(
        plate=PLATE,
        axes=LIMITS.axes,
        stroke=LIMITS.stroke,
        parts=setup.parts,
        seed=seed,
        part_radius=setup.radius if contacts else None,
    )


def _emulated(
    setup: Setup, seed: int, scene_dir: Path, contacts: bool = False
) -> tuple[subprocess.Popen[str], str, str]:
    scene = {
        "parts": setup.parts.tolist(),
        "part_radius": setup.radius if contacts else None,
        "labels": setup.labels,
        "mu": 0.3,
        "plate": [PLATE.mass, PLATE.inertia, PLATE.lever],
        "stroke": LIMITS.stroke,
    }
    if "camera" in setup.view:  # the emulator's camera as the demo's (a finer one for small parts)
        scene["camera"] = {"size": list(setup.view["camera"].size)}
    if "radius" in setup.view:
        scene["render"] = {"radius": setup.view["radius"]}
    path = scene_dir / "scene.json"
    path.write_text(json.dumps(scene))
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "upm.board.emulator",
            "--scene",
            str(path),
            "--camera-port",
            "0",
            "--seed",
            str(seed),
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    tty = proc.stdout.readline().strip()
    camera = proc.stdout.readline().strip().removeprefix("camera ")
    if not tty or not camera:
        proc.kill()
        raise RuntimeError("the board emulator did not start")
    return proc, tty, camera


def run_demo(
    name: str,
    out: Path | str = "out",
    *,
    board: bool = False,
    quick: bool = False,
    seed: int = 1,
    mp4: bool = False,
    verbose: bool = True,
    cycles: int | None = None,
    contacts: bool = True,
    planner: str | None = None,
    rrd: bool = False,
    entry: tuple[Demo, Setup] | None = None,
    pipeline: float | None = None,
) -> dict[str, Any]:
    """Run demo ``name`` (see :data:`DEMOS`), write its outputs to ``out/name/``, print the report
    and return the metrics. ``board``: the plate runs in a board emulator process reached over the
    protocol; ``quick``: a short version; ``cycles``: at most this many cycles; ``contacts``: the
    parts are disks of the demo's part radius that collide (rapier2d); ``False``: points that pass
    through each other; ``planner``: one of :data:`PLANNERS` instead of the demo's thesis planner
    (``predictive`` plays one pulse a cycle, so it gets four times the cycles); ``rrd``: also
    record the run for rerun to ``out/name/run.rrd`` (extra ``viz``); ``entry``: a demo and its
    set-up built elsewhere (:mod:`upm.scale_demos`), run under ``name``; ``pipeline`` [m]: plan
    while the plate plays (``Loop(pipeline=)``, the predictive planner only)."""
    if entry is None and name not in DEMOS:
        raise ParameterError(f"demo must be one of {sorted(DEMOS)}; got {name!r}")
    demo, setup = (DEMOS[name], DEMOS[name].build(quick, seed)) if entry is None else entry
    if planner is not None:
        setup.planner = _planner(planner, setup, contacts)
        if planner == "predictive":
            setup.cycles *= 4
    if cycles is not None:
        setup.cycles = int(cycles)
    if pipeline is not None:
        setup.pipeline = float(pipeline)
    say = print if verbose else (lambda *a, **k: None)
    using = "" if planner is None else f"; planner: {type(setup.planner).__name__} instead"
    say(
        f"upm demo {name}: {demo.summary} (thesis {demo.figure}{using})"
        + ("  [board emulator]" if board else "")
    )
    started = time.perf_counter()
    recording = Path(out) / name / "run.rrd" if rrd else None
    if board:
        from ..board import Board
        from ..control import BoardDevice
        from ..vision import RemoteCamera

        with tempfile.TemporaryDirectory() as tmp:
            proc, tty, address = _emulated(setup, seed, Path(tmp), contacts)
            try:
                with Board(tty) as link, RemoteCamera(address) as camera:
                    device = BoardDevice(link, LIMITS, wait_rest=True)
                    loop = Loop(device, camera, setup.planner, setup.task, part_radius=setup.radius,
                                pipeline=setup.pipeline, keep_frames=setup.keep_frames)  # fmt: skip
                    log = loop.run(setup.cycles, recording=recording)
                    truth = camera.truth()
                    stroke = camera.max_excursion()
            finally:
                proc.kill()
                proc.wait()
        fallen = int(np.sum(~np.all(np.isfinite(truth), axis=1)))
    else:
        plant = _plant(setup, seed, contacts)
        loop = Loop(
            SimulatedDevice(plant),
            plant.camera(setup.labels, seed=seed, **setup.view),
            setup.planner,
            setup.task,
            part_radius=setup.radius,
            pipeline=setup.pipeline,
            keep_frames=setup.keep_frames,
        )
        log = loop.run(setup.cycles, recording=recording)
        fallen = plant.fallen
        stroke = plant.max_excursion
    metrics = demo_metrics(name, log, setup, fallen, time.perf_counter() - started, board)
    metrics["contacts"] = contacts
    metrics["seed"] = seed
    metrics["planner"] = type(setup.planner).__name__
    metrics["max_stroke"] = float(stroke)
    metrics["pipeline"] = setup.pipeline
    metrics["kept_share"] = float(np.mean(log.kept)) if log.kept else 0.0
    metrics["revised"] = int(log.meta.get("revised", 0))  # plans made ahead chosen again
    # where the wall time went: the loop (the rest: starting the plant or the emulator), and in
    # it the playing (the pulses' own time and what the link adds to it)
    metrics["loop_wall"] = float(log.meta.get("wall", math.nan))
    metrics["playing"] = float(np.sum(log.execution))
    metrics["cut"] = int(log.meta.get("cut", 0))
    metrics["refused"] = int(log.meta.get("refused", 0))
    errs = getattr(setup.planner, "step_errors", None)
    metrics["prediction_error_median"] = float(np.median(errs)) if errs else float("nan")
    written = write_outputs(name, Path(out) / name, log, loop, setup, metrics, mp4) + (
        [recording] if recording else []
    )
    for line in demo.report(log, setup, metrics):
        say("  " + line)
    say(
        f"  wall time {metrics['wall_time']:.1f} s; vision {metrics['vision_ms']:.1f} ms/frame, planning "
        f"{metrics['planning_ms']:.0f} ms/cycle; step tracking error median "
        f"{1000 * metrics['tracking_error_median']:.1f} mm"
        + (
            f"; predicted-vs-achieved step error median {1000 * metrics['prediction_error_median']:.1f} mm"
            if np.isfinite(metrics["prediction_error_median"])
            else ""
        )
        + f"; largest plate-corner excursion {1000 * metrics['max_stroke']:.1f} mm"
    )
    say("  wrote " + ", ".join(str(p) for p in written))
    return metrics
