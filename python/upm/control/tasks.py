"""Tasks: what the parts should do, as small desired steps each cycle (thesis 4.3, 5.3, 6.3).

A task sees the tracked parts (:class:`State`) and answers the steps it wants [m], whether it is
done, and each part's error against its reference. Parts are bound to the task's slots (goals,
paths) on the first cycle by minimum total distance (``scipy.optimize.linear_sum_assignment``),
or to the nearest of the given ``starts``; a part lost from view asks for nothing until it is seen
again.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import integer, point, real
from .._errors import ParameterError, ShapeError
from ..plate.drive import PLATE_SIZE
from ._steps import PointTargets, clip, distance_sum, points, positions_of
from .state import Slots, State, Task
from .trajectory import TrajectoryTask

__all__ = ["GatherTask", "GotoTask", "SortTask", "State", "Task", "TrajectoryTask", "WatchTask"]

FloatArray = NDArray[np.float64]


class GotoTask(PointTargets):
    """Every part to its goal.

    Parameters
    ----------
    goals : (K, 2) array_like
        Goals [m].
    starts : (K, 2) array_like, optional
        Where the part for each goal starts (binding by nearest); default: parts are bound to goals
        by minimum total distance.
    gain : float
        Fraction of the remaining error asked for per cycle.
    max_step : float
        Longest step asked for [m].
    tolerance : float
        Done when every part is within this of its goal [m].
    first_step : float, optional
        Longest step on the first cycle [m] (e.g. the whole way, open loop, as in Fig. 5.3).
    """

    def __init__(
        self,
        goals: ArrayLike,
        *,
        starts: ArrayLike | None = None,
        gain: float = 0.8,
        max_step: float = 0.02,
        tolerance: float = 0.003,
        first_step: float | None = None,
    ) -> None:
        self.goals = points("goals", goals)
        anchors = self.goals if starts is None else points("starts", starts)
        if anchors.shape != self.goals.shape:
            raise ShapeError(f"starts must match goals' shape {self.goals.shape}; got {anchors.shape}")
        self.slots = Slots(anchors)
        self.gain, self.max_step, self.tolerance = float(gain), float(max_step), float(tolerance)
        self.first_step = self.max_step if first_step is None else float(first_step)

    def targets(self, state: State) -> FloatArray:
        """Each tracked part's goal (NaN: not bound to one) [m]."""
        slot = self.slots.bind(state)
        out = np.full_like(state.positions, np.nan)
        out[slot >= 0] = self.goals[slot[slot >= 0]]
        return out

    def steps(self, state: State) -> FloatArray:
        d = self.targets(state) - state.positions
        d = np.where(np.isfinite(d), d, 0.0)
        near = np.hypot(d[:, 0], d[:, 1]) <= self.tolerance / 2
        d[near] = 0.0
        if state.cycle == 0:
            return clip(d, self.first_step)
        return clip(self.gain * d, self.max_step)

    def done(self, state: State) -> bool:
        e = self.errors(state)
        bound = self.slots.bind(state) >= 0
        return bool(len(self.slots.of) == len(self.goals) and np.all(e[bound] <= self.tolerance))


class SortTask:
    """Parts pushed by label to opposite sides of the plate (thesis 4.3.2, 6.3).

    Each part with a label in ``sides`` is pushed along x towards its side (``-1`` left, ``+1``
    right) until it is ``margin`` from the edge; parts closer than ``spacing`` push apart along y so
    they pass each other (the "dodging" of 4.3.2). Sorted when every such part is beyond ``line``.

    Parameters
    ----------
    sides : mapping of label to -1 or +1
    plate_size : float
        Side of the plate [m].
    line : float
        Sorted: ``side * x >= line`` [m] (default a quarter of the plate from the centre).
    margin : float
        Pushing stops this far from the edge [m].
    spacing : float
        Parts closer than this [m] are spread apart.
    max_step : float
        Step asked for per cycle [m].
    past : float
        A sorted part is pushed no further than ``line + past`` [m].
    clear : float
        :meth:`cost` pulls a part hardest until it is this far past its line [m] (then lightly on
        to ``line + past / 2``).
    free_y : bool
        Leave y free (NaN) for parts that are not being spread apart and are more than
        ``margin`` from the top and bottom edges (beyond it they are brought back): planners that
        solve for every constrained component (:class:`~upm.control.RotationsPlanner`) then have
        about half the constraints.
    part_radius : float, optional
        The parts' radius [m]: on the first cycle, a side given more parts than its region holds
        (beyond ``line``, ``margin / 2`` from the edges, as a hexagonal packing) is refused with a
        :class:`upm.ParameterError`; :meth:`fit_line` places the line for a count.
    ignore : collection of str
        Labels of parts the sort leaves where they are. A part whose label is neither in ``sides``
        nor here is refused on the first cycle (:class:`upm.ParameterError`): a sort that reports
        done with a part of an unexpected colour left unsorted would be silently wrong.
    """

    NEAR, FAR = 2.0, 0.3
    """:meth:`cost`'s weights on the distance to ``clear`` past the line and to ``past / 2``."""
    REACH = 0.6
    """:meth:`cost`'s bend, as a share of the plate's side: a part ``d`` from ``clear`` past its
    line counts ``NEAR * d * (1 + d / (REACH * plate_size))``, so a metre of the farthest part's
    way weighs more than a metre of a near one's and the planner does not leave it for last."""

    def __init__(
        self,
        sides: Mapping[str, int],
        *,
        plate_size: float = PLATE_SIZE,
        line: float | None = None,
        margin: float = 0.04,
        spacing: float = 0.045,
        max_step: float = 0.02,
        past: float = 0.02,
        clear: float = 0.003,
        free_y: bool = False,
        part_radius: float | None = None,
        ignore: Collection[str] = (),
    ) -> None:
        if not isinstance(sides, Mapping):
            raise ParameterError(
                f"sides must map labels to -1 (left) or +1 (right), e.g. {{'red': -1, 'blue': 1}}; got "
                f"{type(sides).__name__} {sides!r}"
            )
        if isinstance(ignore, str) or not all(isinstance(lab, str) for lab in ignore):
            raise ParameterError(f"ignore must be a collection of labels (str); got {ignore!r}")
        self.ignore = frozenset(ignore)
        if self.ignore & set(sides):
            raise ParameterError(f"ignore and sides share labels {sorted(self.ignore & set(sides))}")
        self.free_y = bool(free_y)
        self.part_radius = (
            None if part_radius is None else real("part_radius", part_radius, low=0.0, low_open=True)
        )
        for name, value in (("past", past), ("clear", clear)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ParameterError(f"{name} must be finite and >= 0 [m]; got {value!r}")
        self.past, self.clear = float(past), float(clear)
        self.expected: int | None = None  # labelled parts seen on the first cycle
        if not sides or any(v not in (-1, 1) for v in sides.values()):
            raise ParameterError(f"sides must map labels to -1 (left) or +1 (right); got {dict(sides)}")
        self.sides = dict(sides)
        if not (math.isfinite(plate_size) and plate_size > 0):
            raise ParameterError(f"plate_size must be finite and > 0 [m]; got {plate_size!r}")
        self.half = plate_size / 2
        self.line = plate_size / 4 if line is None else float(line)
        self.margin, self.spacing, self.max_step = float(margin), float(spacing), float(max_step)
        if not 0 < self.line < self.half - self.margin:
            raise ParameterError(f"line must be in (0, {self.half - self.margin:.3g}) m; got {self.line!r}")

    @staticmethod
    def capacity(
        line: float, part_radius: float, *, plate_size: float = PLATE_SIZE, margin: float = 0.04
    ) -> int:
        """How many disks of ``part_radius`` [m] one side's region holds: centres beyond ``line``
        (plus a radius) and ``margin / 2`` inside the edges, hexagonally packed 5 % apart."""
        half, d = plate_size / 2, 2.1 * part_radius
        width = half - margin / 2 - line - part_radius
        height = 2 * (half - margin / 2)
        if width < 0 or height < 0:
            return 0
        nx, ny = int(width / (d * math.sqrt(3) / 2)) + 1, int(height / d) + 1
        return nx * ny - nx // 2

    @classmethod
    def fit_line(cls, count: int, part_radius: float, *, plate_size: float = PLATE_SIZE, margin: float = 0.04,
                 room: float = 1.5) -> float:  # fmt: skip
        """The farthest line from the centre (at most a quarter of the plate) whose regions hold
        ``room`` times ``count`` parts of ``part_radius`` [m] a side. :class:`upm.ParameterError`
        when even a line a radius from the centre does not."""
        count = integer("count", count, low=1)
        r = real("part_radius", part_radius, low=0.0, low_open=True)
        for line in np.arange(plate_size / 4, r, -0.0025):
            if cls.capacity(float(line), r, plate_size=plate_size, margin=margin) >= room * count:
                return float(line)
        most = cls.capacity(r, r, plate_size=plate_size, margin=margin)
        raise ParameterError(
            f"{count} parts of radius {1000 * r:.1f} mm a side cannot be sorted on a "
            f"{1000 * plate_size:.0f} mm plate: a side holds at most {most} with room {room:g}x; "
            "use fewer or smaller parts"
        )

    def _fits(self, state: State) -> None:
        """:class:`upm.ParameterError` when a part's label is neither sorted nor ignored, or a side
        is given more parts than its region holds."""
        unknown = sorted({lab for lab in state.labels if lab not in self.sides and lab not in self.ignore})
        if unknown:
            raise ParameterError(
                f"SortTask: parts labelled {unknown} are on the plate, but sides only names "
                f"{sorted(self.sides)}: give each label a side, or pass ignore={unknown} to leave them be"
            )
        if self.part_radius is None:
            return
        room = self.capacity(self.line, self.part_radius, plate_size=2 * self.half, margin=self.margin)
        for side in (-1, 1):
            n = int(np.sum(self._side(state) == side))
            if n > room:
                raise ParameterError(
                    f"SortTask: {n} parts go to the {'left' if side < 0 else 'right'}, but beyond line = "
                    f"{self.line:.3g} m the region holds {room} parts of radius "
                    f"{1000 * self.part_radius:.1f} mm; "
                    "move the line in (SortTask.fit_line), or sort fewer or smaller parts"
                )

    def lines(self) -> list[FloatArray]:
        """The two sorting lines ``x = +-line`` [m]."""
        h = self.half
        return [np.array([[s * self.line, -h], [s * self.line, h]]) for s in (-1.0, 1.0)]

    def _side(self, state: State) -> FloatArray:
        return np.array([float(self.sides.get(lab, 0)) for lab in state.labels])

    def errors(self, state: State) -> FloatArray:
        """Distance [m] still to go to the sorted line (0 once beyond it)."""
        side = self._side(state)
        out: FloatArray = np.where(
            side != 0, np.maximum(self.line - side * state.positions[:, 0], 0.0), np.nan
        )
        return out

    def steps(self, state: State) -> FloatArray:
        pos = state.positions
        side = self._side(state)
        seen = np.all(np.isfinite(pos), axis=1)
        goal = self.half - self.margin
        goal = min(goal, self.line + self.past)
        out = np.zeros_like(pos)
        go = seen & (side != 0)
        out[go, 0] = side[go] * np.clip(goal - side[go] * pos[go, 0], 0.0, self.max_step)
        spread = np.zeros(len(pos), dtype=bool)
        # spread close pairs apart, mostly across the direction of travel
        for a in np.nonzero(seen)[0]:
            for b in np.nonzero(seen)[0]:
                if b <= a:
                    continue
                d = pos[b] - pos[a]
                dist = float(np.hypot(*d))
                if dist >= self.spacing:
                    continue
                dy = d[1] if abs(d[1]) > 1e-9 else (1.0 if a % 2 else -1.0) * 1e-3
                push = 0.5 * (self.spacing - dist) * math.copysign(1.0, dy)
                out[a, 1] -= push
                out[b, 1] += push
                spread[[a, b]] = True
        out[:, 1] = np.clip(
            out[:, 1], -self.half + self.margin - pos[:, 1], self.half - self.margin - pos[:, 1]
        )
        out[~seen] = 0.0
        out = clip(out, self.max_step)
        if self.free_y:  # free across, but not out towards the edges parallel to the travel
            inner = self.half - self.margin
            over = np.abs(pos[:, 1]) - inner
            out[seen & (over > 0), 1] = -np.sign(pos[seen & (over > 0), 1]) * over[seen & (over > 0)]
            out[seen & ~spread & (over <= 0), 1] = np.nan
        return out

    def cost(self, state: State, positions: FloatArray | None = None, elapsed: ArrayLike = 0.0) -> FloatArray:
        """Sum over labelled parts of two distances [m] still to go along x: ``d`` to ``clear``
        past ``line``, weighted 2 and bent (``2 d (1 + d / (REACH * plate_size))``), and to
        ``line`` plus half of ``past``, weighted 0.3. A part's way over its line counts most, so
        a planner spends no pulse on parts already over it while others are not; the bend makes
        the farthest part's way count most, so the last part is not left for last (a linear
        cost traded it against the jitter of parts just over their lines: sort8, 10 seeds, max
        26.6 -> 23.9 s); the light pull on past the line keeps vision noise and the far field of
        a pulse that moves another part from unsorting a part just over it. A lost part (NaN)
        counts as the plate's width at both weights, bent."""
        q = positions_of(state, positions)
        side = self._side(state)
        on = side != 0
        # in place where it can be: a planner scores (K, R, M) layouts at once, and every fresh
        # array of that size costs its page faults
        x = q[..., on, 0] * side[on]  # the labelled parts' way along their sides
        near = np.subtract(self.line + self.clear, x)
        np.maximum(near, 0.0, out=near)
        far = np.subtract(self.line + 0.5 * self.past, x, out=x)
        np.maximum(far, 0.0, out=far)
        reach = self.REACH * 2 * self.half
        far *= self.FAR
        cost = np.multiply(near, self.NEAR / reach)  # NEAR d (1 + d / reach) + FAR f
        cost += self.NEAR
        cost *= near
        cost += far
        # a lost part as the plate's side at both weights, bent
        width = 2 * self.half
        cost[~np.isfinite(cost)] = self.NEAR * width * (1 + width / reach) + self.FAR * width
        out: FloatArray = np.sum(cost, axis=-1)
        return out

    def done(self, state: State) -> bool:
        """Every labelled part beyond its line, and none lost: at least as many labelled parts
        seen now as on the first cycle (a part that fell off the plate is missing for good; the
        tracker may give a part a new id, so ids are not counted)."""
        e = self.errors(state)
        sorted_ = e[np.isfinite(e)]
        if self.expected is None:
            self._fits(state)
            self.expected = len(sorted_)
        return bool(len(sorted_) and len(sorted_) >= self.expected and np.all(sorted_ <= 0.0))


class GatherTask:
    """Every part into a pile: within ``radius`` [m] of ``center`` (what a sink does without sensing,
    docs/ppod.md). Steps point at the centre, ``gain`` of the way beyond ``radius / 2``, at most
    ``max_step``; lost parts (NaN) are not done."""

    def __init__(
        self,
        center: ArrayLike = (0.0, 0.0),
        *,
        radius: float = 0.04,
        gain: float = 0.8,
        max_step: float = 0.03,
    ) -> None:
        self.center = np.asarray(point("center", center), dtype=np.float64)
        for name, v in (("radius", radius), ("gain", gain), ("max_step", max_step)):
            if not (math.isfinite(v) and v > 0):
                raise ParameterError(f"{name} must be finite and > 0; got {v!r}")
        self.radius, self.gain, self.max_step = float(radius), float(gain), float(max_step)

    def targets(self, state: State) -> FloatArray:
        """The centre, for every part [m]."""
        return np.broadcast_to(self.center, state.positions.shape).copy()

    def lines(self) -> list[FloatArray]:
        """The circle the parts must end within [m]."""
        a = np.linspace(0.0, 2 * np.pi, 65)
        return [self.center + self.radius * np.stack([np.cos(a), np.sin(a)], axis=-1)]

    def errors(self, state: State) -> FloatArray:
        d = state.positions - self.center
        out: FloatArray = np.maximum(np.hypot(d[:, 0], d[:, 1]) - self.radius, 0.0)
        return out

    def cost(self, state: State, positions: FloatArray | None = None, elapsed: ArrayLike = 0.0) -> FloatArray:
        """Sum of the parts' distances beyond ``radius`` from the centre [m] (a lost part: 1 m)."""
        q = positions_of(state, positions)
        return distance_sum(q, np.broadcast_to(self.center, q.shape), self.radius)

    def steps(self, state: State) -> FloatArray:
        d = self.center - state.positions
        r = np.hypot(d[:, 0], d[:, 1])
        want = np.maximum(r - 0.5 * self.radius, 0.0) / np.maximum(r, 1e-300)
        return clip(np.where(np.isfinite(d), d * (self.gain * want)[:, None], 0.0), self.max_step)

    def done(self, state: State) -> bool:
        e = self.errors(state)
        return bool(len(e) and np.all(np.isfinite(state.positions)) and np.all(e <= 0.0))


class WatchTask:
    """Asks for nothing; done after ``cycles`` cycles (for open-loop flows under a
    :class:`~upm.control.FixedPlanner`, watched through the same loop)."""

    def __init__(self, cycles: int) -> None:
        if cycles < 1:
            raise ParameterError(f"cycles must be >= 1; got {cycles}")
        self.cycles = int(cycles)

    def steps(self, state: State) -> FloatArray:
        return np.full_like(state.positions, np.nan)  # nothing asked: every component free

    def done(self, state: State) -> bool:
        return state.cycle >= self.cycles

    def errors(self, state: State) -> FloatArray:
        return np.zeros(len(state.positions))

    def cost(self, state: State, positions: FloatArray | None = None, elapsed: ArrayLike = 0.0) -> FloatArray:
        """Nothing to do: zero."""
        q = positions_of(state, positions)
        return np.zeros(q.shape[:-2])
