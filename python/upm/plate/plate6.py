"""A plate driven by six linear actuators: the 6-DOF plate's hardware model (docs/ppod.md,
"The six-actuator plate").

Geometry (:data:`PPOD_LIKE`, after the PPOD's layout of three in-plane and three vertical voice
coils under a square plate): three **horizontal** actuators push tangentially at radius ``R`` at
90°, 210° and 330° (they give x, y and the rotation about z), three **vertical** actuators push
along z at radius ``R`` at 30°, 150° and 270° (they give z and the rocking about x and y). Each
actuator ``i`` applies a force ``f_i`` along its unit direction ``d_i`` at its point ``p_i`` on the
plate, so the wrench is ``W = A f`` with column ``i`` of the actuator Jacobian ``A`` equal to
``(d_i, p_i x d_i)``; the plate's accelerations are ``M^-1 W`` with ``M = diag(m, m, m, Ixx, Iyy,
Izz)`` (small motions; the plate's weight is carried by its flexures). Playing a harmonic motion
takes the forces ``f = A^-1 M a`` per harmonic; each actuator's peak force and its stroke along
its own direction are checked against its limits.

Accelerometers (:data:`PPOD_ACCELEROMETERS`): three 3-axis sensors at radius 0.17 m, 120° apart
(the PPOD group's radius). A sensor at ``p`` reads ``a + alpha x p`` (centripetal terms are of
second order in the small rotation rates), nine readings linear in the six accelerations; any
three sensors not on one line observe all six, and :meth:`Plate6.estimate` recovers each axis's
harmonic acceleration from sampled readings by least squares.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import as_float, real
from .._errors import ParameterError, ShapeError
from ..physics.motion import PlateMotion
from .drive import StrokeError
from .pulses import Channel

__all__ = ["PPOD_ACCELEROMETERS", "PPOD_LIKE", "Actuator", "Plate6"]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]


@dataclass(frozen=True)
class Actuator:
    """A linear actuator: it pushes at ``point`` (x, y on the plate, z = 0) [m] along the unit
    ``direction`` (3-D), with at most ``max_force`` [N] and ``stroke`` [m] along it."""

    point: tuple[float, float]
    direction: tuple[float, float, float]
    max_force: float = 60.0
    stroke: float = 0.003


def _ring(radius: float, angles_deg: tuple[float, ...], vertical: bool, **limits: float) -> list[Actuator]:
    out = []
    for a in np.radians(angles_deg):
        p = (radius * math.cos(a), radius * math.sin(a))
        d = (0.0, 0.0, 1.0) if vertical else (-math.sin(a), math.cos(a), 0.0)
        out.append(Actuator(p, d, **limits))
    return out


PPOD_LIKE: tuple[Actuator, ...] = (
    *_ring(0.18, (90.0, 210.0, 330.0), vertical=False, max_force=60.0, stroke=0.003),
    *_ring(0.18, (30.0, 150.0, 270.0), vertical=True, max_force=60.0, stroke=0.003),
)
"""Three tangential actuators and three vertical ones at 0.18 m (see the module)."""

PPOD_ACCELEROMETERS: tuple[tuple[float, float], ...] = tuple(
    (0.17 * math.cos(a), 0.17 * math.sin(a)) for a in np.radians((0.0, 120.0, 240.0))
)
"""Three 3-axis accelerometers at radius 0.17 m, 120° apart [m]."""


@dataclass(frozen=True)
class Plate6:
    """A rigid plate of ``mass`` [kg] and ``inertia`` ``(Ixx, Iyy, Izz)`` [kg m²] on six
    ``actuators``, watched by 3-axis ``accelerometers`` at the given points [m].

    The default is a 1.5 kg, 0.3 m square plate (its inertia as a thin square) on
    :data:`PPOD_LIKE` with :data:`PPOD_ACCELEROMETERS`."""

    mass: float = 1.5
    inertia: tuple[float, float, float] = (0.01125, 0.01125, 0.0225)
    actuators: tuple[Actuator, ...] = PPOD_LIKE
    accelerometers: tuple[tuple[float, float], ...] = PPOD_ACCELEROMETERS
    _a: FloatArray = field(init=False, repr=False, compare=False)
    _h: FloatArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        real("mass", self.mass, low=0.0, low_open=True)
        for i, v in enumerate(self.inertia):
            real(f"inertia[{i}]", v, low=0.0, low_open=True)
        if len(self.actuators) != 6:
            raise ParameterError(f"a 6-DOF plate needs 6 actuators; got {len(self.actuators)}")
        cols = []
        for i, act in enumerate(self.actuators):
            d = np.asarray(act.direction, dtype=float)
            if d.shape != (3,) or not np.isclose(np.linalg.norm(d), 1.0):
                raise ParameterError(f"actuators[{i}].direction must be a unit 3-vector; got {act.direction}")
            if not (act.max_force > 0 and act.stroke > 0):
                raise ParameterError(f"actuators[{i}]: max_force and stroke must be > 0")
            p = np.array([*act.point, 0.0])
            cols.append(np.concatenate([d, np.cross(p, d)]))
        a = np.array(cols).T
        if np.linalg.matrix_rank(a, tol=1e-9) < 6:
            raise ParameterError("the actuators cannot move every axis: their Jacobian has rank < 6")
        h = self._sensor_matrix()
        if np.linalg.matrix_rank(h, tol=1e-9) < 6:
            raise ParameterError(
                "the accelerometers do not observe all six accelerations: "
                "use three 3-axis sensors not on one line"
            )
        object.__setattr__(self, "_a", a)
        object.__setattr__(self, "_h", h)

    def _sensor_matrix(self) -> FloatArray:
        rows = []
        for px, py in self.accelerometers:
            # a_P = a + alpha x p, p = (px, py, 0)
            rows.append([1, 0, 0, 0, 0, -py])
            rows.append([0, 1, 0, 0, 0, px])
            rows.append([0, 0, 1, py, -px, 0])
        if not rows:
            raise ParameterError("accelerometers must list the 3-axis sensors' positions")
        return np.array(rows, dtype=float)

    @property
    def jacobian(self) -> FloatArray:
        """``A`` (6, 6): the wrench ``(Fx, Fy, Fz, Mx, My, Mz)`` per unit actuator force."""
        return self._a.copy()

    @property
    def sensor_matrix(self) -> FloatArray:
        """``H`` (3S, 6): the sensors' readings per unit axis acceleration."""
        return self._h.copy()

    def inertia_matrix(self) -> FloatArray:
        return np.diag([self.mass, self.mass, self.mass, *self.inertia])

    def forces(self, accelerations: ArrayLike) -> NDArray[np.generic]:
        """Actuator forces [N] for axis accelerations ``(..., 6)`` (real, or complex phasors)."""
        acc = np.asarray(accelerations)
        if acc.shape[-1:] != (6,):
            raise ShapeError(f"accelerations must have shape (..., 6); got {acc.shape}")
        out: NDArray[np.generic] = np.linalg.solve(self._a, (self.inertia_matrix() @ acc[..., None]))[..., 0]
        return out

    def accelerations(self, forces: ArrayLike) -> NDArray[np.generic]:
        """Axis accelerations of actuator forces ``(..., 6)``."""
        f = np.asarray(forces)
        out: NDArray[np.generic] = np.linalg.solve(self.inertia_matrix(), self._a @ f[..., None])[..., 0]
        return out

    def demands(self, motion: PlateMotion) -> tuple[FloatArray, FloatArray]:
        """Each actuator's peak force [N] and peak excursion along its direction [m] playing the
        harmonic ``motion`` (amplitudes of its harmonics added: an upper bound reached when they
        line up)."""
        f, terms = motion.harmonic_phasors()
        w = 2 * math.pi * f
        force = np.zeros(6)
        reach = np.zeros(6)
        points = np.array([[*a.point, 0.0] for a in self.actuators])
        dirs = np.array([a.direction for a in self.actuators])
        for k, s in terms.items():
            force += np.abs(self.forces(s))
            disp = -s / (k * w) ** 2  # displacement phasors of the six axes
            lin, ang = disp[:3], disp[3:]
            moved = lin[None, :] + np.cross(np.broadcast_to(ang, points.shape), points)
            reach += np.abs(np.sum(moved * dirs, axis=1))
        return force, reach

    def check(self, motion: PlateMotion) -> None:
        """`ParameterError` when an actuator's force, :class:`upm.drive.StrokeError` when its stroke,
        would be exceeded by ``motion`` (naming the actuator)."""
        force, reach = self.demands(motion)
        for i, act in enumerate(self.actuators):
            if force[i] > act.max_force * (1 + 1e-9):
                raise ParameterError(
                    f"actuator {i} needs {force[i]:.3g} N, beyond its {act.max_force:g} N: lower the motion"
                )
            if reach[i] > act.stroke * (1 + 1e-9):
                raise StrokeError(
                    f"actuator {i} would travel {1e3 * reach[i]:.3g} mm, "
                    f"beyond its {1e3 * act.stroke:g} mm stroke"
                )

    def achieved(self, motion: PlateMotion, gains: ArrayLike) -> PlateMotion:
        """The motion the plate really plays when actuator ``i`` delivers ``gains[i]`` times the
        force :meth:`forces` asks of it (a calibration error), as a harmonic motion."""
        g = as_float("gains", gains).reshape(-1)
        if g.shape != (6,):
            raise ShapeError(f"gains must have 6 values, one per actuator; got {g.shape}")
        f, terms = motion.harmonic_phasors()
        real = {
            k: self.accelerations(g * np.asarray(self.forces(s), dtype=np.complex128))
            for k, s in terms.items()
        }
        return PlateMotion.from_phasors(f, real)

    def channels(self, motion: PlateMotion) -> list[Channel]:
        """The six actuator channels playing the harmonic ``motion``, as the board's SET_CHANNEL
        fields (:class:`upm.plate.pulses.Channel`, ``amplitude = 1`` N, force ``h1 cos(wt + p1) +
        h2 cos(2wt + p2)``; protocol version 2, docs/protocol.md). Harmonics 1 and 2 only."""
        f, terms = motion.harmonic_phasors()
        if any(k not in (1, 2) for k in terms):
            raise ParameterError(f"a board channel plays harmonics 1 and 2; the motion has {sorted(terms)}")
        out = []
        forces = {k: np.asarray(self.forces(s)) for k, s in terms.items()}
        for i in range(6):
            ch = {"amplitude": 1.0, "frequency": f, "h1_amplitude": 0.0, "h1_phase": 0.0,
                  "h2_amplitude": 0.0, "h2_phase": 0.0, "h23_amplitude": 0.0, "h23_phase": 0.0}  # fmt: skip
            for k, fk in forces.items():
                # Im(F e^{ikwt}) = |F| sin(kwt + arg F) = |F| cos(kwt + arg F - pi/2)
                ch[f"h{k}_amplitude"] = float(abs(fk[i]))
                ch[f"h{k}_phase"] = float(np.angle(fk[i]) - math.pi / 2)
            out.append(Channel(**ch))
        return out

    def motion_of_channels(self, channels: Sequence[Any]) -> PlateMotion:
        """The harmonic motion six channels (objects with ``amplitude``, ``frequency``,
        ``h1_amplitude``, ``h1_phase``, ``h2_amplitude``, ``h2_phase`` as in SET_CHANNEL) give the
        plate: the inverse of :meth:`channels`. They must share one frequency."""
        if len(channels) != 6:
            raise ParameterError(f"a six-actuator plate has 6 channels; got {len(channels)}")
        f = float(channels[0].frequency)
        if any(not math.isclose(float(c.frequency), f, rel_tol=1e-6) for c in channels):
            raise ParameterError("the six channels must share one frequency")
        acc = {}
        for k in (1, 2):
            amp = np.array([c.amplitude * getattr(c, f"h{k}_amplitude") for c in channels])
            phase = np.array([getattr(c, f"h{k}_phase") for c in channels])
            acc[k] = self.accelerations(amp * np.exp(1j * (phase + math.pi / 2)))
        return PlateMotion.from_phasors(f, acc)

    def readings(self, motion: PlateMotion, t: ArrayLike) -> FloatArray:
        """What the accelerometers read [m/s²] at times ``t`` (T, 3S) while the plate plays ``motion``."""
        f, terms = motion.harmonic_phasors()
        ts = as_float("t", t).reshape(-1)
        acc = np.zeros((len(ts), 6))
        for k, s in terms.items():
            acc += np.imag(s[None, :] * np.exp(1j * k * 2 * math.pi * f * ts)[:, None])
        out: FloatArray = acc @ self._h.T
        return out

    def estimate(
        self, readings: ArrayLike, sample_rate: float, frequency: float, harmonics: tuple[int, ...] = (1, 2)
    ) -> dict[int, ComplexArray]:
        """The six axes' acceleration phasors per harmonic (``a = Im(S e^{i k w t})``) from sampled
        accelerometer ``readings`` (T, 3S) taken at ``sample_rate`` [Hz] from t = 0: a least-squares
        fit of each harmonic (and an offset) to every reading, then the sensors' least squares."""
        r = as_float("readings", readings)
        if r.ndim != 2 or r.shape[1] != self._h.shape[0]:
            raise ShapeError(f"readings must have shape (T, {self._h.shape[0]}); got {r.shape}")
        rate = real("sample_rate", sample_rate, low=0.0, low_open=True)
        f = real("frequency", frequency, low=0.0, low_open=True)
        if max(harmonics) * f >= rate / 2:
            raise ParameterError(
                f"sample_rate {rate:g} Hz cannot resolve harmonic {max(harmonics)} of {f:g} Hz"
            )
        if len(r) < rate / f:
            raise ParameterError("readings must span at least one period")
        t = np.arange(len(r)) / rate
        cols = [np.ones_like(t)]
        for k in harmonics:
            cols += [np.sin(2 * math.pi * k * f * t), np.cos(2 * math.pi * k * f * t)]
        basis = np.stack(cols, axis=1)
        coef, *_ = np.linalg.lstsq(basis, r, rcond=None)
        pinv = np.linalg.pinv(self._h)
        out = {}
        for j, k in enumerate(harmonics):
            # a sin + b cos = Im((a + i b) e^{i k w t})
            per_sensor = coef[1 + 2 * j] + 1j * coef[2 + 2 * j]
            out[k] = pinv @ per_sensor
        return out
