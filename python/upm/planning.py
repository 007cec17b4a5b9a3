"""From plans to executable plate motions (SPEC §5, §7; thesis 5.1.2, 5.2.3, 6.1).

* :func:`plan_to_motion` executes a :class:`~upm.RotationPlan` (average forces) or a
  :class:`~upm.DisplacementPlan` (small steps) as a sequence of time-asymmetric rotations about the
  plan's centres, in the plan's order.
* :func:`jet_plan` moves parts one at a time, round robin, each with a jet focused on it.

Time-asymmetric rotation: angular velocity ``w(t) = W (cos wt - cos(2wt)/2)`` gives every resting
part the same tangential force ``0.2386 mu m g`` whatever its distance from the centre (not too
near it). A pulse (raised-cosine attack, sustain ``S``, decay, then rest while the parts slide to a
stop) moves a part by about ``d ∝ S^2``; the sustain for each step is found by simulating the pulse
on one part with the exact integrator (``upm.simulate``) and solving for the requested step.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ._arrays import as_float
from ._errors import ConvergenceError, ParameterError, PlanWarning, ShapeError
from .feeding import mean_force
from .motion import PlateMotion
from .pulses import Pulse, program
from .sim import simulate, simulate_batch
from .solvers import DisplacementPlan, RotationPlan
from .waveforms import Harmonics, TwoHarmonic, Waveform

__all__ = [
    "jet_plan",
    "jet_pulses",
    "plan_pulses",
    "plan_to_motion",
    "sustain_for_displacement",
    "trim_rests",
]


def _harmonics(waveform: Waveform | None, amplitude: float, frequency: float) -> Harmonics:
    if waveform is None:
        _positive("amplitude", amplitude)
        _positive("frequency", frequency)
        return Harmonics([amplitude, -amplitude / 2], [0.0, 0.0], frequency)
    if isinstance(waveform, TwoHarmonic):
        waveform = waveform.to_harmonics()
    if not isinstance(waveform, Harmonics) or waveform.shape != ():
        raise ParameterError(
            "waveform must be a single upm.Harmonics or upm.TwoHarmonic (the angular velocity, rad/s); "
            f"got {waveform!r}"
        )
    return waveform


def _scaled(h: Harmonics, factor: float) -> Harmonics:
    return Harmonics(h.cos * factor, h.sin * factor, float(h.frequency))


def _positive(name: str, value: float) -> float:
    if not (isinstance(value, (int, float, np.floating, np.integer)) and math.isfinite(value) and value > 0):
        raise ParameterError(f"{name} must be finite and > 0; got {value!r}")
    return float(value)


def _solve_increasing(f: Callable[[float], float], target: float, x0: float, name: str) -> float:
    """``x > 0`` with ``f(x) = target`` for increasing ``f``: geometric bracketing, then Illinois
    false position on ``log x``, to 1e-4 relative."""
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
        hi *= 2
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


class _Probe:
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


def _envelope(x: float, rise: float) -> tuple[float, float, float]:
    """Attack, sustain, decay of a pulse of size ``x`` [s]: ``(rise, x - rise, rise)`` once
    ``x >= rise``, and ``(x, 0, x)`` below, so the pulse (and the step it gives) shrinks to zero."""
    return (rise, x - rise, rise) if x >= rise else (x, 0.0, x)


def _settle(pulse: float, mu: float, mu_s: float, rest: float | None) -> float:
    """Rest after a pulse of length ``pulse`` [s] long enough for every part to stop: friction
    accelerates a part by at most ``mu_s g`` during the pulse and brakes it by ``mu g`` after."""
    stop = 1.05 * pulse * mu_s / mu + 1e-3
    return stop if rest is None else max(float(rest), stop)


def plan_to_motion(
    plan: RotationPlan | DisplacementPlan,
    waveform: Waveform | None = None,
    **options: Any,
) -> PlateMotion:
    """The executable plate motion of a plan: :func:`plan_pulses` played one after another
    (same parameters)."""
    return program(plan_pulses(plan, waveform, **options))


def plan_pulses(
    plan: RotationPlan | DisplacementPlan,
    waveform: Waveform | None = None,
    *,
    amplitude: float = 2.0,
    frequency: float = 35.0,
    duration: float = 1.0,
    mu: float | None = None,
    mu_s: float | None = None,
    g: float = 9.81,
    attack: float | None = None,
    rest: float | None = None,
    intensity: str = "duration",
    sustain: float | None = None,
    refine: int = 12,
) -> list[Pulse]:
    """The pulses executing a plan: time-asymmetric rotations about its centres, in order.

    Parameters
    ----------
    plan : RotationPlan or DisplacementPlan
    waveform : Harmonics or TwoHarmonic, optional
        Angular velocity [rad/s] of one rotation; its time asymmetry sets the force direction
        (negated for negative strengths). Default ``amplitude (cos wt - cos(2wt)/2)`` at
        ``frequency`` [Hz].
    duration : float
        RotationPlan only: length of the program [s]. Rotation ``j`` runs for
        ``duration |k_j| / (N f0)`` rounded to whole drive periods (``f0`` = the waveform's force at
        rest / (mu m g), 0.2386 by default), so the plate returns home after each rotation and the
        program's average force at the parts is the plan's, to within one period per rotation; the
        remaining time is rest. Needs ``sum |k_j| <= N f0``: otherwise lengthen nothing, bound
        the plan with ``max_strength``. With ``attack`` the rotations are enveloped (attack, on
        time less one attack, attack: the same area), as motors need; by default they start and
        stop abruptly (an ideal plate).
    mu, mu_s, g : float
        DisplacementPlan only: friction of the parts and gravity, for sizing the pulses.
    attack : float
        Rise (= fall) time of each pulse [s] (DisplacementPlan: default one period; smaller steps
        shrink the whole pulse).
    rest : float
        DisplacementPlan only: rest after each pulse [s] (default: long enough for the fastest
        part to stop).
    intensity : "duration" or "amplitude"
        DisplacementPlan only: size each pulse by its sustain (``S ∝ sqrt(d)``) or, with a fixed
        ``sustain``, by the waveform's amplitude. A RotationPlan is always sized by duration: the
        force on a resting part depends on the sign of the plate velocity only (4.5), not its size.

    Returns
    -------
    list of Pulse
    """
    h = _harmonics(waveform, amplitude, frequency)
    if isinstance(plan, RotationPlan):
        if intensity != "duration":
            raise ParameterError(
                "intensity must be 'duration' for a RotationPlan: the average force on a resting part "
                "does not depend on the amplitude of the plate velocity, only on its sign (4.5)"
            )
        rise = None if attack is None else _positive("attack", attack)
        return _force_program(plan, h, _positive("duration", duration), rise)
    if isinstance(plan, DisplacementPlan):
        if mu is None:
            raise ParameterError("mu is required to size the pulses of a DisplacementPlan")
        mu_f = _positive("mu", mu)
        mu_s_f = mu_f if mu_s is None else float(mu_s)
        if intensity not in ("duration", "amplitude"):
            raise ParameterError(f"intensity must be 'duration' or 'amplitude'; got {intensity!r}")
        if isinstance(refine, bool) or not isinstance(refine, int) or refine < 0:
            raise ParameterError(f"refine must be an integer >= 0; got {refine!r}")
        return _pulse_program(
            plan, h, mu_f, mu_s_f, _positive("g", g), attack, rest, intensity, sustain, refine
        )
    raise ParameterError(f"plan must be a RotationPlan or a DisplacementPlan; got {type(plan).__name__}")


def _force_program(plan: RotationPlan, h: Harmonics, duration: float, rise: float | None) -> list[Pulse]:
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
        wave = h if k[j] > 0 else _scaled(h, -1.0)
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


def _pulse_program(
    plan: DisplacementPlan,
    h: Harmonics,
    mu: float,
    mu_s: float,
    g: float,
    attack: float | None,
    rest: float | None,
    intensity: str,
    sustain: float | None,
    refine: int,
) -> list[Pulse]:
    d = np.array(plan.strengths, dtype=np.float64)
    if d.ndim != 1:
        raise ShapeError("plan must be a single plan, not a batch")
    period = 1.0 / float(h.frequency)
    rise = period if attack is None else _positive("attack", attack)
    hold = _positive("sustain", 4 * period if sustain is None else sustain)
    parts, centers = plan.parts, plan.centers
    m, n = parts.shape[0], centers.shape[0]
    targets = np.concatenate([plan.predicted_steps[:, 0], plan.predicted_steps[:, 1]])
    biggest = float(np.max(np.abs(d))) if n else 0.0
    if biggest == 0.0:
        return [Pulse.pause(period)]
    kappa = 0.5 * 0.2386 * mu * g * 1.2386  # step ≈ kappa * on-time^2 for slow parts
    tables = [
        _PulseTable(centers[j], parts, h, rise, hold, intensity, mu, mu_s, g, rest, kappa, biggest, period)
        for j in range(n)
    ]
    # Each pulse is sized for its arc length at the median radius; what it does to every part
    # (not just the first-order tangential step) is measured. Secant iterations then correct the
    # arc lengths by minimum-norm changes until the measured steps add up to the plan's, with
    # backtracking so a poorly conditioned layout cannot make it worse than the plan.
    # A pulse cannot be shorter than a fraction of a period, so arc lengths have a floor. The
    # minimum-norm plan spreads small steps thinly over many centres: drop the centre furthest
    # below its floor and re-solve on the rest until every arc length can be executed.
    floor = np.array([t.smallest for t in tables])
    tangential = np.stack([np.concatenate(_columns(parts, c)) for c in centers], axis=1)
    active = np.arange(n)
    while np.any(np.abs(d[active]) < floor[active]):
        worst = active[np.argmin(np.abs(d[active]) / floor[active])]
        active = active[active != worst]
        if active.size < 2 * m:
            raise ParameterError(
                f"the steps are too small for pulses at {float(h.frequency):g} Hz: a pulse about a centre "
                f"moves parts at least about {float(np.median(floor)):.2g} m; raise the frequency "
                "(steps scale as 1/frequency^2), lower mu, or ask for larger steps"
            )
        d[:] = 0.0
        d[active] = np.linalg.lstsq(tangential[:, active], targets, rcond=None)[0]

    def measured(arcs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        effect = np.zeros((2 * m, active.size))
        for k, j in enumerate(active):
            size = max(abs(arcs[j]), floor[j])
            effect[:, k] = tables[j].steps(size) / size
        sizes = np.maximum(np.abs(arcs[active]), floor[active]) * np.sign(arcs[active])
        return effect @ sizes, effect

    total, effect = measured(d)
    error = float(np.linalg.norm(total - targets))
    for _ in range(8):
        change = np.linalg.lstsq(effect, targets - total, rcond=None)[0]
        for _ in range(6):
            trial = d.copy()
            trial[active] += change
            try:
                t_total, t_effect = measured(trial)
            except ParameterError:  # beyond the largest tabulated pulse: a shorter change
                t_error = math.inf
            else:
                t_error = float(np.linalg.norm(t_total - targets))
            if t_error < error:
                break
            change = change / 2
        else:
            break
        d, total, effect, error = trial, t_total, t_effect, t_error
        if error <= 1e-3 * np.linalg.norm(targets):
            break

    def pulses(arcs: np.ndarray) -> list[Pulse]:
        items = [
            tables[j].pulse(max(abs(arcs[j]), floor[j]), np.sign(arcs[j]))
            for j in plan.order
            if j in active and arcs[j] != 0.0
        ]
        return items or [Pulse.pause(period)]

    if not refine:
        return pulses(d)

    # Refinement on the whole program: pulses follow one another, so each one starts from where
    # the previous ones left the parts (the second-order error of 5.4.4). Simulate the program with
    # the exact integrator and correct the arc lengths by the measured miss, with the single-pulse
    # effects as the Jacobian, while the miss shrinks.
    def miss(arcs: np.ndarray) -> np.ndarray:
        motion = program(pulses(arcs))
        duration = motion.duration or period
        dt = 1.0 / (200.0 * motion.max_frequency) if motion.max_frequency > 0 else duration / 10
        run = simulate(motion, parts, duration=duration, dt=dt, mu=mu, mu_s=mu_s, g=g,
                       record_every=max(1, int(duration / dt)))  # fmt: skip
        moved = run.positions[-1] - parts
        out: np.ndarray = targets - np.concatenate([moved[:, 0], moved[:, 1]])
        return out

    residual = miss(d)
    for _ in range(refine):
        if np.linalg.norm(residual) <= 1e-3 * np.linalg.norm(targets):
            break
        change = np.linalg.lstsq(effect, residual, rcond=None)[0]
        for _ in range(5):
            trial = d.copy()
            trial[active] += change
            try:
                measured(trial)  # in the table's range
                t_residual = miss(trial)
            except ParameterError:
                t_residual = np.full_like(residual, np.inf)
            if np.linalg.norm(t_residual) < np.linalg.norm(residual):
                break
            change = change / 2
        else:
            break
        # Broyden's update: the Jacobian learns what the step really did.
        seen = residual - t_residual
        effect = effect + np.outer(seen - effect @ change, change) / (change @ change)
        d, residual = trial, t_residual
    miss_rel = float(np.linalg.norm(residual) / np.linalg.norm(targets))
    if miss_rel > 0.1:
        warnings.warn(
            f"the program misses the plan's steps by {100 * miss_rel:.0f}% (simulated): the layout is "
            f"poorly conditioned (condition number {plan.condition_number:.3g}) or the steps too large "
            "for sequential rotations; use smaller steps in a closed loop, redundant centres or damping",
            PlanWarning,
            stacklevel=3,
        )
    return pulses(d)


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
    mu_f = _positive("mu", mu)
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


def _columns(parts: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x and y components of the unit tangential field of ``c`` at the parts."""
    r = parts - c
    n = np.hypot(r[:, 0], r[:, 1])
    return -r[:, 1] / n, r[:, 0] / n


#: The largest multiple of the waveform's amplitude in the sizing table of ``intensity="amplitude"``.
AMPLITUDE_TOP = 20.0


class _PulseTable:
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
        longest += _settle(longest, mu, mu_s, rest)
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
        return replace(p, rest=_settle(p.on_time, self.mu, self.mu_s, self.rest))

    def motion(self, x: float, sign: float) -> PlateMotion:
        return self.shape(x, sign, knob=True).motion()

    def shape(self, d: float, sign: float, knob: bool = False) -> Pulse:
        x = d if knob else self.knob(d)
        if self.intensity == "duration":
            wave = self.h if sign > 0 else _scaled(self.h, -1.0)
            return Pulse.rotation(self.c, wave, *_envelope(x, self.rise))
        return Pulse.rotation(self.c, _scaled(self.h, sign * x), self.rise, self.hold, self.rise)


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
    feel the jet's small far field only (SPEC §7).

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
    mu_f = _positive("mu", mu)
    mu_s_f = mu_f if mu_s is None else float(mu_s)
    _positive("amplitude", amplitude)
    _positive("frequency", frequency)
    if rho is None:
        gaps = np.hypot(*(p[:, None, :] - p[None, :, :]).transpose(2, 0, 1))
        gaps[np.diag_indices(len(p))] = np.inf
        rho = 0.05 if len(p) < 2 else float(gaps.min()) / 4
        if not rho > 0:
            raise ParameterError("parts must be distinct to size the jets (two share a position)")
    rho = _positive("rho", rho)
    period = 3.0 / frequency  # the jet's period, 6 pi / w
    rise = period if attack is None else _positive("attack", attack)
    items: list[Pulse] = []
    sequence = range(len(p)) if order is None else [int(i) for i in np.asarray(order).reshape(-1)]
    if any(not 0 <= i < len(p) for i in sequence):
        raise ParameterError(f"order must list part indices in 0..{len(p) - 1}; got {list(sequence)}")
    for i in sequence:
        length = float(np.hypot(*s[i]))
        if length <= min_step:
            continue
        axis = s[i] / length
        probe = _Probe(p[i], axis, mu_f, mu_s_f, g)

        def pulse(x: float, i: int = i, axis: np.ndarray = axis) -> Pulse:
            shape = _envelope(x, rise)
            after = _settle(sum(shape), mu_f, mu_s_f, rest)
            return Pulse.jet(p[i], axis, rho, amplitude, frequency, *shape, rest=after)

        def step(x: float, pulse: Callable[[float], Pulse] = pulse, probe: _Probe = probe) -> float:
            return probe(pulse(x).motion())

        items.append(pulse(_solve_increasing(step, length, period, "sustain")))
    return items or [Pulse.pause(period)]


def sustain_for_displacement(
    d: float,
    *,
    radius: float,
    mu: float,
    mu_s: float | None = None,
    g: float = 9.81,
    waveform: Waveform | None = None,
    amplitude: float = 2.0,
    frequency: float = 35.0,
    attack: float | None = None,
) -> float:
    """Sustain [s] of a rotation pulse that moves a part by arc length ``d`` [m] (5.2.3).

    The pulse is ``waveform`` (default ``amplitude (cos wt - cos(2wt)/2)`` [rad/s] at
    ``frequency``) about a centre, under a raised-cosine envelope ``(attack, S, attack)`` (attack
    default one period), followed by rest; the part rests at ``radius`` [m] from the centre. While
    the part is slow next to the plate the step grows as ``S^2`` (so ``S ∝ sqrt(d)``); the sustain
    is solved against the exact integrator (time step 1/200 of the highest frequency's period),
    coast after the pulse included, so it stays right beyond that regime. `ParameterError` when
    even a pulse without sustain moves the part further.
    """
    h = _harmonics(waveform, amplitude, frequency)
    target = _positive("d", d)
    r = _positive("radius", radius)
    mu_f = _positive("mu", mu)
    mu_s_f = mu_f if mu_s is None else float(mu_s)
    period = 1.0 / float(h.frequency)
    rise = period if attack is None else _positive("attack", attack)
    probe = _Probe(np.array([r, 0.0]), np.array([0.0, 1.0]), mu_f, mu_s_f, _positive("g", g))

    def step(sustain: float) -> float:
        pulse = PlateMotion.rotation((0.0, 0.0), h).with_envelope(rise, sustain, rise)
        rest = _settle(pulse.duration or 0.0, mu_f, mu_s_f, None)
        return probe(PlateMotion.sequence([pulse, PlateMotion.rest(rest)]))

    shortest = step(0.0)
    if target <= shortest:
        raise ParameterError(
            f"d = {target:.3g} m is below what the attack and decay alone give ({shortest:.3g} m): "
            "shorten the attack or raise the frequency"
        )
    return _solve_increasing(step, target, 4 * period, "sustain")
