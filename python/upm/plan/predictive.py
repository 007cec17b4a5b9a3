"""Receding-horizon planning on the batched simulator: every cycle, one pulse, the best predicted.

Each cycle :class:`PredictivePlanner`

1. builds a few hundred candidate pulses at the drive's force and stroke limits
   (:func:`upm.plan.candidates.generate`: translations, rotations about a grid and about each
   part, rotations about the centres that serve the task best by a quick model
   (:func:`~upm.plan.candidates.aligned_centers`), jets at each part; several frequencies and
   on-times);
2. predicts them all from the tracked positions in batched :func:`upm.simulate_batch` calls (one
   per on-time and frequency; point parts, a coarse step, while the plate moves; then each part
   slides to rest in closed form), each part's predicted step scaled by its learnt gain;
3. scores each by the task's own cost (``task.cost(state, positions, elapsed)``) against resting
   for as long, plus penalties for parts leaving the plate's usable area and for overlapping
   parts, per second of plate time (the pulse and the rest while the parts stop); the best few
   also as the first of two pulses, each followed by the best of the one-step favourites predicted
   from where it leaves the parts (all those layouts in one batched call), and as the first of a
   pulse and a long one from displacement tables (:class:`~upm.plan.macros.MacroTable`);
4. re-ranks the best few with disks that collide (rapier2d) at a finer step, and plays the best
   (expected as the board plays it, :mod:`upm.plan.played`); none when no gain reaches ``min_gain``.

On the next cycle it compares the predicted and achieved steps (:attr:`step_errors`), fits the
friction coefficient that best explains the last pulse (one batched call over candidate values,
damped update), and a per-part gain on the predicted step. So a plate whose friction differs
from the planner's by tens of per cent still works.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any, Protocol, cast

import numpy as np
from numpy.typing import NDArray

from .._errors import ParameterError
from ..physics.motion import PlateMotion
from ..physics.sim import Disk, simulate_batch
from ..plate.drive import DriveLimits, drive_frequency
from ..plate.pulses import Pulse
from .aim import aimed, descent
from .candidates import Candidates, aligned_centers, generate, narrow_radii
from .fitting import learn, restarted
from .goals import PositionsView, StepsGoal
from .lookahead import pair_rates, pair_sizes, two_step
from .macros import MacroTable
from .penalties import penalty
from .played import as_played
from .sizing import positive as _positive
from .sizing import separate, slide_to_rest

__all__ = ["SHORTLIST", "PredictivePlanner"]

#: Candidates of a plan made ahead that :meth:`PredictivePlanner.revise` scores again.
SHORTLIST = 32

#: When no candidate gains, the search is made once more with the edge band's weight times this,
#: the guard and the loss at full price (sort32 seed 3 idled 500 cycles with a chip 0.7 mm short:
#: every nudge of it also nudged a part in the band outward, at five times the task's price).
RELAXED = 0.3

FloatArray = NDArray[np.float64]


class _CostTask(Protocol):
    def cost(self, state: Any, positions: FloatArray | None = None, elapsed: Any = 0.0) -> Any: ...


class PredictivePlanner:
    """Sampling receding-horizon planner on the batched simulator (see the module docstring).

    Parameters
    ----------
    limits : DriveLimits
        The device's plate, motors and stroke (``device.limits``); every candidate is sized
        within them.
    mu, mu_s : float
        The planner's friction estimate (adapted online when ``adapt``).
    part_radius : float or None
        Parts are disks of this radius [m]: overlaps are penalised, and the best ``rerank``
        candidates are predicted again with contacts (rapier2d).
    drive : bool
        A pulse planned afresh is expected where the board's drive puts the parts (it envelopes
        the motors' forces: :func:`~upm.plan.played.drive_shift`): the tracker's guide and the
        start of a plan made ahead (a kept plan's expectation is the model's own, restarted).
    frequencies, on_times : tuple of float
        Drive frequencies [Hz] and on-times [s] of the candidates.
    use : float
        Fraction of the force and stroke headroom a candidate may use.
    edge : float
        Parts predicted closer than this to a plate edge [m] are penalised; beyond the edge a part
        counts as lost (``lost_cost`` [m of task cost]), and within ``guard`` [m] of it as half
        lost besides its depth: a pulse predicted to leave a part at the very edge may drop it,
        while a part already there is worth bringing back (12 mm: sort32 seed 1 lost a chip left
        10 mm from the edge, outside an 8 mm guard, to a pulse 10 mm off).
    spread : float
        A prediction's error grows with the way a part travels: a part predicted to move ``d``
        is scored by the edge penalty where it would be ``spread * d`` further toward the
        nearer edge on each axis (its worst case).
    edge_weight : float
        The penalty per metre a part is predicted inside that band [m of cost per m]; the band's
        outer half counts five times more (a steep one stalls the end of a sort whose sorted
        parts lie along the edge); :data:`RELAXED` when nothing gains.
    min_gain : float
        No pulse when the best predicted cost decrease is below this [m].
    adapt : bool
        Fit friction and per-part gains online from predicted against achieved steps.
    dt_factor : int
        Integrator steps per period of the highest harmonic when ranking (re-ranking uses twice).
    grid, jet_radii :
        Rotation centres on a ``grid x grid`` lattice over the plate's middle half and its middle
        lines; jet radii [m].
    narrow : bool
        With ``part_radius``, jets at a part whose nearest neighbour is closer than the smallest
        of ``jet_radii`` also at that distance (:func:`~upm.plan.candidates.narrow_radii`): they
        move the part while the neighbour holds (the last millimetres of a shape).
    lookahead : float or None
        On-time [s] of the long pulses (:class:`~upm.plan.macros.MacroTable`) each candidate is
        also scored with as a second step; ``None``: one step only.
    pairs : (int, int) or None
        Two-pulse search: the ``pairs[0]`` best candidates each followed by the best of the
        ``pairs[1]`` best one-step candidates from where the first leaves the parts (gain per
        second over both); the first of the best pair is played. ``None``: off.
    aligned : int
        Rotations about this many centres picked each cycle for the task by a quick model
        (:func:`~upm.plan.candidates.aligned_centers`), each at on-times 0.2 and 0.4 s: pulses
        that move many parts toward their goals at once. 0: none.
    learn_tilt : bool
        Also learn the plate's slope on line (:attr:`tilt_estimate`, :func:`.fitting.fit_tilt`;
        with ``adapt``). Off: half a degree off level it helped goto6 but lost a sort8 chip.
    focus : int or None
        Pulses at parts (rotations about a part, jets at it) only for this many parts a cycle,
        those whose cost falls most steeply as they move; ``None``: at every part. Keeps a
        cycle's candidates as many for 100 parts as for 16.
    """

    def __init__(
        self,
        limits: DriveLimits,
        *,
        mu: float = 0.3,
        mu_s: float | None = None,
        part_radius: float | None = None,
        drive: bool = True,
        frequencies: Sequence[float] = (25.0, 35.0, 50.0, 70.0),
        on_times: Sequence[float] = (0.2, 0.4, 0.8),
        use: float = 0.9,
        edge: float = 0.035,
        guard: float = 0.012,
        edge_weight: float = 1.0,
        spread: float = 0.15,
        lost_cost: float = 10.0,
        min_gain: float = 1e-4,
        rerank: int = 4,
        adapt: bool = True,
        dt_factor: int = 24,
        grid: int = 5,
        jet_radii: Sequence[float] = (0.04, 0.08, 0.12),
        narrow: bool = True,
        lookahead: float | None = 1.0,
        pairs: tuple[int, int] | None = (16, 100),
        aligned: int = 16,
        focus: int | None = 16,
        learn_tilt: bool = False,
    ) -> None:
        if not isinstance(limits, DriveLimits):
            raise ParameterError(f"limits must be a upm.DriveLimits; got {type(limits).__name__}")
        self.limits = limits
        self.mu = _positive("mu", mu)
        self.mu_s = None if mu_s is None else _positive("mu_s", mu_s)
        self.part_radius = None if part_radius is None else _positive("part_radius", part_radius)
        self.frequencies = tuple(drive_frequency("frequencies", f) for f in frequencies)
        self.on_times = tuple(_positive("on_times", t) for t in on_times)
        if not self.frequencies or not self.on_times:
            raise ParameterError("frequencies and on_times must each hold at least one value")
        if not 0 < use <= 1:
            raise ParameterError(f"use must be in (0, 1]; got {use!r}")
        self.use = float(use)
        named = (
            ("edge", edge),
            ("edge_weight", edge_weight),
            ("lost_cost", lost_cost),
            ("min_gain", min_gain),
        )
        for name, value in named:
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ParameterError(f"{name} must be finite and >= 0; got {value!r}")
        for name, count in (("rerank", rerank), ("aligned", aligned)):
            if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
                raise ParameterError(f"{name} must be an integer >= 0; got {count!r}")
        self.aligned = int(aligned)
        if focus is not None and (
            isinstance(focus, bool) or not isinstance(focus, (int, np.integer)) or focus < 1
        ):
            raise ParameterError(f"focus must be None or an integer >= 1; got {focus!r}")
        self.focus = None if focus is None else int(focus)
        self.edge = float(edge)
        if not (isinstance(guard, (int, float)) and 0 <= guard < self.edge):
            raise ParameterError(f"guard must be >= 0 and below edge ({self.edge:g} m); got {guard!r}")
        self.guard = float(guard)
        self.edge_weight = float(edge_weight)
        if not (isinstance(spread, (int, float)) and 0 <= spread <= 1):
            raise ParameterError(f"spread must be in [0, 1]; got {spread!r}")
        self.spread = float(spread)
        self.lost_cost = float(lost_cost)
        self.min_gain = float(min_gain)
        self.rerank = int(rerank)
        self.adapt = bool(adapt)
        if dt_factor < 20:
            raise ParameterError(f"dt_factor must be >= 20 (the integrator's bound); got {dt_factor}")
        self.dt_factor = int(dt_factor)
        self.grid = int(grid)
        self.jet_radii = tuple(_positive("jet_radii", r) for r in jet_radii)
        self.narrow, self.drive = bool(narrow), bool(drive)
        self.mu_estimate = self.mu
        self.pairs = None if pairs is None else pair_sizes(pairs)
        self.macros = (
            None if lookahead is None else MacroTable(limits, mu=self.mu, mu_s=mu_s, on_time=lookahead)
        )
        self.gains: dict[int, float] = {}
        self.learn_tilt = bool(learn_tilt)
        self.tilt_estimate = (0.0, 0.0)
        """The plate's slope [rad] along x and y as the parts' drift shows it (learnt on line with
        ``learn_tilt`` and ``adapt``: :func:`.fitting.fit_tilt`; or set it when known); every
        prediction carries it (not the look-ahead's long pulses)."""
        self.headroom = 1.0
        """Share of ``use`` the candidates take: lowered each time the device refuses a pulse as
        beyond its stroke (:meth:`refused`; motors stronger than the model)."""
        self.step_errors: list[float] = []
        """|predicted - achieved| step of every part after every pulse [m]."""
        self.expected: tuple[NDArray[np.int64], FloatArray] | None = None
        """Part ids and where the last pulse is predicted to leave them (for the tracker)."""
        self._cache: dict[tuple[object, ...], tuple[float, float]] = {}
        self._pulses: dict[tuple[object, ...], Pulse] = {}
        self._motions: dict[int, tuple[Pulse, PlateMotion]] = {}  # by id of the pulse
        self._plate = np.zeros((3, 2))  # the plate's state expected after the last pulse and its rest
        self._t_next = 0.0  # plate time at which that is
        self._last: tuple[Pulse, NDArray[np.int64], FloatArray, FloatArray] | None = None
        self._ranked: list[Pulse] = []  # the last search's best candidates, best first
        self.revisions = 0
        """Plans made ahead that did not hold and were chosen again among their best candidates
        (:meth:`revise`)."""

    # -- prediction ---------------------------------------------------------------------------
    @property
    def _static(self) -> float:
        """``mu_s / mu``: the static friction keeps its ratio as the estimate of ``mu`` moves."""
        return 1.0 if self.mu_s is None else self.mu_s / self.mu

    def _coast(self, pulses: Sequence[Pulse]) -> float:
        """Longest time parts need to stop after a pulse (gaining ``mu_s g``, losing ``mu g``)."""
        return 1.05 * max(p.on_time for p in pulses) * self._static + 0.02

    def predict(
        self,
        pulses: Sequence[Pulse],
        positions: FloatArray,
        *,
        mu: float | FloatArray | None = None,
        disks: bool = False,
        fine: bool = False,
        tilt: tuple[float, float] | None = None,
    ) -> tuple[FloatArray, FloatArray]:
        """Positions ``(K, M, 2)`` after each pulse once the parts have stopped, and the plate time
        ``(K,)`` [s] each takes (the pulse and the rest until the last part stops: in closed form
        for points, to 10 ms with disks), on a plate of slope ``tilt`` [rad] (default the
        planner's estimate, :attr:`tilt_estimate`)."""
        mu_v = self.mu_estimate if mu is None else mu
        slope = self.tilt_estimate if tilt is None else (float(tilt[0]), float(tilt[1]))
        # gravity's in-plane part [m/s^2]: the plate rises toward +x and +y
        downhill = -9.81 * np.array([math.sin(slope[0]), math.sin(slope[1])])
        mu_s = np.asarray(mu_v, dtype=float) * self._static
        if disks and self.part_radius is not None:
            apart = separate(positions, self.part_radius)
            parts: Any = [Disk((float(x), float(y)), self.part_radius) for x, y in apart]
            extra: dict[str, Any] = {"contacts": True, "plate_size": self.limits.size}
        else:
            parts, extra = positions, {}
        final = np.empty((len(pulses), len(positions), 2))
        durations = np.empty(len(pulses))
        # one batched call per on-time and highest frequency: each simulated for its own horizon
        groups: dict[tuple[float, float], list[int]] = {}
        motions = [self._motion(p) for p in pulses]
        for k, (p, m) in enumerate(zip(pulses, motions, strict=True)):
            groups.setdefault((round(p.on_time, 6), m.max_frequency), []).append(k)
        for (on, top), members in groups.items():
            dt = 1.0 / ((2 if fine else 1) * self.dt_factor * top)
            if not extra:
                # points: simulated while the plate moves, then each slides to a stop on the
                # resting plate in closed form (a constant deceleration mu g along its velocity,
                # which the integrator's step reproduces exactly)
                run = simulate_batch(
                    [motions[k] for k in members], parts, duration=on, dt=dt, mu=mu_v, mu_s=mu_s,
                    record_every=2**40, tilt=slope,
                )  # fmt: skip
                at_rest, stopping = slide_to_rest(run.positions[:, -1], run.velocities[:, -1], mu_v)
                if np.any(downhill):  # the slope's pull over the slide to rest (first order)
                    at_rest = at_rest + 0.5 * downhill * (stopping**2)[..., None]
                final[members] = at_rest
                durations[members] = on + np.max(stopping, axis=1, initial=0.0)
                continue
            horizon = on + self._coast([pulses[k] for k in members])
            seq = [
                PlateMotion.sequence([motions[k], PlateMotion.rest(horizon - pulses[k].on_time + 1e-3)])
                for k in members
            ]
            every = max(1, round(0.01 / dt))
            run = simulate_batch(seq, parts, duration=horizon, dt=dt, mu=mu_v, mu_s=mu_s, record_every=every,
                                 tilt=slope, **extra)  # fmt: skip
            out = run.positions[:, -1].copy()
            out[np.asarray(run.left_plate)] = np.nan
            final[members] = out
            # stopped: every part stuck from then on, after the pulse's end
            moving: NDArray[np.bool_] = np.asarray(~np.all(run.stuck, axis=2))  # (K, T)
            t = run.t
            for row, k in enumerate(members):
                late = np.nonzero(moving[row] & (t >= on - 1e-9))[0]
                stop = t[late[-1]] + t[1] - t[0] if len(late) else on
                durations[k] = max(stop, on)
        return final, durations

    def _motion(self, pulse: Pulse) -> PlateMotion:
        """The pulse's motion, kept while the pulse is (the cached ones recur every cycle; the
        pulse is held with it, so its id is not reused)."""
        hit = self._motions.get(id(pulse))
        if hit is not None and hit[0] is pulse:
            return hit[1]
        if len(self._motions) > 4000:
            self._motions = {}
        m = pulse.motion(rest=False)
        self._motions[id(pulse)] = (pulse, m)
        return m

    # -- scoring --------------------------------------------------------------------------------
    def _penalty(self, q: FloatArray, overlaps: bool = True, start: FloatArray | None = None) -> FloatArray:
        """:func:`.penalties.penalty` of predicted positions ``(K, M, 2)`` by this planner's edge,
        loss and spread settings (and overlaps of its parts' radius, with ``overlaps``)."""
        return penalty(q, half=self.limits.size / 2, edge=self.edge, edge_weight=self.edge_weight,
                       lost_cost=self.lost_cost, guard=self.guard, spread=self.spread,
                       part_radius=self.part_radius if overlaps else None, start=start)  # fmt: skip

    def _score(
        self, task: _CostTask, state: Any, pos: FloatArray, final: FloatArray, durations: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Cost decrease against resting for as long, and that per second."""
        still = np.broadcast_to(pos, final.shape)
        rest_cost = np.asarray(task.cost(state, still, durations), dtype=float) + self._penalty(pos[None])[0]
        safe = np.where(np.isfinite(final), final, still)
        after = np.asarray(task.cost(state, safe, durations), dtype=float) + self._penalty(final, start=pos)
        gain = rest_cost - after
        return gain, gain / durations

    # -- online correction ----------------------------------------------------------------------
    def _correct(self, ids: NDArray[np.int64], pos: FloatArray) -> None:
        """Learn from the last pulse, its parts ``ids`` seen now at ``pos`` (:func:`.fitting.learn`)."""
        last, self._last = self._last, None
        if last is not None:
            learn(self, last, ids, pos)

    # -- planning ----------------------------------------------------------------------------------
    def _carried(self) -> float:
        """Largest corner excursion the plate's leftover motion may still make (its free
        response from the expected state over the longest candidate and 0.3 s more)."""
        if not np.any(self._plate):
            return 0.0
        pose, _ = self.limits.ride_out(self._plate, max(self.on_times) + 0.3, dt=1e-3)
        return self.limits.excursion(pose)

    def _advance_plate(self, pulse: Pulse) -> None:
        """The plate's state after ``pulse`` and its rest, by the limits' plate model."""
        _, self._plate = self.limits.play(pulse, self._plate)

    def candidates(
        self,
        positions: FloatArray,
        toward: FloatArray | None = None,
        carried: float | None = None,
        aligned: tuple[FloatArray, FloatArray] | None = None,
        crowd: FloatArray | None = None,
    ) -> Candidates:
        """This cycle's candidates for parts at ``positions`` (see :mod:`upm.plan.candidates`),
        within the stroke the plate's leftover motion leaves (``carried`` [m], default from the
        planner's plate model); jets along ``toward (M, 2)``; rotations about the ``aligned``
        centres and senses; ``narrow`` jets by the neighbours among ``crowd`` (all the parts)."""
        narrow, crowd = None, positions if crowd is None else crowd
        if self.narrow and self.part_radius is not None and self.jet_radii:
            narrow = narrow_radii(positions, crowd, self.part_radius, min(self.jet_radii))
        carried = self._carried() if carried is None else carried
        return generate(self.limits, positions, frequencies=self.frequencies, on_times=self.on_times,
                        grid=self.grid, jet_radii=self.jet_radii, use=self.use * self.headroom,
                        cache=self._cache, carried=carried, jet_toward=toward, pulse_cache=self._pulses,
                        jet_on_times=(0.35, 0.6), rotation_on_times=self.on_times[:2], aligned=aligned,
                        narrow=narrow)  # fmt: skip

    def choose(
        self, task: _CostTask, state: Any, pulses: Sequence[Pulse], ids: NDArray[np.int64] | None = None
    ) -> tuple[int | None, FloatArray, FloatArray]:
        """Index of the best of ``pulses`` for ``task`` (``None``: none gains ``min_gain``), with
        every pulse's predicted gain [m] and gain per second."""
        best, gain, rate, _, _ = self._choose(task, state, pulses, ids)
        return best, gain, rate

    def _choose(
        self, task: _CostTask, state: Any, pulses: Sequence[Pulse], ids: NDArray[np.int64] | None = None
    ) -> tuple[int | None, FloatArray, FloatArray, float, FloatArray]:
        """:meth:`choose`, and the best pulse's plate time [s] and predicted final positions."""
        pos = np.asarray(state.positions, dtype=float)
        ids = np.arange(len(pos)) if ids is None else ids
        final, durations = self.predict(pulses, pos)
        gain_of = np.array([self.gains.get(int(i), 1.0) for i in ids])
        final = pos + gain_of[None, :, None] * (final - pos)
        gain, rate = self._score(task, state, pos, final, durations)
        among = None
        if self.focus is not None and len(pos) > self.focus:
            # many parts: the look-ahead for the best few by their own rate (its cost is K R M)
            among = np.argsort(-np.where(np.isfinite(rate), rate, -np.inf), kind="stable")[: 8 * self.focus]
        rate = np.maximum(rate, two_step(self, task, state, pos, final, durations, among))
        pair_rate = np.full(len(pulses), -np.inf)
        pair_gain = np.zeros(len(pulses))
        if self.pairs is not None and len(pulses):
            # two pulses: the best few first pulses, each followed by the best of the one-step
            # favourites from where it leaves the parts
            one = np.where(np.isfinite(gain), gain / np.maximum(durations, 1e-9), -np.inf)
            second = [int(k) for k in np.argsort(-one)[: self.pairs[1]] if np.isfinite(one[k])]
            ok = np.isfinite(rate) & np.all(np.isfinite(final), axis=(1, 2))
            first = [int(k) for k in np.argsort(-np.where(ok, rate, -np.inf))[: self.pairs[0]] if ok[k]]
            if first and second:
                pair_rate[first], pair_gain[first] = pair_rates(
                    self, task, state, pos, [pulses[k] for k in second], durations[second],
                    final[first], durations[first], gain_of,
                )  # fmt: skip
                rate = np.maximum(rate, pair_rate)
        order = np.argsort(-np.where(np.isfinite(rate), rate, -np.inf))
        self._ranked = [pulses[int(k)] for k in order[:SHORTLIST] if np.isfinite(rate[k])]
        best: int | None = int(order[0]) if len(order) else None
        if self.part_radius is not None and self.rerank > 0 and len(order):
            top = [int(k) for k in order[: self.rerank]]
            f2, d2 = self.predict([pulses[k] for k in top], pos, disks=True, fine=True)
            f2 = np.where(np.isfinite(f2), pos + gain_of[None, :, None] * (f2 - pos), np.nan)
            g2, r2 = self._score(task, state, pos, f2, d2)
            r2 = np.maximum(r2, two_step(self, task, state, pos, f2, d2))
            gain[top], rate[top] = g2, r2
            best = top[int(np.argmax(np.where(np.isfinite(r2), r2, -np.inf)))]
            # the re-ranked pulses' fine predictions replace the coarse ones
            durations, final = durations.copy(), final.copy()
            durations[top], final[top] = d2, f2
        if best is not None and not (
            gain[best] >= self.min_gain or rate[best] * durations[best] >= self.min_gain
        ):
            # the look-ahead's favourite does not hold up: the best sure one-step gain instead, or
            # else the best pair that gains (the last part to place moves its neighbours: the
            # second pulse puts them back)
            one_step = np.where(gain >= self.min_gain, gain / np.maximum(durations, 1e-9), -np.inf)
            if not np.isfinite(one_step).any():
                one_step = np.where(pair_gain >= self.min_gain, pair_rate, -np.inf)
            best = int(np.argmax(one_step)) if np.isfinite(one_step).any() else None
        if best is None:
            return None, gain, rate, math.nan, np.full_like(pos, np.nan)
        return best, gain, rate, float(durations[best]), final[best]

    def plan_task(self, state: Any, task: _CostTask) -> list[Pulse]:
        """One pulse for ``task`` from the tracked ``state`` (its parts all seen), or none."""
        return self._plan(state, task)

    def _plan(self, state: Any, task: _CostTask, among: Sequence[Pulse] | None = None) -> list[Pulse]:
        """:meth:`plan_task`; ``among``: choose among these pulses only (no search)."""
        pos = np.asarray(state.positions, dtype=float)
        ids = np.asarray(getattr(state, "ids", np.arange(len(pos))), dtype=np.int64)
        self._correct(ids, pos)
        now = float(getattr(state, "time", self._t_next))
        if now > self._t_next + 1e-6 and np.any(self._plate):  # the plate rode out the idle time
            _, self._plate = self.limits.ride_out(self._plate, min(now - self._t_next, 5.0))
        self._t_next = now
        if not len(pos):
            return []
        self.expected = None
        if among is not None:
            best, _, _, duration, final = self._choose(task, state, among, ids)
            return [] if best is None else self._played(among[best], duration, now, ids, pos, final)
        pulses = self._search(state, task, pos, ids, now)
        if pulses or self.edge_weight <= 0:
            return pulses
        weight, self.edge_weight = self.edge_weight, RELAXED * self.edge_weight
        try:
            return self._search(state, task, pos, ids, now)
        finally:
            self.edge_weight = weight

    def _search(
        self, state: Any, task: _CostTask, pos: FloatArray, ids: NDArray[np.int64], now: float
    ) -> list[Pulse]:
        """The full search of :meth:`_plan`: candidates aimed at the parts with most to gain."""
        carried = self._carried()
        aligned = None
        if self.aligned:
            aligned = aligned_centers(
                lambda q: task.cost(state, q, 0.0), pos, self.limits.size, count=self.aligned
            )
        toward = descent(task, state, pos)
        focus = self.focus if self.focus is not None and len(pos) > self.focus else None
        best = None
        for near, way in aimed(task, state, pos, toward, focus):
            # pulses at parts only for the parts with the most to gain: the candidates stay as
            # many whatever the count of parts, and each prediction O(M)
            cands = self.candidates(near, way, carried, aligned, pos)
            if self.macros is not None:  # the long pulses of the look-ahead are playable themselves
                cands = cands + self.macros.playable(carried, self.headroom)
            best, _, _, duration, final = self._choose(task, state, cands.pulses, ids)
            if best is not None:
                break
        if best is None:
            return []
        return self._played(cands.pulses[best], duration, now, ids, pos, final)

    def _played(
        self, pulse: Pulse, duration: float, now: float, ids: NDArray[np.int64], pos: FloatArray, final: Any
    ) -> list[Pulse]:
        """Play ``pulse`` with the rest its parts need to stop (``duration`` in all) from plate time
        ``now``: the plate model advanced, the prediction kept to learn from and to track by."""
        played = replace(pulse, rest=max(duration - pulse.on_time + 0.01, 0.0))
        seen = as_played(self, pulse, pos, final)  # expected as the board plays it
        self._advance_plate(played)
        self._t_next = now + played.duration
        self._last = (played, ids.copy(), pos.copy(), np.asarray(final, dtype=float))
        self.expected = (ids.copy(), seen)
        return [played]

    def speculate(self, state: Any, task: _CostTask) -> tuple[list[Pulse], object]:
        """Plan the next pulse from ``state`` as the last pulse is predicted to leave it, while that
        pulse plays (:class:`upm.control.Loop`'s ``pipeline``). Nothing the planner has learnt
        or expects changes: the pulses and a token for :meth:`adopt`, which keeps the plan."""
        saved = (self._plate.copy(), self._t_next, self._last, self.expected)
        self._last = None  # a prediction teaches nothing: the pulse before is corrected on adoption
        self._ranked = []
        try:
            pulses = self.plan_task(state, task)
            after = (self._plate.copy(), self._t_next, self._last, self.expected, tuple(self._ranked))
        finally:
            self._plate, self._t_next, self._last, self.expected = saved
        return pulses, after

    def adopt(self, token: object, ids: NDArray[np.int64], positions: FloatArray) -> None:
        """Keep a plan from :meth:`speculate`: learn from the pulse that has just played (the parts
        ``ids`` seen at ``positions``), then take the state the kept plan leaves."""
        seen_ids = np.asarray(ids, dtype=np.int64)
        seen = np.asarray(positions, dtype=np.float64)
        self._correct(seen_ids, seen)
        plate, t_next, last, _, _ = cast(tuple[FloatArray, float, Any, Any, Any], token)
        self._plate, self._t_next = plate, t_next
        self._last = None if last is None else restarted(last, seen_ids, seen)
        self.expected = None if self._last is None else (self._last[1].copy(), self._last[3].copy())

    def revise(self, token: object, state: Any, task: _CostTask) -> list[Pulse]:
        """A plan from :meth:`speculate` did not hold (the parts ended too far from where the last
        pulse was predicted to leave them): plan from the seen ``state`` among that plan's best
        candidates only (its :data:`SHORTLIST` best by gain per second, each predicted and scored
        again from where the parts are, the best few with contacts), a quarter of a full search's
        time; the full search when none of them gains, and for more than ``focus`` parts (sort32
        seeds 1 and 2 lost chips choosing again; 0 lost on 5 seeds with a full search)."""
        ranked = cast(tuple[Any, ...], token)[4]
        if self.focus is not None and len(np.asarray(state.positions)) > self.focus:
            ranked = ()
        pulses = self._plan(state, task, list(ranked)) if ranked else []
        if pulses:
            self.revisions += 1
            return pulses
        return self.plan_task(state, task)

    def refused(self) -> None:
        """The device refused the last pulse as beyond its stroke, and nothing played: the motors
        swing the plate further than the model says. Later candidates are sized 15 % lower each
        time (down to a quarter of ``use``); the plate is taken to be home (the device waited
        for it) and the refused pulse's prediction is dropped."""
        self.headroom = max(0.85 * self.headroom, 0.25)
        self._plate = np.zeros((3, 2))
        self._last = None
        self.expected = None

    def cut(self) -> None:
        """The board cut the last pulse short (:class:`upm.PulseCut`): it did not play as
        predicted, so its prediction is dropped (nothing to learn from it about friction or the
        parts' gains)."""
        self._last = None
        self.expected = None

    def plan(self, positions: FloatArray, steps: FloatArray) -> list[Pulse]:
        """Without a task: the pulse that best brings each part to ``positions + steps`` (NaN
        components free)."""
        pos = np.asarray(positions, dtype=float)
        goal = pos + np.asarray(steps, dtype=float)
        return self.plan_task(PositionsView(pos), StepsGoal(goal))

    def __repr__(self) -> str:
        return (
            f"PredictivePlanner(mu={self.mu:g}, mu_estimate={self.mu_estimate:.3g}, "
            f"stroke={1000 * self.limits.stroke:g} mm, frequencies={self.frequencies})"
        )
