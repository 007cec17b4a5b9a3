"""Many parts at once, through the full loop: ``upm demo sort32``, ``sort64``, ``shape100`` and
``upm demo shape --parts N --shape NAME``.

The anchor is the Chladni-plate line (Kopitca, Latifi & Zhou, *Sci. Adv.* 7:eabi7716, 2021): one
piezo under a 50 mm plate assembles up to 100 particles into a shape, each within 0.9 % of the
plate's side. Here the 16 in plate does it with its three motors on flexures (10 mm stroke),
colliding disks, the virtual camera and vision: ``shape*`` moves 10 mm disks (washers) onto
:mod:`upm.shapes` target sets (:class:`upm.control.ShapeTask`), ``sort32`` sorts 32 poker chips by
colour and ``sort64`` 64 chips of 20 mm, each sort's line placed so its side holds its chips
(:meth:`upm.control.SortTask.fit_line`). The predictive planner runs by default;
``--planner greedy`` runs the peer (:class:`upm.control.GreedyLibraryPlanner`).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from .._errors import ParameterError
from ..control import GreedyLibraryPlanner, Log, ShapeTask, SortTask
from ..control.shapes import scatter
from ..plan import PredictivePlanner
from ..vision.synthetic import Camera
from .demos import CHIP, LIMITS, Demo, Setup, run_demo

__all__ = ["DEMOS", "SMALL_CHIP", "WASHER", "run_scale_demo", "shape_setup", "shape_targets", "sort_setup"]

#: A washer's radius [m]: the 10 mm parts of the ``shape`` demos.
WASHER = 0.005
#: The ``sort64`` chips' radius [m].
SMALL_CHIP = 0.01
#: A camera fine enough for 100 parts of 10 mm (about 19 px across each).
CAMERA = Camera(size=(1280, 960))
#: The scale demos' planners.
PLANNERS = ("predictive", "greedy")


def shape_targets(shape: str, n: int, seed: int = 0) -> Any:
    """The ``n`` target points of ``shape`` on the 16 in plate [m]: ``ring``, ``grid``, one capital
    letter, or the path of a mask image (spread over 0.26 m), each sized for 10 mm parts."""
    from ..control import shapes

    spacing = 2 * WASHER * 1.4  # room for a part to pass between two placed ones
    if shape == "ring":
        return shapes.ring(n, max(0.06, n * spacing / (2 * math.pi)))
    if shape == "grid":
        return shapes.grid(n, spacing)
    if len(shape) == 1 and shape.isalpha():
        # a letter's strokes hold about 0.24 height^2; each part takes a hexagon of the spacing
        height = max(0.1, math.sqrt(n * 0.87 * spacing**2 / 0.24))
        while True:  # taller until the spread leaves room between parts (k-means is not a packing)
            points = shapes.letter(shape, n, height, seed=seed)
            if shapes.min_spacing(points) >= 2.2 * WASHER or height >= 0.3:
                return points
            height *= 1.08
    path = Path(shape)
    if path.suffix and path.exists():
        return shapes.from_mask(path, n, 0.26, seed=seed)
    raise ParameterError(
        f"shape must be ring, grid, a capital letter A-Z or a mask image's path; got {shape!r}"
    )


#: The predictive planner plans while the plate plays, keeping plans whose parts end within this.
AHEAD = 0.006


def _ahead(kind: str) -> float | None:
    return AHEAD if kind == "predictive" else None


def _planner(kind: str, radius: float) -> Any:
    if kind == "predictive":
        return PredictivePlanner(LIMITS, mu=0.3, part_radius=radius)
    if kind == "greedy":
        return GreedyLibraryPlanner(LIMITS, mu=0.3)
    raise ParameterError(f"planner must be one of {PLANNERS}; got {kind!r}")


def shape_setup(quick: bool, seed: int, parts: int, shape: str, planner: str = "predictive") -> Setup:
    """The ``shape`` demos' set-up: ``parts`` washers scattered by ``seed`` over the plate's
    middle, ``shape``'s points (:func:`shape_targets`) as a :class:`~upm.control.ShapeTask`."""
    rng = np.random.default_rng(seed)
    targets = shape_targets(shape, parts)
    task = ShapeTask(targets, part_radius=WASHER, max_step=0.02)
    start = scatter(rng, parts, 0.15, 2.6 * WASHER)
    cycles = (40 if quick else 600) + 4 * parts
    view = {"camera": CAMERA, "radius": WASHER}
    return Setup(start, ["penny"] * parts, WASHER, _planner(planner, WASHER), task, cycles, view=view,
                 pipeline=_ahead(planner), keep_frames=5)  # fmt: skip


def sort_setup(quick: bool, seed: int, count: int, radius: float, planner: str = "predictive") -> Setup:
    """The scale sorts' set-up: ``count`` chips of ``radius`` [m], half red and half blue,
    scattered by ``seed`` over a square about the centre reaching 2 cm past the lines, or wider
    where that square cannot hold them apart (at most 15 cm); the lines are placed by
    :meth:`~upm.control.SortTask.fit_line` so that each side holds its chips."""
    rng = np.random.default_rng(seed)
    labels = ["red"] * (count // 2) + ["blue"] * (count - count // 2)
    margin = 0.08
    line = SortTask.fit_line(count - count // 2, radius, margin=margin)
    gap = 2.3 * radius
    parts = scatter(rng, count, min(0.15, max(line + 0.02, 0.51 * math.ceil(math.sqrt(count)) * gap)), gap)
    task = SortTask({"red": -1, "blue": 1}, margin=margin, spacing=2.4 * radius, max_step=0.025, line=line,
                    part_radius=radius)  # fmt: skip
    view = {"camera": CAMERA, "radius": radius}
    return Setup(parts, labels, radius, _planner(planner, radius), task, 30 if quick else 400 + 8 * count,
                 view=view, pipeline=_ahead(planner), keep_frames=5)  # fmt: skip


def _report(log: Log, setup: Setup, m: dict[str, Any]) -> list[str]:
    what = "assembled" if isinstance(setup.task, ShapeTask) else "sorted"
    state = what if log.done else f"NOT {what}"
    return [
        f"{len(setup.parts)} parts {state} in {m['plate_time']:.1f} s of plate time ({m['cycles']} cycles, "
        f"{m['wall_time']:.0f} s of wall time, {m['dead_time']:.0f} s of it the plate idle while the host "
        f"saw and planned); {m['fallen']} lost; the farthest part {1000 * m['final_error_max']:.1f} mm from "
        f"its point (Chladni anchor, Sci. Adv. 2021: up to 100 particles, each within 0.9 % of the side)"
    ]


DEMOS: dict[str, Demo] = {
    "sort32": Demo("sort32", "scale", "32 poker chips sorted by colour (16 a side)",
                   lambda q, s: sort_setup(q, s, 32, CHIP), _report),
    "sort64": Demo("sort64", "scale", "64 chips of 20 mm sorted by colour (32 a side)",
                   lambda q, s: sort_setup(q, s, 64, SMALL_CHIP), _report),
    "shape100": Demo("shape100", "scale", "100 washers of 10 mm into the letter L",
                     lambda q, s: shape_setup(q, s, 100, "L"), _report),
    "shape": Demo("shape", "scale", "N washers into a shape (--parts N --shape ring|grid|A-Z|mask.png)",
                  lambda q, s: shape_setup(q, s, 12, "ring"), _report),
}  # fmt: skip


def run_scale_demo(
    name: str,
    out: Path | str = "out",
    *,
    parts: int | None = None,
    shape: str | None = None,
    planner: str = "predictive",
    seed: int = 1,
    quick: bool = False,
    cycles: int | None = None,
    verbose: bool = True,
    rrd: bool = False,
    pipeline: float | None = None,
    board: bool = False,
) -> dict[str, Any]:
    """Run scale demo ``name`` (:data:`DEMOS`) through :func:`upm.demos.run_demo`; ``parts`` and
    ``shape`` set the ``shape`` demo's count and shape; ``planner``: ``predictive`` or ``greedy``;
    ``pipeline`` [m]: the threshold of plans made while the plate plays (default :data:`AHEAD`
    for the predictive planner); ``board``: the plate in a board emulator process."""
    if name not in DEMOS:
        raise ParameterError(f"demo must be one of {sorted(DEMOS)}; got {name!r}")
    if planner not in PLANNERS:
        raise ParameterError(f"planner must be one of {PLANNERS}; got {planner!r}")
    if name == "shape":
        n = 12 if parts is None else int(parts)
        if not 1 <= n <= 400:
            raise ParameterError(f"parts must be in [1, 400]; got {parts!r}")
        setup = shape_setup(quick, seed, n, shape or "ring", planner)
    elif parts is not None or shape is not None:
        raise ParameterError(f"--parts and --shape are for the shape demo; {name} has its own")
    elif name.startswith("sort"):
        setup = sort_setup(quick, seed, int(name[4:]), CHIP if name == "sort32" else SMALL_CHIP, planner)
    else:
        setup = shape_setup(quick, seed, 100, "L", planner)
    if cycles is not None:
        setup.cycles = int(cycles)
    return run_demo(
        name, out, seed=seed, verbose=verbose, rrd=rrd, entry=(DEMOS[name], setup), pipeline=pipeline
    )
