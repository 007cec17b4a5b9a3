"""The plate and its drive limits: one home for the model every planner and device shares.

A :class:`DriveLimits` holds what bounds a plate motion on real hardware: the plate as the motors
see it (:class:`~upm.actuation.Plate`: mass, inertia, lever arm), its suspension (three
:class:`~upm.actuation.Axis`, x, y and rotation, 5.26), the largest force of one motor [N], and the
**stroke**: the largest excursion [m] any corner of the square plate (side ``size``) may make from
home. Devices own their limits (``SimulatedUPM.limits``, ``BoardDevice.limits``, the emulator's);
planners read them; :class:`upm.control.Loop` refuses a planner whose limits differ from its
device's.

The thesis's plate "oscillations are of just a few millimeters" (a 16" plate on nylon flexure
rods); the default stroke is 10 mm. The motors map to the wrench of (5.8) through
:data:`WRENCH_OF_MOTORS` (lever 1; :func:`wrench_matrix` scales it).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from .._arrays import as_float, real
from .._errors import ParameterError, ShapeError, StrokeError
from .actuation import Axis, Plate, wrench_matrix
from .pulses import HARMONICS, MAX_FREQUENCY, Pulse, drive_frequency, motor_sharing

__all__ = [
    "DEFAULT_PLATE",
    "MAX_FREQUENCY",  # at home in upm.plate.pulses, with drive_frequency
    "PLATE_SIZE",
    "DriveLimits",
    "StrokeError",
    "drive_frequency",
    "flexures",
    "wrench_matrix",  # at home in upm.plate.actuation
]

FloatArray = NDArray[np.float64]

#: Side of the thesis's square plate [m] (16 inches).
PLATE_SIZE = 0.4064
#: The thesis's 16" honeycomb plate as the motors see it: 1 kg, 0.0275 kg m^2, motors at 0.2 m.
DEFAULT_PLATE = Plate(1.0, 0.0275, 0.2)


def envelope(t: FloatArray, attack: float, sustain: float, decay: float) -> FloatArray:
    """The raised-cosine envelope at times ``t`` [s] (0 outside the pulse): what the board
    multiplies every motor's force by (``upm.plant.Envelope``)."""
    on = attack + sustain + decay
    e = np.where((t >= 0) & (t <= on), 1.0, 0.0)
    if attack > 0:
        rise = (t >= 0) & (t < attack)
        e[rise] = 0.5 - 0.5 * np.cos(np.pi * t[rise] / attack)
    if decay > 0:
        fall = (t > attack + sustain) & (t <= on)
        e[fall] = 0.5 - 0.5 * np.cos(np.pi * (on - t[fall]) / decay)
    out: FloatArray = e
    return out


@functools.lru_cache(maxsize=256)
def _unit_response(
    limits: DriveLimits, frequency: float, attack: float, sustain: float, decay: float, samples: int
) -> tuple[FloatArray, FloatArray]:
    """Pose of each axis under a unit complex wrench phasor of each harmonic, enveloped, from
    rest (:meth:`DriveLimits.respond`; the real part of a phasor times it is the response to that
    phasor, by linearity): real and imaginary parts, each ``(harmonic, axis, T)`` flattened."""

    on = attack + sustain + decay
    dt = on / (samples - 1)
    t = np.arange(samples, dtype=np.float64) * dt
    env = envelope(t, attack, sustain, decay)
    out = np.empty((len(HARMONICS), samples, 3), complex)
    for j, h in enumerate(HARMONICS):
        z = env * np.exp(2j * np.pi * h * frequency * t)
        wrench = np.zeros((2, samples, 3))
        wrench[0] = z.real[:, None]
        wrench[1] = z.imag[:, None]
        _, _, pose, _ = limits.respond(wrench, dt)
        # Re(F z) = Re F Re z - Im F Im z: the response to F z is Re(F (pose_re - i pose_im))
        out[j] = pose[0] - 1j * pose[1]
    # as the extension reads it: (harmonic, axis, T), real and imaginary parts apart
    flat = np.ascontiguousarray(out.transpose(0, 2, 1)).reshape(-1)
    return np.ascontiguousarray(flat.real), np.ascontiguousarray(flat.imag)


def flexures(mass: float, inertia: float, hz: float = 3.0, zeta: float = 0.2) -> tuple[Axis, Axis, Axis]:
    """Flexure rods: every axis resonates at ``hz`` with damping ratio ``zeta`` (well below the
    drive, so 5.10 holds to a few per cent, and the plate comes home after each pulse)."""
    w0 = 2 * math.pi * hz
    x, y, r = (Axis(m, 2 * zeta * m * w0, m * w0 * w0) for m in (mass, mass, inertia))
    return (x, y, r)


def _check(name: str, value: float) -> float:
    return real(name, value, low=0.0, low_open=True)


@dataclass(frozen=True)
class DriveLimits:
    """What a plate can play: motors, suspension, stroke.

    Parameters
    ----------
    plate : Plate
        Moving mass [kg], inertia [kg m^2], motor lever arm [m] (default :data:`DEFAULT_PLATE`).
    axes : (Axis, Axis, Axis) or None
        Suspension of x, y, rotation (default :func:`flexures` of the default plate; use
        :meth:`of` for another plate's); ``None``: a free plate (the inertial regime of 5.10).
    force : float
        Largest peak force of one motor [N].
    stroke : float
        Largest excursion of any plate corner from home [m].
    size : float
        Side of the square plate [m].
    """

    plate: Plate = DEFAULT_PLATE
    axes: tuple[Axis, Axis, Axis] | None = field(
        default_factory=lambda: flexures(DEFAULT_PLATE.mass, DEFAULT_PLATE.inertia)
    )
    force: float = 200.0
    stroke: float = 0.010
    size: float = PLATE_SIZE

    def __post_init__(self) -> None:
        if not isinstance(self.plate, Plate):
            raise ParameterError(f"plate must be a upm.actuation.Plate; got {type(self.plate).__name__}")
        if self.axes is not None:
            axes = tuple(self.axes)
            if len(axes) != 3 or not all(isinstance(a, Axis) for a in axes):
                raise ParameterError("axes must be three upm.actuation.Axis (x, y, rotation) or None (free)")
            object.__setattr__(self, "axes", axes)
        for name in ("force", "stroke", "size"):
            object.__setattr__(self, name, _check(name, getattr(self, name)))

    @classmethod
    def of(cls, plate: Plate, **options: float) -> DriveLimits:
        """Limits of ``plate`` on its own flexures (:func:`flexures`)."""
        return cls(plate, flexures(plate.mass, plate.inertia), **options)

    @property
    def corners(self) -> FloatArray:
        """The plate's four corners at home, (4, 2) [m]."""
        h = self.size / 2
        return np.array([[-h, -h], [h, -h], [h, h], [-h, h]])

    def excursion(self, pose: ArrayLike) -> float:
        """Largest distance [m] of any corner from home over plate poses ``(..., 3)`` =
        ``(x [m], y [m], theta [rad])`` of the plate's centre (exact rigid motion)."""
        far = self.excursions(pose)
        return float(far.max()) if far.size else 0.0

    def excursions(self, pose: ArrayLike) -> FloatArray:
        """Largest distance [m] of any corner from home at each plate pose ``(..., 3)`` =
        ``(x [m], y [m], theta [rad])``: shape ``(...)`` (exact rigid motion)."""
        q = as_float("pose", pose)
        if q.shape[-1:] != (3,):
            raise ShapeError(f"pose must have shape (..., 3) (x, y, theta); got {q.shape}")
        lead = q.shape[:-1]
        q = q.reshape(-1, 3)
        c, s = np.cos(q[:, 2])[:, None], np.sin(q[:, 2])[:, None]
        k = self.corners[None]
        moved_x = c * k[..., 0] - s * k[..., 1] + q[:, :1] - k[..., 0]
        moved_y = s * k[..., 0] + c * k[..., 1] + q[:, 1:2] - k[..., 1]
        out: FloatArray = np.sqrt(np.max(moved_x**2 + moved_y**2, axis=1)).reshape(lead)
        return out

    def respond(
        self, wrench: ArrayLike, dt: float, state: ArrayLike | None = None
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """The plate under a wrench ``(..., T, 3)`` = ``(fx, fy, tau)`` sampled every ``dt`` [s]:
        acceleration, velocity and pose ``(..., T, 3)``, and the state after ``(..., 3, 2)`` (per axis
        position, velocity), from ``state`` (default at rest at home).

        Each axis is ``f = m q'' + b q' + k q`` (5.26; ``b = k = 0`` on a free plate) stepped by
        semi-implicit Euler, ``v[n] = v[n-1] + dt (f[n] - b v[n-1] - k q[n-1]) / m``,
        ``q[n] = q[n-1] + dt v[n]``, in the core (one run of the recurrence per axis and batch
        entry)."""
        f_all = np.asarray(wrench, dtype=np.float64)
        if f_all.shape[-1:] != (3,) or f_all.ndim < 2:
            raise ShapeError(f"wrench must have shape (..., T, 3); got {f_all.shape}")
        lead = f_all.shape[:-2]
        x0 = (
            np.zeros((*lead, 3, 2))
            if state is None
            else np.broadcast_to(np.asarray(state, float), (*lead, 3, 2))
        )
        inertia = (self.plate.mass, self.plate.mass, self.plate.inertia)
        acc, vel, pos = (np.empty_like(f_all) for _ in range(3))
        after = np.array(x0, dtype=np.float64, copy=True)
        if f_all.shape[-2] == 0:
            return acc, vel, pos, after
        for k in range(3):
            b = 0.0 if self.axes is None else self.axes[k].damping
            st = 0.0 if self.axes is None else self.axes[k].stiffness
            f = np.ascontiguousarray(f_all[..., k]).reshape(-1, f_all.shape[-2])
            q0 = np.ascontiguousarray(x0[..., k, 0], dtype=np.float64).reshape(-1)
            v0 = np.ascontiguousarray(x0[..., k, 1], dtype=np.float64).reshape(-1)
            a, v, q = _core.axis_steps(inertia[k], b, st, f, dt, q0, v0)
            acc[..., k], vel[..., k], pos[..., k] = (x.reshape(f_all.shape[:-1]) for x in (a, v, q))
            after[..., k, 0], after[..., k, 1] = pos[..., -1, k], vel[..., -1, k]
        return acc, vel, pos, after

    def respond_motors(
        self, forces: ArrayLike, dt: float, state: ArrayLike | None = None
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """:meth:`respond` to the four motors' forces ``(..., T, 4)`` (``X1, X2, Y1, Y2``) through
        the plate's lever arm (5.8)."""
        f = np.asarray(forces, dtype=np.float64)
        if f.shape[-1:] != (4,):
            raise ShapeError(f"forces must have shape (..., T, 4) (X1, X2, Y1, Y2); got {f.shape}")
        return self.respond(f @ wrench_matrix(self.plate.lever).T, dt, state)

    def ride_out(self, state: ArrayLike, seconds: float, dt: float = 5e-4) -> tuple[FloatArray, FloatArray]:
        """The plate left to move freely on its suspension for ``seconds`` from ``state``: its
        pose ``(T, 3)`` and the state after (:meth:`respond` with no force)."""
        _, _, pose, after = self.respond(np.zeros((max(int(seconds / dt), 1), 3)), dt, state)
        return pose, after

    def responses(self, frequency: float) -> NDArray[np.complex128]:
        """Velocity per force of each axis at each harmonic of ``frequency`` [Hz], ``(3, 3)``
        (harmonic 1, 2, 2/3; axis x, y, rotation): each axis's
        :meth:`~upm.actuation.Axis.velocity_response`, or the free plate's inertia (5.10)."""

        hz = np.array(HARMONICS) * float(frequency)
        if self.axes is None:
            inertia = np.array([self.plate.mass, self.plate.mass, self.plate.inertia])
            out: NDArray[np.complex128] = 1.0 / (1j * 2 * np.pi * hz[:, None] * inertia)
            return out
        return np.stack([np.asarray(x.velocity_response(hz), dtype=np.complex128) for x in self.axes], axis=1)

    def play(
        self, pulse: Pulse, state: ArrayLike | None = None, sample_rate: float = 5000.0
    ) -> tuple[FloatArray, FloatArray]:
        """The plate's pose ``(T, 3)`` while ``pulse`` and its rest play from ``state`` (per axis
        position, velocity; default at rest at home), and the state after: the precompensated,
        enveloped wrench through :meth:`respond`."""

        t = np.arange(round(pulse.duration * sample_rate)) / sample_rate
        wrench = np.zeros((len(t), 3))
        if pulse.kind != "rest":
            ph = pulse.phasors()
            force = np.stack([ph[h] for h in HARMONICS]) / self.responses(pulse.frequency)
            for j, h in enumerate(HARMONICS):
                wrench += np.real(np.exp(2j * np.pi * h * pulse.frequency * t)[:, None] * force[j][None])
            wrench *= envelope(t, pulse.attack, pulse.sustain, pulse.decay)[:, None]
        _, _, pose, after = self.respond(wrench, 1.0 / sample_rate, state)
        return pose, after

    def reach(
        self,
        phasors: ArrayLike,
        frequency: ArrayLike,
        attack: ArrayLike,
        sustain: ArrayLike,
        decay: ArrayLike,
        samples: int = 4096,
    ) -> tuple[FloatArray, FloatArray]:
        """Peak motor force [N] and largest corner excursion [m] of ``K`` pulses at once.

        ``phasors (K, 3, 3)``: the plate velocity ``(u1, u2, u3)`` per harmonic (1, 2 and 2/3 of
        ``frequency`` [Hz], :data:`upm.pulses.HARMONICS`) while the envelope is 1
        (:meth:`upm.Pulse.phasors`); the raised-cosine envelope's ``attack``, ``sustain``, ``decay``
        [s] (each ``(K,)`` or scalar). Forces: each harmonic divided by the axes' velocity response
        (precompensation; the inertial response on a free plate), shared among the motors with
        minimum norm (5.8), the harmonics' amplitudes summed. Excursion: the enveloped,
        precompensated wrench drives the suspension (:meth:`respond`, ``samples`` steps over the
        longest pulse) from rest at home, and the corners move rigidly with the pose (the
        envelope's ramps leave a small velocity drift that the suspension turns into a slow
        wander, larger at higher frequencies). Both scale linearly with a pulse's amplitude."""

        v = np.asarray(phasors, dtype=np.complex128)
        if v.ndim != 3 or v.shape[1:] != (3, 3):
            raise ShapeError(f"phasors must have shape (K, 3, 3) (pulse, harmonic, axis); got {v.shape}")
        k = len(v)
        named = (("frequency", frequency), ("attack", attack), ("sustain", sustain), ("decay", decay))
        f, a, s_, d = (np.broadcast_to(as_float(n, x), (k,)) for n, x in named)
        share = motor_sharing(self.plate.lever)
        force = np.empty(k)
        excursion = np.empty(k)
        groups: dict[tuple[float, float, float, float], list[int]] = {}
        for i in range(k):
            groups.setdefault((float(f[i]), float(a[i]), float(s_[i]), float(d[i])), []).append(i)
        for key, members in groups.items():
            idx = np.array(members)
            wrench = v[idx] / self.responses(key[0])[None]  # (n, harmonic, axis) wrench phasors
            # each motor's peak: its harmonics' amplitudes summed (minimum-norm sharing, 5.8)
            force[idx] = np.abs(wrench @ share.T).sum(axis=1).max(axis=1)
            g_re, g_im = _unit_response(self, *key, samples)  # (harmonic, axis, T)
            w = np.ascontiguousarray(wrench).reshape(-1)
            excursion[idx] = _core.corner_excursions(
                np.ascontiguousarray(w.real), np.ascontiguousarray(w.imag), g_re, g_im, samples, self.corners
            )
        return force, excursion

    def _reach_of(self, pulse: Pulse) -> tuple[float, float]:

        ph = pulse.phasors()
        v = np.stack([ph[h] for h in HARMONICS])[None]
        force, excursion = self.reach(v, pulse.frequency, pulse.attack, pulse.sustain, pulse.decay)
        return float(force[0]), float(excursion[0])

    def pulse_excursion(self, pulse: Pulse) -> float:
        """Largest corner excursion [m] of ``pulse`` played from home (see :meth:`reach`)."""
        return 0.0 if pulse.kind == "rest" else self._reach_of(pulse)[1]

    def peak_force(self, pulse: Pulse) -> float:
        """Largest peak force [N] any motor needs for ``pulse`` (see :meth:`reach`)."""
        return 0.0 if pulse.kind == "rest" else self._reach_of(pulse)[0]

    def headroom(self, pulse: Pulse) -> float:
        """How many times ``pulse``'s amplitude fits within both the force and the stroke
        (``>= 1``: playable as it is)."""
        if pulse.kind == "rest":
            return math.inf
        force, reach = self._reach_of(pulse)
        return min(
            self.force / force if force > 0 else math.inf, self.stroke / reach if reach > 0 else math.inf
        )

    def check(self, pulse: Pulse) -> None:
        """Raise :class:`StrokeError` or ``ParameterError`` when ``pulse`` exceeds the stroke or the
        motor force (the host's check before sending a pulse)."""

        if not isinstance(pulse, Pulse):
            raise ParameterError(f"pulse must be a upm.Pulse; got {type(pulse).__name__}")
        if pulse.kind == "rest":
            return
        force, reach = self._reach_of(pulse)
        if force > self.force * (1 + 1e-9):
            raise ParameterError(
                f"the pulse needs {force:.4g} N of motor force, beyond the limit of {self.force:g} N"
            )
        if reach > self.stroke * (1 + 1e-9):
            raise StrokeError(
                f"the pulse swings a plate corner {1000 * reach:.2f} mm from home, beyond the stroke of "
                f"{1000 * self.stroke:.2f} mm: lower its amplitude or raise its frequency"
            )
