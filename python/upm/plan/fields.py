"""Planning with velocity fields on a plate that moves out of its plane (docs/ppod.md).

:class:`FieldPlanner` plays one field pulse a cycle: from the PPOD2 library and, when the task's
steps point the parts at a common place, a sink designed there (:func:`upm.design_field`, cached
on a 5 mm grid). Each candidate's drift field is computed once on a grid over the plate (the exact
stick–slip drift at the planner's ``mu``); a pulse's outcome is predicted by carrying every part
through the interpolated field for the pulse's effective time, and the planner plays the pulse
that brings the parts closest to their steps' ends per second of plate time. Fields move every
part at once, so this planner serves collective tasks (gathering, carrying a group, positioning
one part) rather than independent goals.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._errors import ParameterError
from ..physics.motion import PlateMotion
from ..physics.ppod import PPOD_FIELDS, drift_field
from ..plate.pulses import Pulse
from .field_design import design_field

__all__ = ["FieldPlanner"]

FloatArray = NDArray[np.float64]

DEFAULT_FIELDS = ("Sink", "Source", "Whirlpool", "Centrifuge", "TransX", "TransNegX", "TransY", "TransNegY",
                  "LineSinkX", "LineSinkY", "ShearX", "ShearY")  # fmt: skip


class _Grid:
    """A velocity field sampled on a square grid, bilinearly interpolated (zero outside)."""

    def __init__(self, motion: PlateMotion, half: float, n: int, mu: float) -> None:
        self.xs = np.linspace(-half, half, n)
        pts = np.stack(np.meshgrid(self.xs, self.xs), axis=-1)
        self.v = drift_field(motion, pts, mu=mu, steps=400, tol=1e-5).velocity  # (n, n, 2): [y, x]
        self.half, self.h = half, self.xs[1] - self.xs[0]

    def __call__(self, q: FloatArray) -> FloatArray:
        n = len(self.xs)
        fx = (q[..., 0] + self.half) / self.h
        fy = (q[..., 1] + self.half) / self.h
        inside = (fx >= 0) & (fx <= n - 1) & (fy >= 0) & (fy <= n - 1)
        i = np.clip(np.floor(np.nan_to_num(fx)), 0, n - 2).astype(int)
        j = np.clip(np.floor(np.nan_to_num(fy)), 0, n - 2).astype(int)
        tx = np.clip(np.nan_to_num(fx) - i, 0, 1)[..., None]
        ty = np.clip(np.nan_to_num(fy) - j, 0, 1)[..., None]
        v = self.v
        out = (1 - ty) * ((1 - tx) * v[j, i] + tx * v[j, i + 1]) + ty * (
            (1 - tx) * v[j + 1, i] + tx * v[j + 1, i + 1]
        )
        out = np.asarray(np.where(inside[..., None], out, 0.0))
        return out


def _focus(q: FloatArray, s: FloatArray) -> FloatArray | None:
    """Where the steps ``s`` from ``q`` lead together: one part's step end, or the point nearest
    (least squares) to every moving part's line of travel when those lines pass within 1 cm of it;
    None otherwise."""
    moving = np.hypot(s[:, 0], s[:, 1]) > 1e-4
    if not moving.any():
        return None
    if moving.sum() == 1:
        out: FloatArray = (q + s)[moving][0]
        return out
    d = s[moving] / np.hypot(s[moving, 0], s[moving, 1])[:, None]
    p = q[moving]
    proj = np.eye(2)[None] - d[:, :, None] * d[:, None, :]  # onto each line's normal
    a = proj.sum(axis=0)
    if np.linalg.cond(a) > 1e6:
        return None
    c = np.linalg.solve(a, np.einsum("kij,kj->i", proj, p))
    miss = np.einsum("kij,kj->ki", proj, c - p)
    return c if float(np.sqrt(np.mean(np.sum(miss**2, axis=1)))) < 0.01 else None


class FieldPlanner:
    """One velocity-field pulse a cycle, chosen by predicting every part through each candidate's
    drift field (see the module).

    Parameters
    ----------
    fields : names of library fields (:data:`upm.PPOD_FIELDS`) to choose from.
    mu : the friction coefficient the drift fields are computed for.
    design : also offer a sink designed at the parts' common goal (when their steps agree on one).
    durations : sustains to choose from [s]; each pulse ramps over ``ramp`` periods at each end.
    extent : half the side of the square the fields are sampled on [m] (the plate's half side).
    rest : rest after each pulse [s].
    """

    def __init__(
        self,
        fields: Sequence[str] = DEFAULT_FIELDS,
        *,
        mu: float = 0.3,
        design: bool = True,
        durations: Sequence[float] = (0.25, 0.5, 1.0, 2.0),
        extent: float = 0.15,
        grid: int = 25,
        ramp: int = 2,
        rest: float = 0.05,
        strength: float = 0.5,
    ) -> None:
        unknown = [f for f in fields if f not in PPOD_FIELDS]
        if unknown or not fields:
            raise ParameterError(f"fields must be names of PPOD_FIELDS; unknown: {unknown or 'none given'}")
        if not (mu > 0 and extent > 0 and grid >= 5 and ramp >= 0 and rest >= 0 and strength > 0):
            raise ParameterError("mu, extent and strength must be > 0, grid >= 5, ramp and rest >= 0")
        if not durations or min(durations) <= 0:
            raise ParameterError(f"durations must be positive seconds; got {list(durations)}")
        self.mu, self.design, self.extent, self.n = float(mu), bool(design), float(extent), int(grid)
        self.durations, self.ramp, self.rest, self.strength = (
            tuple(map(float, durations)),
            ramp,
            rest,
            strength,
        )
        self.candidates: dict[str, tuple[PlateMotion, _Grid, tuple[float, float]]] = {}
        for name in fields:
            m = PlateMotion.ppod(name)
            self.candidates[name] = (m, _Grid(m, self.extent, self.n, self.mu), (0.0, 0.0))
        self._designed: dict[tuple[int, int], tuple[PlateMotion, _Grid, tuple[float, float]]] = {}
        self.chosen: list[str] = []
        """The candidate played each cycle (``"sink@(x, y)"`` for a designed sink)."""

    def _sink_at(self, goal: FloatArray) -> tuple[str, tuple[PlateMotion, _Grid, tuple[float, float]]]:
        key = (round(goal[0] / 0.005), round(goal[1] / 0.005))
        if key not in self._designed:
            c = (key[0] * 0.005, key[1] * 0.005)
            m = design_field("sink", c, self.strength, mu=self.mu).motion
            self._designed[key] = (m, _Grid(m, self.extent, self.n, self.mu), c)
        c = self._designed[key][2]
        return f"sink@({c[0]:.3f}, {c[1]:.3f})", self._designed[key]

    @staticmethod
    def _carry(field: _Grid, q: FloatArray, seconds: FloatArray) -> FloatArray:
        """Positions ``(D, M, 2)`` after ``seconds (D,)`` in ``field`` (midpoint steps of <= 0.05 s)."""
        out = np.repeat(q[None], len(seconds), axis=0)
        steps = int(np.ceil(np.max(seconds) / 0.05))
        h = (seconds / steps)[:, None, None]
        for _ in range(steps):
            mid = out + 0.5 * h * field(out)
            out = out + h * field(mid)
        return out

    def plan(self, positions: FloatArray, steps: FloatArray) -> list[Pulse]:
        q = np.asarray(positions, dtype=np.float64)
        s = np.asarray(steps, dtype=np.float64)
        seen = np.all(np.isfinite(q), axis=1)
        target = q + s
        ask = np.isfinite(target) & seen[:, None]
        if not ask.any():
            return []
        q0 = np.where(seen[:, None], q, 0.0)

        def cost(p: FloatArray) -> FloatArray:
            d = np.where(ask, target - p, 0.0)
            out: FloatArray = np.sum(d**2, axis=(-1, -2))
            return out

        now = float(cost(q0))
        options = dict(self.candidates)
        focus = _focus(q0[np.all(ask, axis=1)], s[np.all(ask, axis=1)])
        if self.design and focus is not None and np.all(np.abs(focus) < self.extent):
            name, entry = self._sink_at(focus)
            options[name] = entry
        durations = np.array(self.durations)
        best: tuple[float, str, float] = (0.0, "", 0.0)
        for name, (motion, field, _) in options.items():
            period = 1.0 / motion.max_frequency
            ramp = self.ramp * period
            effective = durations + ramp  # the raised-cosine ramps count half each
            after = cost(self._carry(field, q0, effective))
            rate = (now - after) / (durations + 2 * ramp + self.rest)
            k = int(np.argmax(rate))
            if rate[k] > best[0]:
                best = (float(rate[k]), name, float(durations[k]))
        if not best[1]:
            return []
        name = best[1]
        motion, _, center = options[name]
        ramp = self.ramp / motion.max_frequency
        self.chosen.append(name)
        return [Pulse.field(motion, ramp, best[2], ramp, self.rest, center=center)]

    def __repr__(self) -> str:
        return f"FieldPlanner({len(self.candidates)} library fields, design={self.design}, mu={self.mu:g})"

    def describe(self) -> dict[str, Any]:
        """What it chose so far: counts per candidate."""
        names, counts = np.unique(self.chosen, return_counts=True)
        return {str(n): int(c) for n, c in zip(names, counts, strict=True)}
