"""Planning poses: the pulse that best brings polygon parts towards target positions and angles,
chosen by simulating every candidate (issue 27, docs/polygons.md).

Candidates, within the plate's force and stroke (:meth:`upm.drive.DriveLimits.headroom`):

* rotations about a part's centroid, either way (the thesis's ``cos t - sin 2t`` drive as the
  plate's angular velocity: the part, at the centre, turns by stick–slip as a point part feeds,
  while parts farther out are carried round a little);
* jets centred on a part towards its goal (6.1: a strong push where the part is, little
  elsewhere), at twice the frequency (a jet's slow rotation term needs the stroke: at 35 Hz the
  plate plays a tenth of the amplitude it plays at 70 Hz), two widths, full and at 30 % (a
  nudge to finish).

Parts may have different shapes (``part`` a list of outlines, ``kinds`` naming each part's):
each is rolled out and scored as its own.

Each is rolled out by :func:`upm.simulate_batch` on the polygons as they are seen (the exact
stick–slip step; no contacts, for speed), through its rest until the parts stop, and scored by
``sum_i (d_i / position_scale)² + (a_i / angle_scale)²`` (``d`` the distance, ``a`` the angle
error modulo the outline's symmetry) plus ``edge_weight (e_i / position_scale)²`` for a centroid
``e_i`` into the band of width ``edge`` along the plate's edge; the best is played if it lowers
the score.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import as_float, instance, real
from .._errors import ParameterError, ShapeError
from ..physics.motion import PlateMotion
from ..physics.polygon import Polygon
from ..physics.sim import simulate_batch
from ..physics.waveforms import Harmonics
from ..plate.drive import DriveLimits
from ..plate.pulses import Pulse

__all__ = ["PosePlanner", "pose_errors"]

FloatArray = NDArray[np.float64]


def pose_errors(
    poses: FloatArray, targets: FloatArray, symmetry: int | NDArray[np.int64]
) -> tuple[FloatArray, FloatArray]:
    """Distances [m] and angle errors [rad, in ``(-pi/k, pi/k]``] of ``poses`` ``(N, 3)`` (x, y,
    angle) from ``targets`` ``(N, 3)`` for an outline of ``symmetry``-fold symmetry (or each
    part's, ``(N,)``)."""
    period = 2 * math.pi / np.asarray(symmetry)
    d = np.hypot(*(poses[:, :2] - targets[:, :2]).T)
    a = np.mod(poses[:, 2] - targets[:, 2] + period / 2, period) - period / 2
    return d, a


@dataclass
class PosePlanner:
    """Chooses each pulse by simulating the candidates (module docs). ``part``: the parts'
    outline, or a list of the outlines they may have (``kinds`` then index it)."""

    part: Polygon | Sequence[Polygon]
    limits: DriveLimits
    mu: float = 0.3
    mu_s: float | None = None
    frequency: float = 35.0
    position_scale: float = 0.005
    angle_scale: float = math.radians(5.0)
    sustains: tuple[float, ...] = (0.1, 0.3)
    edge: float = 0.04
    edge_weight: float = 10.0
    symmetry: int = field(init=False)
    shapes: list[Polygon] = field(init=False)
    symmetries: NDArray[np.int64] = field(init=False)

    def __post_init__(self) -> None:
        many = isinstance(self.part, (list, tuple)) and len(self.part) > 0
        if not many:
            instance("part", self.part, Polygon, "a upm.Polygon or a non-empty list of them")
        self.shapes = list(self.part) if many else [self.part]  # type: ignore[arg-type, list-item]
        for i, p in enumerate(self.shapes):
            instance(f"part[{i}]", p, Polygon, "a upm.Polygon")
        self.symmetries = np.array([p.symmetry for p in self.shapes], dtype=np.int64)
        instance("limits", self.limits, DriveLimits, "a upm.drive.DriveLimits (device.limits)")
        for name in ("mu", "frequency", "position_scale", "angle_scale"):
            real(name, getattr(self, name), low=0.0, low_open=True)
        self.symmetry = int(self.symmetries[0])
        if not self.sustains or min(self.sustains) <= 0:
            raise ParameterError(f"sustains must be positive times [s]; got {self.sustains!r}")

    def _kinds(self, kinds: ArrayLike | None, n: int) -> NDArray[np.int64]:
        """``kinds`` ``(n,)`` checked against the shapes (zeros when None)."""
        if kinds is None:
            return np.zeros(n, dtype=np.int64)
        k = np.asarray(kinds)
        if (
            k.shape != (n,)
            or not np.issubdtype(k.dtype, np.integer)
            or k.min() < 0
            or k.max() >= len(self.shapes)
        ):
            raise ParameterError(
                f"kinds must be {n} indices into the planner's {len(self.shapes)} shapes; got {kinds!r}"
            )
        return k.astype(np.int64)

    def _centroids(self, poses: FloatArray, kinds: NDArray[np.int64]) -> FloatArray:
        offsets = [self.shapes[k].centroid_offset(poses[..., i, 2]) for i, k in enumerate(kinds)]
        out: FloatArray = poses[..., :2] + np.stack(offsets, axis=-2)
        return out

    def score(self, poses: FloatArray, targets: FloatArray, kinds: ArrayLike | None = None) -> FloatArray:
        """The score of poses ``(..., N, 3)`` against ``targets`` ``(N, 3)`` (module docs), the
        parts of shapes ``kinds`` ``(N,)`` (indices into ``part``; all the first by default)."""
        k = self._kinds(kinds, targets.shape[0])
        period = 2 * math.pi / self.symmetries[k]
        d = np.hypot(*np.moveaxis(poses[..., :2] - targets[:, :2], -1, 0))
        a = np.mod(poses[..., 2] - targets[:, 2] + period / 2, period) - period / 2
        band = np.maximum(np.abs(self._centroids(poses, k)) - (0.5 * self.limits.size - self.edge), 0.0).sum(
            axis=-1
        )
        terms = (d / self.position_scale) ** 2 + (a / self.angle_scale) ** 2
        terms = terms + self.edge_weight * (band / self.position_scale) ** 2
        out: FloatArray = terms.sum(axis=-1)
        return out

    def _fit(self, make: Callable[[float], Pulse], amplitude: float) -> Pulse:
        """The pulse ``make(amplitude)`` scaled down to 90 % of what the plate can play."""
        pulse = make(amplitude)
        room = self.limits.headroom(pulse)
        return make(amplitude * 0.9 * room) if room < 1.0 else pulse

    def candidates(
        self, poses: FloatArray, targets: FloatArray, kinds: ArrayLike | None = None
    ) -> list[Pulse]:
        """The candidate pulses for parts at ``poses`` ``(N, 3)`` of shapes ``kinds`` (module docs)."""
        k = self._kinds(kinds, len(poses))
        d, a = pose_errors(poses, targets, self.symmetries[k])
        centroids = self._centroids(poses, k)
        out: list[Pulse] = []
        f = self.frequency
        # ramps of a few periods (a jet's period is three of its base frequency's): a plate on
        # flexures plays them as asked, without a drift the suspension turns into a wander
        ramp, jet_ramp = 3 / f, 3 * 3 / (2 * f)
        for i in range(len(poses)):
            for sustain in self.sustains:
                if abs(a[i]) > 0.2 * self.angle_scale:
                    for sign in (1.0, -1.0):

                        def spin(
                            amp: float, sign: float = sign, i: int = i, sustain: float = sustain
                        ) -> Pulse:
                            wave = Harmonics([sign * amp, 0.0], [0.0, -sign * amp], frequency=f)
                            return Pulse.rotation(centroids[i], wave, ramp, sustain, ramp, 0.1)

                        out.append(self._fit(spin, 1.0))
                if d[i] > 0.2 * self.position_scale:
                    goal = targets[i, :2] - poses[i, :2]
                    for rho in (0.06, 0.1):

                        def jet(
                            amp: float,
                            i: int = i,
                            sustain: float = sustain,
                            goal: FloatArray = goal,
                            rho: float = rho,
                        ) -> Pulse:
                            return Pulse.jet(
                                centroids[i], goal, rho, amp, 2 * f, jet_ramp, sustain, jet_ramp, 0.1
                            )

                        strong = self._fit(jet, 0.3)
                        out += [strong, jet(0.3 * strong.amplitude)]  # and a nudge, to finish
        return out

    def predict(self, poses: FloatArray, pulses: list[Pulse], kinds: ArrayLike | None = None) -> FloatArray:
        """The poses ``(K, N, 3)`` each pulse leaves the parts at ``poses`` (of shapes ``kinds``)
        in once they stop."""
        k = self._kinds(kinds, len(poses))
        longest = max(c.duration for c in pulses)
        coast = 0.15
        motions = [
            PlateMotion.sequence([c.motion(), PlateMotion.rest(longest - c.duration + coast)]) for c in pulses
        ]
        parts = [
            self.shapes[j].moved((float(x), float(y)), float(a))
            for j, (x, y, a) in zip(k, poses, strict=True)
        ]
        dt = 1.0 / (20.0 * 2 * 2 * self.frequency)  # 20 steps a period of the jets' 2nd harmonic
        run = simulate_batch(motions, parts, duration=longest + coast, dt=dt, mu=self.mu, mu_s=self.mu_s,
                             record_every=10**9)  # fmt: skip
        out: FloatArray = np.concatenate([run.positions[:, -1], run.angles[:, -1, :, None]], axis=-1)
        return out

    def plan(self, poses: ArrayLike, targets: ArrayLike, kinds: ArrayLike | None = None) -> Pulse | None:
        """The best candidate for parts at ``poses`` ``(N, 3)`` (frame origins and angles), of
        shapes ``kinds`` ``(N,)`` (indices into ``part``; all the first by default), towards
        ``targets`` ``(N, 3)``, or None when none lowers the score."""
        p = as_float("poses", poses)
        t = as_float("targets", targets)
        if p.ndim != 2 or p.shape[1] != 3 or t.shape != p.shape:
            raise ShapeError(f"poses and targets must both have shape (N, 3); got {p.shape} and {t.shape}")
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(t))):
            raise ParameterError("poses and targets must be finite")
        k = self._kinds(kinds, len(p))
        cands = self.candidates(p, t, k)
        if not cands:
            return None
        scores = self.score(self.predict(p, cands, k), t, k)
        best = int(np.argmin(scores))
        if scores[best] >= float(self.score(p, t, k)) * (1 - 1e-6):
            return None
        return cands[best]
