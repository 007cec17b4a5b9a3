"""Actuation, calibration and sensing (docs/spec.md §6; thesis 5.2-5.4): from motor amplitudes to
centres of rotation and back.

Plate frame, origin at the plate's centre [m]. Four voice coils ``X1, X2, Y1, Y2`` push on the
plate's sides at lever arm ``r`` (5.8): ``fx = X1 - X2``, ``fy = Y1 - Y2``,
``tau = r [(Y1 + Y2) - (X1 + X2)]``; with motor forces ``cos wt - sin 2wt`` (5.9) and the drive far
above every resonance, the plate velocity is ``(fx/M, fy/M, tau/I) (1/w) [sin wt + cos(2wt)/2]``
(5.10). The kinematics, fits and the accelerometer centre of rotation run in Rust.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from .._arrays import as_float, instance, integer, items, real, vector
from .._errors import ParameterError, ResonanceWarning, ShapeError

__all__ = [
    "TABLE_5_1",
    "AccelerometerRotation",
    "Axis",
    "CorMap",
    "HarmonicFit",
    "Plate",
    "center_of_rotation",
    "check_drive",
    "cor_from_accelerometers",
    "cor_library",
    "cross_validate_cor_map",
    "fit_cor_map",
    "harmonic_fit",
    "positive_force",
    "precompensate",
    "synthetic_accelerometers",
    "velocity_from_fit",
    "wrench",
    "wrench_matrix",
]

FloatArray = NDArray[np.float64]


def wrench_matrix(lever: float) -> FloatArray:
    """``(fx, fy, tau) = W @ (X1, X2, Y1, Y2)`` (5.8): ``fx = X1 - X2``, ``fy = Y1 - Y2``,
    ``tau = lever [(Y1 + Y2) - (X1 + X2)]``; shape (3, 4)."""
    r = float(lever)
    return np.array([[1.0, -1.0, 0.0, 0.0], [0.0, 0.0, 1.0, -1.0], [-r, -r, r, r]])


def wrench(motors: ArrayLike, lever: float) -> FloatArray:
    """``(fx, fy, tau)`` of motor amplitudes ``(X1, X2, Y1, Y2)`` at lever arm ``lever`` [m] (5.8)."""
    arm = real("lever", lever, low=0.0, low_open=True)
    out: FloatArray = wrench_matrix(arm) @ vector("motors", motors, 4)
    return out


def center_of_rotation(u: ArrayLike) -> tuple[FloatArray, float]:
    """Centre of rotation [m] and angular rate of a plate velocity ``(u1, u2, u3)`` (4.6, 5.7):
    ``c = (-u2/u3, u1/u3)``. A pure translation raises `ParameterError` (its centre is at infinity)."""
    c, w = _core.center_of_rotation(tuple(vector("u", u, 3)))
    return np.array(c), float(w)


@dataclass(frozen=True)
class Plate:
    """The plate as the motors see it: moving ``mass`` [kg], ``inertia`` about the centre
    [kg m^2], and the ``lever`` arm of every motor [m]."""

    mass: float
    inertia: float
    lever: float

    def __post_init__(self) -> None:
        for name in ("mass", "inertia", "lever"):
            object.__setattr__(self, name, real(name, getattr(self, name), low=0.0, low_open=True))

    def velocity_amplitudes(self, motors: ArrayLike) -> FloatArray:
        """``(fx/M, fy/M, tau/I)``: the plate velocity per unit of ``(1/w)[sin wt + cos(2wt)/2]`` (5.10)."""
        m = vector("motors", motors, 4)
        return np.array(_core.velocity_amplitudes(self.mass, self.inertia, self.lever, tuple(m)))

    def motors_for(self, u: ArrayLike, limit: float | None = None) -> FloatArray:
        """Motor amplitudes giving velocity amplitudes ``u``: minimum norm over the four motors,
        shifted along ``(1, 1, 1, 1)`` (which moves nothing) to keep every ``|motor| <= limit``.
        `ParameterError` when no shift can."""
        out = _core.motors_for(self.mass, self.inertia, self.lever, tuple(vector("u", u, 3)), limit)
        return np.array(out)

    def motors_for_rotation(self, center: ArrayLike, omega: float, limit: float | None = None) -> FloatArray:
        """Motor amplitudes placing the centre of rotation at ``center`` [m] with angular-rate
        amplitude ``omega`` [rad/s per unit waveform] (5.7, 5.16)."""
        cx, cy = vector("center", center, 2)
        if not (math.isfinite(omega) and omega != 0):
            raise ParameterError(f"omega must be finite and non-zero; got {omega}")
        return self.motors_for((omega * cy, -omega * cx, omega), limit)

    def center_of_rotation(self, motors: ArrayLike) -> tuple[FloatArray, float]:
        """Centre of rotation [m] and angular-rate amplitude of motor amplitudes."""
        return center_of_rotation(self.velocity_amplitudes(motors))


@dataclass(frozen=True)
class Axis:
    """One axis of the suspension, ``f = m q'' + b q' + k q`` (5.26): ``mass`` [kg or kg m^2],
    ``damping`` [N s/m], ``stiffness`` [N/m]."""

    mass: float
    damping: float
    stiffness: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "mass", real("mass", self.mass, low=0.0, low_open=True))
        object.__setattr__(self, "damping", real("damping", self.damping, low=0.0))
        object.__setattr__(self, "stiffness", real("stiffness", self.stiffness, low=0.0))

    def _response(self, w: FloatArray) -> tuple[float | None, FloatArray, FloatArray]:
        resonance, re, im = _core.axis_response(
            self.mass, self.damping, self.stiffness, np.ascontiguousarray(w)
        )
        return resonance, re, im

    @property
    def resonance(self) -> float | None:
        """Damped resonance ``sqrt(k/m - (b/2m)^2)`` [rad/s] (5.27); ``None`` if over-damped."""
        return self._response(np.zeros(0))[0]

    def velocity_response(self, frequency: ArrayLike) -> Any:
        """Velocity per force at ``frequency`` [Hz], complex: ``i w / (k - m w^2 + i b w)``."""
        f = as_float("frequency", frequency)
        _, re, im = self._response(2 * np.pi * f.reshape(-1))
        out = (re + 1j * im).reshape(f.shape)
        return complex(out) if out.ndim == 0 else out


def _harmonics(harmonics: Sequence[float]) -> tuple[float, ...]:
    """Harmonic numbers: a non-empty sequence of positive reals."""
    h = as_float("harmonics", harmonics)
    if h.ndim != 1 or h.size == 0 or not np.all(h > 0):
        raise ParameterError(f"harmonics must be a non-empty sequence of numbers > 0; got {harmonics!r}")
    return tuple(float(x) for x in h)


def check_drive(
    frequency: float, axes: Sequence[Axis], *, margin: float = 3.0, harmonics: Sequence[float] = (1.0, 2.0)
) -> bool:
    """Whether every component of the drive (``harmonics`` of ``frequency`` [Hz]; jets add 2/3)
    is at least ``margin`` times above every axis's resonance, where velocity is the integral of
    force over mass (5.10). Warns `upm.ResonanceWarning` and returns False otherwise."""
    f = real("frequency", frequency, low=0.0, low_open=True)
    listed = items("axes", axes, Axis, "a upm.actuation.Axis", min_len=1)
    ratio = real("margin", margin, low=0.0)
    lowest = min(_harmonics(harmonics)) * f * 2 * np.pi
    worst = max((a.resonance or 0.0) for a in listed)
    margin = ratio
    if lowest < margin * worst:
        warnings.warn(
            f"the drive's lowest component ({lowest / (2 * np.pi):.4g} Hz) is within {margin:g}x of a "
            f"resonance ({worst / (2 * np.pi):.4g} Hz): the plate velocity will not have the commanded "
            "shape; raise the frequency or precompensate",
            ResonanceWarning,
            stacklevel=2,
        )
        return False
    return True


def precompensate(axis: Axis, frequency: float, velocity: Mapping[float, complex]) -> dict[float, complex]:
    """Force phasors that give the axis the velocity phasors ``velocity`` = {harmonic: phasor}.

    A phasor ``p`` at harmonic ``h`` means ``Re(p e^{i h w t})``; each force is the wanted velocity
    divided by the axis's velocity response at ``h frequency`` (amplitude and phase corrected), so
    the plate moves as intended near resonances too.
    """
    return {h: complex(v) / complex(axis.velocity_response(h * frequency)) for h, v in velocity.items()}


@dataclass(frozen=True)
class HarmonicFit:
    """A least-squares harmonic fit (5.13): ``a(t) = offset + sum_h c_h cos(h w t) + s_h sin(h w t)``."""

    coefficients: FloatArray
    """``[c_h1, s_h1, c_h2, s_h2, ...]``."""
    offset: float
    residual: float
    """Root-mean-square residual, in the samples' unit."""
    frequency: float
    harmonics: tuple[float, ...]

    def velocity(self) -> FloatArray:
        """Velocity coefficients of these acceleration coefficients (5.14)."""
        return velocity_from_fit(self.coefficients, self.frequency, self.harmonics)


def harmonic_fit(
    samples: ArrayLike, sample_rate: float, frequency: float, harmonics: Sequence[float] = (1.0, 2.0)
) -> HarmonicFit:
    """Fit harmonics of ``frequency`` [Hz] to ``samples`` taken at ``sample_rate`` [Hz] from t = 0.

    `ParameterError` for records shorter than one period of the lowest harmonic, a sample rate
    that cannot resolve the highest, or an all-zero record.
    """
    s = as_float("samples", samples)
    if s.ndim != 1:
        raise ShapeError(f"samples must be one-dimensional; got shape {s.shape}")
    h = _harmonics(harmonics)
    f = real("frequency", frequency, low=0.0, low_open=True)
    rate = real("sample_rate", sample_rate, low=0.0, low_open=True)
    c, offset, residual = _core.harmonic_fit(np.ascontiguousarray(s), rate, f, list(h))
    return HarmonicFit(c, float(offset), float(residual), f, h)


def velocity_from_fit(
    coefficients: ArrayLike, frequency: float, harmonics: Sequence[float] = (1.0, 2.0)
) -> FloatArray:
    """Velocity coefficients from acceleration coefficients (5.14): for (5.13)'s basis,
    ``(1/w)[-s1, c1, -s2/2, c2/2]``."""
    c = np.ascontiguousarray(as_float("coefficients", coefficients).reshape(-1))
    return np.asarray(_core.velocity_from_fit(c, float(frequency), [float(x) for x in harmonics]))


def positive_force(coefficients: ArrayLike) -> Any:
    """The positive-force test (5.15) on acceleration coefficients ``[c1, s1, c2, s2]`` (any
    leading shape): ``2 s1 c1 c2 + s2 (s1^2 - c1^2) > 0`` iff the average friction force on a
    resting part along that axis is positive."""
    c = as_float("coefficients", coefficients)
    if c.ndim == 0 or c.shape[-1] != 4:
        raise ShapeError(f"coefficients must have shape (..., 4); got {c.shape}")
    out = np.asarray(_core.positive_force(np.ascontiguousarray(c.reshape(-1, 4)))).reshape(c.shape[:-1])
    return bool(out) if out.ndim == 0 else out


@dataclass(frozen=True)
class AccelerometerRotation:
    """The plate's rotation as two accelerometers see it."""

    center: FloatArray
    """Centre of rotation [m]."""
    omega: FloatArray
    """Angular-velocity coefficients [rad/s] in the fitted basis ``[c_h, s_h, ...]``."""
    residual: float
    """RMS residual of the four harmonic fits [m/s^2]."""


def cor_from_accelerometers(
    first: ArrayLike,
    second: ArrayLike,
    r1: ArrayLike,
    sample_rate: float,
    frequency: float,
    harmonics: Sequence[float] = (1.0, 2.0),
) -> AccelerometerRotation:
    """Centre of rotation from two 2-axis accelerometers at ``r1`` and ``-r1`` [m] (5.11-5.12,
    5.20-5.21), from their raw records ``(T, 2)`` [m/s^2] through harmonic fits:
    ``|w| = |v2 - v1| / (2 |r1|)``, ``c = R90(v1 + v2) / (2 w)``."""
    a = np.ascontiguousarray(as_float("first", first))
    b = np.ascontiguousarray(as_float("second", second))
    for name, rec in (("first", a), ("second", b)):
        if rec.ndim != 2 or rec.shape[1] != 2:
            raise ShapeError(f"{name} must have shape (T, 2); got {rec.shape}")
    x, y = vector("r1", r1, 2)
    c, w, residual = _core.cor_from_accelerometers(
        a, b, (float(x), float(y)), float(sample_rate), float(frequency), [float(h) for h in harmonics]
    )
    return AccelerometerRotation(np.array(c), np.asarray(w), float(residual))


#: The most samples :func:`synthetic_accelerometers` records (an hour at 5 kHz).
MAX_SAMPLES = 18_000_000


def synthetic_accelerometers(
    plate: Plate,
    motors: ArrayLike,
    r1: ArrayLike,
    frequency: float,
    duration: float,
    *,
    sample_rate: float = 5000.0,
    bits: int | None = 11,
    full_scale: float | None = None,
    snr_db: float | None = None,
    seed: int | np.random.Generator | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Records ``(T, 2)`` of two 2-axis accelerometers at ``r1`` and ``-r1`` on a plate driven by
    ``motors`` with forces ``cos wt - sin 2wt`` (5.9-5.10), as the hardware of record sampled them
    (docs/spec.md §6: 5 kHz, 11-bit A/D): the rigid-body acceleration including the centripetal term,
    white noise at ``snr_db`` (relative to the signal's RMS; ``None``: none) from ``seed``, then
    quantised to ``bits`` over ``+-full_scale`` (default: 1.25 x the peak).
    """
    u = instance("plate", plate, Plate, "a upm.actuation.Plate").velocity_amplitudes(motors)
    f = real("frequency", frequency, low=0.0, low_open=True)
    rate = real("sample_rate", sample_rate, low=0.0, low_open=True)
    span = real("duration", duration, low=0.0, low_open=True)
    count = span * rate
    if count < 2 or count > MAX_SAMPLES:
        raise ParameterError(
            f"duration * sample_rate must give 2..{MAX_SAMPLES} samples; got {count:.3g} "
            f"(duration {span:g} s at {rate:g} Hz)"
        )
    if bits is not None:
        integer("bits", bits, low=2, high=32)
    if full_scale is not None:
        real("full_scale", full_scale, low=0.0, low_open=True)
    if snr_db is not None:
        real("snr_db", snr_db)
    if seed is not None and not isinstance(seed, np.random.Generator):
        integer("seed", seed, low=0)
    w = 2 * np.pi * f
    t = np.arange(round(count)) / rate
    shape = (np.sin(w * t) + 0.5 * np.cos(2 * w * t)) / w  # velocity per unit amplitude
    dshape = np.cos(w * t) - np.sin(2 * w * t)  # its derivative
    p1 = vector("r1", r1, 2)
    rng = np.random.default_rng(seed)
    records = []
    for p in (p1, -p1):
        # v(P) = (u1 - u3 y, u2 + u3 x) g(t); a = dv/dt - w(t)^2 (P - c)-like centripetal term.
        vel = np.array([u[0] - u[2] * p[1], u[1] + u[2] * p[0]])
        acc = vel[None, :] * dshape[:, None]
        rate = u[2] * shape
        acc = acc - (rate**2)[:, None] * p[None, :]
        if snr_db is not None:
            rms = float(np.sqrt(np.mean(acc**2)))
            acc = acc + rng.normal(0.0, rms * 10 ** (-snr_db / 20), acc.shape)
        if bits is not None:
            scale = 1.25 * float(np.abs(acc).max()) if full_scale is None else float(full_scale)
            step = 2 * scale / 2**bits
            acc = np.clip(np.round(acc / step) * step, -scale, scale)
        records.append(acc)
    return records[0], records[1]


TABLE_5_1: dict[str, FloatArray] = {
    "motors": np.array(
        [
            [-128, -128, 128, 128],
            [-256, 0, 128, 128],
            [-256, 0, 0, 256],
            [-128, -128, 0, 256],
            [-128, -128, -128, 384],
            [0, -256, -128, 384],
        ],
        dtype=np.float64,
    ),
    "cor_inches": np.array(
        [[-0.22, 0.02], [2.92, 0.04], [2.72, 2.52], [-0.18, 2.66], [-0.14, 5.34], [-3.25, 5.54]]
    ),
}
"""Thesis Table 5.1: motor amplitudes ``(X1, X2, Y1, Y2)`` (board units) and the centre of
rotation measured by the accelerometers, in inches from the centre of an 8" x 8" table. Rows
(a)-(f). Every row keeps ``(Y1 + Y2) - (X1 + X2) = 512``. The printed difference columns are
labelled inconsistently with the moves (erratum E5): fit the map from the data."""


@dataclass(frozen=True)
class CorMap:
    """Affine calibration ``c = matrix @ [X1 - X2, Y1 - Y2] / s + offset``, ``s = (Y1+Y2) - (X1+X2)``
    (the steering laws 5.16 with their constants fitted)."""

    matrix: FloatArray
    offset: FloatArray
    residual: float
    """RMS distance between the fitted and the measured centres (the centres' unit)."""

    def predict(self, motors: ArrayLike) -> FloatArray:
        """Centres of rotation of motor rows ``(..., 4)``."""
        m = as_float("motors", motors)
        if m.shape[-1:] != (4,):
            raise ShapeError(f"motors must have shape (..., 4); got {m.shape}")
        s = (m[..., 2] + m[..., 3]) - (m[..., 0] + m[..., 1])
        if np.any(s == 0):
            raise ParameterError("motors must have (Y1 + Y2) - (X1 + X2) != 0: no rotation, no centre")
        d = np.stack([m[..., 0] - m[..., 1], m[..., 2] - m[..., 3]], axis=-1) / s[..., None]
        out: FloatArray = d @ self.matrix.T + self.offset
        return out

    def motors_for(self, center: ArrayLike, strength: float, limit: float | None = None) -> FloatArray:
        """Motor amplitudes placing the centre at ``center`` with rotation control
        ``(Y1+Y2) - (X1+X2) = strength``: the minimum-norm amplitudes (as every row of Table 5.1
        is), shifted to respect ``limit``; `ParameterError` when out of reach."""
        c = vector("center", center, 2)
        d = np.linalg.solve(self.matrix, c - self.offset) * strength
        return np.array(_core.motors_for(1.0, 1.0, 1.0, (float(d[0]), float(d[1]), float(strength)), limit))


def fit_cor_map(motors: ArrayLike, centers: ArrayLike) -> CorMap:
    """Fit the affine steering map from measured ``(motors (K, 4), centers (K, 2))`` pairs by least
    squares; needs at least three rows whose differences are not collinear."""
    m = as_float("motors", motors)
    c = as_float("centers", centers)
    if m.ndim != 2 or m.shape[1] != 4 or c.shape != (m.shape[0], 2):
        raise ShapeError(f"motors must be (K, 4) and centers (K, 2); got {m.shape} and {c.shape}")
    s = (m[:, 2] + m[:, 3]) - (m[:, 0] + m[:, 1])
    if np.any(s == 0):
        raise ParameterError("every row needs (Y1 + Y2) - (X1 + X2) != 0 (a rotation)")
    d = np.stack([m[:, 0] - m[:, 1], m[:, 2] - m[:, 3]], axis=1) / s[:, None]
    design = np.hstack([d, np.ones((len(d), 1))])
    if len(d) < 3 or np.linalg.matrix_rank(design) < 3:
        raise ParameterError(
            "the rows must vary both differences independently (at least 3 rows, not collinear)"
        )
    coef, *_ = np.linalg.lstsq(design, c, rcond=None)
    fitted = design @ coef
    residual = float(np.sqrt(np.mean(np.sum((fitted - c) ** 2, axis=1))))
    return CorMap(np.asarray(coef[:2].T, dtype=np.float64), np.asarray(coef[2], dtype=np.float64), residual)


def cor_library(
    cor_map: CorMap, centers: ArrayLike, strength: float, limit: float | None = None
) -> FloatArray:
    """The "COR library" (5.3.1): motor amplitudes ``(K, 4)`` for each target centre ``(K, 2)``."""
    cs = as_float("centers", centers).reshape(-1, 2)
    return np.stack([cor_map.motors_for(c, strength, limit) for c in cs])


def cross_validate_cor_map(motors: ArrayLike, centers: ArrayLike) -> FloatArray:
    """Leave-one-out validation of :func:`fit_cor_map`: for each row, the distance between its
    measured centre and the one predicted by the map fitted to the other rows, ``(K,)``."""
    m = as_float("motors", motors)
    c = as_float("centers", centers)
    if m.ndim != 2 or m.shape[1] != 4 or c.shape != (m.shape[0], 2):
        raise ShapeError(f"motors must be (K, 4) and centers (K, 2); got {m.shape} and {c.shape}")
    errors = np.empty(len(m))
    for i in range(len(m)):
        keep = np.arange(len(m)) != i
        fitted = fit_cor_map(m[keep], c[keep])
        errors[i] = float(np.hypot(*(fitted.predict(m[i]) - c[i])))
    return errors
