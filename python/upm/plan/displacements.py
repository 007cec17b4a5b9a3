"""Chapter 5: displacement fields and pulses. Small steps of the parts as arc lengths about centres.

* :func:`plan_pulses` / :func:`plan_to_motion`: a :class:`~upm.DisplacementPlan` (or a
  :class:`~upm.RotationPlan`, through :func:`~upm.plan.rotations.rotation_pulses`) as shaped
  pulses, each sized against the exact integrator and refined on the whole program;
  :func:`sustain_for_displacement`: one pulse's sustain for one step.
* :class:`DisplacementPlanner`: the closed-loop planner of 5.2.5.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._errors import ParameterError, PlanWarning, RankWarning, ShapeError
from ..physics.motion import PlateMotion
from ..physics.sim import simulate
from ..physics.waveforms import Harmonics, Waveform
from ..plate.actuation import Axis, Plate
from ..plate.drive import DriveLimits
from ..plate.pulses import Pulse, program
from .rotations import rotation_pulses
from .sizing import (
    AMPLITUDE_TOP,
    Probe,
    PulseTable,
    as_centers,
    clear_of_centers,
    drive_limits,
    friction,
    harmonics_of,
    positive,
    settle_time,
    solve_increasing,
    tangential_columns,
    trim_rests,
)
from .solvers import DisplacementPlan, RotationPlan, solve_displacements

__all__ = ["DisplacementPlanner", "plan_pulses", "plan_to_motion", "sustain_for_displacement"]

FloatArray = NDArray[np.float64]


#: The largest simulated miss of a program, as a fraction of its steps, that
#: :class:`DisplacementPlanner` plays; beyond it the steps are halved (a miss over half the step
#: can carry a part away from its goal).
MAX_MISS = 0.5


def program_steps(pulses: list[Pulse], parts: FloatArray, mu: float, mu_s: float | None,
                  g: float = 9.81) -> FloatArray:  # fmt: skip
    """The steps ``(M, 2)`` [m] that ``pulses`` played one after another give point ``parts`` on
    an ideal plate (the exact integrator at 1/200 of the highest frequency's period)."""
    motion = program(pulses)
    duration = float(motion.duration or 0.0)  # a program of pulses ends
    if duration <= 0:
        return np.zeros_like(parts)
    dt = 1.0 / (200.0 * motion.max_frequency) if motion.max_frequency > 0 else duration / 10
    run = simulate(motion, parts, duration=duration, dt=dt, mu=mu, mu_s=mu_s, g=g,
                   record_every=max(1, int(duration / dt)))  # fmt: skip
    return np.asarray(run.positions[-1] - parts, dtype=np.float64)


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
    h = harmonics_of(waveform, amplitude, frequency)
    if isinstance(plan, RotationPlan):
        if intensity != "duration":
            raise ParameterError(
                "intensity must be 'duration' for a RotationPlan: the average force on a resting part "
                "does not depend on the amplitude of the plate velocity, only on its sign (4.5)"
            )
        rise = None if attack is None else positive("attack", attack)
        return rotation_pulses(plan, h, positive("duration", duration), rise)
    if isinstance(plan, DisplacementPlan):
        if mu is None:
            raise ParameterError("mu is required to size the pulses of a DisplacementPlan")
        mu_f = positive("mu", mu)
        mu_s_f = mu_f if mu_s is None else float(mu_s)
        if intensity not in ("duration", "amplitude"):
            raise ParameterError(f"intensity must be 'duration' or 'amplitude'; got {intensity!r}")
        if isinstance(refine, bool) or not isinstance(refine, int) or refine < 0:
            raise ParameterError(f"refine must be an integer >= 0; got {refine!r}")
        return _pulse_program(
            plan, h, mu_f, mu_s_f, positive("g", g), attack, rest, intensity, sustain, refine
        )[0]
    raise ParameterError(f"plan must be a RotationPlan or a DisplacementPlan; got {type(plan).__name__}")


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
) -> tuple[list[Pulse], float | None]:
    """The pulses of a DisplacementPlan (:func:`plan_pulses`) and, when refined, how far their
    simulated steps miss the plan's, as a fraction of its steps."""
    d = np.array(plan.strengths, dtype=np.float64)
    if d.ndim != 1:
        raise ShapeError("plan must be a single plan, not a batch")
    period = 1.0 / float(h.frequency)
    rise = period if attack is None else positive("attack", attack)
    hold = positive("sustain", 4 * period if sustain is None else sustain)
    parts, centers = plan.parts, plan.centers
    m, n = parts.shape[0], centers.shape[0]
    targets = np.concatenate([plan.predicted_steps[:, 0], plan.predicted_steps[:, 1]])
    biggest = float(np.max(np.abs(d))) if n else 0.0
    if biggest == 0.0:
        return [Pulse.pause(period)], 0.0
    kappa = 0.5 * 0.2386 * mu * g * 1.2386  # step ≈ kappa * on-time^2 for slow parts
    tables = [
        PulseTable(centers[j], parts, h, rise, hold, intensity, mu, mu_s, g, rest, kappa, biggest, period)
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
    tangential = np.stack([np.concatenate(tangential_columns(parts, c)) for c in centers], axis=1)
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
        return pulses(d), None

    # Refinement on the whole program: pulses follow one another, so each one starts from where
    # the previous ones left the parts (the second-order error of 5.4.4). Simulate the program with
    # the exact integrator and correct the arc lengths by the measured miss, with the single-pulse
    # effects as the Jacobian, while the miss shrinks.
    def miss(arcs: np.ndarray) -> np.ndarray:
        moved = program_steps(pulses(arcs), parts, mu, mu_s, g)
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
    return pulses(d), miss_rel


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
    h = harmonics_of(waveform, amplitude, frequency)
    target = positive("d", d)
    r = positive("radius", radius)
    if target > math.pi * r:
        raise ParameterError(
            f"d must be at most half a turn about the centre, pi * radius = {math.pi * r:.3g} m; got "
            f"{target:.3g} m: split the displacement into several pulses"
        )
    mu_f, mu_s_f = friction(mu, mu_s)
    period = 1.0 / float(h.frequency)
    rise = period if attack is None else positive("attack", attack)
    probe = Probe(np.array([r, 0.0]), np.array([0.0, 1.0]), mu_f, mu_s_f, positive("g", g))

    def step(sustain: float) -> float:
        pulse = PlateMotion.rotation((0.0, 0.0), h).with_envelope(rise, sustain, rise)
        rest = settle_time(pulse.duration or 0.0, mu_f, mu_s_f, None)
        return probe(PlateMotion.sequence([pulse, PlateMotion.rest(rest)]))

    shortest = step(0.0)
    if target <= shortest:
        raise ParameterError(
            f"d = {target:.3g} m is below what the attack and decay alone give ({shortest:.3g} m): "
            "shorten the attack or raise the frequency"
        )
    return solve_increasing(step, target, 4 * period, "sustain")


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
        self.centers = as_centers(centers)
        self.limits = drive_limits(limits, plate, axes, limit)
        self.mu = positive("mu", mu)
        self.mu_s = mu_s
        self.h = harmonics_of(waveform, amplitude, frequency)
        self.attack = 3.0 / float(self.h.frequency) if attack is None else float(attack)
        self.max_arc, self.refine, self.rcond, self.damping = max_arc, refine, rcond, damping
        self.sustain = positive("sustain", sustain)
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
        st = clear_of_centers(pos, st, self.centers, 0.01)
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
        mu_s = self.mu if self.mu_s is None else float(self.mu_s)
        for halvings in range(1, 6):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", PlanWarning)  # the miss is weighed below
                try:
                    pulses, miss = _pulse_program(plan, self.h, self.mu, mu_s, 9.81, self.attack, None,
                                                  "amplitude", self.sustain, self.refine)  # fmt: skip
                except ParameterError:  # an arc beyond what a pulse reaches: half the steps
                    pulses, miss = [], None
            if pulses and miss is None:  # not refined: simulated here
                asked = plan.predicted_steps
                size = float(np.linalg.norm(asked))
                moved = program_steps(pulses, pos, self.mu, mu_s)
                miss = float(np.linalg.norm(moved - asked)) / size if size > 0 else 0.0
            if pulses and (halvings == 5 or (miss is not None and miss <= MAX_MISS)):
                break
            # a program that misses its steps by more than half (simulated: large steps in
            # different directions, sequential rotations far from linear) carries the parts
            # elsewhere, away from their goals; half the steps, as the thesis's closed loop does
            pulses = []
            plan = solve_displacements(
                pos, st * 0.5**halvings, self.centers, rcond=self.rcond, damping=self.damping
            )
        if not pulses:
            return []
        return trim_rests([p for p in pulses if p.kind != "rest"], pos, mu=self.mu, mu_s=self.mu_s)
