"""Planners: desired small steps of the parts → the pulses that make them (chapters 4, 5, 6).

* :class:`RotationsPlanner` (chapter 4): steps are read as average forces (``f = step / gain``),
  the rotation strengths solve (4.10) by SVD (minimum norm over redundant centres, optionally
  damped) with calibrated columns, and rotation ``j`` gets short pulses in proportion to ``|k_j|``.
* :class:`DisplacementPlanner` (chapter 5): arc lengths about the centres from
  :func:`upm.solve_displacements`, one shaped pulse per centre sized against the exact integrator
  (:func:`upm.plan_pulses`).
* :class:`JetPlanner` (chapter 6): a jet focused on each part in turn (:func:`upm.jet_pulses`), no
  matrix inversion.
* :class:`FixedPlanner`: the same pulses every cycle (open-loop flows such as the race track).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import as_float
from .._errors import ParameterError, PlanWarning, RankWarning
from ..actuation import Axis, Plate
from ..drive import DriveLimits
from ..feeding import mean_force
from ..fields import rotation_field
from ..motion import PlateMotion
from ..planning import (
    AMPLITUDE_TOP,
    _harmonics,
    _positive,
    jet_pulses,
    plan_pulses,
    stopping_time,
    trim_rests,
)
from ..pulses import Pulse
from ..sim import simulate_batch
from ..solvers import rotation_order, solve_displacements
from ..waveforms import Harmonics, Waveform

__all__ = ["DisplacementPlanner", "FixedPlanner", "JetPlanner", "Planner", "RotationsPlanner"]

FloatArray = NDArray[np.float64]


@runtime_checkable
class Planner(Protocol):
    """``plan(positions (M, 2), steps (M, 2)) -> list[Pulse]`` [m]. A NaN component of a step is
    free: the task does not care where the part goes along it."""

    def plan(self, positions: FloatArray, steps: FloatArray) -> list[Pulse]: ...


def _limits(
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
    return DriveLimits(plate, None if axes is None else tuple(axes), _positive("limit", limit))  # type: ignore[arg-type]


def _centers(centers: ArrayLike) -> FloatArray:
    c = as_float("centers", centers)
    if c.ndim != 2 or c.shape[1] != 2 or len(c) < 1:
        raise ParameterError(f"centers must have shape (N, 2) with N >= 1; got {c.shape}")
    return np.array(c, dtype=np.float64)


def _clear_of_centers(
    positions: FloatArray, steps: FloatArray, centers: FloatArray, clearance: float
) -> FloatArray:
    """Parts sitting on a centre of rotation feel no force from it; such parts keep still this cycle."""
    near = np.min(np.linalg.norm(positions[:, None] - centers[None], axis=2), axis=1) < clearance
    out = steps.copy()
    out[near] = 0.0
    return out


class RotationsPlanner:
    """Chapter 4: average forces from rotations about fixed centres, solved by SVD.

    The steps asked for are read as average forces (``f = step / gain``) and
    the strengths solve (4.10) by SVD, minimum norm over redundant centres, as
    :func:`upm.solve_rotations` does, with each column scaled per part by what a pulse about that
    centre really does at that distance (see :meth:`_solve_some`). The
    model holds for parts that start from rest: a time-asymmetric rotation pushes every resting
    part with the same tangential force whatever its distance from the centre, but a part that has
    picked up speed feels a force that falls off with speed relative to the plate, which is slower
    nearer the centre (measured: a 0.8 s rotation moves parts 10 and 30 cm from the centre by 30
    and 82 mm; a 0.1 s one by 0.92 and 1.05 mm). So every rotation is played as repeated ``short``
    pulses, each followed by the rest in which the parts stop; rotation ``j`` gets a number of
    pulses proportional to ``|k_j|``, and the rotations are interleaved round robin. When they do
    not fit in one ``cycle`` the forces are scaled down together. The remainder of a rotation's
    displacement below one pulse's step is played as one shorter pulse, its on-time read from a
    table of the step against on-time (simulated once), so small strengths are not rounded away.

    Parameters
    ----------
    centers : (N, 2) array_like
        Centres of rotation [m]; ``N >= 2M`` (more is redundancy, used for the minimum-norm solution).
    cycle : float
        Longest plate motion [s].
    short : float
        On-time of each pulse [s] (attack and decay included).
    mu : float
        Friction of the parts (for calibrating the pulse's step and the rest after it).
    waveform, amplitude, frequency :
        Angular velocity of each rotation (default ``amplitude (cos wt - cos(2wt)/2)``).
    attack : float or None
        Rise and fall of each pulse [s] (default 1.5 periods).
    rcond, damping :
        Singular values below ``rcond * s_max`` dropped; Tikhonov ``damping`` (as in
        :func:`upm.solve_rotations`).

    limits : DriveLimits, optional
        The device's limits: the waveform's amplitude is lowered to what the drive plays about
        every centre within its motor force and stroke.

    Free step components (NaN) are left out of the linear system (4.10): a sort that only needs
    parts to move along x constrains M rows, not 2M, and the redundant centres go much further.
    """

    def __init__(
        self,
        centers: ArrayLike,
        *,
        cycle: float = 2.0,
        short: float = 0.1,
        mu: float = 0.3,
        waveform: Waveform | None = None,
        amplitude: float = 1.0,
        frequency: float = 35.0,
        attack: float | None = None,
        rcond: float | None = 1e-3,
        damping: float | None = None,
        limits: DriveLimits | None = None,
    ) -> None:
        self.centers = _centers(centers)
        self.limits = _limits(limits, None, None, 200.0)
        self.cycle = _positive("cycle", cycle)
        self.h = _harmonics(waveform, amplitude, frequency)
        period = 1.0 / float(self.h.frequency)
        self.attack = 1.5 * period if attack is None else float(attack)
        self.short = max(_positive("short", short), 2 * self.attack + period)
        self.f0 = float(mean_force(self.h, 0.0))
        if not self.f0 > 0:
            raise ParameterError(
                f"waveform must push resting parts forward (force at rest > 0); got {self.f0:.4g}"
            )
        self.rcond, self.damping = rcond, damping
        self.mu = _positive("mu", mu)
        self.rest = 0.0
        if self.limits is not None:  # the largest rotation the drive plays about every centre
            room = min(self.limits.headroom(self._pulse(c, 1.0)) for c in self.centers)
            if room < 1:
                self.h = Harmonics(self.h.cos * 0.95 * room, self.h.sin * 0.95 * room, float(self.h.frequency))
        self.step, self.rest = self._calibrate()
        # metres per (mu m g) of average force per cycle: a cycle full of pulses about one centre
        self.gain = self.step * self.cycle / (self.short + self.rest) / self.f0

    def _pulse(self, center: ArrayLike, sign: float, on: float | None = None) -> Pulse:
        on = self.short if on is None else on
        a = min(self.attack, on / 2)
        wave = self.h if sign > 0 else Harmonics(-self.h.cos, -self.h.sin, float(self.h.frequency))
        return Pulse.rotation(center, wave, a, on - 2 * a, a, self.rest)

    def _calibrate(self) -> tuple[float, float]:
        """Step of a pulse against its on-time (mean over parts 5 to 30 cm from the centre), the
        time the parts take to stop after the longest (+20%), and the full pulse's step against
        the distance from its centre (``self.radii``, ``self.by_radius``, relative to the mean)."""
        self.radii = np.geomspace(0.005, 1.0, 40)
        probe = Pulse.rotation((0.0, 0.0), self.h, self.attack, self.short - 2 * self.attack, self.attack)
        ring = PlateMotion.sequence([probe.motion(), PlateMotion.rest(self.short)])
        far = simulate_batch([ring], np.stack([self.radii, np.zeros_like(self.radii)], axis=1),
                             duration=ring.duration or 0.0, dt=1.0 / (200.0 * ring.max_frequency), mu=self.mu,
                             record_every=10**9)  # fmt: skip
        self.by_radius = far.positions[0, -1, :, 1]
        radii = np.linspace(0.05, 0.3, 6)
        parts = np.stack([radii, np.zeros_like(radii)], axis=1)
        period = 1.0 / float(self.h.frequency)
        self.on_times = np.append(np.arange(period, self.short, period / 4), self.short)
        motions = [
            PlateMotion.sequence(
                [self._pulse((0.0, 0.0), 1.0, t).motion(rest=False), PlateMotion.rest(self.short)]
            )
            for t in self.on_times
        ]
        dt = 1.0 / (200.0 * motions[0].max_frequency)
        run = simulate_batch(
            motions,
            parts,
            duration=max(m.duration or 0.0 for m in motions),
            dt=dt,
            mu=self.mu,
            record_every=max(1, int(1e-3 / dt)),
        )
        self.steps = np.maximum.accumulate(np.maximum(np.mean(run.positions[:, -1, :, 1], axis=1), 0.0))
        stop = stopping_time(run.t, run.stuck[-1], self.short)
        if not self.steps[-1] > 0:
            raise ParameterError("the waveform does not move parts forward; check its time asymmetry")
        self.by_radius = self.by_radius / self.steps[-1]
        return float(self.steps[-1]), 1.2 * stop + 2e-3

    def _split(self, strengths: FloatArray) -> tuple[NDArray[np.int64], FloatArray]:
        """Whole pulses of each rotation, and the on-time of its shorter last pulse (0: none)."""
        wanted = self.gain * np.abs(strengths) / len(self.centers)
        whole = np.floor(wanted / self.step).astype(np.int64)
        left = wanted - whole * self.step
        on = np.interp(left, self.steps, self.on_times)
        on[left < self.steps[0] / 2] = 0.0
        return whole, on

    def _time(self, strengths: FloatArray) -> float:
        whole, on = self._split(strengths)
        return float(whole.sum() * (self.short + self.rest) + np.sum(on + self.rest * (on > 0)))

    def _solve_some(self, pos: FloatArray, forces: FloatArray) -> FloatArray:
        """Strengths for the given (finite) force components: (4.10)'s rows ``A_ij = Phi_j(P_i)``
        (the unit rotation field), each scaled by what a pulse about ``C_j`` really does at
        ``|P_i - C_j|`` relative to the mean (from the calibration: less very near the centre),
        minimum norm by SVD (``rcond``), with Tikhonov ``damping``. The scaling matters because
        redundant centres cancel each other: a few per cent of model error on every rotation is
        larger than what is left of them."""
        n = len(self.centers)
        scale = np.interp(
            np.linalg.norm(pos[:, None] - self.centers[None], axis=2), self.radii, self.by_radius
        )
        field = np.stack([rotation_field(pos, c) for c in self.centers], axis=-1) * scale[:, None, :]
        given = np.isfinite(forces).reshape(-1)
        a = field.reshape(-1, n)[given]
        b = n * forces.reshape(-1)[given]
        if self.damping:
            a = np.vstack([a, self.damping * np.eye(n)])
            b = np.concatenate([b, np.zeros(n)])
        out: FloatArray = np.linalg.lstsq(a, b, rcond=self.rcond)[0]
        return out

    def plan(self, positions: FloatArray, steps: FloatArray) -> list[Pulse]:
        pos, st = np.asarray(positions, float), np.asarray(steps, float)
        if len(pos) == 0 or not np.any(np.nan_to_num(st)):
            return []
        st = _clear_of_centers(pos, st, self.centers, 0.01)
        rows = int(np.isfinite(st).sum())
        if rows > len(self.centers):
            raise ParameterError(
                f"{rows} constrained step components need at least as many centres of rotation; the planner "
                f"has {len(self.centers)}"
            )
        k = self._solve_some(pos, st / self.gain)
        order = rotation_order(k, pos, self.centers)
        # the solution is linear in the forces: scaling them scales k
        if self._time(k) > self.cycle:  # too much for one cycle: all forces down together
            lo, hi = 0.0, 1.0
            for _ in range(40):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if self._time(k * mid) <= self.cycle else (lo, mid)
            k = k * lo
        whole, on = self._split(k)
        counts = whole + (on > 0)
        out: list[Pulse] = []
        for turn in range(int(counts.max(initial=0))):  # round robin, in the plan's order
            for j in order:
                if whole[j] > turn:
                    out.append(self._pulse(self.centers[j], float(np.sign(k[j]))))
                elif whole[j] == turn and on[j] > 0:
                    out.append(self._pulse(self.centers[j], float(np.sign(k[j])), float(on[j])))
        return out


class DisplacementPlanner:
    """Chapter 5: arc lengths about the centres (:func:`upm.solve_displacements`), executed as
    shaped pulses sized against the exact integrator (:func:`upm.plan_pulses`).

    Parameters
    ----------
    centers : (N, 2) array_like
        Centres [m], ``N >= 2M``.
    mu, mu_s : float
        Friction of the parts (for sizing the pulses).
    max_arc : float or None
        Bound on every arc length [m] (the solution is scaled down to it).
    sustain : float
        Sustain of every pulse [s]; each pulse is sized by the waveform's amplitude
        (``intensity="amplitude"`` of :func:`upm.plan_pulses`), so steps can be as small as asked
        while the envelope stays long enough for motors to play it cleanly.
    refine : int
        Refinement iterations of the whole program (0: size each pulse alone).
    limits : DriveLimits, optional
        The device's limits (or the older ``plate``, ``axes`` and motor force ``limit`` [N], with
        the default stroke): the pulses' largest amplitude (20 times the base, the top of the
        sizing table) is what the drive can play about the most demanding centre, within force and
        stroke, and the base amplitude is set from it.
    """

    def __init__(
        self,
        centers: ArrayLike,
        *,
        plate: Plate | None = None,
        axes: Sequence[Axis] | None = None,
        limit: float = 200.0,
        mu: float = 0.3,
        mu_s: float | None = None,
        waveform: Waveform | None = None,
        amplitude: float = 1.0,
        frequency: float = 35.0,
        attack: float | None = None,
        max_arc: float | None = 0.025,
        sustain: float = 0.15,
        refine: int = 2,
        rcond: float | None = 1e-3,
        damping: float | None = None,
        limits: DriveLimits | None = None,
    ) -> None:
        self.centers = _centers(centers)
        self.limits = _limits(limits, plate, axes, limit)
        self.mu = _positive("mu", mu)
        self.mu_s = mu_s
        self.h = _harmonics(waveform, amplitude, frequency)
        self.attack = 3.0 / float(self.h.frequency) if attack is None else float(attack)
        self.max_arc, self.refine, self.rcond, self.damping = max_arc, refine, rcond, damping
        self.sustain = _positive("sustain", sustain)
        if self.limits is not None:
            room = min(
                self.limits.headroom(Pulse.rotation(c, self.h, self.attack, self.sustain, self.attack))
                for c in self.centers
            )
            top = 0.98 * room  # the largest playable multiple of h
            self.h = Harmonics(
                self.h.cos * top / AMPLITUDE_TOP, self.h.sin * top / AMPLITUDE_TOP, float(self.h.frequency)
            )

    def plan(self, positions: FloatArray, steps: FloatArray) -> list[Pulse]:
        pos, st = np.asarray(positions, float), np.nan_to_num(np.asarray(steps, float))  # free: stay
        if len(pos) == 0 or not np.any(st):
            return []
        st = _clear_of_centers(pos, st, self.centers, 0.01)
        if 2 * len(pos) > len(self.centers):
            raise ParameterError(
                f"{len(pos)} parts need at least {2 * len(pos)} centres; got {len(self.centers)}"
            )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RankWarning)
            plan = solve_displacements(pos, st, self.centers, rcond=self.rcond, damping=self.damping)
        biggest = float(np.max(np.abs(plan.strengths)))
        if self.max_arc is not None and biggest > self.max_arc:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RankWarning)
                plan = solve_displacements(
                    pos, st * (self.max_arc / biggest), self.centers, rcond=self.rcond, damping=self.damping
                )
        pulses: list[Pulse] = []
        for halvings in range(1, 6):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", PlanWarning)  # the loop measures and corrects the miss
                try:
                    pulses = plan_pulses(
                        plan,
                        self.h,
                        mu=self.mu,
                        mu_s=self.mu_s,
                        attack=self.attack,
                        refine=self.refine,
                        intensity="amplitude",
                        sustain=self.sustain,
                    )
                    break
                except ParameterError:  # an arc beyond what a pulse reaches: half the steps
                    plan = solve_displacements(
                        pos, st * 0.5**halvings, self.centers, rcond=self.rcond, damping=self.damping
                    )
        if not pulses:
            return []
        return trim_rests([p for p in pulses if p.kind != "rest"], pos, mu=self.mu, mu_s=self.mu_s)


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
        self.limits = _limits(limits, plate, axes, limit)
        self.mu = _positive("mu", mu)
        self.mu_s = mu_s
        self.amplitude = _positive("amplitude", amplitude)
        self.frequency = _positive("frequency", frequency)
        self.rho, self.max_rho = rho, _positive("max_rho", max_rho)
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


class FixedPlanner:
    """The same pulses every cycle, whatever the steps (an open-loop flow)."""

    def __init__(self, pulses: Sequence[Pulse]) -> None:
        self.pulses = list(pulses)
        if not all(isinstance(p, Pulse) for p in self.pulses):
            raise ParameterError("pulses must be upm.pulses.Pulse objects")

    def plan(self, positions: FloatArray, steps: FloatArray) -> list[Pulse]:
        return list(self.pulses)
