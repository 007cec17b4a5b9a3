"""Running a named experiment of a table ``{name: (summary, fn(quick, folder) -> metrics)}``: the
M-Chip and 6-DOF plate demos share it (``upm demo NAME``)."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from ._errors import ParameterError

Experiment = tuple[str, Callable[[bool, Path], dict[str, Any]]]


def run_named(
    table: Mapping[str, Experiment], name: str, out: Path | str, quick: bool, verbose: bool
) -> dict[str, Any]:
    """Run ``table[name]``, write ``out/name/metrics.json`` (with its wall time) and return the metrics."""
    if name not in table:
        raise ParameterError(f"demo must be one of {sorted(table)}; got {name!r}")
    summary, fn = table[name]
    folder = Path(out) / name
    folder.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    metrics = fn(quick, folder)
    metrics["wall_time_s"] = time.perf_counter() - started
    (folder / "metrics.json").write_text(json.dumps(metrics, indent=1, default=float))
    if verbose:
        print(f"upm demo {name}: {summary}")
        print(json.dumps(metrics, indent=1, default=float))
        print(f"  wrote {folder}")
    return metrics
