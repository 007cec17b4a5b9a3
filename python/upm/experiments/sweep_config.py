"""``upm sweep CONFIG.toml`` and ``upm sweep --list``: a sweep described by a TOML file (target,
``[grid]``, ``[fixed]``, store, ...; docs/sweeps.md) run through :func:`upm.sweep`."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .._errors import ParameterError

__all__ = ["sweep_command"]


def _axis(name: str, spec: Any) -> Any:
    """A grid axis from TOML: a list, or a table ``{start, stop, num[, log]}``."""
    if isinstance(spec, dict):
        unknown = set(spec) - {"start", "stop", "num", "log"}
        if unknown or not {"start", "stop", "num"} <= set(spec):
            raise ParameterError(f"grid.{name} must be a list or {{start, stop, num[, log]}}; got {spec}")
        space = np.geomspace if spec.get("log", False) else np.linspace
        return space(float(spec["start"]), float(spec["stop"]), int(spec["num"]))
    return spec


def sweep_command(config: Path | None, listing: bool, n_jobs: int | None, quiet: bool) -> int:
    """``upm sweep CONFIG.toml`` and ``upm sweep --list``."""
    from .sweeps import SCENARIOS, sweep

    if listing or config is None:
        import textwrap

        for s in SCENARIOS.values():
            print(textwrap.fill(f"{s.name}: {s.doc}", width=100, subsequent_indent="    "))
            for k, (low, high) in s.ranges.items():
                kind = "integer" if k in s.integers else "number"
                default = f", default {s.defaults[k]:g}" if k in s.defaults else ", required"
                print(f"    {k:16s} {kind} in [{low:g}, {high:g}]{default}")
            for k, unit in s.outputs.items():
                print(textwrap.fill(f"    -> {k}: {unit}", width=100, subsequent_indent="       "))
        if config is None and not listing:
            print("\nusage: upm sweep CONFIG.toml  (keys: target, [grid], [fixed], store, n_jobs, backend, "
                  "scheduler, chunk, plot)")  # fmt: skip
        return 0
    import importlib
    import tomllib

    try:
        spec = tomllib.loads(config.read_text())
    except (OSError, tomllib.TOMLDecodeError) as error:
        raise ParameterError(f"cannot read sweep config {str(config)!r}: {error}") from error
    allowed = {
        "target",
        "grid",
        "fixed",
        "store",
        "n_jobs",
        "backend",
        "scheduler",
        "chunk",
        "plot",
        "resume",
    }
    unknown = set(spec) - allowed
    if unknown:
        raise ParameterError(f"unknown keys {sorted(unknown)} in {config}; allowed: {sorted(allowed)}")
    if "target" not in spec or "grid" not in spec:
        raise ParameterError(f"{config} needs target = ... and a [grid] table")
    target: Any = spec["target"]
    if isinstance(target, str) and ":" in target:  # "package.module:function"
        module, _, attr = target.partition(":")
        target = getattr(importlib.import_module(module), attr)
    grid = {k: _axis(k, v) for k, v in spec["grid"].items()}
    name = spec["target"].split(":")[-1]
    store = Path(spec.get("store", f"out/{name}.zarr"))
    store.parent.mkdir(parents=True, exist_ok=True)
    ds = sweep(
        target,
        grid,
        n_jobs=n_jobs if n_jobs is not None else spec.get("n_jobs"),
        backend=spec.get("backend", "threads"),
        client=spec.get("scheduler"),
        store=store,
        resume=spec.get("resume", True),
        progress=not quiet,
        chunk=spec.get("chunk"),
        **spec.get("fixed", {}),
    )
    print(ds)
    print(f"wrote {store}")
    if "plot" in spec:
        from ..viz import plot

        out = Path(spec["plot"])
        out.parent.mkdir(parents=True, exist_ok=True)
        plot.sweep(ds).savefig(out, dpi=120)
        print(f"wrote {out}")
    return 0
