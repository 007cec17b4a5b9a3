"""Periodic one-dimensional plate velocities (docs/spec.md §2): the drives of the Coulomb pump.

Every waveform describes a plate *velocity* ``v(t)`` [m/s] with zero mean over its period. Its
parameters are array-like and broadcast against each other, so one object can stand for a whole
grid of drives (``TwoHarmonic(b=B[:, None], phi=PHI[None, :])``); :attr:`Waveform.shape` is the
broadcast shape, and every function of a waveform returns an array of that shape (a float for a
single waveform).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .. import _core
from .._arrays import FloatArray, as_float, broadcast_shape, check_range, flat, shaped
from .._errors import ParameterError

__all__ = ["BangBang", "Harmonics", "TwoHarmonic", "Waveform"]

_DEFAULT_FREQUENCY = 1.0 / (2.0 * math.pi)


class Waveform(ABC):
    """A periodic plate velocity, or a broadcast array of them (see the module docstring)."""

    shape: tuple[int, ...]

    @abstractmethod
    def _build(self, shape: tuple[int, ...]) -> _core.WaveformBatch:
        """The Rust batch of these waveforms broadcast to ``shape``, flattened in C order."""

    @abstractmethod
    def _args(self) -> tuple[FloatArray, ...]:
        """The constructor's arguments that rebuild this waveform (pickling, equality)."""

    @cached_property
    def _batch(self) -> _core.WaveformBatch:
        return self._build(self.shape)

    def __reduce__(self) -> tuple[Any, tuple[FloatArray, ...]]:
        return type(self), tuple(np.array(a) for a in self._args())

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        assert isinstance(other, Waveform)
        return all(np.array_equal(a, b) for a, b in zip(self._args(), other._args(), strict=True))

    def __hash__(self) -> int:
        return hash((type(self).__name__, *(np.asarray(a).tobytes() for a in self._args())))

    def _validate(self) -> None:
        """Build the Rust batch now, so invalid parameters raise in the constructor, not later."""
        _ = self._batch

    @property
    def size(self) -> int:
        """Number of waveforms (the product of :attr:`shape`)."""
        return math.prod(self.shape)

    @property
    def period(self) -> Any:
        """Period [s]: a float, or an array of :attr:`shape`."""
        return shaped(self._batch.period(), self.shape)

    def _rows(self, name: str, values: FloatArray) -> tuple[_core.WaveformBatch, FloatArray, tuple[int, ...]]:
        """Pair ``values`` with waveforms as a ``(rows, cols)`` table; returns the output shape.

        A single waveform takes all values as one row (its expensive set-up runs once); otherwise
        waveforms and values are broadcast together, one value per row.
        """
        out_shape = broadcast_shape(**{"waveform": np.empty(self.shape), name: values})
        if self.shape == ():
            return (
                self._batch,
                np.ascontiguousarray(values, dtype=np.float64).reshape(1, -1),
                values.shape,
            )
        batch = self._batch if out_shape == self.shape else self._build(out_shape)
        return batch, flat(values, out_shape).reshape(-1, 1), out_shape

    def __call__(self, t: ArrayLike) -> Any:
        """Velocity [m/s] at times ``t`` [s]; shape: ``broadcast(shape, t.shape)``."""
        batch, table, shape = self._rows("t", as_float("t", t))
        return shaped(batch.evaluate(table, 0), shape)

    def acceleration(self, t: ArrayLike) -> Any:
        """Acceleration [m/s^2] at times ``t`` [s] (bang-bang: the value just after ``t``)."""
        batch, table, shape = self._rows("t", as_float("t", t))
        return shaped(batch.evaluate(table, 1), shape)

    def velocity_range(self) -> tuple[Any, Any]:
        """Exact ``(min, max)`` of the velocity over a period [m/s], from the extrema."""
        lo, hi = self._batch.velocity_range()
        return shaped(lo, self.shape), shaped(hi, self.shape)


def _pad(a: FloatArray, k: int) -> FloatArray:
    """``a`` with zeros appended along its last axis up to length ``k``."""
    return np.concatenate([a, np.zeros((*a.shape[:-1], k - a.shape[-1]))], axis=-1)


def _harmonic_batch(
    cos: FloatArray, sin: FloatArray, frequency: FloatArray, shape: tuple[int, ...]
) -> _core.WaveformBatch:
    """The Rust batch of harmonic series broadcast to ``shape`` (coefficients on the last axis)."""
    k = cos.shape[-1]
    c = np.ascontiguousarray(np.broadcast_to(cos, (*shape, k))).reshape(-1, k)
    s = np.ascontiguousarray(np.broadcast_to(sin, (*shape, k))).reshape(-1, k)
    return _core.WaveformBatch.harmonics(c, s, flat(frequency, shape))


#: The most terms a :class:`Harmonics` series may have (1000 terms defeat the exact root
#: isolation that ``feed_rate`` and ``mean_force`` rely on; the cost grows with the terms).
MAX_HARMONICS = 256


class Harmonics(Waveform):
    """A finite harmonic series ``v(t) = sum_k cos[k-1] cos(k w t) + sin[k-1] sin(k w t)``.

    Parameters
    ----------
    cos, sin : array_like, shape (..., K)
        Coefficients [m/s] of harmonic ``k = 1..K`` (the last axis, ``K <= 256``); the shorter one
        is padded with zeros. Leading axes are batch axes and broadcast with ``frequency``.
    frequency : array_like, optional
        Base frequency ``w / (2 pi)`` [Hz], > 0. The default ``1/(2 pi)`` gives the thesis's period
        ``2 pi`` (time in radians).
    """

    def __init__(self, cos: ArrayLike, sin: ArrayLike = (), frequency: ArrayLike = _DEFAULT_FREQUENCY):
        c = np.atleast_1d(as_float("cos", cos))
        s = np.atleast_1d(as_float("sin", sin))
        f = as_float("frequency", frequency)
        check_range("frequency", f, low=0.0, low_open=True)
        k = max(c.shape[-1], s.shape[-1], 1)
        if k > MAX_HARMONICS:
            raise ParameterError(
                f"a Harmonics series has at most {MAX_HARMONICS} terms (the exact root isolation of its "
                f"velocity needs a few per term and a period); got {k}: truncate the series"
            )
        c, s = _pad(c, k), _pad(s, k)
        self.shape = broadcast_shape(cos=c[..., 0], sin=s[..., 0], frequency=f)
        self.cos: FloatArray = np.broadcast_to(c, (*self.shape, k))
        self.sin: FloatArray = np.broadcast_to(s, (*self.shape, k))
        self.frequency: FloatArray = np.broadcast_to(f, self.shape)
        self._validate()

    def _build(self, shape: tuple[int, ...]) -> _core.WaveformBatch:
        return _harmonic_batch(self.cos, self.sin, self.frequency, shape)

    def _args(self) -> tuple[FloatArray, ...]:
        return self.cos, self.sin, self.frequency

    def __repr__(self) -> str:
        if self.shape == ():
            c, s, f = self.cos.tolist(), self.sin.tolist(), float(self.frequency)
            return f"Harmonics(cos={c}, sin={s}, frequency={f})"
        return f"Harmonics(shape={self.shape}, harmonics={self.cos.shape[-1]})"


class TwoHarmonic(Waveform):
    """The two-harmonic drive (3.13): ``v(t) = amplitude (sin(w t) + b sin(2 w t + phi))``.

    Parameters
    ----------
    b : array_like
        Relative amplitude of the second harmonic.
    phi : array_like
        Phase of the second harmonic [rad].
    amplitude : array_like, optional
        Amplitude of the first harmonic [m/s], non-zero.
    frequency : array_like, optional
        Base frequency [Hz], > 0; default ``1/(2 pi)`` (the thesis's ``t`` in radians).

    Examples
    --------
    >>> import upm, numpy as np
    >>> round(upm.feed_rate(upm.TwoHarmonic(b=0.5, phi=np.pi / 2)), 12)
    0.5
    """

    def __init__(
        self,
        b: ArrayLike,
        phi: ArrayLike,
        amplitude: ArrayLike = 1.0,
        frequency: ArrayLike = _DEFAULT_FREQUENCY,
    ):
        self.b = as_float("b", b)
        self.phi = as_float("phi", phi)
        self.amplitude = as_float("amplitude", amplitude)
        self.frequency = as_float("frequency", frequency)
        if np.any(self.amplitude == 0):
            raise ParameterError("amplitude must be non-zero; got 0")
        check_range("frequency", self.frequency, low=0.0, low_open=True)
        self.shape = broadcast_shape(
            b=self.b, phi=self.phi, amplitude=self.amplitude, frequency=self.frequency
        )
        self._validate()

    def coefficients(self) -> tuple[FloatArray, FloatArray]:
        """``(cos, sin)`` coefficient arrays of shape ``(*shape, 2)`` of the equivalent series."""
        a = np.broadcast_to(self.amplitude, self.shape)
        b, phi = np.broadcast_to(self.b, self.shape), np.broadcast_to(self.phi, self.shape)
        with np.errstate(over="ignore"):
            ab = a * b
        if not np.all(np.isfinite(ab)):
            raise ParameterError(
                "amplitude * b must be finite (the second harmonic's amplitude); it overflows"
            )
        cos = np.stack([np.zeros(self.shape), ab * np.sin(phi)], axis=-1)
        sin = np.stack([a * np.ones(self.shape), ab * np.cos(phi)], axis=-1)
        return cos, sin

    def to_harmonics(self) -> Harmonics:
        """The same waveform as a :class:`Harmonics` series."""
        cos, sin = self.coefficients()
        return Harmonics(cos, sin, np.broadcast_to(self.frequency, self.shape))

    def _build(self, shape: tuple[int, ...]) -> _core.WaveformBatch:
        cos, sin = self.coefficients()
        return _harmonic_batch(cos, sin, self.frequency, shape)

    def _args(self) -> tuple[FloatArray, ...]:
        return self.b, self.phi, self.amplitude, self.frequency

    def __repr__(self) -> str:
        if self.shape == ():
            return (
                f"TwoHarmonic(b={float(self.b)}, phi={float(self.phi)}, "
                f"amplitude={float(self.amplitude)}, frequency={float(self.frequency)})"
            )
        return f"TwoHarmonic(shape={self.shape})"


class BangBang(Waveform):
    """Bang-bang acceleration (docs/spec.md §2.1): ``+a_max``, dwell, ``-a_max``; zero-mean velocity.

    ``a_s = +a_max`` on ``[0, t1)``, ``0`` on ``[t1, t2)``, ``-a_max`` on ``[t2, T)`` with
    ``t1 = (1 - z) T / 2`` and ``t2 = (1 + z) T / 2``.

    Parameters
    ----------
    z : array_like
        Dwell fraction, in ``[0, 1)``.
    a_max : array_like, optional
        Peak acceleration [m/s^2], > 0.
    period : array_like, optional
        Period ``T`` [s], > 0.
    """

    def __init__(self, z: ArrayLike, a_max: ArrayLike = 1.0, period: ArrayLike = 1.0):
        self.z = as_float("z", z)
        self.a_max = as_float("a_max", a_max)
        self._period = as_float("period", period)
        check_range("z", self.z, low=0.0, high=1.0, high_open=True)
        check_range("a_max", self.a_max, low=0.0, low_open=True)
        check_range("period", self._period, low=0.0, low_open=True)
        self.shape = broadcast_shape(z=self.z, a_max=self.a_max, period=self._period)
        self._validate()

    def _build(self, shape: tuple[int, ...]) -> _core.WaveformBatch:
        return _core.WaveformBatch.bang_bang(
            flat(self.z, shape), flat(self.a_max, shape), flat(self._period, shape)
        )

    def _args(self) -> tuple[FloatArray, ...]:
        return self.z, self.a_max, self._period

    def __repr__(self) -> str:
        if self.shape == ():
            return f"BangBang(z={float(self.z)}, a_max={float(self.a_max)}, period={float(self._period)})"
        return f"BangBang(shape={self.shape})"
