"""Field-based manipulation without sensing on a plate that moves out of its plane (docs/ppod.md).

``upm demo ppod``: parts scattered over the plate gathered to a point by a sink (the PPOD2
library's, and one designed by :func:`upm.design_field` off the centre), open loop, over several
seeds. ``upm demo ppod-sequences``: the PPOD2 controller's "sinkSource" and "square" sequences.
``upm demo ppod-library``: quiver figures of every library field, drift and asymptotic side by
side with the measured motion of simulated parts.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..physics.motion import PlateMotion
from ..physics.ppod import (
    PPOD_FIELDS,
    PPOD_SEQUENCES,
    asymptotic_field,
    divergence_curl,
    drift_field,
    field_angle,
)
from ..physics.sim import simulate
from ..plan.field_design import design_field
from .runner import keep, run_named

__all__ = ["DEMOS", "run_ppod_demo"]

MU = 0.3
HALF = 0.1  # the scattered parts' square [m] (the PPOD plate is about 0.3 m across)


def _dt(motion: PlateMotion) -> float:
    return 1.0 / (400.0 * motion.max_frequency)


def _gather(quick: bool, out: Path) -> dict[str, Any]:
    """Sensorless gathering: no camera, one field, parts anywhere in the square."""
    seeds = range(3 if quick else 5)
    n = 20 if quick else 40
    duration = 12.0 if quick else 20.0
    center = np.array([0.03, -0.02])
    sinks = {
        "library Sink at (0, 0)": (PlateMotion.ppod("Sink"), np.zeros(2)),
        "designed sink at (0.03, -0.02)": (design_field("sink", center, 0.5, mu=MU).motion, center),
    }
    metrics: dict[str, Any] = {}
    traces: dict[str, Any] = {}
    for label, (motion, c) in sinks.items():
        finals, medians, inside, gathered = [], [], [], []
        for seed in seeds:
            start = np.random.default_rng(seed).uniform(-HALF, HALF, (n, 2))
            r = simulate(motion, start, duration=duration, dt=_dt(motion), mu=MU, record_every=400)
            d = np.linalg.norm(r.positions[-1] - c, axis=1)
            finals.append(float(d.max()))
            medians.append(float(np.median(d)))
            inside.append(float(np.mean(d < 0.01)))
            every = np.all(np.linalg.norm(r.positions - c, axis=2) < 0.01, axis=1)
            gathered.append(float(r.t[np.argmax(every)]) if every.any() else float("nan"))
            if seed == 0:
                if not traces:
                    keep(r, out)  # the library Sink's first seed
                traces[label] = (r, c)
        metrics[label] = {
            "seeds": len(finals),
            "parts": n,
            "seconds": duration,
            "median_distance_mm": 1e3 * float(np.median(medians)),
            "max_distance_mm": {"median": 1e3 * float(np.median(finals)), "max": 1e3 * float(np.max(finals))},
            "fraction_within_1cm": float(np.min(inside)),
            "time_all_within_1cm_s": {"median": float(np.median(gathered)), "max": float(np.max(gathered))},
        }
    _gather_figure(traces, out / "gather.png")
    return metrics


def _gather_figure(traces: dict[str, Any], path: Path) -> None:
    from ..viz.plot import _pyplot

    plt = _pyplot()
    fig, axes = plt.subplots(1, len(traces), figsize=(5.2 * len(traces), 5.0), layout="constrained")
    for ax, (label, (r, c)) in zip(np.atleast_1d(axes), traces.items(), strict=True):
        for k in range(r.positions.shape[1]):
            ax.plot(r.positions[:, k, 0], r.positions[:, k, 1], lw=0.8)
        ax.plot(r.positions[0, :, 0], r.positions[0, :, 1], "ko", ms=3, label="start")
        ax.plot(*c, "r+", ms=14, mew=2, label="sink")
        ax.set(aspect="equal", xlabel="x [m]", ylabel="y [m]", title=f"{label}: {r.t[-1]:.0f} s, no camera")
        ax.legend(loc="upper right", fontsize=8)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _sequences(quick: bool, out: Path) -> dict[str, Any]:
    """The PPOD2 sequences, each field for ``dwell`` seconds, on a cluster of parts."""
    from ..viz.plot import _pyplot

    dwell = 2.5  # s: TransX carries a cluster about 11 cm, the square stays on a 0.3 m plate
    start = np.stack(np.meshgrid(np.linspace(-0.04, 0.04, 3), np.linspace(-0.04, 0.04, 3)), -1).reshape(-1, 2)
    plt = _pyplot()
    fig, axes = plt.subplots(1, len(PPOD_SEQUENCES), figsize=(10.4, 5.0), layout="constrained")
    metrics: dict[str, Any] = {}
    for ax, (name, fields) in zip(axes, PPOD_SEQUENCES.items(), strict=True):
        motion = PlateMotion.sequence([PlateMotion.ppod(f).for_duration(dwell) for f in fields])
        r = simulate(motion, start, duration=dwell * len(fields), dt=_dt(motion), mu=MU, record_every=200,
                     plate_size=0.3)  # fmt: skip
        ends = [int(np.searchsorted(r.t, dwell * (k + 1) - 1e-9)) for k in range(len(fields))]
        centroids = [r.positions[e].mean(axis=0) for e in ends]
        spread = [
            float(np.max(np.linalg.norm(r.positions[e] - r.positions[e].mean(0), axis=1))) for e in ends
        ]
        metrics[name] = {
            "fields": list(fields),
            "dwell_s": dwell,
            "centroid_after_each_mm": [[round(1e3 * float(v), 2) for v in c] for c in centroids],
            "spread_after_each_mm": [round(1e3 * s, 2) for s in spread],
            "lost": int(np.sum(r.left_plate)),
        }
        colours = plt.cm.tab10(np.arange(len(fields)) % 10)
        bounds = [0, *ends]
        for k, f in enumerate(fields):
            seg = r.positions[bounds[k] : bounds[k + 1] + 1]
            for j in range(seg.shape[1]):
                ax.plot(seg[:, j, 0], seg[:, j, 1], color=colours[k], lw=0.8, label=f if j == 0 else None)
        ax.set(aspect="equal", xlabel="x [m]", ylabel="y [m]", title=f'"{name}", {dwell:g} s a field')
        ax.legend(loc="upper right", fontsize=7)
    fig.savefig(out / "sequences.png", dpi=110)
    plt.close(fig)
    return metrics


def _library(quick: bool, out: Path) -> dict[str, Any]:
    """Every library field: drift (at MU, with simulated parts) beside the asymptotic field."""
    from ..viz.plot import _pyplot, field

    plt = _pyplot()
    names = ("Sink", "Source", "Whirlpool", "TransX") if quick else PPOD_FIELDS
    xs = np.linspace(-HALF, HALF, 9)
    grid = np.stack(np.meshgrid(xs, xs), -1)
    metrics: dict[str, Any] = {}
    for name in names:
        motion = PlateMotion.ppod(name)
        fig = field("both", (-HALF, -HALF, HALF, HALF), motion=motion, mu=MU, resolution=9)
        fig.savefig(out / f"{name}.png", dpi=80)
        plt.close(fig)
        d = drift_field(motion, grid, mu=MU)
        a = asymptotic_field(motion, grid, mu=MU)
        div, curl = divergence_curl(d.velocity, xs, xs)
        metrics[name] = {
            "drift_speed_max_mm_s": round(1e3 * float(d.speed.max()), 2),
            "divergence_at_centre_1_s": round(float(div[4, 4]), 3),
            "curl_at_centre_1_s": round(float(curl[4, 4]), 3),
            "median_angle_drift_asymptotic_deg": round(float(np.nanmedian(np.abs(field_angle(d, a)))), 1),
            "validity_min": round(float(np.min(d.validity)), 3),
            "lift_off_max": round(float(np.max(a.lift_off)), 3),
        }
    return metrics


DEMOS: dict[str, tuple[str, Callable[[bool, Path], dict[str, Any]]]] = {
    "ppod": ("sensorless gathering by a sink: the library's and a designed one (no camera)", _gather),
    "ppod-sequences": ('the PPOD2 sequences "sinkSource" and "square"', _sequences),
    "ppod-library": ("every field of the PPOD2 library: drift, asymptotic and simulated parts", _library),
}


def run_ppod_demo(
    name: str, out: Path | str = "out", quick: bool = False, verbose: bool = True
) -> dict[str, Any]:
    """Run 6-DOF plate demo ``name`` (see :data:`DEMOS`); write ``out/name/`` and return the metrics."""
    return run_named(DEMOS, name, out, quick, verbose)
