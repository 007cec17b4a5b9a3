"""Actions of the environments: one enveloped pulse from a vector of numbers in ``[-1, 1]``, sized
within the drive's force and stroke, for a whole batch at once.

An action ``a`` (7 numbers; anything outside ``[-1, 1]`` is clipped, never refused):

====  ====================================================================================
a[0]  kind: translation below -1/3, rotation up to 1/3, jet above
a[1]  centre x: a rotation's over ``+-0.75`` plate sides, a jet's over the plate (``+-1/2``)
a[2]  centre y, likewise
a[3]  direction ``pi a[3]`` of a translation or a jet; a rotation's sense (``>= 0``: counter-clockwise)
a[4]  amplitude: ``(a[4] + 1) / 2`` of the largest the force and the stroke allow (0: a rest)
a[5]  drive frequency: the nearest of :data:`FREQUENCIES` over ``[-1, 1]``
a[6]  on-time: the nearest of :data:`ON_TIMES` over ``[-1, 1]``
====  ====================================================================================

Sizing: a pulse's motor forces and its plate-corner excursion are linear in its amplitude, so
each shape is sized once at unit amplitude by :meth:`upm.drive.DriveLimits.reach` on a lattice
of centres and directions per frequency and on-time (a table built once per set of limits). For a
centre between lattice nodes the largest of the cell's four corners bounds it (force and
excursion are convex in the centre: a maximum of norms of affine maps); for a direction between
two nodes the larger, with :data:`USE` of the headroom kept as margin for the arc between them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from .._errors import ParameterError
from ..physics.waveforms import Harmonics
from ..plan.candidates import _unit_phasors
from ..plate.drive import DriveLimits
from ..plate.pulses import Pulse

__all__ = [
    "ACTION_SIZE",
    "FREQUENCIES",
    "JET_RADIUS",
    "ON_TIMES",
    "USE",
    "Decoded",
    "PulseActions",
    "library",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Numbers in one action.
ACTION_SIZE = 7
#: Drive frequencies an action picks from [Hz].
FREQUENCIES = (25.0, 35.0, 50.0)
#: On-times an action picks from [s].
ON_TIMES = (0.15, 0.3, 0.5)
#: A jet's radius [m] (where its two terms have equal peaks, 6.4).
JET_RADIUS = 0.04
#: Fraction of the force and stroke headroom the largest amplitude uses.
USE = 0.97
KINDS = ("translation", "rotation", "jet")
_DIRECTIONS = {"translation": 64, "jet": 32}
_CENTRES = {"rotation": (17, 0.75), "jet": (9, 0.5)}  # lattice nodes a side, half-span [plate sides]
_SAMPLES = 1024


def _timing(jet: ArrayLike, frequency: ArrayLike, on: ArrayLike) -> tuple[Any, Any]:
    """Attack (= decay) and sustain [s]: 3 drive periods of ramp, jets 4 (as the planner's), at
    most half the on-time (scalars or arrays alike)."""
    attack = np.minimum(np.where(jet, 4.0, 3.0) / np.asarray(frequency), np.asarray(on) / 2)
    return attack, np.asarray(on) - 2 * attack


@dataclass(frozen=True)
class Decoded:
    """A batch of ``B`` decoded actions."""

    kind: IntArray
    """0 translation, 1 rotation, 2 jet."""
    center: FloatArray
    direction: FloatArray
    amplitude: FloatArray
    """[m/s] (translations, jets) or [rad/s] (rotations, signed by the sense); 0: a rest."""
    frequency: IntArray
    """Index into :data:`FREQUENCIES`."""
    on: IntArray
    """Index into :data:`ON_TIMES`."""

    def __len__(self) -> int:
        return len(self.kind)


_TABLES: dict[str, dict[str, tuple[FloatArray, FloatArray]]] = {}


class PulseActions:
    """Decodes actions (see the module docstring) into pulses within ``limits``."""

    def __init__(self, limits: DriveLimits) -> None:
        if not isinstance(limits, DriveLimits):
            raise ParameterError(f"limits must be a upm.DriveLimits; got {type(limits).__name__}")
        self.limits = limits
        key = repr(limits)
        if key not in _TABLES:
            _TABLES[key] = self._tables()
        self.tables = _TABLES[key]

    # -- sizing tables ------------------------------------------------------------------------
    def _nodes(self, kind: str) -> tuple[FloatArray, FloatArray]:
        """Centres ``(C, 2)`` and directions ``(D, 2)`` of ``kind``'s lattice."""
        if kind in _CENTRES:
            n, span = _CENTRES[kind]
            line = np.linspace(-span, span, n) * self.limits.size
            centres = np.stack(np.meshgrid(line, line, indexing="ij"), -1).reshape(-1, 2)
        else:
            centres = np.zeros((1, 2))
        d = _DIRECTIONS.get(kind, 1)
        angle = 2 * np.pi * np.arange(d) / d
        return centres, np.stack([np.cos(angle), np.sin(angle)], 1)

    def _tables(self) -> dict[str, tuple[FloatArray, FloatArray]]:
        """Unit-amplitude peak force [N] and corner excursion [m] of each kind per frequency,
        on-time, centre and direction: ``(F, T, C, D)`` each."""
        out = {}
        for kind in KINDS:
            centres, dirs = self._nodes(kind)
            ph = np.stack(
                [_unit_phasors(kind, c, d, JET_RADIUS) for c in centres for d in dirs]
            )  # (C D, 3, 3)
            force = np.empty((len(FREQUENCIES), len(ON_TIMES), len(centres), len(dirs)))
            reach = np.empty_like(force)
            for i, f in enumerate(FREQUENCIES):
                for j, on in enumerate(ON_TIMES):
                    a, s = _timing(kind == "jet", f, on)
                    fo, ex = self.limits.reach(ph, f, a, s, a, samples=_SAMPLES)
                    force[i, j] = fo.reshape(len(centres), len(dirs))
                    reach[i, j] = ex.reshape(len(centres), len(dirs))
            out[kind] = (force, reach)
        return out

    def _bound(
        self, kind: str, fi: IntArray, oi: IntArray, center: FloatArray, angle: FloatArray
    ) -> FloatArray:
        """Largest amplitude ``(n,)`` of ``kind`` at each centre and direction angle [rad] within
        the limits: the bound over the enclosing lattice cell and directions."""
        force, reach = self.tables[kind]
        n = len(fi)
        if kind in _CENTRES:
            k, span = _CENTRES[kind]
            u = (center / (span * self.limits.size) + 1) / 2 * (k - 1)  # lattice units
            lo = np.clip(np.floor(u), 0, k - 2).astype(np.int64)
            cells = [(lo[:, 0] + dx) * k + lo[:, 1] + dy for dx in (0, 1) for dy in (0, 1)]
        else:
            cells = [np.zeros(n, dtype=np.int64)]
        d = force.shape[-1]
        if d > 1:
            step = 2 * np.pi / d
            j0 = np.floor(np.mod(angle, 2 * np.pi) / step).astype(np.int64) % d
            ways = [j0, (j0 + 1) % d]
        else:
            ways = [np.zeros(n, dtype=np.int64)]
        f_max = np.zeros(n)
        r_max = np.zeros(n)
        for c in cells:
            for w in ways:
                f_max = np.maximum(f_max, force[fi, oi, c, w])
                r_max = np.maximum(r_max, reach[fi, oi, c, w])
        out: FloatArray = USE * np.minimum(
            self.limits.force / np.maximum(f_max, 1e-300), self.limits.stroke / np.maximum(r_max, 1e-300)
        )
        return out

    # -- decoding -----------------------------------------------------------------------------
    def decode(self, actions: ArrayLike) -> Decoded:
        """Actions ``(B, 7)`` (clipped into ``[-1, 1]``; NaN counts as 0) as pulses."""
        a = np.nan_to_num(np.asarray(actions, dtype=np.float64).reshape(-1, ACTION_SIZE), nan=0.0)
        a = np.clip(a, -1.0, 1.0)
        b = len(a)
        kind = np.where(a[:, 0] < -1 / 3, 0, np.where(a[:, 0] <= 1 / 3, 1, 2)).astype(np.int64)
        fi = np.rint((a[:, 5] + 1) / 2 * (len(FREQUENCIES) - 1)).astype(np.int64)
        oi = np.rint((a[:, 6] + 1) / 2 * (len(ON_TIMES) - 1)).astype(np.int64)
        angle = np.pi * a[:, 3]
        direction = np.stack([np.cos(angle), np.sin(angle)], 1)
        center = np.zeros((b, 2))
        top = np.zeros(b)
        for k, name in enumerate(KINDS):
            at = kind == k
            if not at.any():
                continue
            if name in _CENTRES:
                center[at] = a[at, 1:3] * _CENTRES[name][1] * self.limits.size
            top[at] = self._bound(name, fi[at], oi[at], center[at], angle[at])
        amplitude = (a[:, 4] + 1) / 2 * top
        amplitude = np.where(kind == 1, np.where(a[:, 3] >= 0, 1.0, -1.0) * amplitude, amplitude)
        direction[kind == 1] = 0.0
        return Decoded(kind, center, direction, amplitude, fi, oi)

    def motions(self, d: Decoded, rows: ArrayLike | None = None) -> list[Any]:
        """The core motions of decoded actions (``rows`` of them), enveloped, without a rest (in
        one call: :meth:`upm._core.PlateMotion.pulses`)."""
        at = np.arange(len(d)) if rows is None else np.asarray(rows, dtype=np.int64)
        f = np.asarray(FREQUENCIES)[d.frequency[at]]
        on = np.asarray(ON_TIMES)[d.on[at]]
        kind = d.kind[at]
        attack, sustain = _timing(kind == 2, f, on)
        amp = d.amplitude[at]
        return _core.PlateMotion.pulses(
            np.where(amp == 0.0, 3, kind).astype(np.int64), np.ascontiguousarray(d.center[at]),
            np.ascontiguousarray(d.direction[at]), amp, f, attack, sustain, JET_RADIUS,
        )  # fmt: skip

    def pulse(self, action: ArrayLike) -> Pulse:
        """One action as a :class:`upm.Pulse` (what a real plate would be sent)."""
        d = self.decode(np.asarray(action, dtype=np.float64).reshape(1, ACTION_SIZE))
        f, on, k, amp = FREQUENCIES[d.frequency[0]], ON_TIMES[d.on[0]], int(d.kind[0]), float(d.amplitude[0])
        if amp == 0.0:
            return Pulse.pause(on)
        a, s = (float(x) for x in _timing(k == 2, f, on))
        if k == 2:
            return Pulse.jet(d.center[0], d.direction[0], JET_RADIUS, amp, f, a, s, a)
        wave = Harmonics([amp, -amp / 2], [0.0, 0.0], f)
        if k == 0:
            return Pulse.translation(d.direction[0], wave, a, s, a)
        return Pulse.rotation(d.center[0], wave, a, s, a)


def library() -> FloatArray:
    """A fixed motion library as actions ``(K, 7)`` at full amplitude (the Chladni line's
    interface): translations along 8 directions at two on-times; rotations about a 5 x 5 lattice
    over the plate's middle, both senses, at two on-times; jets at a 3 x 3 lattice along 8
    directions. Middle frequency."""
    rows: list[list[float]] = []
    mid = 0.0  # the middle frequency
    for on in (-1.0, 0.0):
        for j in range(8):
            rows.append([-1.0, 0.0, 0.0, -1.0 + j / 4, 1.0, mid, on])
    lattice = np.linspace(-0.5, 0.5, 5) / 1.5  # over the middle half of the plate
    for on in (-1.0, 0.0):
        for x in lattice:
            for y in lattice:
                for sense in (1.0, -1.0):
                    rows.append([0.0, float(x), float(y), sense, 1.0, mid, on])
    for x in (-0.5, 0.0, 0.5):
        for y in (-0.5, 0.0, 0.5):
            for j in range(8):
                rows.append([1.0, x, y, -1.0 + j / 4, 1.0, mid, -1.0])
    return np.array(rows, dtype=np.float64)
