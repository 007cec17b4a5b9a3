"""The published Chladni-plate controller, re-implemented as a peer: greedy, one step, a fixed library.

Kopitca, Latifi & Zhou (*Science Advances* 7:eabi7716, 2021) assemble up to 100 particles on a
plate driven by one piezo. Their controller has no physics model: for each of a fixed set of
vibration notes it holds a map of the displacement a particle makes from any point of the plate
(learned from recordings). Each step it matches the particles to the target points (Hungarian
assignment; the shape may turn, Kabsch alignment), predicts every particle's displacement under
every note from the maps, and plays the note that lowers the total squared distance most.

:class:`GreedyLibraryPlanner` is that algorithm on upm's plate. The library is a fixed set of
pulses sized within the drive's force and stroke (translations, rotations about a lattice of
centres, jets at a lattice of foci); its maps are computed once by upm's exact simulator (point
parts on a lattice of nodes, slid to rest) instead of learned, and read by linear interpolation
(``scipy.interpolate.RegularGridInterpolator``). The assignment and the alignment are the task's
(:class:`upm.control.ShapeTask` solves both every cycle); for a task without target points (a
sort) the task's own cost is lowered instead of the squared distance.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._errors import ParameterError
from ..plate.drive import DriveLimits
from ..plate.pulses import Pulse
from .candidates import generate
from .goals import PositionsView, StepsGoal
from .sizing import positive

__all__ = ["GreedyLibraryPlanner", "default_library"]

FloatArray = NDArray[np.float64]


def default_library(
    limits: DriveLimits,
    *,
    on_times: Sequence[float] = (0.2, 0.5),
    frequencies: Sequence[float] = (25.0, 35.0, 50.0, 70.0),
    use: float = 0.85,
) -> list[Pulse]:
    """A fixed library of pulses at the largest amplitude the drive allows (``use`` of its force
    and stroke headroom), each at the best of ``frequencies``, for each of ``on_times`` [s]:
    translations along 8 directions; rotations both ways about a 3 x 3 lattice over the plate's
    middle half, about points of its middle lines beyond it, and about a 3 x 3 lattice of foci
    at a quarter of the plate's side; jets at those foci along 4 directions (radius a fifth of the
    side). About 110 pulses an on-time."""
    q = limits.size / 4
    foci = np.array([(x, y) for x in (-q, 0.0, q) for y in (-q, 0.0, q)])
    made = generate(
        limits,
        foci,
        frequencies=tuple(float(f) for f in frequencies),
        on_times=tuple(float(t) for t in on_times),
        rotation_on_times=tuple(float(t) for t in on_times),
        jet_on_times=tuple(float(t) for t in on_times),
        grid=3,
        directions=8,
        jet_radii=(limits.size / 5,),
        jet_directions=4,
        fine=(),
        use=use,
    )
    return list(made.pulses)


class GreedyLibraryPlanner:
    """Greedy one-step planner over a fixed library of pulses with displacement maps (see the
    module docstring): the peer of :class:`~upm.plan.PredictivePlanner`.

    Parameters
    ----------
    limits : DriveLimits
        The device's plate, motors and stroke.
    mu, mu_s : float
        Friction the maps are computed with.
    library : sequence of Pulse, optional
        The notes (default :func:`default_library`).
    resolution : int
        The maps' lattice: ``resolution x resolution`` nodes over the plate.
    use : float
        Fraction of the stroke a note may take (the library's sizing); a note's rest is long
        enough for the plate's leftover motion to fit in the rest of the stroke.
    guard : float
        A note predicted to leave a part within this of an edge [m] is not played.
    """

    def __init__(
        self,
        limits: DriveLimits,
        *,
        mu: float = 0.3,
        mu_s: float | None = None,
        library: Sequence[Pulse] | None = None,
        resolution: int = 33,
        use: float = 0.85,
        guard: float = 0.015,
    ) -> None:
        from .predictive import PredictivePlanner

        if not isinstance(limits, DriveLimits):
            raise ParameterError(f"limits must be a upm.DriveLimits; got {type(limits).__name__}")
        if isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer)) or resolution < 2:
            raise ParameterError(f"resolution must be an integer >= 2; got {resolution!r}")
        if not 0 < use <= 1:
            raise ParameterError(f"use must be in (0, 1]; got {use!r}")
        self.limits, self.mu, self.use = limits, positive("mu", mu), float(use)
        self.guard = float(guard)
        if not (math.isfinite(self.guard) and 0 <= self.guard < limits.size / 2):
            raise ParameterError(f"guard must be in [0, {limits.size / 2:g}) m; got {guard!r}")
        notes = default_library(limits, use=use) if library is None else list(library)
        if not notes or not all(isinstance(p, Pulse) and p.kind != "rest" for p in notes):
            raise ParameterError("library must hold at least one upm.Pulse, none of them a rest")
        self.library = [replace(p, rest=0.0) for p in notes]
        half = limits.size / 2
        self.axis = np.linspace(-half, half, int(resolution))
        nodes = np.stack(np.meshgrid(self.axis, self.axis, indexing="ij"), axis=-1).reshape(-1, 2)
        predictor = PredictivePlanner(limits, mu=mu, mu_s=mu_s, lookahead=None, pairs=None, aligned=0)
        final, durations = predictor.predict(self.library, nodes)
        g = int(resolution)
        self.maps = (final - nodes[None]).reshape(len(notes), g, g, 2)
        """Displacement of a resting part from each node ``(K, G, G, 2)`` [m] after each note."""
        self.rests = np.array([self._rest(p, float(d)) for p, d in zip(self.library, durations, strict=True)])
        """Each note's rest [s]: until its parts stop and the plate's leftover motion fits the
        stroke the next note leaves."""
        from scipy.interpolate import RegularGridInterpolator

        values = self.maps.transpose(1, 2, 0, 3)  # (G, G, K, 2)
        self._interp = RegularGridInterpolator(
            (self.axis, self.axis), values, bounds_error=False, fill_value=None
        )
        self.expected: tuple[NDArray[np.int64], FloatArray] | None = None

    def _rest(self, pulse: Pulse, settled: float) -> float:
        """The rest after ``pulse``: its parts' stop (``settled`` [s] from its start) and the
        plate's free motion after, superposed on the next note's, within the stroke."""
        margin = (1.0 - self.use) * self.limits.stroke
        long = replace(pulse, rest=2.0)
        pose, _ = self.limits.play(long, sample_rate=1000.0)
        reach = self.limits.excursions(pose)
        carried = np.maximum.accumulate(reach[::-1])[::-1]  # the largest excursion from then on
        t = np.arange(len(reach)) / 1000.0
        fits = np.nonzero((carried <= margin) & (t >= pulse.on_time))[0]
        free = float(t[fits[0]] if len(fits) else t[-1]) - pulse.on_time
        return max(free, settled - pulse.on_time, 0.0) + 0.01

    def displacements(self, positions: FloatArray) -> FloatArray:
        """Each note's predicted displacement of parts at ``positions (M, 2)``: ``(K, M, 2)`` [m]."""
        p = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
        out: FloatArray = np.asarray(self._interp(np.nan_to_num(p)), dtype=np.float64).transpose(1, 0, 2)
        return out

    def plan_task(self, state: Any, task: Any) -> list[Pulse]:
        """The note that lowers the parts' total squared distance to the task's target points
        most (``task.targets(state)``), or, for a task without points, the task's ``cost``; none
        when no note lowers it."""
        pos = np.asarray(state.positions, dtype=np.float64)
        self.expected = None
        if not len(pos):
            return []
        after = pos[None] + self.displacements(pos)  # (K, M, 2)
        targets = getattr(task, "targets", None)
        if targets is not None:
            goal = np.asarray(targets(state), dtype=np.float64)
            has = np.all(np.isfinite(goal), axis=1)
            now = float(np.sum((pos[has] - goal[has]) ** 2))
            cost = np.sum((after[:, has] - goal[has][None]) ** 2, axis=(1, 2))
        else:
            now = float(np.asarray(task.cost(state, pos[None], 0.0), dtype=float).reshape(-1)[0])
            cost = np.asarray(task.cost(state, after, 0.0), dtype=float).reshape(-1)
        edge = self.limits.size / 2 - self.guard
        cost = np.where(np.any(np.abs(after) > edge, axis=(1, 2)), np.inf, cost)
        best = int(np.argmin(cost))
        if not cost[best] < now:
            return []
        ids = np.asarray(getattr(state, "ids", np.arange(len(pos))), dtype=np.int64)
        self.expected = (ids.copy(), after[best])
        return [replace(self.library[best], rest=float(self.rests[best]))]

    def plan(self, positions: FloatArray, steps: FloatArray) -> list[Pulse]:
        """Without a task: the note that brings the parts closest to ``positions + steps`` (NaN
        components free)."""
        pos = np.asarray(positions, dtype=np.float64)
        goal = pos + np.asarray(steps, dtype=np.float64)
        return self.plan_task(PositionsView(pos), StepsGoal(goal))

    def __repr__(self) -> str:
        return f"GreedyLibraryPlanner({len(self.library)} notes, mu={self.mu:g}, maps {len(self.axis)}^2)"
