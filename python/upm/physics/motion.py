"""Plate motion programs: the plate's in-plane velocity ``(u1, u2, u3)(t)`` (docs/spec.md §1, thesis 4.2).

World frame, metres and seconds. The plate's surface velocity at ``P = (x, y)`` is
``v_s(P) = (u1 - u3 y, u2 + u3 x)`` [m/s]; ``u3`` is the angular rate [rad/s]. Plate displacements
are assumed small, so the plate and world frames coincide for friction.

A motion without a duration repeats forever; ``for_duration`` and ``with_envelope`` give it one,
and ``PlateMotion.sequence`` plays timed motions one after another. After the last timed motion
the plate is at rest.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .. import _core
from .._arrays import as_float, items, point, real
from .._errors import ParameterError, ShapeError
from .ppod_library import LIBRARY, PPOD_FIELDS
from .waveforms import Waveform

__all__ = ["PlateMotion"]


def _scalar_waveform(waveform: Any) -> _core.WaveformBatch:
    if not isinstance(waveform, Waveform):
        kind = type(waveform).__name__
        raise ParameterError(
            f"waveform must be a upm waveform (TwoHarmonic, BangBang, Harmonics); got {kind}"
        )
    if waveform.shape != ():
        raise ShapeError(f"waveform must be a single waveform (shape ()); got shape {waveform.shape}")
    return waveform._batch


class PlateMotion:
    """A plate motion program. Build one with the class methods; combine with :meth:`sequence`.

    Examples
    --------
    >>> import upm, numpy as np
    >>> drive = upm.TwoHarmonic(0.5, np.pi / 2, amplitude=0.02, frequency=35.0)
    >>> pulse = upm.PlateMotion.translation((1, 0), drive).with_envelope(0.02, 0.2, 0.02)
    >>> program = upm.PlateMotion.sequence([pulse, upm.PlateMotion.rest(0.5)])
    >>> round(program.duration, 6)
    0.74
    """

    __slots__ = ("_inner", "_recipe")

    def __init__(self, inner: _core.PlateMotion, recipe: tuple[Any, ...] | None = None):
        if not isinstance(inner, _core.PlateMotion):
            raise ParameterError(
                f"inner must be the core's motion; got {type(inner).__name__}: build a PlateMotion with "
                "its class methods (translation, rotation, jet, harmonic, rest, sequence, ...)"
            )
        self._inner = inner
        self._recipe = recipe  # how it was built: rebuilds it (pickling) and compares it (==)

    @classmethod
    def translation(cls, direction: ArrayLike, waveform: Waveform) -> PlateMotion:
        """Translation along ``direction`` (normalised) with speed ``waveform(t)`` [m/s]."""
        d = point("direction", direction)
        return cls(_core.PlateMotion.translation(d, _scalar_waveform(waveform)), ("translation", d, waveform))

    @classmethod
    def rotation(cls, center: ArrayLike, waveform: Waveform) -> PlateMotion:
        """Rotation about ``center`` [m] at angular rate ``waveform(t)`` [rad/s]."""
        c = point("center", center)
        return cls(_core.PlateMotion.rotation(c, _scalar_waveform(waveform)), ("rotation", c, waveform))

    @classmethod
    def jet(
        cls, center: ArrayLike, direction: ArrayLike, rho: float, amplitude: float, frequency: float
    ) -> PlateMotion:
        """The jet (6.4): ``A d [cos wt - cos 2wt] + (2A/rho) sin(2wt/3) R90(P - C)``.

        Parts near ``center`` feed along ``direction`` with a third of ``mu m g`` at the focus;
        far away the force vanishes; ``rho`` [m] is where the two terms have equal peaks. Period
        ``3 / frequency``.
        """
        a = real("amplitude", amplitude)
        if a == 0:
            raise ParameterError("amplitude must be non-zero; got 0 (a jet of amplitude 0 is a rest)")
        args = (point("center", center), point("direction", direction), real("rho", rho), a,
                real("frequency", frequency))  # fmt: skip
        return cls(_core.PlateMotion.jet(*args), ("jet", *args))

    @classmethod
    def harmonic(
        cls,
        frequency: float,
        *,
        x: Sequence[Sequence[float]] = (),
        y: Sequence[Sequence[float]] = (),
        z: Sequence[Sequence[float]] = (),
        rx: Sequence[Sequence[float]] = (),
        ry: Sequence[Sequence[float]] = (),
        rz: Sequence[Sequence[float]] = (),
    ) -> PlateMotion:
        """Harmonic accelerations of the plate's six axes, repeating forever (docs/ppod.md).

        Each axis is a list of ``(harmonic, amplitude, phase)`` terms ``A sin(k w t + p)`` with
        ``w = 2 pi frequency``: ``x, y, z`` in m/s², ``rx, ry, rz`` (about the x, y and z axes
        through the plate's centre) in rad/s². The velocities are their zero-mean integrals.
        ``z``, ``rx`` and ``ry`` move the plate out of its plane: the normal force on a part at
        ``(x, y)`` becomes ``m (g + z'' + y rx'' - x ry'')`` and the part flies while it is
        negative. Small motions only: at most 0.05 rad and 1 cm per term.

        >>> import upm
        >>> m = upm.PlateMotion.harmonic(20.0, x=[(1, 15.0, 0.0)], z=[(1, 5.0, 4.712)])
        >>> m.is_spatial
        True
        """
        axes = {"x": x, "y": y, "z": z, "rx": rx, "ry": ry, "rz": rz}
        terms = [_terms(name, value) for name, value in axes.items()]
        f = real("frequency", frequency, low=0.0, low_open=True)
        recipe = ("harmonic", f, *(tuple(t) for t in terms))
        return cls(_core.PlateMotion.spatial(f, terms), recipe)

    @classmethod
    def ppod(cls, name: str) -> PlateMotion:
        """A field of the PPOD2 library (docs/ppod.md; Vose, Umbanhowar and Lynch): ``"Sink"``,
        ``"Source"``, ``"Whirlpool"``, ``"Centrifuge"``, ``"TransX"``, ... (``upm.PPOD_FIELDS``
        lists them all)."""
        if name not in LIBRARY:
            raise ParameterError(f"unknown PPOD field {name!r}; known: {', '.join(PPOD_FIELDS)}")
        period, axes = LIBRARY[name]
        terms = {a: [(1, float(amp), float(ph))] for a, (amp, ph) in axes.items()}
        return cls.harmonic(1.0 / period, **terms)

    def harmonic_phasors(self) -> tuple[float, dict[int, np.ndarray]]:
        """The base frequency [Hz] of a motion built by :meth:`harmonic` (or :meth:`ppod`) and its
        acceleration phasors per harmonic ``k``: the six axes' ``S`` (complex, ``(6,)``) with
        ``a(t) = Im(S e^{i k w t})``."""
        recipe = self._recipe
        if recipe is None or recipe[0] != "harmonic":
            raise ParameterError("motion must be a upm.PlateMotion built by PlateMotion.harmonic or .ppod")
        f, *axes = recipe[1:]
        out: dict[int, np.ndarray] = {}
        for k, terms in enumerate(axes):
            for harmonic, amplitude, phase in terms:
                out.setdefault(int(harmonic), np.zeros(6, complex))[k] += amplitude * np.exp(1j * phase)
        return float(f), out

    @classmethod
    def from_phasors(cls, frequency: float, phasors: Mapping[int, ArrayLike]) -> PlateMotion:
        """The harmonic motion with the six axes' acceleration phasors ``phasors[k]`` (the inverse
        of :meth:`harmonic_phasors`; terms below 1e-12 are left out)."""
        axes: dict[str, list[tuple[int, float, float]]] = {a: [] for a in ("x", "y", "z", "rx", "ry", "rz")}
        if not isinstance(phasors, Mapping):
            raise ParameterError(
                f"phasors must map harmonics to 6 complex amplitudes; got {type(phasors).__name__}"
            )
        for k, s in sorted(phasors.items()):
            if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
                raise ParameterError(f"phasors' keys must be harmonics (integers >= 1); got {k!r}")
            try:
                amp = np.asarray(s, dtype=np.complex128)
            except (TypeError, ValueError) as e:
                raise ParameterError(f"phasors[{k}] must be 6 complex amplitudes; got {s!r}") from e
            if amp.size != 6:
                raise ShapeError(
                    f"phasors[{k}] must hold 6 amplitudes (x, y, z, rx, ry, rz); got shape {amp.shape}"
                )
            for name, a in zip(axes, amp.reshape(6), strict=True):
                if abs(a) > 1e-12:
                    axes[name].append((k, float(abs(a)), float(np.angle(a))))
        return cls.harmonic(frequency, **axes)

    @property
    def is_spatial(self) -> bool:
        """Whether the plate moves out of its plane (vertical or rocking vibration)."""
        return bool(self._inner.is_spatial())

    def normal_acceleration(self, t: ArrayLike) -> np.ndarray:
        """The out-of-plane accelerations ``(z'', rx'', ry'')`` at times ``t`` [s]: shape
        ``(*t.shape, 3)`` (zero for a plate that stays in its plane)."""
        ts = as_float("t", t)
        return self._inner.normal(np.ascontiguousarray(ts.reshape(-1))).reshape(*ts.shape, 3)

    @classmethod
    def rest(cls, duration: float) -> PlateMotion:
        """The plate at rest for ``duration`` [s]."""
        seconds = real("duration", duration)
        return cls(_core.PlateMotion.rest(seconds), ("rest", seconds))

    @classmethod
    def from_samples(cls, t: ArrayLike, u1: ArrayLike, u2: ArrayLike, u3: ArrayLike) -> PlateMotion:
        """Measured or synthesised plate velocities, linearly interpolated.

        ``t`` [s] strictly increasing; ``u1, u2`` [m/s] and ``u3`` [rad/s] of the same length.
        The motion lasts ``t[-1] - t[0]``.
        """
        ts = np.ascontiguousarray(as_float("t", t).reshape(-1))
        cols = [as_float(n, v).reshape(-1) for n, v in (("u1", u1), ("u2", u2), ("u3", u3))]
        if any(c.size != ts.size for c in cols):
            raise ShapeError(
                f"t, u1, u2, u3 must have equal lengths; got {ts.size}, {[c.size for c in cols]}"
            )
        u = np.ascontiguousarray(np.stack(cols, axis=1))
        return cls(_core.PlateMotion.from_samples(ts, u), ("from_samples", ts, *cols))

    @classmethod
    def sequence(cls, motions: Sequence[PlateMotion]) -> PlateMotion:
        """The motions one after another; every one but the last needs a duration."""
        listed = items("motions", motions, PlateMotion, "a upm.PlateMotion", min_len=1)
        return cls(_core.PlateMotion.sequence([m._inner for m in listed]), ("sequence", tuple(listed)))

    def for_duration(self, seconds: float) -> PlateMotion:
        """This motion for ``seconds`` [s] only."""
        t = real("seconds", seconds)
        return PlateMotion(self._inner.for_duration(t), ("for_duration", self, t))

    def with_envelope(self, attack: float, sustain: float, decay: float) -> PlateMotion:
        """This motion under a raised-cosine envelope (docs/spec.md §5), ``attack + sustain + decay`` long."""
        times = real("attack", attack), real("sustain", sustain), real("decay", decay)
        return PlateMotion(self._inner.with_envelope(*times), ("with_envelope", self, *times))

    @property
    def duration(self) -> float | None:
        """Total duration [s]; ``None`` when the motion repeats forever."""
        return self._inner.duration()

    @property
    def max_frequency(self) -> float:
        """Highest frequency in the program [Hz]; the integrator needs ``dt <= 1 / (20 max_frequency)``."""
        return self._inner.max_frequency()

    def velocity(self, t: ArrayLike) -> np.ndarray:
        """Plate velocity ``(u1, u2, u3)`` at times ``t`` [s]: shape ``(*t.shape, 3)``."""
        ts = as_float("t", t)
        u, _ = self._inner.evaluate(np.ascontiguousarray(ts.reshape(-1)))
        return u.reshape(*ts.shape, 3)

    def acceleration(self, t: ArrayLike) -> np.ndarray:
        """Plate acceleration ``d(u1, u2, u3)/dt`` at times ``t`` [s]: shape ``(*t.shape, 3)``."""
        ts = as_float("t", t)
        _, a = self._inner.evaluate(np.ascontiguousarray(ts.reshape(-1)))
        return a.reshape(*ts.shape, 3)

    def displacement(self) -> np.ndarray:
        """Net pose change ``(dx [m], dy [m], dtheta [rad])`` over the program (one period if it
        repeats forever), integrated with RK4."""
        return np.array(self._inner.displacement())

    def is_closed(self, tol: float = 1e-9) -> bool:
        """Whether the plate returns home: every component of :meth:`displacement` within ``tol``."""
        bound = real("tol", tol, low=0.0)
        return bool(np.all(np.abs(self.displacement()) <= bound))

    # -- value semantics: pickling, equality, a repr that says what it is ---------------------
    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        if self._recipe is None:
            raise ParameterError(
                "this PlateMotion was built from the extension directly and cannot be pickled"
            )
        return _rebuild, (self._recipe,)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, PlateMotion):
            return NotImplemented
        if self._recipe is None or other._recipe is None:
            return self is other
        return bool(_key(self._recipe) == _key(other._recipe))

    def __hash__(self) -> int:
        return hash(_key(self._recipe)) if self._recipe is not None else id(self)

    def __repr__(self) -> str:
        d = self.duration
        what = _describe(self._recipe) if self._recipe is not None else f"{len(self._inner)} items"
        if len(what) > 160:
            what = what[:157] + "..."
        return f"PlateMotion({what}; duration={'forever' if d is None else f'{d:g} s'})"


def _terms(axis: str, value: Any) -> list[tuple[int, float, float]]:
    """An axis's ``(harmonic, amplitude, phase)`` terms, checked."""
    try:
        rows = [tuple(t) for t in value]
    except TypeError:
        raise ParameterError(
            f"{axis} must be a list of (harmonic, amplitude, phase) terms; got {value!r}"
        ) from None
    out = []
    for j, row in enumerate(rows):
        if len(row) != 3:
            raise ParameterError(
                f"{axis}[{j}] must be (harmonic, amplitude, phase); got {row!r} ({len(row)} values)"
            )
        k, a, p = row
        integral = isinstance(k, (int, np.integer)) or (isinstance(k, float) and k.is_integer())
        if isinstance(k, bool) or not integral or not 1 <= int(k) <= 64:
            raise ParameterError(f"{axis}[{j}]: harmonic must be an integer 1..64; got {k!r}")
        out.append((int(k), real(f"{axis}[{j}] amplitude", a), real(f"{axis}[{j}] phase", p)))
    return out


def _rebuild(recipe: tuple[Any, ...]) -> PlateMotion:
    """The motion ``recipe`` describes, built again through the public constructors."""
    kind, *args = recipe
    if kind == "harmonic":
        f, *axes = args
        return PlateMotion.harmonic(f, **dict(zip(("x", "y", "z", "rx", "ry", "rz"), axes, strict=True)))
    if kind == "raw_translation":  # built straight from coefficients (upm.sweep's fast path)
        d, cos, sin, f = args
        inner = _core.PlateMotion.translation(d, _core.WaveformBatch.harmonics(cos, sin, f))
        return PlateMotion(inner, recipe)
    if kind in ("for_duration", "with_envelope"):
        base = _rebuild(args[0]._recipe)
        return getattr(base, kind)(*args[1:])  # type: ignore[no-any-return]
    if kind == "sequence":
        return PlateMotion.sequence([_rebuild(m._recipe) for m in args[0]])
    return getattr(PlateMotion, kind)(*args)  # type: ignore[no-any-return]


def _key(value: Any) -> Any:
    """A hashable, comparable form of a recipe (arrays by shape and bytes)."""
    if isinstance(value, PlateMotion):
        return ("motion", _key(value._recipe)) if value._recipe is not None else ("id", id(value))
    if isinstance(value, (tuple, list)):
        return tuple(_key(v) for v in value)
    if isinstance(value, np.ndarray):
        return ("array", value.shape, np.ascontiguousarray(value, dtype=np.float64).tobytes())
    return value


def _describe(recipe: tuple[Any, ...]) -> str:
    kind, *args = recipe
    if kind in ("for_duration", "with_envelope"):
        inner = args[0]._recipe
        base = _describe(inner) if inner is not None else "..."
        return f"{base}.{kind}({', '.join(f'{a:g}' for a in args[1:])})"
    if kind == "sequence":
        return "sequence[" + ", ".join(_describe(m._recipe) if m._recipe else "..." for m in args[0]) + "]"
    if kind == "from_samples":
        return f"from_samples({len(args[0])} samples)"
    if kind == "harmonic":
        named = [
            f"{n}={list(a)}" for n, a in zip(("x", "y", "z", "rx", "ry", "rz"), args[1:], strict=True) if a
        ]
        return f"harmonic({args[0]:g} Hz, {', '.join(named)})"
    if kind == "raw_translation":
        return f"translation({args[0]}, {args[1].shape[-1]} harmonics at {float(args[3][0]):g} Hz)"
    shown = ", ".join(repr(a) if not isinstance(a, float) else f"{a:g}" for a in args)
    return f"{kind}({shown})"
