"""Long pulses as displacement tables: the predictive planner's look-ahead.

A rotation about ``C`` moves a resting part at ``P`` by a displacement that depends only on
``|P - C|``, turned with ``P - C`` (the plate's velocity, ``w R90(P - C)``, is symmetric about
``C``); a translation moves every resting part alike. So each "macro" pulse (a long rotation about
a centre, a long translation) is simulated once, on a ray of parts at increasing distances from its
centre (exact integrator, point parts), and then applied to any layout by interpolation: thousands
of layouts per millisecond. The planner scores each candidate by the better of its own gain per
second and the gain per second of the candidate followed by the best macro, so a pulse that sets
the parts up for one long rotation (colours on either side of a line) is worth playing.

The table ignores part–part contacts and the plate's edges (the planner's penalties see where the
parts would end); it is rebuilt when the planner's friction estimate moves by more than 5 %.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from .. import _core
from ..physics.sim import simulate_batch
from ..plate.drive import DriveLimits
from ..plate.pulses import Pulse
from .candidates import Candidates, generate
from .sizing import scaled, slide_to_rest

__all__ = ["MacroTable"]

FloatArray = NDArray[np.float64]


class MacroTable:
    """Displacement tables of long pulses (see the module docstring).

    Parameters
    ----------
    limits : DriveLimits
    mu, mu_s : float
        Friction of the parts.
    on_time : float
        On-time of every macro pulse [s].
    centres : (N, 2) array_like, optional
        Centres of the macro rotations (default: the plate's two middle lines, from past one edge
        to past the other, and its centre).
    directions : int
        Translations along this many evenly spread directions.
    """

    def __init__(
        self,
        limits: DriveLimits,
        *,
        mu: float,
        mu_s: float | None = None,
        on_time: float = 1.0,
        centres: Sequence[Sequence[float]] | None = None,
        directions: int = 8,
        frequencies: tuple[float, ...] = (25.0, 35.0, 50.0, 70.0),
    ) -> None:
        self.limits, self.mu, self.on_time = limits, float(mu), float(on_time)
        self.static = 1.0 if mu_s is None else float(mu_s) / self.mu  # mu_s / mu, kept as mu moves
        if centres is None:
            line = np.linspace(-0.75 * limits.size, 0.75 * limits.size, 13)
            c = np.vstack(
                [np.stack([np.zeros_like(line), line], 1), np.stack([line, np.zeros_like(line)], 1)]
            )
            at = np.unique(np.round(c, 9), axis=0)
        else:
            at = np.asarray(centres, dtype=float).reshape(-1, 2)
        # translations, and rotations about the centres (each "part" here), at their best frequency
        made = generate(limits, at, frequencies=frequencies, on_times=(self.on_time,), directions=directions,
                        grid=0, jet_radii=(), jet_directions=0, fine=())  # fmt: skip
        keep = np.isin(made.family, ("part-rotation", "translation"))
        order = np.argsort(made.family[keep] != "part-rotation", kind="stable")  # rotations first
        self.sized = Candidates(
            [made.pulses[k] for k in np.nonzero(keep)[0][order]],
            np.full(int(keep.sum()), "macro"),
            made.force[keep][order],
            made.excursion[keep][order],
        )
        self.pulses: list[Pulse] = self.sized.pulses
        self.rotations = [p for p in self.pulses if p.kind == "rotation"]
        self.translations = [p for p in self.pulses if p.kind == "translation"]
        self.radii = np.concatenate([[0.0], np.geomspace(0.003, 1.2 * limits.size, 47)])
        self._playable: dict[float, Candidates] = {}  # by the share of the stroke left
        self._build()

    def _build(self) -> None:
        """Simulate every macro once, in one batched call: a rotation's effect on a part depends
        only on where the part is from its centre (the plate's velocity there is
        ``w R90(P - C)``), so every rotation is played about the origin on one ray of parts, and
        the translations on the same ray (they move every part alike)."""
        about_origin = [replace(p, center=(0.0, 0.0)) if p.kind == "rotation" else p for p in self.pulses]
        motions = [p.motion(rest=False) for p in about_origin]
        ray = np.stack([self.radii, np.zeros(len(self.radii))], 1)
        dt = 1.0 / (40.0 * max(m.max_frequency for m in motions))
        # simulated while the plate moves; the parts then slide to rest in closed form
        run = simulate_batch(motions, ray, duration=self.on_time, dt=dt, mu=self.mu,
                             mu_s=self.mu * self.static, record_every=2**40)  # fmt: skip
        final, stop = slide_to_rest(run.positions[:, -1], run.velocities[:, -1], self.mu)
        moved = final - ray[None]
        n_rot = len(self.rotations)
        self.turn = np.ascontiguousarray(moved[:n_rot])  # displacement of a part at (r, 0) from the centre
        self.shift = np.ascontiguousarray(moved[n_rot:, 0])
        inside = self.radii <= 0.75 * self.limits.size  # parts that can be on the plate
        self.durations = self.on_time + np.concatenate(
            [np.max(stop[:n_rot, inside], axis=1, initial=0.0), stop[n_rot:, 0]]
        )
        self.centres = np.array([p.center for p in self.rotations], dtype=np.float64).reshape(-1, 2)

    def playable(self, carried: float = 0.0, share: float = 1.0) -> Candidates:
        """The macro pulses as candidates, their amplitude lowered in proportion to the stroke
        that the plate's leftover motion (``carried`` [m]) leaves, and to ``share`` of it."""
        room = share * min(1.0, max(self.limits.stroke - carried, 0.0) / self.limits.stroke)
        if room >= 1.0:
            return self.sized
        room = math.floor(room * 80) / 80  # down to 1/80 of the stroke: the sets recur
        hit = self._playable.get(room)
        if hit is not None:
            return hit
        pulses = [
            replace(p, amplitude=p.amplitude * room)
            if p.kind == "jet"
            else replace(p, waveform=scaled(p.waveform, room))  # type: ignore[arg-type]
            for p in self.pulses
        ]
        out = Candidates(pulses, self.sized.family, self.sized.force * room, self.sized.excursion * room)
        self._playable[room] = out
        return out

    def refresh(self, mu: float) -> None:
        """Rebuild for a new friction estimate when it moved by more than 5 %."""
        if abs(mu / self.mu - 1.0) > 0.05:
            self.mu = float(mu)
            self._build()

    def apply(self, positions: FloatArray) -> FloatArray:
        """Positions ``(..., n_macro, M, 2)`` after each macro pulse from ``positions (..., M, 2)``
        (resting parts; NaN stays NaN): linear interpolation in each macro's table, turned with
        the part about its centre, in the extension (``upm_core::plan``)."""
        q = np.ascontiguousarray(positions, dtype=np.float64)
        lead, m = q.shape[:-2], q.shape[-2]
        out: FloatArray = _core.apply_rays(
            q.reshape(-1, m, 2), self.radii, self.centres, self.turn, self.shift
        )
        return out.reshape(*lead, out.shape[1], m, 2)
