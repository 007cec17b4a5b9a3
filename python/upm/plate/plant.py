"""``SimulatedUPM``: the embedded default device (docs/spec.md §6, thesis 5.2).

Four motor channels (``X1, X2, Y1, Y2``), each ``amplitude [h1 cos(wt + p1) + h2 cos(2wt + p2) +
h23 cos(2wt/3 + p23)]`` under a raised-cosine envelope, push the plate (5.8); the plate moves as
mass and inertia far above its suspension's resonances (5.10), or through per-axis springs and
dampers (5.26) when ``axes`` are given; two 2-axis accelerometers at ``sensor`` and ``-sensor``
read its acceleration (centripetal term included) as signed 11-bit counts with noise; the parts
on it follow through the exact integrator (``upm.simulate``). The board emulator drives it;
:meth:`SimulatedUPM.camera` is its overhead camera (frames rendered by ``upm.vision.synthetic``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import as_float, integer, real
from .._errors import ParameterError, ShapeError
from ..physics.motion import PlateMotion
from ..physics.polygon import Polygon
from ..physics.sim import Disk, simulate
from ..physics.surface import friction_grid, gravity
from .actuation import Axis, Plate
from .drive import DEFAULT_PLATE, PLATE_SIZE, DriveLimits, StrokeError, envelope, flexures
from .pulses import Channel

if TYPE_CHECKING:
    from ..vision.synthetic import Camera, VirtualCamera

__all__ = ["Channel", "Envelope", "SimulatedUPM"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Played:
    """The plate's response to motor forces (:meth:`SimulatedUPM.ahead`), not yet committed."""

    acc: FloatArray
    vel: FloatArray
    pos: FloatArray
    state: FloatArray


@dataclass(frozen=True)
class Moved:
    """Where a pulse moved the parts (:meth:`SimulatedUPM.settled`), not yet applied."""

    parts: FloatArray
    """(M, 2) positions [m], NaN for a part that fell off."""
    angles: FloatArray | None
    min_gap: float
    trace: tuple[FloatArray, FloatArray] | None


@dataclass(frozen=True)
class Envelope:
    """Raised-cosine attack, sustain, decay [s]."""

    attack: float = 0.02
    sustain: float = 0.2
    decay: float = 0.02

    def __post_init__(self) -> None:
        for name in ("attack", "sustain", "decay"):
            object.__setattr__(self, name, real(name, getattr(self, name), low=0.0))

    @property
    def duration(self) -> float:
        return self.attack + self.sustain + self.decay

    def __call__(self, t: FloatArray) -> FloatArray:
        """The envelope's values at times ``t`` [s] (:func:`upm.plate.drive.envelope`)."""
        return envelope(np.asarray(t, dtype=np.float64), self.attack, self.sustain, self.decay)


def _min_gap(positions: FloatArray, gone: NDArray[np.bool_], radius: float) -> float:
    """Smallest distance between the rims of two disks still on the plate over recorded rows."""
    p = positions[:, ~gone]
    if p.shape[1] < 2:
        return math.inf
    i, j = np.triu_indices(p.shape[1], 1)
    return float(np.linalg.norm(p[:, i] - p[:, j], axis=-1).min() - 2 * radius)


def _per_motor(name: str, value: Any, low: float, high: float) -> FloatArray:
    """Four finite values within ``(low, high]`` (one per motor), or `ParameterError`."""
    a = as_float(name, value)
    if a.shape != (4,) or not np.all(np.isfinite(a)) or np.any(a <= low) or np.any(a > high):
        raise ParameterError(
            f"{name} must be 4 numbers (X1, X2, Y1, Y2) in ({low:g}, {high:g}]; got {value!r}"
        )
    return np.array(a, dtype=np.float64)


def _friction(mu: Any, mu_s: Any, m: int) -> tuple[Any, Any]:
    """``mu`` and ``mu_s`` checked: each one value or ``(m,)`` values, finite, ``mu > 0`` and
    ``mu_s >= mu`` (a float stays a float)."""
    out: list[Any] = []
    for name, value in (("mu", mu), ("mu_s", mu_s)):
        if value is None:
            out.append(None)
            continue
        a = as_float(name, value)
        if a.ndim > 1 or (a.ndim == 1 and a.shape != (m,)):
            raise ShapeError(f"{name} must be one value or one per part ({m},); got shape {a.shape}")
        low = 0.0 if name == "mu" else out[0]
        if not np.all(np.isfinite(a)) or np.any(a <= 0.0) or (low is not None and np.any(a < low)):
            raise ParameterError(
                f"{name} must be finite, > 0{' and >= mu' if name == 'mu_s' else ''}; got {value!r}"
            )
        out.append(float(a) if a.ndim == 0 else np.array(a))
    return out[0], out[1]


def _stuck(stuck: Any, mu: Any, mu_s: Any, m: int) -> Any:
    """``mu_s`` with each stuck part's (``{part: acceleration [m/s^2]}``) raised to hold it."""
    if stuck is None or (isinstance(stuck, dict) and not stuck):
        return mu_s
    if not isinstance(stuck, dict):
        raise ParameterError(
            f"stuck must be a dict {{part: acceleration [m/s^2]}}; got {type(stuck).__name__}"
        )
    out = np.array(np.broadcast_to(mu if mu_s is None else mu_s, (m,)), dtype=np.float64)
    for part, grip in stuck.items():
        i = integer("stuck part", part, low=0, high=m - 1)
        out[i] = max(out[i], real(f"stuck[{i}]", grip, low=0.0, low_open=True, high=1e4) / 9.81)
    return out


@dataclass
class SimulatedUPM:
    """A simulated plate with four motors, two accelerometers and parts on it.

    Parameters
    ----------
    plate : Plate
        Mass [kg], inertia [kg m^2] and motor lever arm [m] (default
        :data:`upm.drive.DEFAULT_PLATE`: the 16" honeycomb plate, 1 kg, 0.0275 kg m^2, 0.2 m).
    axes : (Axis, Axis, Axis) or None
        Suspension of x, y and rotation (5.26); default flexures resonating at 3 Hz with damping
        ratio 0.2 (:func:`upm.drive.flexures`; the plate returns home after a pulse); ``None``: a
        free plate (the pure inertial regime of 5.10, in which a pulse's net impulse leaves the
        plate drifting).
    stroke, motor_force : float
        The largest excursion of any plate corner from home [m] and of one motor's force [N]:
        :attr:`limits`. A pulse that would swing a corner beyond the stroke is refused
        (:class:`upm.drive.StrokeError`) before anything moves; the plate's pose is recorded
        (:attr:`pose`, :attr:`max_excursion`).
    sensor : (2,) array_like
        Position of the first accelerometer [m]; the second is at ``-sensor``.
    full_scale : float
        Accelerometer range [m/s^2] mapped onto the signed 11-bit counts -1024..1023.
    snr_db : float or None
        Sensor noise relative to ``full_scale`` (None: none).
    parts : (M, 2) array_like
        Part positions [m]; ``mu``, ``mu_s`` their friction: one value, or one per part (``(M,)``:
        parts of different materials, or worn). A part whose centre leaves the plate
        (``plate_size`` [m] square, centred on the origin) falls off: its row becomes NaN.
    tilt : (float, float)
        The plate's slope [rad] along x and along y (a plate that is not level: :func:`upm.simulate`'s
        ``tilt``; gravity pulls every part downhill, in the integrator's every step).
    friction_map : (ny, nx) array_like or callable, optional
        The plate's friction over its surface, a factor on each part's ``mu`` and ``mu_s`` where it
        is (:func:`upm.simulate`'s ``friction_map``, over this plate; a function is sampled once).
    stuck : dict of int to float, optional
        Parts that stick: ``{i: a}`` holds part ``i`` to the plate until the plate's acceleration
        under it exceeds ``a`` [m/s^2] (its static friction raised to ``a / g``); it then slides
        with its own ``mu``, and holds again whenever it comes to rest on the plate.
    motor_gain, motor_phase : (4,) array_like
        Motors that are not quite the model: motor ``i`` (X1, X2, Y1, Y2) delivers ``motor_gain[i]``
        times the force asked, ``motor_phase[i]`` [rad] late at its drive frequency (a delay: each
        harmonic ``k`` lags ``k motor_phase[i]``). Gains within ``(0, 2]``, phases within ``pi/2``.
    part_radius : float or None
        Parts are disks of this radius [m] that collide with each other (``upm.simulate`` with
        ``contacts=True``, ``restitution`` and ``part_friction``); ``None``: point parts that pass
        through each other. ``min_gap`` [m] is then the smallest distance between two disks' rims
        seen so far (sampled every ``gap_every`` steps; negative: they overlapped).
    part_shape : upm.Polygon, sequence of M of them, or None
        Parts are convex polygons of this outline (its vertices and feet; its own pose is
        ignored), or each of its own (mixed shapes), that collide with each other: ``parts`` are
        then their frames' origins and :attr:`angles` their orientations [rad] (the pose
        ``upm.simulate`` records; the camera draws them). Exclusive with ``part_radius``.
    angles : (M,) array_like
        The polygon parts' orientations [rad] (zeros by default; ignored for disks and points).
    camera_latency, pixel_noise, lighting_drift : float
        What its :meth:`camera` gets wrong: each frame shows the parts as they were
        ``camera_latency`` [s, at most 1] of plate time before it is read (:meth:`parts_at`; a
        frame read while parts still slide shows them short of where they stop), each part moved
        by ``pixel_noise`` [px] of Gaussian jitter, and the light's brightness drifting as a random
        walk of ``lighting_drift`` per frame (relative). Disks and points only for the latency.
    """

    plate: Plate = DEFAULT_PLATE
    axes: tuple[Axis, Axis, Axis] | None = field(
        default_factory=lambda: flexures(DEFAULT_PLATE.mass, DEFAULT_PLATE.inertia)
    )
    sensor: tuple[float, float] = (-0.18, -0.18)
    full_scale: float = 200.0
    snr_db: float | None = 60.0
    sample_rate: float = 5000.0
    parts: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    mu: Any = 0.3
    mu_s: Any = None
    seed: int = 0
    plate_size: float = PLATE_SIZE
    stroke: float = 0.010
    motor_force: float = 200.0
    part_radius: float | None = None
    part_shape: Polygon | Sequence[Polygon] | None = None
    angles: FloatArray | None = None
    restitution: float = 0.5
    part_friction: float = 0.3
    gap_every: int = 20
    tilt: tuple[float, float] = (0.0, 0.0)
    friction_map: Any = None
    stuck: Any = None
    motor_gain: Any = (1.0, 1.0, 1.0, 1.0)
    motor_phase: Any = (0.0, 0.0, 0.0, 0.0)
    camera_latency: float = 0.0
    pixel_noise: float = 0.0
    lighting_drift: float = 0.0

    def __post_init__(self) -> None:
        parts = np.array(as_float("parts", self.parts), dtype=np.float64)
        if parts.size == 0:
            parts = parts.reshape(0, 2)
        if parts.ndim != 2 or parts.shape[1] != 2:
            raise ShapeError(f"parts must have shape (M, 2) [m]; got {parts.shape}")
        self.parts = parts
        self.mu, self.mu_s = _friction(self.mu, self.mu_s, len(parts))
        self.mu_s = _stuck(self.stuck, self.mu, self.mu_s, len(parts))
        self.friction_map = friction_grid(self.friction_map, self.plate_size)
        self.motor_gain = _per_motor("motor_gain", self.motor_gain, 0.0, 2.0)
        self.motor_phase = _per_motor("motor_phase", self.motor_phase, -math.pi / 2, math.pi / 2)
        gravity(9.81, self.tilt)  # checked now, not at the first pulse
        self.tilt = (float(self.tilt[0]), float(self.tilt[1]))
        slope = math.hypot(math.tan(self.tilt[0]), math.tan(self.tilt[1]))
        if slope >= float(np.min(self.mu_s if self.mu_s is not None else self.mu)):
            raise ParameterError(
                f"tilt {self.tilt} is steeper than the parts' friction angle (slope {slope:.3g} >= mu_s): "
                "they would slide off a plate at rest"
            )
        self.seed = integer("seed", self.seed, low=0)
        self.restitution = real("restitution", self.restitution, low=0.0, high=1.0)
        self.part_friction = real("part_friction", self.part_friction, low=0.0)
        self.gap_every = integer("gap_every", self.gap_every, low=1)
        if self.part_radius is not None and not (np.isfinite(self.part_radius) and self.part_radius > 0):
            raise ParameterError(f"part_radius must be None or finite and > 0; got {self.part_radius}")
        if self.part_radius is not None and len(self.parts) > 1:
            gap = _min_gap(self.parts[None], np.zeros(len(self.parts), bool), self.part_radius)
            if gap < -1e-9:
                raise ParameterError(
                    f"parts must not overlap: two disks of part_radius {self.part_radius:g} m overlap by "
                    f"{-1000 * gap:.3g} mm; space their centres at least 2 * part_radius apart"
                )
        if self.part_shape is not None:
            one = isinstance(self.part_shape, Polygon)
            many = isinstance(self.part_shape, (list, tuple)) and all(
                isinstance(p, Polygon) for p in self.part_shape
            )
            if not (one or many):
                raise ParameterError(
                    "part_shape must be a upm.Polygon, a list of them (one per part) or None; got "
                    f"{type(self.part_shape).__name__}"
                )
            if isinstance(self.part_shape, (list, tuple)):
                self.part_shape = list(self.part_shape)
                if len(self.part_shape) != len(self.parts):
                    raise ShapeError(
                        f"part_shape must hold one upm.Polygon per part ({len(self.parts)}); "
                        f"got {len(self.part_shape)}"
                    )
            if self.part_radius is not None:
                raise ParameterError("give part_radius (disks) or part_shape (polygons), not both")
        self.angles = self._angles(self.angles)
        self.min_gap = math.inf
        if not (self.full_scale > 0 and self.sample_rate > 0):
            raise ParameterError("full_scale and sample_rate must be > 0")
        self._rng = np.random.default_rng(self.seed)
        self._state = np.zeros((3, 2))  # per axis (position, velocity) of the plate
        for name, top in (("camera_latency", 1.0), ("pixel_noise", 50.0), ("lighting_drift", 0.2)):
            setattr(self, name, real(name, getattr(self, name), low=0.0, high=top))
        if self.camera_latency > 0 and self.part_shape is not None:
            raise ParameterError("camera_latency is modelled for disks and points; not with part_shape")
        self.clock = 0.0
        """Plate time [s]: pulses, their rests and the plate's rides home played so far."""
        self._trace: list[tuple[FloatArray, FloatArray]] = []  # (times (T,), parts (T, M, 2)) of late moves
        _ = self.limits  # validates stroke, motor_force and plate_size
        self._poses: list[FloatArray] = []
        self.max_excursion = 0.0
        """Largest corner excursion from home seen so far [m]."""

    @property
    def limits(self) -> DriveLimits:
        """The plate's :class:`~upm.drive.DriveLimits` (what planners must respect)."""
        return DriveLimits(self.plate, self.axes, self.motor_force, self.stroke, self.plate_size)

    @property
    def pose(self) -> FloatArray:
        """The plate's recorded pose ``(T, 3)`` = ``(x [m], y [m], theta [rad])``, every 10th
        sample of every pulse played (and the last of each)."""
        return np.concatenate(self._poses) if self._poses else np.zeros((0, 3))

    def forces(self, channels: list[Channel], t: FloatArray, envelope: FloatArray) -> FloatArray:
        """Motor forces ``(T, 4)`` at times ``t`` under envelope values ``envelope``."""
        if len(channels) != 4:
            raise ShapeError(f"channels must hold 4 motors (X1, X2, Y1, Y2); got {len(channels)}")
        late = [p / (2 * math.pi * c.frequency) if c.frequency > 0 else 0.0
                for c, p in zip(channels, self.motor_phase, strict=True)]  # fmt: skip
        asked = np.stack([c.force(t - d) for c, d in zip(channels, late, strict=True)], axis=1)
        out: FloatArray = asked * self.motor_gain * envelope[:, None]
        return out

    def _respond(
        self, forces: FloatArray, state: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Acceleration, velocity and pose ``(T, 3)`` for motor forces ``(T, 4)`` from ``state``
        (per axis position, velocity), and the state after (:meth:`DriveLimits.respond`)."""
        return self.limits.respond_motors(forces, 1.0 / self.sample_rate, state)

    def plate_state(self, forces: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Plate acceleration and velocity ``(T, 3)`` (``d/dt`` and ``(u1, u2, u3)``) for motor
        forces sampled at ``sample_rate``, continuing from the previous call; the pose is recorded
        (:attr:`pose`, :attr:`max_excursion`)."""
        played = self.ahead(forces)
        self.commit(played)
        return played.acc, played.vel

    def ahead(self, forces: FloatArray) -> Played:
        """What :meth:`plate_state` would give for ``forces``, the plate left where it is (a board
        emulator works a pulse out when it starts, and :meth:`commit` it when it ends)."""
        return Played(*self._respond(forces, self._state))

    def commit(self, played: Played) -> None:
        """The plate moved as ``played`` (from :meth:`ahead` at the present state) says."""
        self._state = played.state
        if len(played.pos):
            self._poses.append(np.vstack([played.pos[::10], played.pos[-1:]]))
            self.max_excursion = max(self.max_excursion, self.limits.excursion(played.pos))

    def pulse_ahead(self, channels: list[Channel], envelope: Envelope) -> tuple[FloatArray, Played]:
        """A pulse's motor forces ``(T, 4)`` (its time starting with it) and the plate's response
        from its present state (:meth:`ahead`), computed without moving anything."""
        n = round(envelope.duration * self.sample_rate)
        t = np.arange(n) / self.sample_rate
        forces = self.forces(channels, t, envelope(t))
        return forces, self.ahead(forces)

    def excursion(self, channels: list[Channel], envelope: Envelope) -> float:
        """Largest corner excursion [m] the pulse would cause from the plate's present state,
        computed without moving anything (the board's check before a PULSE)."""
        return self.reach(self.pulse_ahead(channels, envelope)[1])

    def reach(self, played: Played) -> float:
        """Largest corner excursion [m] of a response from :meth:`ahead`."""
        return self.limits.excursion(played.pos) if len(played.pos) else 0.0

    def ride_out(self, seconds: float) -> None:
        """Let the plate move freely on its suspension for ``seconds`` (no motor force): it comes
        home. The parts do not move (the plate's free motion is far too gentle to slide them)."""
        n = round(seconds * self.sample_rate)
        if n > 0:
            self.plate_state(np.zeros((n, 4)))
            self.clock += n / self.sample_rate

    def check_stroke(self, channels: list[Channel], envelope: Envelope) -> None:
        """:class:`~upm.drive.StrokeError` when the pulse would exceed the stroke."""
        reach = self.excursion(channels, envelope)
        if reach > self.stroke:
            raise StrokeError(
                f"the pulse would swing a plate corner {1000 * reach:.2f} mm from home, beyond the stroke "
                f"of {1000 * self.stroke:.2f} mm"
            )

    def sensor_counts(self, acc: FloatArray, vel: FloatArray) -> NDArray[np.int16]:
        """Both accelerometers' readings ``(T, 4)`` = ``(a1x, a1y, a2x, a2y)`` in 11-bit counts."""
        out = []
        for sign in (1.0, -1.0):
            x, y = sign * self.sensor[0], sign * self.sensor[1]
            ax = acc[:, 0] - acc[:, 2] * y - vel[:, 2] ** 2 * x
            ay = acc[:, 1] + acc[:, 2] * x - vel[:, 2] ** 2 * y
            out += [ax, ay]
        return self.counts(np.stack(out, axis=1))

    def counts(self, readings: FloatArray) -> NDArray[np.int16]:
        """Accelerometer ``readings`` [m/s²] as the sensors report them: with their noise
        (``snr_db``), in signed 11-bit counts of ``full_scale``."""
        a = readings
        if self.snr_db is not None:
            a = a + self._rng.normal(0.0, self.full_scale * 10 ** (-self.snr_db / 20), a.shape)
        return np.clip(np.round(a / self.full_scale * 1024), -1024, 1023).astype(np.int16)

    def run(self, channels: list[Channel], envelope: Envelope, rest: float = 0.0) -> NDArray[np.int16]:
        """Play one pulse (then ``rest`` [s] of stillness); the parts move through the exact
        integrator; returns the accelerometer record ``(T, 4)`` in counts.
        :class:`~upm.drive.StrokeError` (nothing played) when it would exceed the stroke."""
        self.check_stroke(channels, envelope)
        n = round((envelope.duration + rest) * self.sample_rate)
        t = np.arange(n) / self.sample_rate
        acc, vel = self.plate_state(self.forces(channels, t, envelope(t)))
        self.settle_parts(vel)
        self.clock += n / self.sample_rate
        return self.sensor_counts(acc, vel)

    def settle_parts(self, velocity: FloatArray) -> None:
        """Move the parts under a recorded plate velocity ``(T, 3)`` sampled at ``sample_rate``,
        then let them slide to rest on the still plate (exact integrator)."""
        self.apply(self.settled(velocity))

    def settled(self, velocity: FloatArray) -> Moved | None:
        """Where :meth:`settle_parts` would move the parts, computed without moving them (a board
        emulator works it out while the pulse plays, and :meth:`apply` it when the pulse ends)."""
        if not len(self.parts) or not len(velocity):
            return None
        n = len(velocity)
        t = np.arange(n + 1) / self.sample_rate
        u = np.vstack([velocity, np.zeros((1, 3))])
        coast = 2.0 * n / self.sample_rate * self._grip() + 0.01
        motion = PlateMotion.sequence(
            [PlateMotion.from_samples(t, u[:, 0], u[:, 1], u[:, 2]), PlateMotion.rest(coast)]
        )
        return self._moved(motion, 0.099 / self.sample_rate)

    def play(self, motion: PlateMotion) -> None:
        """Move the parts under a plate that follows ``motion`` exactly (an ideal plate, no motors),
        then let them slide to rest; the suspension and sensors are not involved."""
        if not isinstance(motion, PlateMotion) or motion.duration is None:
            raise ParameterError("motion must be a upm.PlateMotion with a duration")
        top = motion.max_frequency
        dt = 1.0 / (200.0 * top) if top > 0 else 1e-3
        coast = (motion.duration or 0.0) * self._grip() + 0.01
        self._advance(PlateMotion.sequence([motion, PlateMotion.rest(coast)]), dt)
        self.clock += motion.duration or 0.0

    def _grip(self) -> float:
        """The largest static over sliding friction of any part (a coast long enough for all)."""
        return float(
            np.max(np.asarray(self.mu_s if self.mu_s is not None else self.mu) / np.asarray(self.mu))
        )

    def _advance(self, motion: PlateMotion, dt: float) -> None:
        self.apply(self._moved(motion, dt))

    def _moved(self, motion: PlateMotion, dt: float) -> Moved | None:
        """The parts moved by ``motion`` (integrator step ``dt``), the plant left as it is."""
        on = np.all(np.isfinite(self.parts), axis=1)
        if not np.any(on):
            return None
        mu, mu_s = (None if f is None else (f[on] if np.ndim(f) else f) for f in (self.mu, self.mu_s))
        opts: dict[str, Any] = {"duration": motion.duration or 0.0, "dt": dt, "mu": mu, "mu_s": mu_s,
                                "plate_size": self.plate_size, "tilt": self.tilt,
                                "friction_map": self.friction_map}  # fmt: skip
        r = self.part_radius
        shapes = self.shapes
        angles, gap, trace = None, math.inf, None
        if shapes is not None:
            angles = self._angles(self.angles).copy()
            polygons = [shapes[i].moved((float(x), float(y)), float(angles[i]))
                        for i, (x, y) in zip(np.flatnonzero(on), self.parts[on], strict=True)]  # fmt: skip
            result = simulate(
                motion, polygons, record_every=10**9, contacts=True,
                restitution=self.restitution, part_friction=self.part_friction, **opts,
            )  # fmt: skip
            angles[on] = result.angles[-1]
        elif r is None:
            every = 10**9 if self.camera_latency == 0 else max(1, round(2e-3 / dt))  # the camera looks back
            result = simulate(motion, self.parts[on], record_every=every, **opts)
        else:
            disks = [Disk((float(x), float(y)), r) for x, y in self.parts[on]]
            result = simulate(
                motion, disks, record_every=self.gap_every, contacts=True,
                restitution=self.restitution, part_friction=self.part_friction, **opts,
            )  # fmt: skip
            gap = _min_gap(result.positions, result.left_plate, r)
        moved = self.parts.copy()
        moved[on] = result.positions[-1]
        moved[np.flatnonzero(on)[result.left_plate]] = np.nan  # its centre crossed an edge: it fell off
        if self.camera_latency > 0:
            path = np.full((len(result.t), *self.parts.shape), np.nan)
            path[:, on] = result.positions
            trace = (self.clock + np.asarray(result.t, dtype=np.float64), path)
        return Moved(moved, angles, gap, trace)

    def apply(self, moved: Moved | None) -> None:
        """Put the parts where :meth:`settled` (or a pulse) moved them."""
        if moved is None:
            return
        if moved.angles is not None:
            self.angles = moved.angles
        self.min_gap = min(self.min_gap, moved.min_gap)
        if moved.trace is not None:
            self._remember(*moved.trace)
        self.parts[...] = moved.parts

    def _remember(self, times: FloatArray, path: FloatArray) -> None:
        """Keep the parts' way ``path (T, M, 2)`` at plate ``times`` for :meth:`parts_at`, and no
        more of the past than the camera's latency reaches."""
        self._trace.append((times, path))
        while len(self._trace) > 1 and self._trace[1][0][0] <= self.clock - 2 * self.camera_latency - 1.0:
            self._trace.pop(0)

    def parts_at(self, time: float) -> FloatArray:
        """Where the parts were at plate ``time`` [s] (``clock - camera_latency`` for the camera):
        on their recorded way when they moved then, else where they came to rest (parts moved by
        hand since, :meth:`move_parts`, are where they were put)."""
        out = self.parts.copy()
        for times, path in reversed(self._trace):
            if path.shape[1] != len(out) or time >= times[-1]:
                break
            if time >= times[0]:
                k = int(np.searchsorted(times, time, side="right")) - 1
                w = (time - times[k]) / max(times[k + 1] - times[k], 1e-12)
                out = (1 - w) * path[k] + w * path[k + 1]
                break
            out = path[0].copy()
        return out

    @property
    def fallen(self) -> int:
        """How many parts have fallen off the plate."""
        return int(np.sum(~np.all(np.isfinite(self.parts), axis=1)))

    def idle(self, n: int) -> NDArray[np.int16]:
        """``n`` samples of a plate at rest (noise only)."""
        return self.sensor_counts(np.zeros((n, 3)), np.zeros((n, 3)))

    def camera(self, labels: Sequence[str] | str = "penny", camera: Camera | None = None, seed: int = 0,
               **options: Any) -> VirtualCamera:  # fmt: skip
        """The overhead camera: a :class:`upm.vision.synthetic.VirtualCamera` whose ``read()``
        renders the parts where they are now (``labels`` per part; ``camera`` a
        :class:`upm.vision.synthetic.Camera`; ``options`` go to :func:`upm.vision.synthetic.render`).
        Needs OpenCV (``upm[vision]``)."""
        from ..vision import synthetic

        if not isinstance(labels, str):
            if not all(isinstance(lab, str) for lab in labels):
                raise ParameterError(f"labels must be a label (str) or one per part; got {labels!r}")
            if len(labels) != len(self.parts):
                raise ShapeError(
                    f"labels must hold one label per part ({len(self.parts)}); got {len(labels)}"
                )
            labels = list(labels)
        return synthetic.VirtualCamera(self, camera or synthetic.Camera(), labels, dict(options), seed)

    @property
    def shapes(self) -> list[Polygon] | None:
        """Each part's outline (None: disks or points)."""
        if self.part_shape is None:
            return None
        if isinstance(self.part_shape, Polygon):
            return [self.part_shape] * len(self.parts)
        return list(self.part_shape)

    def move_parts(self, parts: ArrayLike, angles: ArrayLike | None = None) -> None:
        """Place the parts [m] (polygons: their frames' origins, turned by ``angles`` [rad])."""
        p = np.array(as_float("parts", parts), dtype=np.float64).reshape(-1, 2)
        if isinstance(self.part_shape, list) and len(p) != len(self.part_shape):
            raise ShapeError(f"parts must keep one row per shape ({len(self.part_shape)}); got {len(p)}")
        self.parts = p
        self.angles = self._angles(angles)
        self._trace = []  # put there now: the camera sees them there whatever its latency

    def _angles(self, angles: ArrayLike | None) -> FloatArray:
        """``angles`` (M,) for the parts (zeros when None), checked."""
        m = len(self.parts)
        if angles is None:
            return np.zeros(m)
        a = np.array(as_float("angles", angles), dtype=np.float64).reshape(-1)
        if a.shape != (m,):
            raise ShapeError(f"angles must hold one angle per part ({m}); got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ParameterError("angles must be finite")
        return a

    def centroids(self) -> FloatArray:
        """The parts' centroids [m] (for polygons, ``parts`` are their frames' origins; NaN rows:
        fallen off)."""
        shapes = self.shapes
        if shapes is None:
            return self.parts.copy()
        angles = self._angles(self.angles)
        offsets = [p.centroid_offset(a) for p, a in zip(shapes, angles, strict=True)]
        out: FloatArray = self.parts + np.reshape(offsets, (-1, 2))
        return out
