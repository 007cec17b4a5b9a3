"""Sizing a pulse against the integrator: the helpers every planning method shares.

Waveform defaults (:func:`harmonics_of`), the envelope of a pulse of a given size, the rest a pulse
needs for its parts to stop (:func:`settle_time`, :func:`trim_rests`, measured by simulation), a
monotone solver for the size giving a step (:func:`solve_increasing`, with :class:`Probe`: one
part's step under a motion), tables of what a pulse about a centre does to every part
(:class:`PulseTable`), and the drive limits a planner sizes within (:func:`drive_limits`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import as_float, real
from .._errors import ConvergenceError, ParameterError
from ..physics.motion import PlateMotion
from ..physics.sim import simulate, simulate_batch
from ..physics.waveforms import Harmonics, TwoHarmonic, Waveform
from ..plate.actuation import Axis, Plate
from ..plate.drive import DriveLimits, drive_frequency
from ..plate.pulses import Pulse

__all__ = [
    "AMPLITUDE_TOP",
    "Probe",
    "PulseTable",
    "as_centers",
    "clear_of_centers",
    "drive_limits",
    "envelope_times",
    "harmonics_of",
    "positive",
    "scaled",
    "separate",
    "settle_time",
    "slide_to_rest",
    "solve_increasing",
    "stopping_time",
    "tangential_columns",
    "trim_rests",
]

FloatArray = NDArray[np.float64]


def harmonics_of(waveform: Waveform | None, amplitude: float, frequency: float) -> Harmonics:
    if waveform is None:
        positive("amplitude", amplitude)
        drive_frequency("frequency", frequency)
        return Harmonics([amplitude, -amplitude / 2], [0.0, 0.0], frequency)
    if isinstance(waveform, TwoHarmonic):
        waveform = waveform.to_harmonics()
    if not isinstance(waveform, Harmonics) or waveform.shape != ():
        raise ParameterError(
            "waveform must be a single upm.Harmonics or upm.TwoHarmonic (the angular velocity, rad/s); "
            f"got {waveform!r}"
        )
    drive_frequency("waveform's frequency", float(waveform.frequency))
    return waveform


def scaled(h: Harmonics, factor: float) -> Harmonics:
    return Harmonics(h.cos * factor, h.sin * factor, float(h.frequency))


def positive(name: str, value: float) -> float:
    return real(name, value, low=0.0, low_open=True)


#: Friction coefficients above this are not sliding friction (and make pulses unbounded).
MAX_MU = 10.0


def friction(mu: float, mu_s: float | None) -> tuple[float, float]:
    """``(mu, mu_s)`` checked: ``0 < mu <= 10`` and ``mu <= mu_s <= 10`` (``mu_s`` default ``mu``)."""
    kinetic = real("mu", mu, low=0.0, low_open=True, high=MAX_MU)
    static = kinetic if mu_s is None else real("mu_s", mu_s, low=kinetic, high=MAX_MU)
    return kinetic, static


#: The longest sustain [s] a pulse is sized to; beyond it the step asked for is out of reach.
MAX_SUSTAIN = 60.0


def solve_increasing(
    f: Callable[[float], float], target: float, x0: float, name: str, high: float = MAX_SUSTAIN
) -> float:
    """``x > 0`` with ``f(x) = target`` for increasing ``f``: geometric bracketing (up to
    ``high``), then Illinois false position on ``log x``, to 1e-4 relative."""
    x0 = min(x0, high)
    lo, hi = x0, x0
    f_lo = f_hi = f(x0)
    for _ in range(40):
        if f_lo <= target:
            break
        lo /= 2
        f_lo = f(lo)
    for _ in range(40):
        if f_hi >= target:
            break
        if hi >= high:
            raise ParameterError(
                f"no {name} up to {high:g} s gives a step of {target:g} m ({f_hi:.3g} m at {high:g} s): "
                "ask for a smaller step, or a stronger drive"
            )
        hi = min(2 * hi, high)
        f_hi = f(hi)
    if not (f_lo <= target <= f_hi):
        raise ConvergenceError(f"could not bracket the {name} giving a step of {target:g} m")
    a, b, fa, fb, side = math.log(lo), math.log(hi), f_lo - target, f_hi - target, 0
    for _ in range(100):
        x = (a * fb - b * fa) / (fb - fa) if fb != fa else 0.5 * (a + b)
        fx = f(math.exp(x)) - target
        if abs(fx) <= 1e-4 * target:
            return math.exp(x)
        if fx < 0:
            a, fa = x, fx
            if side == -1:
                fb /= 2  # Illinois: the end kept twice in a row counts half
            side = -1
        else:
            b, fb = x, fx
            if side == 1:
                fa /= 2
            side = 1
        if b - a < 1e-12:
            break
    raise ConvergenceError(
        f"the {name} giving a step of {target:g} m did not converge (the step jumps there)"
    )


class Probe:
    """Step of one resting part at ``start`` under ``motion(x)``, along ``axis``, after it stops."""

    def __init__(self, start: np.ndarray, axis: np.ndarray, mu: float, mu_s: float, g: float):
        self.start, self.axis, self.mu, self.mu_s, self.g = start, axis, mu, mu_s, g

    def __call__(self, motion: PlateMotion) -> float:
        duration = motion.duration
        assert duration is not None
        dt = 1.0 / (200.0 * motion.max_frequency)
        r = simulate(motion, self.start[None, :], duration=duration, dt=dt, mu=self.mu, mu_s=self.mu_s,
                     g=self.g, record_every=max(1, int(duration / dt)))  # fmt: skip
        return float((r.positions[-1, 0] - self.start) @ self.axis)


def envelope_times(x: float, rise: float) -> tuple[float, float, float]:
    """Attack, sustain, decay of a pulse of size ``x`` [s]: ``(rise, x - rise, rise)`` once
    ``x >= rise``, and ``(x, 0, x)`` below, so the pulse (and the step it gives) shrinks to zero."""
    return (rise, x - rise, rise) if x >= rise else (x, 0.0, x)


def settle_time(pulse: float, mu: float, mu_s: float, rest: float | None) -> float:
    """Rest after a pulse of length ``pulse`` [s] long enough for every part to stop: friction
    accelerates a part by at most ``mu_s g`` during the pulse and brakes it by ``mu g`` after."""
    stop = 1.05 * pulse * mu_s / mu + 1e-3
    return stop if rest is None else max(float(rest), stop)


def slide_to_rest(
    positions: FloatArray, velocities: FloatArray, mu: ArrayLike, g: float = 9.81
) -> tuple[FloatArray, FloatArray]:
    """Where point parts at ``positions (..., M, 2)`` moving at ``velocities`` come to rest on a
    plate at rest, and how long each takes [s]: a sliding part decelerates at ``mu g`` along its
    velocity, which the integrator's implicit step reproduces exactly (``mu`` per part or one)."""
    speed = np.hypot(velocities[..., 0], velocities[..., 1])
    decel = np.broadcast_to(np.asarray(mu, dtype=float), speed.shape[-1:]) * g
    final: FloatArray = positions + velocities * (speed / (2 * decel))[..., None]
    stop: FloatArray = speed / decel
    return final, stop


def stopping_time(t: np.ndarray, stuck: np.ndarray, after: float) -> float:
    """How long after time ``after`` [s] the last part still slid: ``stuck`` (T, M) records at
    times ``t`` (T,) from the integrator."""
    moving = ~np.all(stuck, axis=1) & (t > after)
    return float(t[moving].max()) - after if np.any(moving) else 0.0


def trim_rests(
    pulses: list[Pulse],
    parts: ArrayLike,
    *,
    mu: float,
    mu_s: float | None = None,
    g: float = 9.81,
    margin: float = 0.2,
) -> list[Pulse]:
    """The pulses with each rest cut to when every part has actually stopped (plus ``margin``
    of it, and 5 ms), found by simulating the pulses in turn on all ``parts`` (M, 2) [m].

    The rests :func:`plan_pulses` and :func:`jet_pulses` put after a pulse are safe bounds (a part
    can gain at most ``mu_s g`` per second of pulse); on a real plate time is what they cost.
    """
    pos = as_float("parts", parts).reshape(-1, 2).copy()
    mu_f = positive("mu", mu)
    if isinstance(pulses, Pulse) or not all(isinstance(p, Pulse) for p in pulses):
        raise ParameterError(f"pulses must be a list of upm.Pulse; got {pulses!r}")
    out: list[Pulse] = []
    for pulse in pulses:
        if pulse.kind == "rest" or not len(pos):
            out.append(pulse)
            continue
        on = pulse.on_time
        tail = max(pulse.rest, 0.05)
        motion = PlateMotion.sequence([pulse.motion(rest=False), PlateMotion.rest(tail)])
        dt = 1.0 / (200.0 * motion.max_frequency)
        every = max(1, int(2e-3 / dt))
        run = simulate(motion, pos, duration=on + tail, dt=dt, mu=mu_f, mu_s=mu_s, g=g, record_every=every)
        stop = stopping_time(run.t, run.stuck, on)
        out.append(replace(pulse, rest=min(pulse.rest, (1 + margin) * stop + 5e-3)))
        pos = run.positions[-1]
    return out


def tangential_columns(parts: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x and y components of the unit tangential field of ``c`` at the parts."""
    r = parts - c
    n = np.hypot(r[:, 0], r[:, 1])
    return -r[:, 1] / n, r[:, 0] / n


#: The largest multiple of the waveform's amplitude in the sizing table of ``intensity="amplitude"``.
AMPLITUDE_TOP = 20.0


class PulseTable:
    """What a pulse about one centre does to every part, tabulated against its size ``x``: the
    on-time [s] (``intensity="duration"``) or the amplitude scale (``"amplitude"``), on a geometric
    grid, by one batched run of the exact integrator. A virtual part at the median radius sets the
    scale: ``steps(d)`` are the parts' steps for the pulse that moves it by ``d`` along the flow."""

    def __init__(
        self, c: np.ndarray, parts: np.ndarray, h: Harmonics, rise: float, hold: float, intensity: str,
        mu: float, mu_s: float, g: float, rest: float | None, kappa: float, biggest: float,
        period: float,
    ) -> None:  # fmt: skip
        self.c, self.h, self.rise, self.hold, self.intensity = c, h, rise, hold, intensity
        radii = np.hypot(*(parts - c).T)
        r_ref = float(np.median(radii))
        probes = np.vstack([parts, c + np.array([r_ref, 0.0])])
        if intensity == "duration":
            # Linear in on-time, eight points a drive period: the step oscillates a little with the
            # phase at which the sustain ends, and the table must resolve that.
            top = max(2.0 * (math.sqrt(2.0 * biggest / kappa) + rise), 4 * rise)
            grid = np.arange(period / 4, top + period / 8, period / 8)
        else:
            grid = np.geomspace(0.05, AMPLITUDE_TOP, 48)
        self.mu, self.mu_s, self.rest = mu, mu_s, rest
        motions = [self.motion(x, 1.0) for x in grid]
        longest = max(mo.duration or 0.0 for mo in motions)
        longest += settle_time(longest, mu, mu_s, rest)
        dt = 1.0 / (200.0 * motions[-1].max_frequency)
        run = simulate_batch(motions, probes, duration=longest, dt=dt, mu=mu, mu_s=mu_s, g=g,
                             record_every=max(1, int(longest / dt)))  # fmt: skip
        moved = run.positions[:, -1] - probes[None]
        ref = np.maximum.accumulate(moved[:, -1, 1])  # tangential step at (r_ref, 0) from c
        self.grid, self.ref, self.moved = grid, ref, moved[:, :-1]
        self.smallest = float(ref[0])
        self.largest = float(ref[-1])

    def knob(self, d: float) -> float:
        if not d <= self.largest:
            what = "duration" if self.intensity == "duration" else "amplitude"
            raise ParameterError(
                f"a step of {d:.3g} m about centre ({self.c[0]:.3g}, {self.c[1]:.3g}) is beyond what the "
                f"pulses reach by {what} ({self.largest:.3g} m): raise the waveform's amplitude, the "
                "sustain, or split the step"
            )
        return float(np.interp(d, self.ref, self.grid))

    def steps(self, d: float) -> np.ndarray:
        """Steps of every part, ``(2M,)`` (x then y), for the pulse sized for ``d``."""
        x = self.knob(d)
        out = [
            np.interp(x, self.grid, self.moved[:, i, k]) for k in (0, 1) for i in range(self.moved.shape[1])
        ]
        return np.array(out)

    def pulse(self, d: float, sign: float) -> Pulse:
        """The pulse for arc length ``d`` in direction ``sign``, with the rest after it."""
        p = self.shape(d, sign)
        return replace(p, rest=settle_time(p.on_time, self.mu, self.mu_s, self.rest))

    def motion(self, x: float, sign: float) -> PlateMotion:
        return self.shape(x, sign, knob=True).motion()

    def shape(self, d: float, sign: float, knob: bool = False) -> Pulse:
        x = d if knob else self.knob(d)
        if self.intensity == "duration":
            wave = self.h if sign > 0 else scaled(self.h, -1.0)
            return Pulse.rotation(self.c, wave, *envelope_times(x, self.rise))
        return Pulse.rotation(self.c, scaled(self.h, sign * x), self.rise, self.hold, self.rise)


def drive_limits(
    limits: DriveLimits | None, plate: Plate | None, axes: Sequence[Axis] | None, limit: float
) -> DriveLimits | None:
    """The drive limits a planner sizes its pulses within: ``limits``, or the older ``plate``,
    ``axes`` and motor ``limit`` with the default stroke."""
    if limits is not None:
        if not isinstance(limits, DriveLimits):
            raise ParameterError(f"limits must be a upm.DriveLimits; got {type(limits).__name__}")
        return limits
    if plate is None:
        return None
    return DriveLimits(plate, None if axes is None else tuple(axes), positive("limit", limit))  # type: ignore[arg-type]


def as_centers(centers: ArrayLike) -> FloatArray:
    c = as_float("centers", centers)
    if c.ndim != 2 or c.shape[1] != 2 or len(c) < 1:
        raise ParameterError(f"centers must have shape (N, 2) with N >= 1; got {c.shape}")
    return np.array(c, dtype=np.float64)


def clear_of_centers(
    positions: FloatArray, steps: FloatArray, centers: FloatArray, clearance: float
) -> FloatArray:
    """Parts sitting on a centre of rotation feel no force from it; such parts keep still this cycle."""
    near = np.min(np.linalg.norm(positions[:, None] - centers[None], axis=2), axis=1) < clearance
    out = steps.copy()
    out[near] = 0.0
    return out


def separate(positions: FloatArray, radius: float, gap: float = 1e-4) -> FloatArray:
    """Tracked disks moved apart just enough not to overlap (vision puts touching disks a
    millimetre or two into each other), each pair pushed symmetrically along its line."""
    q = np.array(positions, dtype=float)
    for _ in range(50):
        d = q[:, None] - q[None]
        r = np.hypot(d[..., 0], d[..., 1])
        np.fill_diagonal(r, np.inf)
        need = 2 * radius + gap - r
        if not np.any(need > 0):
            break
        i, j = np.nonzero(np.triu(need > 0, 1))
        for a, b in zip(i, j, strict=True):
            u = d[a, b] / r[a, b] if r[a, b] > 0 else np.array([1.0, 0.0])
            q[a] += 0.5 * (need[a, b] + gap) * u
            q[b] -= 0.5 * (need[a, b] + gap) * u
    return q
