"""Chapter 4: sequencing rotations. Average forces from rotations about fixed centres.

* :func:`rotation_pulses`: a :class:`~upm.RotationPlan` (strengths from (4.10)) as
  time-asymmetric rotations of whole drive periods in the plan's order (what
  :func:`upm.plan_pulses` plays for a rotation plan).
* :class:`RotationsPlanner`: the closed-loop planner: steps read as average forces, strengths by
  SVD each cycle, played as repeated short pulses.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._errors import ParameterError, ShapeError
from ..physics.feeding import mean_force
from ..physics.fields import rotation_field
from ..physics.motion import PlateMotion
from ..physics.sim import simulate_batch
from ..physics.waveforms import Harmonics, Waveform
from ..plate.drive import DriveLimits
from ..plate.pulses import Pulse
from .sizing import as_centers, clear_of_centers, drive_limits, harmonics_of, positive, scaled, stopping_time
from .solvers import RotationPlan, rotation_order

__all__ = ["RotationsPlanner", "rotation_pulses"]

FloatArray = NDArray[np.float64]


def rotation_pulses(plan: RotationPlan, h: Harmonics, duration: float, rise: float | None) -> list[Pulse]:
    if np.ndim(plan.strengths) != 1:
        raise ShapeError("plan must be a single plan, not a batch")
    k = plan.strengths
    n = k.size
    f0 = float(mean_force(h, 0.0))
    if not f0 > 0:
        raise ParameterError(f"waveform must push resting parts forward (force at rest > 0); got {f0:.4g}")
    period = 1.0 / float(h.frequency)
    fractions = np.abs(k) / (n * f0)
    if fractions.sum() > 1.0 + 1e-12:
        raise ParameterError(
            f"the plan needs rotations for {fractions.sum():.3g} x duration: its strengths sum to "
            f"{np.abs(k).sum():.3g} > N f0 = {n * f0:.3g}; solve with max_strength <= {f0:.4g}"
        )
    periods = np.rint(fractions * duration / period).astype(int)
    items: list[Pulse] = []
    for j in plan.order:
        if periods[j] == 0:
            continue
        wave = h if k[j] > 0 else scaled(h, -1.0)
        on = periods[j] * period
        a = 0.0 if rise is None else min(rise, on / 2)
        items.append(Pulse.rotation(plan.centers[j], wave, a, on - a, a))
    used = float(periods.sum()) * period
    rest = max(duration - used, 0.0 if items else period)
    if rest > 1e-12 * duration:
        if items:
            items[-1] = replace(items[-1], rest=rest)
        else:
            items.append(Pulse.pause(rest))
    return items


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
        self.centers = as_centers(centers)
        self.limits = drive_limits(limits, None, None, 200.0)
        self.cycle = positive("cycle", cycle)
        self.h = harmonics_of(waveform, amplitude, frequency)
        period = 1.0 / float(self.h.frequency)
        self.attack = 1.5 * period if attack is None else float(attack)
        self.short = max(positive("short", short), 2 * self.attack + period)
        self.f0 = float(mean_force(self.h, 0.0))
        if not self.f0 > 0:
            raise ParameterError(
                f"waveform must push resting parts forward (force at rest > 0); got {self.f0:.4g}"
            )
        self.rcond, self.damping = rcond, damping
        self.mu = positive("mu", mu)
        self.rest = 0.0
        if self.limits is not None:  # the largest rotation the drive plays about every centre
            room = min(self.limits.headroom(self._pulse(c, 1.0)) for c in self.centers)
            if room < 1:
                self.h = Harmonics(
                    self.h.cos * 0.95 * room, self.h.sin * 0.95 * room, float(self.h.frequency)
                )
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
        st = clear_of_centers(pos, st, self.centers, 0.01)
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
