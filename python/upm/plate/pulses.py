"""Pulses: the unit of work a plate executes (docs/spec.md §5, §6, §7; thesis 5.2.3, 5.2.5, 6.1).

A :class:`Pulse` is one shaped burst of plate vibration, a rotation about a centre, a translation or a jet,
under a raised-cosine envelope (attack, sustain, decay) and followed by rest while the parts slide
to a stop. The same pulse can be

* simulated exactly: :meth:`Pulse.motion` is its :class:`~upm.PlateMotion` (the plate follows the
  commanded velocity);
* played on motors: :meth:`Pulse.channels` gives the four motor waveforms (``X1, X2, Y1, Y2``, the
  board's SET_CHANNEL fields) whose forces make the plate move with that velocity: every harmonic
  (1, 2 and 2/3 of the base frequency) is a velocity phasor per axis, divided by the axis's
  velocity response (inertial, 5.10, or the suspension of 5.26: precompensation) and shared
  among the motors with minimum norm (5.8).

Planners (:mod:`upm.plan`) return lists of pulses; devices (:mod:`upm.control`) play them.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import real, vector
from .._errors import ParameterError
from ..physics.motion import PlateMotion
from ..physics.waveforms import Harmonics
from .actuation import Axis, Plate, wrench_matrix

__all__ = ["Channel", "Pulse", "program"]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

#: The harmonics a channel can play, as multiples of the base frequency (SET_CHANNEL's fields).
HARMONICS = (1.0, 2.0, 2.0 / 3.0)

#: The highest base frequency a drive may have [Hz]: the board samples at 5 kHz, and a drive's
#: second harmonic must stay below its Nyquist frequency (the thesis drives at 20-70 Hz). Planners
#: and pulse builders refuse higher ones rather than simulate millions of periods.
MAX_FREQUENCY = 1000.0


def drive_frequency(name: str, value: Any) -> float:
    """``value`` as a drive frequency [Hz] in (0, :data:`MAX_FREQUENCY`]; `ParameterError` naming
    ``name`` otherwise."""
    return real(name, value, low=0.0, low_open=True, high=MAX_FREQUENCY)


def _playable(waveform: object) -> None:
    """A single Harmonics of harmonics 1 and 2 only (what a board channel plays)."""
    if not isinstance(waveform, Harmonics) or waveform.shape != ():
        raise ParameterError(f"waveform must be a single upm.Harmonics; got {waveform!r}")
    if waveform.cos.shape[-1] > 2 and np.any(waveform.cos[2:] != 0) | np.any(waveform.sin[2:] != 0):
        raise ParameterError("waveform must have harmonics 1 and 2 only (what a board channel plays)")


def _unit(name: str, value: ArrayLike) -> FloatArray:
    """A non-zero 2-vector, normalised."""
    d = vector(name, value, 2)
    n = math.hypot(float(d[0]), float(d[1]))
    if not n > 0:
        raise ParameterError(f"{name} must be non-zero")
    out: FloatArray = d / n
    return out


_KINDS = ("rotation", "translation", "jet", "field", "rest")
_REAL = (int, float, np.floating, np.integer)


def _pair(name: str, value: object) -> tuple[float, float]:
    """A pulse's stored point or direction: two finite reals (checked in pure Python: every
    candidate pulse of a planning cycle passes here)."""
    if not (
        isinstance(value, (tuple, list))
        and len(value) == 2
        and all(isinstance(v, _REAL) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    ):
        raise ParameterError(f"{name} must be two finite numbers (x, y); got {value!r}")
    return float(value[0]), float(value[1])


def _finite(name: str, value: float, low: float = 0.0, strict: bool = False) -> float:
    ok = isinstance(value, (int, float, np.floating, np.integer)) and math.isfinite(value)
    if not ok or value < low or (strict and value == low):
        relation = ">" if strict else ">="
        raise ParameterError(f"{name} must be finite and {relation} {low:g}; got {value!r}")
    return float(value)


@dataclass(frozen=True)
class Channel:
    """One motor's waveform: force ``amplitude [h1 cos(wt + p1) + h2 cos(2wt + p2) + h23 cos(2wt/3 +
    p23)]`` [N] with ``w = 2 pi frequency``. The thesis's ``cos wt - sin 2wt`` (5.9) is the default.

    The one shape of a motor channel: what :meth:`Pulse.channels` and
    :meth:`upm.plate6.Plate6.channels` give, what the board's SET_CHANNEL carries and the simulated
    plant and the emulator play. It also reads as a mapping of its fields (``c["h1_phase"]``,
    ``Channel(**c)``), the shape these channels had before."""

    amplitude: float = 0.0
    frequency: float = 35.0
    h1_amplitude: float = 1.0
    h1_phase: float = 0.0
    h2_amplitude: float = 1.0
    h2_phase: float = math.pi / 2
    h23_amplitude: float = 0.0
    h23_phase: float = 0.0

    def force(self, t: FloatArray) -> FloatArray:
        w = 2 * math.pi * self.frequency
        shape = (
            self.h1_amplitude * np.cos(w * t + self.h1_phase)
            + self.h2_amplitude * np.cos(2 * w * t + self.h2_phase)
            + self.h23_amplitude * np.cos(2 * w * t / 3 + self.h23_phase)
        )
        out: FloatArray = self.amplitude * shape
        return out

    @property
    def peak(self) -> float:
        """The largest force the channel can ask [N]: its harmonics' amplitudes summed."""
        return abs(self.amplitude) * (
            abs(self.h1_amplitude) + abs(self.h2_amplitude) + abs(self.h23_amplitude)
        )

    def keys(self) -> tuple[str, ...]:
        return _CHANNEL_FIELDS

    def __getitem__(self, name: str) -> float:
        if name not in _CHANNEL_FIELDS:
            raise KeyError(name)
        value: float = getattr(self, name)
        return value


_CHANNEL_FIELDS = tuple(f.name for f in fields(Channel))


@dataclass(frozen=True)
class Pulse:
    """One enveloped plate vibration and the rest after it.

    Build with :meth:`rotation` or :meth:`jet`. ``attack``, ``sustain``, ``decay`` and ``rest``
    are in seconds; ``frequency`` [Hz] is the base frequency of the drive.
    """

    kind: Literal["rotation", "translation", "jet", "field", "rest"]
    center: tuple[float, float]
    frequency: float
    attack: float
    sustain: float
    decay: float
    rest: float = 0.0
    waveform: Harmonics | None = field(default=None, compare=False)
    """Angular velocity [rad/s] of a rotation, or speed [m/s] of a translation."""
    direction: tuple[float, float] = (0.0, 0.0)
    """Unit feeding direction of a jet or a translation."""
    rho: float = 0.0
    amplitude: float = 0.0
    plate_motion: PlateMotion | None = None
    """The harmonic 6-axis motion of a field pulse (:meth:`field`)."""

    def __post_init__(self) -> None:
        """Whatever built it (the builders, ``dataclasses.replace`` or the constructor), a pulse is
        playable: `ParameterError` naming the field otherwise."""
        if self.kind not in _KINDS:
            raise ParameterError(f"kind must be one of {_KINDS}; got {self.kind!r}")
        _pair("center", self.center)
        # the builders pass times, frequency and a jet's radius and amplitude as given: they are
        # checked and stored as floats here, once a pulse
        put = object.__setattr__
        put(self, "frequency", drive_frequency("frequency", self.frequency))
        if self.kind == "rest":
            put(self, "rest", _finite("rest", self.rest, strict=True))
        else:
            times = self._times(self.attack, self.sustain, self.decay, self.rest)
            for name, value in zip(("attack", "sustain", "decay", "rest"), times, strict=True):
                put(self, name, value)
        if self.kind in ("rotation", "translation"):
            _playable(self.waveform)
            base = float(self.waveform.frequency)  # type: ignore[union-attr]
            if abs(base - self.frequency) > 1e-9 * base:
                raise ParameterError(
                    f"frequency must be the waveform's ({base:g} Hz); got {self.frequency:g}"
                )
        if self.kind in ("translation", "jet"):
            if not abs(math.hypot(*_pair("direction", self.direction)) - 1.0) < 1e-6:
                raise ParameterError(f"direction must be a unit vector; got {self.direction!r}")
        if self.kind == "jet":
            put(self, "rho", _finite("rho", self.rho, strict=True))
            put(self, "amplitude", _finite("amplitude", self.amplitude, strict=True))
        if self.kind == "field" and not isinstance(self.plate_motion, PlateMotion):
            got = type(self.plate_motion).__name__
            raise ParameterError(f"plate_motion must be a upm.PlateMotion for a field pulse; got {got}")

    # -- builders ------------------------------------------------------------------------------
    @classmethod
    def rotation(
        cls,
        center: ArrayLike,
        waveform: Harmonics,
        attack: float,
        sustain: float,
        decay: float,
        rest: float = 0.0,
    ) -> Pulse:
        """A rotation about ``center`` [m] at angular rate ``waveform`` [rad/s] (its first two
        harmonics; the board plays no higher ones)."""
        _playable(waveform)
        cx, cy = vector("center", center, 2)
        return cls(
            "rotation",
            (float(cx), float(cy)),
            float(waveform.frequency),
            attack,
            sustain,
            decay,
            rest,
            waveform=waveform,
        )

    @classmethod
    def translation(
        cls,
        direction: ArrayLike,
        waveform: Harmonics,
        attack: float,
        sustain: float,
        decay: float,
        rest: float = 0.0,
    ) -> Pulse:
        """A translation along ``direction`` at speed ``waveform`` [m/s] (its first two harmonics):
        the Coulomb pump of chapter 3, the same force on every part on the plate."""
        _playable(waveform)
        d = _unit("direction", direction)
        return cls(
            "translation",
            (0.0, 0.0),
            float(waveform.frequency),
            attack,
            sustain,
            decay,
            rest,
            waveform=waveform,
            direction=(float(d[0]), float(d[1])),
        )

    @classmethod
    def jet(
        cls,
        center: ArrayLike,
        direction: ArrayLike,
        rho: float,
        amplitude: float,
        frequency: float,
        attack: float,
        sustain: float,
        decay: float,
        rest: float = 0.0,
    ) -> Pulse:
        """The jet (6.4) focused at ``center`` [m], feeding along ``direction``, radius ``rho`` [m],
        translation amplitude ``amplitude`` [m/s] at ``frequency`` [Hz]."""
        cx, cy = vector("center", center, 2)
        d = _unit("direction", direction)
        return cls(
            "jet",
            (float(cx), float(cy)),
            frequency,
            attack,
            sustain,
            decay,
            rest,
            direction=(float(d[0]), float(d[1])),
            rho=rho,
            amplitude=amplitude,
        )

    @classmethod
    def field(
        cls,
        motion: PlateMotion,
        attack: float,
        sustain: float,
        decay: float,
        rest: float = 0.0,
        center: ArrayLike = (0.0, 0.0),
    ) -> Pulse:
        """A velocity field (docs/ppod.md): ``motion`` from :meth:`PlateMotion.harmonic`,
        :meth:`PlateMotion.ppod` or :func:`upm.design_field`, under the envelope. ``center`` [m]
        only labels the pulse (a designed field's centre). A field that moves the plate out of its
        plane plays on a 6-DOF plate only: the simulated plate's ideal device
        (``SimulatedDevice(plant, ideal=True)``); :meth:`channels` refuses it."""
        if not isinstance(motion, PlateMotion):
            raise ParameterError(f"motion must be a upm.PlateMotion; got {type(motion).__name__}")
        frequency, _ = motion.harmonic_phasors()  # ParameterError unless harmonic
        cx, cy = vector("center", center, 2)
        return cls(
            "field",
            (float(cx), float(cy)),
            frequency,
            attack,
            sustain,
            decay,
            rest,
            plate_motion=motion,
        )

    @classmethod
    def pause(cls, seconds: float) -> Pulse:
        """The plate at rest for ``seconds``."""
        return cls("rest", (0.0, 0.0), 1.0, 0.0, 0.0, 0.0, _finite("seconds", seconds, strict=True))

    @staticmethod
    def _times(attack: float, sustain: float, decay: float, rest: float) -> tuple[float, float, float, float]:
        out = tuple(
            _finite(n, v)
            for n, v in zip(
                ("attack", "sustain", "decay", "rest"), (attack, sustain, decay, rest), strict=True
            )
        )
        if out[0] + out[1] + out[2] <= 0:
            raise ParameterError("a pulse needs attack + sustain + decay > 0")
        return out  # type: ignore[return-value]

    # -- what it is --------------------------------------------------------------------------------
    @property
    def on_time(self) -> float:
        """``attack + sustain + decay`` [s]."""
        return self.attack + self.sustain + self.decay

    @property
    def duration(self) -> float:
        """``on_time + rest`` [s]."""
        return self.on_time + self.rest

    def steady(self) -> PlateMotion:
        """The motion while the envelope is 1: periodic, forever (a rest for a rest pulse)."""
        if self.kind == "rest":
            return PlateMotion.rest(self.rest)
        if self.kind == "field":
            assert self.plate_motion is not None
            return self.plate_motion
        if self.kind == "rotation":
            assert self.waveform is not None
            return PlateMotion.rotation(self.center, self.waveform)
        if self.kind == "translation":
            assert self.waveform is not None
            return PlateMotion.translation(self.direction, self.waveform)
        return PlateMotion.jet(self.center, self.direction, self.rho, self.amplitude, self.frequency)

    def motion(self, rest: bool = True) -> PlateMotion:
        """The pulse as a plate motion (enveloped, then its rest when ``rest``)."""
        if self.kind == "rest":
            return PlateMotion.rest(self.rest)
        m = self.steady().with_envelope(self.attack, self.sustain, self.decay)
        if rest and self.rest > 0:
            return PlateMotion.sequence([m, PlateMotion.rest(self.rest)])
        return m

    def phasors(self) -> dict[float, ComplexArray]:
        """Plate velocity ``(u1, u2, u3)`` as phasors per harmonic (keys 1, 2, 2/3 of the base
        frequency): ``u(t) = Re sum_h V_h exp(i h w t)`` while the envelope is 1."""
        cx, cy = self.center
        out: dict[float, ComplexArray] = {h: np.zeros(3, complex) for h in HARMONICS}

        def spin(rate: complex) -> ComplexArray:  # rotation about the centre at a rate phasor
            return np.array([rate * cy, -rate * cx, rate])

        if self.kind == "rest":
            return out
        if self.kind == "field":
            assert self.plate_motion is not None
            w = 2 * math.pi * self.frequency
            for k, s in self.plate_motion.harmonic_phasors()[1].items():
                if float(k) not in out:
                    raise ParameterError(f"a field pulse plays harmonics 1 and 2 only; got {k}")
                # Im(S e^{ikwt}) integrates to Re(-(S / (k w)) e^{ikwt}); in-plane: x, y, rz
                out[float(k)] = np.asarray(-s[[0, 1, 5]] / (k * w), dtype=np.complex128)
            return out
        if self.kind in ("rotation", "translation"):
            assert self.waveform is not None
            c, s = self.waveform.cos, self.waveform.sin
            dx, dy = self.direction
            for k, h in enumerate((1.0, 2.0)):
                if k < c.shape[-1]:
                    rate = complex(c[k], -s[k])
                    out[h] = spin(rate) if self.kind == "rotation" else np.array([rate * dx, rate * dy, 0.0])
        else:
            a, (dx, dy) = self.amplitude, self.direction
            out[1.0] = np.array([a * dx, a * dy, 0.0], complex)
            out[2.0] = np.array([-a * dx, -a * dy, 0.0], complex)
            out[2.0 / 3.0] = spin(-2j * a / self.rho)  # (2A/rho) sin(2wt/3) = Re(-i (2A/rho) e^{i 2wt/3})
        return out

    def channels(
        self, plate: Plate, axes: Sequence[Axis] | None = None, limit: float | None = None
    ) -> list[Channel]:
        """The four motor channels ``X1, X2, Y1, Y2`` playing this pulse on ``plate``.

        Each is a :class:`Channel` (the board's SET_CHANNEL fields) with ``amplitude = 1`` [N] and
        the harmonic amplitudes in newtons. Forces
        are the velocity phasors divided by each axis's velocity response: ``i h w m`` for the
        inertial plate (5.10), or ``axes`` (x, y, rotation; 5.26) to precompensate the suspension.
        ``ParameterError`` when a motor's peak force would exceed ``limit`` [N].
        """
        if self.kind == "field" and self.plate_motion is not None and self.plate_motion.is_spatial:
            raise ParameterError(
                "this field pulse moves the plate out of its plane: the four in-plane motors cannot play "
                "it; play it on a 6-DOF plate (upm.control.SimulatedDevice(plant, ideal=True))"
            )
        w = 2 * math.pi * self.frequency
        inertia = (plate.mass, plate.mass, plate.inertia)
        share = motor_sharing(plate.lever)
        motors: dict[float, ComplexArray] = {}
        for h, v in self.phasors().items():
            if axes is None:
                response = np.array([1.0 / (1j * h * w * m) for m in inertia])
            else:
                if len(axes) != 3:
                    raise ParameterError(
                        f"axes must be three upm.actuation.Axis (x, y, rotation); got {len(axes)}"
                    )
                response = np.array([complex(a.velocity_response(h * self.frequency)) for a in axes])
            motors[h] = share @ (v / response)
        out = []
        for k in range(4):
            m1, m2, m23 = (motors[h][k] for h in HARMONICS)
            phases = (float(np.angle(m)) for m in (m1, m2, m23))
            p1, p2, p23 = phases
            out.append(Channel(1.0, self.frequency, abs(m1), p1, abs(m2), p2, abs(m23), p23))
        if limit is not None:
            peak = _peak(out)
            if peak > limit:
                raise ParameterError(
                    f"the pulse needs {peak:.4g} N of motor force, beyond the limit of {limit:g} N: lower "
                    "the waveform's amplitude (or the jet's), or move its centre closer to the plate"
                )
        return out

    def peak_force(self, plate: Plate, axes: Sequence[Axis] | None = None) -> float:
        """The largest peak force [N] any motor needs to play this pulse (see :meth:`channels`)."""
        return _peak(self.channels(plate, axes))


@functools.lru_cache(maxsize=16)
def motor_sharing(lever: float) -> FloatArray:
    """Minimum-norm motor forces per wrench: the pseudo-inverse of (5.8)."""
    out: FloatArray = np.asarray(np.linalg.pinv(wrench_matrix(lever)), dtype=np.float64)
    return out


def _peak(channels: list[Channel]) -> float:
    return max(c.peak for c in channels)


def program(pulses: Sequence[Pulse]) -> PlateMotion:
    """The pulses one after another (each with its rest) as one plate motion; an empty list is a
    moment of rest."""
    items = [p.motion() for p in pulses]
    if not items:
        return PlateMotion.rest(1e-3)
    return PlateMotion.sequence(items)
