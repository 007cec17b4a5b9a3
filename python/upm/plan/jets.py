"""Chapter 6: jets. A local force field focused on one part at a time, no matrix inversion.

* :func:`jet_pulses` / :func:`jet_plan`: one jet (6.4) per part in turn, its sustain solved
  against the exact integrator.
* :class:`JetPlanner`: the closed-loop planner (round robin over the parts that must move).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import as_float
from .._errors import ParameterError, ShapeError
from ..physics.motion import PlateMotion
from ..plate.actuation import Axis, Plate
from ..plate.drive import DriveLimits, drive_frequency
from ..plate.pulses import Pulse, program
from .sizing import (
    Probe,
    drive_limits,
    envelope_times,
    friction,
    positive,
    settle_time,
    solve_increasing,
    trim_rests,
)

__all__ = ["JetPlanner", "jet_plan", "jet_pulses"]

FloatArray = NDArray[np.float64]


def jet_plan(parts: ArrayLike, steps: ArrayLike, **options: Any) -> PlateMotion:
    """The plate motion moving each part by its small step with a jet: :func:`jet_pulses` played
    one after another (same parameters)."""
    return program(jet_pulses(parts, steps, **options))


def jet_pulses(
    parts: ArrayLike,
    steps: ArrayLike,
    *,
    mu: float,
    mu_s: float | None = None,
    g: float = 9.81,
    amplitude: float = 0.1,
    frequency: float = 35.0,
    rho: float | None = None,
    attack: float | None = None,
    rest: float | None = None,
    min_step: float = 1e-6,
    order: ArrayLike | None = None,
) -> list[Pulse]:
    """Pulses moving each part by its small step with a jet focused on it (6.4), one at a time.

    For every part whose step exceeds ``min_step`` [m], in index order (or ``order``): a jet at the
    part, along its step, under a raised-cosine envelope whose sustain is solved (by simulating the part) so
    the part moves by ``|step|``, then rest while it stops. No matrix inversion; the other parts
    feel the jet's small far field only (docs/spec.md §7).

    Parameters
    ----------
    parts, steps : array_like, shape (M, 2)
        Positions and requested steps [m].
    mu, mu_s, g : float
        Friction of the parts and gravity.
    amplitude : float
        Jet amplitude ``A`` [m/s]; frequency [Hz] of its ``cos wt - cos 2wt`` term.
    rho : float, optional
        Jet radius [m] (default a quarter of the smallest distance between parts, so the others
        sit where the jet's force is a few per cent of its peak; 0.05 for a single part).
    attack : float, optional
        Rise (= fall) time of each jet [s] (default one jet period, ``3 / frequency``).
    order : sequence of int, optional
        The parts to move, in this order (default all, by index).
    """
    p = as_float("parts", parts)
    s = as_float("steps", steps)
    if p.ndim != 2 or p.shape[1] != 2 or s.shape != p.shape:
        raise ShapeError(f"parts and steps must both have shape (M, 2); got {p.shape} and {s.shape}")
    mu_f, mu_s_f = friction(mu, mu_s)
    positive("amplitude", amplitude)
    drive_frequency("frequency", frequency)
    if rho is None:
        gaps = np.hypot(*(p[:, None, :] - p[None, :, :]).transpose(2, 0, 1))
        gaps[np.diag_indices(len(p))] = np.inf
        rho = 0.05 if len(p) < 2 else float(gaps.min()) / 4
        if not rho > 0:
            raise ParameterError("parts must be distinct to size the jets (two share a position)")
    rho = positive("rho", rho)
    period = 3.0 / frequency  # the jet's period, 6 pi / w
    rise = period if attack is None else positive("attack", attack)
    items: list[Pulse] = []
    sequence = range(len(p)) if order is None else [int(i) for i in np.asarray(order).reshape(-1)]
    if any(not 0 <= i < len(p) for i in sequence) or len(set(sequence)) != len(sequence):
        raise ParameterError(
            f"order must list distinct part indices in 0..{len(p) - 1} (each part's step is made once); "
            f"got {list(sequence)}"
        )
    for i in sequence:
        length = float(np.hypot(*s[i]))
        if length <= min_step:
            continue
        axis = s[i] / length
        probe = Probe(p[i], axis, mu_f, mu_s_f, g)

        def pulse(x: float, i: int = i, axis: np.ndarray = axis) -> Pulse:
            shape = envelope_times(x, rise)
            after = settle_time(sum(shape), mu_f, mu_s_f, rest)
            return Pulse.jet(p[i], axis, rho, amplitude, frequency, *shape, rest=after)

        def step(x: float, pulse: Callable[[float], Pulse] = pulse, probe: Probe = probe) -> float:
            return probe(pulse(x).motion())

        items.append(pulse(solve_increasing(step, length, period, "sustain")))
    return items or [Pulse.pause(period)]


class JetPlanner:
    """Chapter 6: one jet per part, in turn, sized against the exact integrator.

    Parameters
    ----------
    mu, mu_s : float
        Friction of the parts.
    amplitude, frequency : float
        Jet amplitude [m/s] and base frequency [Hz].
    rho : float or None
        Jet radius [m] (default a quarter of the closest pair's distance, at most ``max_rho``).
    attack : float or None
        Rise and fall of each jet [s] (default 3 jet periods, so motors play it cleanly).
    min_step : float
        Steps shorter than this [m] are skipped.
    limits : DriveLimits, optional
        The device's limits (or the older ``plate``, ``axes`` and motor force ``limit`` [N], with
        the default stroke): a jet that would exceed the motor force or the stroke gets a
        proportionally lower amplitude (jets far from the plate's centre need large motor forces
        and swing the plate's corners far for their rotation term).
    """

    def __init__(
        self,
        *,
        plate: Plate | None = None,
        axes: Sequence[Axis] | None = None,
        limit: float = 200.0,
        mu: float = 0.3,
        mu_s: float | None = None,
        amplitude: float = 0.06,
        frequency: float = 35.0,
        rho: float | None = None,
        max_rho: float = 0.05,
        attack: float | None = None,
        min_step: float = 5e-4,
        limits: DriveLimits | None = None,
    ) -> None:
        self.limits = drive_limits(limits, plate, axes, limit)
        self.mu = positive("mu", mu)
        self.mu_s = mu_s
        self.amplitude = positive("amplitude", amplitude)
        self.frequency = drive_frequency("frequency", frequency)
        self.rho, self.max_rho = rho, positive("max_rho", max_rho)
        self.attack = 9.0 / self.frequency if attack is None else float(attack)
        self.min_step = float(min_step)

    def _amplitude(self, center: FloatArray, direction: FloatArray, rho: float) -> float:
        if self.limits is None:
            return self.amplitude
        # the stroke depends on the envelope (its drift rings the suspension): the least headroom
        # over the sustains a jet may get, and the shorter ramps of jets too small for a full one
        a = self.attack
        shapes = [(a, s) for s in (0.0, 0.15, 0.3, 0.5, 0.8, 1.2)] + [(a / 2, 0.0), (a / 4, 0.0)]
        room = min(
            self.limits.headroom(Pulse.jet(center, direction, rho, self.amplitude, self.frequency, r, s, r))
            for r, s in shapes
        )
        return self.amplitude * min(1.0, 0.95 * room)

    def plan(self, positions: FloatArray, steps: FloatArray) -> list[Pulse]:
        pos, st = np.asarray(positions, float), np.nan_to_num(np.asarray(steps, float))  # free: stay
        moving = np.hypot(st[:, 0], st[:, 1]) > self.min_step
        if not np.any(moving):
            return []
        rho = self.rho
        if rho is None:
            gaps = np.linalg.norm(pos[:, None] - pos[None], axis=2)
            gaps[np.diag_indices(len(pos))] = np.inf
            rho = min(self.max_rho, float(gaps.min()) / 4) if len(pos) > 1 else self.max_rho
            rho = max(rho, 0.005)
        pulses: list[Pulse] = []
        for i in np.nonzero(moving)[0]:
            amplitude = self._amplitude(pos[i], st[i], rho)
            pulses += jet_pulses(
                pos,
                st,
                mu=self.mu,
                mu_s=self.mu_s,
                amplitude=amplitude,
                frequency=self.frequency,
                rho=rho,
                attack=self.attack,
                min_step=self.min_step,
                order=[i],
            )
        return trim_rests([p for p in pulses if p.kind != "rest"], pos, mu=self.mu, mu_s=self.mu_s)
