"""The one table of every experiment ``upm demo NAME`` runs, with how to run each.

The tables of each family stay beside their experiments (:data:`upm.experiments.demos.DEMOS`, the
thesis's closed-loop demos; ``mchip_demos``, ``ppod_demos``, ``orient_demos``, ``scale_demos``);
:func:`experiments` joins them under one name space, and the command line and the desk look names
up here and own none.
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from .._errors import ParameterError
from .runner import Experiment as Named

__all__ = ["Experiment", "Options", "experiments", "listing", "loop_setup", "run"]


@dataclass(frozen=True)
class Options:
    """How to run an experiment (the options of ``upm demo``); each experiment reads the ones it
    has: ``out`` (outputs go to ``out/NAME/``), ``quick`` (a short version), ``seed``; the loop
    demos also ``board``, ``mp4``, ``contacts``, ``planner``, ``rrd``, ``pipeline`` [m]; the scale
    demos ``parts`` and ``shape``; the feeding tables ``plots``."""

    out: Path = Path("out")
    quick: bool = False
    seed: int = 1
    board: bool = False
    mp4: bool = False
    contacts: bool = True
    planner: str | None = None
    rrd: bool = False
    pipeline: float | None = None
    parts: int | None = None
    shape: str | None = None
    plots: bool = True


@dataclass(frozen=True)
class Experiment:
    """One named experiment: its ``group`` (where it comes from), a one-line ``summary``, and
    ``run(options)`` returning the exit code (0 done; 1 a loop's task not done)."""

    name: str
    group: str
    summary: str
    run: Callable[[Options], int]


def _judged(metrics: dict[str, object], name: str) -> int:
    """0 when a loop's task was done with no part lost; 1 (and why, on stderr) otherwise."""
    if metrics["done"] and not metrics["fallen"]:
        return 0
    print(f"upm demo {name}: the task was not done ({metrics['fallen']} parts lost)", file=sys.stderr)
    return 1


def _loop(name: str) -> Callable[[Options], int]:
    def run(o: Options) -> int:
        from .demos import run_demo

        if o.parts is not None or o.shape is not None:
            raise ParameterError(f"--parts and --shape are for the shape demo; {name} has its own")
        metrics = run_demo(name, o.out, board=o.board, quick=o.quick, seed=o.seed, mp4=o.mp4,
                           contacts=o.contacts, planner=o.planner, rrd=o.rrd,
                           pipeline=o.pipeline)  # fmt: skip
        return _judged(metrics, name)

    return run


def _scale(name: str) -> Callable[[Options], int]:
    def run(o: Options) -> int:
        from .scale_demos import run_scale_demo

        metrics = run_scale_demo(name, o.out, parts=o.parts, shape=o.shape, planner=o.planner or "predictive",
                                 seed=o.seed, quick=o.quick, rrd=o.rrd, pipeline=o.pipeline,
                                 board=o.board)  # fmt: skip
        return _judged(metrics, name)

    return run


def _named(table: Mapping[str, Named], name: str) -> Callable[[Options], int]:
    def run(o: Options) -> int:
        from .runner import run_named

        run_named(table, name, o.out, o.quick, verbose=True, rrd=o.rrd)
        return 0

    return run


def _feeding(o: Options) -> int:
    from .feeding_demo import feeding

    return feeding(o.out, plots=o.plots)


@functools.cache
def experiments() -> dict[str, Experiment]:
    """Every experiment by name, in the order ``upm demo list`` prints them (imports each family's
    table on the first call)."""
    from .demos import DEMOS
    from .mchip_demos import DEMOS as MCHIP
    from .orient_demos import DEMOS as ORIENT
    from .ppod_demos import DEMOS as PPOD
    from .scale_demos import DEMOS as SCALE

    table = {"feeding": Experiment("feeding", "chapter 3", "the two-harmonic pump's tables and Fig. 3.6",
                                   _feeding)}  # fmt: skip
    for d in DEMOS.values():
        table[d.name] = Experiment(d.name, d.figure, d.summary, _loop(d.name))
    for group, named in (("chapter 2", MCHIP), ("6-DOF plate", PPOD), ("polygons", ORIENT)):
        for name, (summary, _) in named.items():
            table[name] = Experiment(name, group, summary, _named(dict(named), name))
    for d in SCALE.values():
        table[d.name] = Experiment(d.name, "many parts", d.summary, _scale(d.name))
    return table


def listing() -> str:
    """``upm demo list``: one line per experiment (name, group, summary)."""
    return "\n".join(f"{e.name:14s} {e.group:14s} {e.summary}" for e in experiments().values())


def run(name: str, options: Options) -> int:
    """Run experiment ``name`` with ``options``; its exit code. An unknown name raises
    :class:`~upm.ParameterError` listing every name."""
    table = experiments()
    if name not in table:
        first, *rest = table  # the feeding tables, then `list`, then the others in order
        raise ParameterError(f"no demo {name!r}; the demos: {', '.join([first, 'list', *sorted(rest)])}")
    return table[name].run(options)


def loop_setup(name: str, quick: bool, seed: int) -> object:
    """The set-up (plant, planner, task, ...) of closed-loop demo ``name``: what the desk steers."""
    from .demos import DEMOS

    if name not in DEMOS:
        raise ParameterError(f"a closed-loop demo must be one of {sorted(DEMOS)}; got {name!r}")
    return DEMOS[name].build(quick, seed)
