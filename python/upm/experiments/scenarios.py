"""The built-in sweep targets (`upm sweep --list`): each vectorised over the points of a chunk,
with its parameters' allowed ranges and its outputs' units."""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .. import _core
from .._errors import ParameterError, RankWarning
from ..physics.feeding import feed_rate, mean_force
from ..physics.fields import jet_field
from ..physics.motion import PlateMotion
from ..physics.sim import simulate_batch
from ..physics.waveforms import TwoHarmonic
from ..plan.solvers import flow_error, ring_centers, solve_displacements

__all__ = ["SCENARIOS", "Outputs", "Scenario"]

FloatArray = NDArray[np.float64]
Outputs = dict[str, NDArray[Any]]

_G = 9.81


@dataclass(frozen=True)
class Scenario:
    """A built-in sweep target, vectorised over the points of a chunk.

    ``ranges`` lists every parameter with its allowed interval; those in ``defaults`` may be
    left out (the others must be a grid axis or fixed); ``outputs`` are the dataset's variables
    with their units; ``integers`` the parameters that must be whole numbers.
    """

    name: str
    doc: str
    ranges: dict[str, tuple[float, float]]
    defaults: dict[str, float]
    outputs: dict[str, str]
    run: Callable[[dict[str, FloatArray]], Outputs] = field(repr=False)
    chunk: int = 64
    integers: tuple[str, ...] = ()
    check: Callable[[Callable[[str], NDArray[Any]]], None] | None = field(default=None, repr=False)

    @property
    def parameters(self) -> tuple[str, ...]:
        return tuple(self.ranges)

    @property
    def required(self) -> tuple[str, ...]:
        return tuple(k for k in self.ranges if k not in self.defaults)


def _peak_acceleration(cos: FloatArray, sin: FloatArray) -> FloatArray:
    """``max_t |v'(t)|`` of the unit-frequency series ``v = sum_k cos_k cos(kt) + sin_k sin(kt)``
    (rows of coefficients, k = 1, 2, ...), sampled at 4096 points a period. (Waveform.acceleration
    would build one Rust waveform per sample for a batch of drives.)"""
    t = np.linspace(0.0, 2.0 * np.pi, 4096, endpoint=False)
    k = np.arange(1, cos.shape[1] + 1)
    kt = k[:, None] * t[None, :]
    a = (sin * k) @ np.cos(kt) - (cos * k) @ np.sin(kt)
    return np.asarray(np.abs(a).max(axis=1), dtype=np.float64)


def _feed_rate(p: dict[str, FloatArray]) -> Outputs:
    b, phi, gamma = p["b"], p["phi"], p["gamma"]
    f, mu = p["frequency"], p["mu"]
    # settle for 1.5 gamma + 20 periods unless told: the part's velocity relaxes to the steady
    # state over about gamma / 4 periods (the viscous model 3.12), slower the stronger the drive
    periods = np.where(p["periods"] > 0, p["periods"], 20 + np.ceil(1.5 * gamma)).astype(np.int64)
    average, steps = int(p["average"][0]), int(p["steps"][0])
    keys = np.column_stack([f, mu, periods, p["average"], p["steps"]])
    if len(np.unique(keys, axis=0)) > 1:  # one simulate_batch call per (f, mu, periods, ...)
        out: Outputs = {}
        for key in np.unique(keys, axis=0):
            sel = np.all(keys == key, axis=1)
            part = _feed_rate(
                {k: v[sel] for k, v in p.items()} | {"periods": periods[sel].astype(np.float64)}
            )
            for name, value in part.items():
                out.setdefault(name, np.empty(len(b), value.dtype))[sel] = value
        return out
    periods_ = int(periods[0])
    drive = TwoHarmonic(b, phi)  # unit amplitude and angular frequency, all points at once
    cos, sin = drive.coefficients()
    amplitude = gamma * mu[0] * _G / (2.0 * np.pi * f[0] * _peak_acceleration(cos, sin))
    # one motion per point straight from its scaled coefficients: a TwoHarmonic per point would
    # hold the GIL (its Python-side checks) for ~10% of the work
    freq = np.full(1, f[0])
    motions = [
        PlateMotion(
            _core.PlateMotion.translation(
                (1.0, 0.0), _core.WaveformBatch.harmonics(a * c[None], a * s_[None], freq)
            ),
            ("raw_translation", (1.0, 0.0), a * c[None], a * s_[None], freq),
        )
        for a, c, s_ in zip(amplitude, cos, sin, strict=True)
    ]
    run = simulate_batch(motions, [[0.0, 0.0]], duration=periods_ / f[0], dt=1.0 / (f[0] * steps), mu=mu[0],
                         record_every=steps, threads=1)  # fmt: skip
    x = run.positions[:, :, 0, 0]
    return {
        "feed_rate": (x[:, -1] - x[:, -1 - average]) * f[0] / average / amplitude,
        "feed_rate_qs": np.asarray(feed_rate(drive), dtype=np.float64),
        "force_at_rest": np.asarray(mean_force(drive, part_velocity=0.0), dtype=np.float64),
        "amplitude": amplitude,
    }


def _jet_focus(p: dict[str, FloatArray]) -> Outputs:
    directions = int(p["directions"][0])
    angles = np.linspace(0.0, 2.0 * np.pi, directions, endpoint=False)
    unit = np.column_stack([np.cos(angles), np.sin(angles)])
    s = np.linspace(0.0, 4.0, 161)  # radii in units of rho
    f0, half = np.empty(len(p["rho"])), np.empty(len(p["rho"]))
    for i, rho in enumerate(p["rho"]):
        pts = (s[:, None, None] * rho * unit[None]).reshape(-1, 2)
        mag = np.linalg.norm(jet_field(pts, center=(0.0, 0.0), direction=(0.0, 1.0), rho=float(rho)), axis=1)
        profile = mag.reshape(len(s), directions).mean(axis=1)
        f0[i] = profile[0]
        below = np.nonzero(profile < profile[0] / 2)[0]
        if not len(below):
            half[i] = np.nan
            continue
        k = below[0]
        frac = (profile[k - 1] - profile[0] / 2) / (profile[k - 1] - profile[k])
        half[i] = (s[k - 1] + frac * (s[k] - s[k - 1])) * rho
    return {"force_at_center": f0, "half_force_radius": half, "half_force_radius_over_rho": half / p["rho"]}


def _rotation_accuracy(p: dict[str, FloatArray]) -> Outputs:
    n = len(p["spacing"])
    residual, flow, cond = np.empty(n), np.empty(n), np.empty(n)
    for i in range(n):
        m, trials = int(p["parts"][i]), int(p["trials"][i])
        step, spacing = p["step"][i], p["spacing"][i]
        centers = ring_centers(int(p["n_centers"][i]), float(p["radius"][i]))
        rng = np.random.default_rng(int(p["seed"][i]))
        res, err, cn = [], [], []
        for _ in range(trials):
            parts = np.column_stack([(np.arange(m) - (m - 1) / 2) * spacing, rng.normal(0.0, spacing / 4, m)])
            a = rng.uniform(0.0, 2.0 * np.pi, m)
            steps = step * np.column_stack([np.cos(a), np.sin(a)])
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RankWarning)
                plan = solve_displacements(parts, steps, centers)
            res.append(np.linalg.norm(plan.predicted_steps - steps, axis=1).max() / step)
            err.append(np.linalg.norm(flow_error(plan, exact=True), axis=1).max() / step)
            cn.append(plan.condition_number)
        residual[i], flow[i], cond[i] = np.mean(res), np.mean(err), np.median(cn)
    return {"residual": residual, "flow_error": flow, "condition": cond}


def _mchip_feed(p: dict[str, FloatArray]) -> Outputs:
    from ..physics import mchip

    n = len(p["duty"])
    names = ("feed_rate", "rebound_share", "collisions", "hop_energy_share", "impact_angle",
             "impact_angular_speed", "part_height", "jam_share")  # fmt: skip
    out = {k: np.empty(n) for k in names}
    for i in range(n):
        design = mchip.Design(
            part_size=(1150e-6, 400e-6, float(p["thickness"][i])),
            part_mass=float(p["mass"][i]),
            ridge_distance=float(p["ridge_distance"][i]),
            ridge_height=float(p["ridge_height"][i]),
            natural_frequency=float(p["natural_frequency"][i]),
            quality=float(p["quality"][i]),
        )
        drive = mchip.Drive(duty=float(p["duty"][i]), peak_angle=float(p["peak_angle"][i]))
        # Replicas: seed 0 starts the part at the default place; any other seed moves it by up to
        # 10 µm in x and y (the runs are chaotic: the replicas' spread is the feed rate's noise).
        seed = int(p["seed"][i])
        shift = np.random.default_rng(seed).uniform(-10e-6, 10e-6, 2) if seed else np.zeros(2)
        duration = float(p["duration"][i])
        run = mchip.simulate(design, drive, duration=duration, record_every=20,
                             part_start=(600e-6 + shift[0], 400e-6 + shift[1]))  # fmt: skip
        skip = min(0.01, 0.3 * duration)
        out["feed_rate"][i] = run.feed_rate(skip=skip)
        out["rebound_share"][i] = run.rebound_share()
        out["collisions"][i] = len(run.collisions)
        out["hop_energy_share"][i] = run.hop_energy_share()
        out["impact_angle"][i] = run.impact_median("angle")
        out["impact_angular_speed"][i] = run.impact_median("angular_speed")
        out["part_height"][i] = run.part_height(skip=skip)
        # The share of the run after `skip` spent jammed (10 ms windows below a quarter of the free
        # rate); NaN if the run holds no whole window (jams() says so).
        try:
            jammed = sum(b - a for a, b in run.jams(skip=skip))
            out["jam_share"][i] = jammed / (run.t[-1] - run.t[0] - skip)
        except ParameterError:
            out["jam_share"][i] = np.nan
    return out


def _check_feed_rate(values: Callable[[str], NDArray[Any]]) -> None:
    periods, average = values("periods"), values("average")
    if np.any((periods > 0) & (periods <= average.max())):
        raise ParameterError(
            f"feed_rate measures over the last `average` = {average.max()} periods: `periods` must "
            f"exceed it (or be 0: automatic); got {periods[(periods > 0) & (periods <= average.max())][0]}"
        )


def _check_rotation_accuracy(values: Callable[[str], NDArray[Any]]) -> None:
    if values("n_centers").min() < 2 * values("parts").max():
        raise ParameterError(
            f"rotation_accuracy needs n_centers >= 2 parts (the system 5.3 has 2 rows per part); got "
            f"n_centers down to {values('n_centers').min()} with parts up to {values('parts').max()}"
        )


SCENARIOS: dict[str, Scenario] = {
    s.name: s
    for s in (
        Scenario(
            "feed_rate",
            "A point part on a plate driven by v = A (sin wt + b sin(2wt + phi)) with peak acceleration "
            "gamma mu g: its steady feed rate from the exact stick-slip integrator (measured over "
            "the last `average` periods of `periods`; 0: 20 + 1.5 gamma, long enough to settle), "
            "beside the quasi-static limit (the median of v, 3.16-3.17) and the force at rest.",
            ranges={
                "b": (0.0, 10.0),
                "phi": (-10.0, 10.0),
                "gamma": (0.0, 1e3),
                "frequency": (1e-3, 1e5),
                "mu": (1e-3, 10.0),
                "periods": (0, 1e6),
                "average": (1, 1e5),
                "steps": (8, 1e5),
            },
            defaults={"frequency": 35.0, "mu": 0.3, "periods": 0, "average": 10, "steps": 400},
            outputs={
                "feed_rate": "steady feed rate / A (exact integrator)",
                "feed_rate_qs": "median of v / A (quasi-static limit)",
                "force_at_rest": "mean force on a part held still / (mu m g)",
                "amplitude": "A [m/s]",
            },
            run=_feed_rate,
            check=_check_feed_rate,
            chunk=128,
            integers=("periods", "average", "steps"),
        ),
        Scenario(
            "jet_focus",
            "The jet's force at its centre and the radius at which the force (averaged over "
            "directions) falls to half of it, versus rho (6.4).",
            ranges={"rho": (1e-9, 10.0), "directions": (1, 360)},
            defaults={"directions": 12},
            outputs={
                "force_at_center": "force / (mu m g)",
                "half_force_radius": "m",
                "half_force_radius_over_rho": "1",
            },
            run=_jet_focus,
            chunk=4,
            integers=("directions",),
        ),
        Scenario(
            "rotation_accuracy",
            "Displacement plans (5.3) for parts in a row at a given spacing with a ring of "
            "n_centers centres: first-order residual and exact flow error relative to the step "
            "(5.28-5.30), and the condition number, averaged over random steps.",
            ranges={
                "spacing": (1e-9, 10.0),
                "n_centers": (1, 10_000),
                "parts": (1, 1000),
                "step": (1e-12, 1.0),
                "radius": (1e-9, 100.0),
                "trials": (1, 10_000),
                "seed": (0, 2**63 - 1),
            },
            defaults={"parts": 4, "step": 0.0005, "radius": 0.2, "trials": 8, "seed": 0},
            outputs={
                "residual": "max |predicted - wanted| / step",
                "flow_error": "max |exact error of the sequence| / step",
                "condition": "condition number of (5.3)",
            },
            run=_rotation_accuracy,
            check=_check_rotation_accuracy,
            chunk=8,
            integers=("n_centers", "parts", "trials", "seed"),
        ),
        Scenario(
            "mchip_feed",
            "The M-Chip resonator array (thesis ch. 2, upm.mchip, rapier3d): the part's feed rate "
            "versus its mass, its thickness (a 1150 x 400 µm part; the mass is `mass` whatever the "
            "thickness), the ridge distance L and height H, the resonators' natural frequency and "
            "quality factor on their joints, the torque's duty cycle and the resonators' peak "
            "angle, with the share of rebounds (collisions within 0.05 ms of the "
            "resonator's previous one) and of the part's kinetic energy in the vertical hop, and "
            "Fig. 2.9's impact angle, impact angular speed (medians of the once-a-cycle impacts) "
            "and the part's height (its underside above the slabs), and the share of the time it "
            "spent jammed (MChipResult.jams: relative to its free rate, so read it with the feed "
            "rate; a part that moved freely for less than a twentieth of the run has no free rate "
            "to compare with). `seed` > 0 "
            "moves the part's start by up to 10 µm (replicas: the runs are chaotic, and the "
            "replicas' spread is the noise of a feed rate). Each point simulates `duration` s "
            "(slow: docs/mchip.md gives measured wall times).",
            ranges={
                "mass": (1e-12, 1e-3),
                "thickness": (1e-6, 1e-3),
                "ridge_distance": (0.0, 135e-6),
                "ridge_height": (1e-7, 1e-4),
                "natural_frequency": (100.0, 20e3),
                "quality": (0.05, 1e4),
                "duty": (1e-3, 1.0),
                "peak_angle": (1e-3, 0.5),
                "seed": (0, 2**63 - 1),
                "duration": (1e-3, 10.0),
            },
            defaults={
                "mass": 2330.0 * 1150e-6 * 400e-6 * 50e-6,
                "thickness": 50e-6,
                "ridge_distance": 130e-6,
                "ridge_height": 5e-6,
                "natural_frequency": 5000.0,
                "quality": 0.8,
                "duty": 0.5,
                "peak_angle": 0.08,
                "seed": 0,
                "duration": 0.05,
            },
            outputs={
                "feed_rate": "m/s along the feed",
                "rebound_share": "1",
                "collisions": "1",
                "hop_energy_share": "1",
                "impact_angle": "rad",
                "impact_angular_speed": "rad/s",
                "part_height": "m",
                "jam_share": "1",
            },
            run=_mchip_feed,
            chunk=1,
            integers=("seed",),
        ),
    )
}
