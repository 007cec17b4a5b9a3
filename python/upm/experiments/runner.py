"""Running a named experiment of a table ``{name: (summary, fn(quick, folder) -> metrics)}``: the
M-Chip and 6-DOF plate demos share it (``upm demo NAME``)."""

from __future__ import annotations

import contextvars
import json
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from .._errors import ParameterError

Experiment = tuple[str, Callable[[bool, Path], dict[str, Any]]]

_RECORDING: contextvars.ContextVar[bool] = contextvars.ContextVar("upm_demo_rrd", default=False)


def keep(result: Any, folder: Path, **options: Any) -> None:
    """With ``upm demo NAME --rrd``: write the experiment's main ``result`` (a ``SimResult`` or an
    ``MChipResult``) to ``folder/run.rrd`` for rerun (``options`` go to its ``to_rerun``)."""
    if _RECORDING.get():
        result.to_rerun(Path(folder) / "run.rrd", **options)


def run_named(
    table: Mapping[str, Experiment],
    name: str,
    out: Path | str,
    quick: bool,
    verbose: bool,
    rrd: bool = False,
) -> dict[str, Any]:
    """Run ``table[name]``, write ``out/name/metrics.json`` (with its wall time) and return the
    metrics; with ``rrd``, experiments that :func:`keep` a result also write ``out/name/run.rrd``."""
    if name not in table:
        raise ParameterError(f"demo must be one of {sorted(table)}; got {name!r}")
    summary, fn = table[name]
    folder = Path(out) / name
    folder.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    token = _RECORDING.set(rrd)
    try:
        metrics = fn(quick, folder)
    finally:
        _RECORDING.reset(token)
    metrics["wall_time_s"] = time.perf_counter() - started
    (folder / "metrics.json").write_text(json.dumps(metrics, indent=1, default=float))
    if verbose:
        print(f"upm demo {name}: {summary}")
        print(json.dumps(metrics, indent=1, default=float))
        print(f"  wrote {folder}")
    return metrics
