"""The environments' plates and tasks, ``B`` at a time: one home for what a single environment and
the vector environment do, so that the two give the same numbers bit for bit.

Physics: each pulse is played on an ideal plate (the commanded motion, as the predictive planner
predicts) by the exact integrator at the planner's step (``dt = 1 / (24 f_max)``), all the worlds
of one drive frequency and on-time in one batched call, each world from its own layout
(:func:`upm.simulate_batch` ``starts``). Point parts then slide to rest in closed form; with
``contacts`` the disks collide (rapier) and are simulated until they stop. A part whose centre
leaves the plate is lost (NaN) for the rest of the episode.

Tasks (the cost is the control task's own, :mod:`upm.control`):

* ``goto``: each part to its own goal, drawn with the layout; the cost of
  :class:`~upm.control.GotoTask` (sum of distances less half the tolerance, a lost part 1 m);
* ``sort``: the first half of the parts to the left of ``-line``, the others to the right of
  ``+line``; :class:`~upm.control.SortTask`'s cost;
* ``shape``: the parts onto a shape's points (:mod:`upm.shapes`), assigned anew every step
  (:func:`upm.control.shape.assign`); :class:`~upm.control.ShapeTask`'s cost;
* ``orient``: polygons to target poses (:mod:`upm.envs.orient`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._errors import ParameterError
from ..control._steps import distance_sum
from ..control.shape import assign
from ..control.shapes import scatter
from ..control.state import State
from ..control.tasks import SortTask
from ..physics.motion import PlateMotion
from ..physics.polygon import Polygon
from ..physics.sim import Disk, simulate_batch
from ..plan.sizing import settle_time, slide_to_rest, stopping_time
from ..plate.drive import DriveLimits
from .actions import FREQUENCIES, ON_TIMES, Decoded, PulseActions

__all__ = ["DT_FACTOR", "TASKS", "Plates", "Task"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Integrator steps per period of a pulse's highest harmonic (the predictive planner's).
DT_FACTOR = 24
TASKS = ("goto", "sort", "shape", "orient")
SHAPES = ("ring", "grid")


class Plates:
    """Plays decoded pulses on ``B`` plates of parts at once."""

    def __init__(
        self,
        limits: DriveLimits,
        mu: float,
        mu_s: float | None,
        radius: float | None,
        contacts: bool,
        polygon: Polygon | None = None,
    ) -> None:
        self.limits, self.mu = limits, float(mu)
        self.mu_s = self.mu if mu_s is None else float(mu_s)
        self.radius, self.contacts, self.polygon = radius, bool(contacts), polygon
        self.actions = PulseActions(limits)

    def play(self, positions: FloatArray, d: Decoded) -> tuple[FloatArray, FloatArray]:
        """Where the parts ``(B, M, 2)`` (poses ``(B, M, 3)`` of polygons; NaN: lost) are once
        they have stopped after each world's pulse, and each world's plate time [s]."""
        m, dim = positions.shape[1], positions.shape[2]
        out = positions.copy()
        durations = np.asarray(ON_TIMES)[d.on]
        moving = d.amplitude != 0.0
        if m == 0 or not moving.any():
            return out, durations
        keys = d.frequency * len(ON_TIMES) + d.on
        # lost parts wait far off the plate, apart (their results are dropped)
        park = np.stack([10.0 + 0.1 * np.arange(m), np.full(m, 10.0), np.zeros(m)], 1)[:, :dim]
        lost = ~np.all(np.isfinite(positions), axis=2)
        start = np.where(lost[..., None], park[None], positions)
        cores = self.actions.motions(d)  # every world's in one call; each group takes its own
        points = not (self.contacts or self.polygon is not None)
        if points:  # each group's end state, then every world slides to rest at once
            end_q, end_v = np.empty_like(positions), np.empty_like(positions)
            left = np.zeros(lost.shape, dtype=bool)
        for key in np.unique(keys[moving]):
            rows = np.nonzero(moving & (keys == key))[0]
            f, t_on = FREQUENCIES[key // len(ON_TIMES)], ON_TIMES[key % len(ON_TIMES)]
            motions = [cores[i] for i in rows]
            dt = 1.0 / (DT_FACTOR * 2 * f)  # (every pulse's highest harmonic: twice its base)
            if not points:
                final, durations[rows] = self._until_still(
                    [PlateMotion(c) for c in motions], start[rows], t_on, dt
                )
                out[rows] = final
                continue
            run = simulate_batch(
                motions, start[rows[0]], duration=t_on, dt=dt, mu=self.mu, mu_s=self.mu_s,
                plate_size=self.limits.size, record_every=2**40, starts=start[rows],
            )  # fmt: skip
            end_q[rows], end_v[rows] = run.positions[:, -1], run.velocities[:, -1]
            left[rows] = run.left_plate
        if points:
            final, stop = slide_to_rest(end_q[moving], end_v[moving], self.mu)
            final[left[moving]] = np.nan
            durations[moving] += np.max(np.where(lost[moving], 0.0, stop), axis=1, initial=0.0)
            out[moving] = final
        moved = out[moving]
        with np.errstate(invalid="ignore"):  # slid off the plate
            moved[np.any(np.abs(moved[..., :2]) > self.limits.size / 2, axis=2)] = np.nan
        moved[lost[moving]] = np.nan
        out[moving] = moved
        return out, durations

    def _until_still(
        self, motions: list[PlateMotion], start: FloatArray, on: float, dt: float
    ) -> tuple[FloatArray, FloatArray]:
        """Colliding disks (rapier) or polygons at ``start`` (poses ``(B, M, 3)``; polygons slide
        through each other): the pulse, then the plate at rest until every part stops. Where they
        end (poses for polygons) and each world's plate time [s]."""
        coast = settle_time(on, self.mu, self.mu_s, None)
        horizon = on + coast
        seq = [PlateMotion.sequence([mo, PlateMotion.rest(coast + 1e-3)]) for mo in motions]
        shape = self.polygon
        if shape is None:
            parts: list[Any] = [Disk((float(x), float(y)), float(self.radius or 0.0)) for x, y in start[0]]
        else:
            parts = [shape.moved((float(x), float(y)), float(a)) for x, y, a in start[0]]
        every = max(1, round(0.01 / dt))
        run = simulate_batch(
            seq, parts, duration=horizon, dt=dt, mu=self.mu, mu_s=self.mu_s, plate_size=self.limits.size,
            record_every=every, contacts=shape is None, starts=start,
        )  # fmt: skip
        final = run.positions[:, -1].copy()
        if shape is not None:
            final = np.concatenate([final, run.angles[:, -1, :, None]], axis=-1)
        final[np.asarray(run.left_plate)] = np.nan
        stuck = np.asarray(run.stuck)
        every_t = run.t[1] - run.t[0]  # a part last seen moving stops within a record after
        stop = [on + stopping_time(run.t, stuck[w], on) + every_t for w in range(len(stuck))]
        return final, np.asarray(stop)


class Task:
    """The task of a family of environments: layouts, goals, cost and completion, batched."""

    def __init__(
        self,
        name: str,
        n_parts: int,
        limits: DriveLimits,
        radius: float | None,
        tolerance: float,
        shape: str = "ring",
    ) -> None:
        if name not in TASKS:
            raise ParameterError(f"task must be one of {TASKS}; got {name!r}")
        self.name, self.m, self.tolerance = name, n_parts, tolerance
        self.half = limits.size / 2
        self.gap = 2.6 * radius if radius else 0.02
        self.sort: SortTask | None = None
        self.shape_points: FloatArray | None = None
        self.sides = np.zeros(n_parts)
        if name == "sort":
            count = n_parts - n_parts // 2
            line = SortTask.fit_line(count, radius, plate_size=limits.size) if radius else None
            self.sort = SortTask(
                {"red": -1, "blue": 1}, plate_size=limits.size, line=line, part_radius=radius
            )
            self.sides = np.where(np.arange(n_parts) < n_parts // 2, -1.0, 1.0)
            self.state = State(0, 0.0, np.arange(n_parts), np.zeros((n_parts, 2)),
                               tuple("red" if s < 0 else "blue" for s in self.sides), 0.0)  # fmt: skip
        elif name == "shape":
            from ..control import shapes

            if shape not in SHAPES:
                raise ParameterError(f"shape must be one of {SHAPES}; got {shape!r}")
            spacing = max(0.028, 1.4 * self.gap)
            if shape == "ring":
                self.shape_points = shapes.ring(n_parts, max(0.06, n_parts * spacing / (2 * math.pi)))
            else:
                self.shape_points = shapes.grid(n_parts, spacing)
            if np.max(np.abs(self.shape_points)) > self.half - 0.03:
                raise ParameterError(f"n_parts = {n_parts} do not fit a {shape} on the plate; use fewer")

    def _scatter(self, rng: np.random.Generator, extent: float) -> FloatArray:
        """``M`` points uniform in ``+-extent`` at least ``gap`` apart (:func:`upm.shapes.scatter`)."""
        try:
            return scatter(rng, self.m, extent, self.gap)
        except ParameterError:
            raise ParameterError(
                f"n_parts = {self.m} do not fit the plate's middle at this size; use fewer"
            ) from None

    def layout(self, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        """A new episode's parts ``(M, 2)`` and goals ``(M, 2)`` (goto's; zeros otherwise)."""
        if self.sort is not None:
            extent = min(0.6 * self.half, self.sort.line + 0.02)
            return self._scatter(rng, extent), np.zeros((self.m, 2))
        parts = self._scatter(rng, 0.7 * self.half)
        if self.name == "goto":
            return parts, self._scatter(rng, 0.6 * self.half)
        return parts, np.zeros((self.m, 2))

    def targets(self, q: FloatArray, goals: FloatArray) -> FloatArray:
        """Each part's point ``(B, M, 2)``: goto's goals, the shape's assigned points, and for a
        sort the side along x (``+-1``) with y 0."""
        if self.name == "goto":
            return goals
        if self.name == "sort":
            return np.broadcast_to(np.stack([self.sides, np.zeros(self.m)], 1), q.shape).copy()
        pts = self.shape_points
        assert pts is not None
        out = np.full(q.shape, np.nan)
        for w in range(len(q)):
            k = assign(q[w], pts)
            out[w, k >= 0] = pts[k[k >= 0]]
        return out

    def cost(self, q: FloatArray, goals: FloatArray) -> FloatArray:
        """The control task's cost of each world ``(B,)`` [m]."""
        if self.sort is not None:
            out: FloatArray = self.sort.cost(self.state, q)
            return out
        return distance_sum(q, self.targets(q, goals), 0.5 * self.tolerance)

    def done(self, q: FloatArray, goals: FloatArray) -> BoolArray:
        """Whether each world's task is done ``(B,)`` (no part lost)."""
        whole = np.all(np.isfinite(q), axis=(1, 2))
        if self.sort is not None:
            with np.errstate(invalid="ignore"):
                over = np.all(self.sides[None] * q[..., 0] >= self.sort.line, axis=1)
            out: BoolArray = whole & over
            return out
        d = q - self.targets(q, goals)
        with np.errstate(invalid="ignore"):
            near = np.all(np.hypot(d[..., 0], d[..., 1]) <= self.tolerance, axis=1)
        both: BoolArray = whole & near
        return both
