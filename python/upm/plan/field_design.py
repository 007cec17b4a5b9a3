"""Designing plate motions for a wanted velocity field (docs/ppod.md, "Designing a field").

The plate translates on a circle in its plane (``x'' = a sin wt``, ``y'' = a cos wt``: a
circular hodograph of speed ``V = a / w``) and moves out of its plane with ``z''``, ``rx''`` and
``ry''`` harmonics of the same frequency. For a small modulation of the normal force the
asymptotic field is linear in the modulation: ``v*(P) ~ (2 / g) <a_z(P, t) v_h(t)>``, and since
``a_z = z'' + y rx'' - x ry''`` is affine in ``P``, so is the field. Each of the three out-of-plane
phasors ``S`` (``A e^{ip}``) sets one column of the field: ``(g / V) (-Im S, Re S)`` is the constant
term (``z``), ``dv/dy`` (``rx``) and ``-dv/dx`` (``ry``). Any affine field ``v = A (P - c) + b``
has one such motion; :func:`design_field` starts there and refines the six numbers by
Gauss–Newton on the exact drift at the given friction (:func:`upm.drift_field`), at points
around ``c``, keeping every axis within its acceleration limit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import as_float, point, real
from .._errors import ParameterError, ShapeError
from ..physics.motion import PlateMotion
from ..physics.ppod import FieldResult, drift_field, field_angle

__all__ = ["FieldDesign", "design_field"]

DEFAULT_LIMITS: dict[str, float] = {"x": 15.0, "y": 15.0, "z": 10.0, "rx": 150.0, "ry": 150.0}
"""Per-axis acceleration amplitude limits [m/s², rad/s²], about the PPOD's."""

_KINDS = ("sink", "source", "rotation", "translation", "shear", "affine")


@dataclass(frozen=True, eq=False)
class FieldDesign:
    """A designed plate motion and how well its drift field matches the wanted one."""

    motion: PlateMotion
    """The 6-DOF harmonic motion (repeats forever)."""
    matrix: NDArray[np.float64]
    """The wanted field's gradient ``A`` [1/s], ``(2, 2)``."""
    offset: NDArray[np.float64]
    """The wanted field at the centre ``b`` [m/s]."""
    center: NDArray[np.float64]
    """The centre ``c`` [m]."""
    wanted: NDArray[np.float64]
    """The wanted field at :attr:`achieved`'s points [m/s], ``(M, 2)``."""
    achieved: FieldResult
    """The drift field of :attr:`motion` at the design points, at the design friction."""
    error: float
    """RMS of (achieved - wanted) over RMS of wanted."""
    max_angle: float
    """Largest angle between achieved and wanted [deg] at the design points."""
    limited: bool
    """Whether an axis sits at its acceleration limit (the field may be weaker than asked)."""
    iterations: int
    """Gauss–Newton iterations of the refinement."""


def _wanted(
    kind: str, strength: ArrayLike, matrix: ArrayLike | None, offset: ArrayLike | None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    if kind not in _KINDS:
        raise ParameterError(f"kind must be one of {', '.join(_KINDS)}; got {kind!r}")
    if kind == "affine":
        if matrix is None:
            raise ParameterError("kind='affine' needs matrix (2, 2) [1/s] and optionally offset (2,) [m/s]")
        a = as_float("matrix", matrix)
        if a.shape != (2, 2):
            raise ShapeError(f"matrix must have shape (2, 2); got {a.shape}")
        b = np.zeros(2) if offset is None else np.asarray(point("offset", offset))
        return a, b
    if matrix is not None or offset is not None:
        raise ParameterError(f"matrix and offset are for kind='affine' only (kind={kind!r})")
    if kind == "translation":
        return np.zeros((2, 2)), np.asarray(point("strength", strength))
    s = real("strength", strength, low=0.0, low_open=True)
    shapes = {
        "sink": [[-s, 0.0], [0.0, -s]],
        "source": [[s, 0.0], [0.0, s]],
        "rotation": [[0.0, -s], [s, 0.0]],  # counter-clockwise
        "shear": [[0.0, s], [0.0, 0.0]],  # v_x = s (y - c_y)
    }
    return np.array(shapes[kind]), np.zeros(2)


def _motion(f: float, a: float, phasors: NDArray[np.float64]) -> PlateMotion:
    """The motion for the circular translation ``a`` and the phasors ``(z, rx, ry)`` (re, im)."""
    terms = {}
    for axis, (re, im) in zip(("z", "rx", "ry"), phasors.reshape(3, 2), strict=True):
        mag = math.hypot(re, im)
        if mag > 0:
            terms[axis] = [(1, mag, math.atan2(im, re))]
    return PlateMotion.harmonic(f, x=[(1, a, 0.0)], y=[(1, a, math.pi / 2)], **terms)


def _clip(phasors: NDArray[np.float64], limits: Mapping[str, float]) -> tuple[NDArray[np.float64], bool]:
    out = phasors.reshape(3, 2).copy()
    hit = False
    for k, axis in enumerate(("z", "rx", "ry")):
        mag = math.hypot(*out[k])
        if mag > limits[axis]:
            out[k] *= limits[axis] / mag
            hit = True
    return out.reshape(-1), hit


def design_field(
    kind: str,
    center: ArrayLike = (0.0, 0.0),
    strength: ArrayLike = 0.5,
    *,
    frequency: float = 20.0,
    mu: float = 0.3,
    limits: Mapping[str, float] | None = None,
    radius: float = 0.05,
    matrix: ArrayLike | None = None,
    offset: ArrayLike | None = None,
    g: float = 9.81,
    iterations: int = 8,
) -> FieldDesign:
    """A 6-DOF harmonic plate motion whose drift field near ``center`` is the wanted one.

    ``kind``: ``"sink"``, ``"source"`` (``strength`` [1/s]: ``v = -/+ s (P - c)``), ``"rotation"``
    (counter-clockwise, ``s R90 (P - c)``), ``"shear"`` (``v_x = s (y - c_y)``), ``"translation"``
    (``strength`` a velocity ``(vx, vy)`` [m/s]), or ``"affine"`` with ``matrix`` ``A`` [1/s] and
    ``offset`` ``b`` [m/s]: ``v = A (P - c) + b``. The field is matched at the centre and at 8
    points on a circle of ``radius`` [m] around it, on the exact drift at friction ``mu``, with
    every axis within ``limits`` (``{"x": .., "y": .., "z": .., "rx": .., "ry": ..}``, m/s² and
    rad/s²; defaults :data:`DEFAULT_LIMITS`; the in-plane circle uses the smaller of x and y).
    """
    a_mat, b = _wanted(kind, strength, matrix, offset)
    c = np.asarray(point("center", center))
    f = real("frequency", frequency, low=0.0, low_open=True, high=1000.0)
    m = real("mu", mu, low=0.0, low_open=True)
    gg = real("g", g, low=0.0, low_open=True)
    r = real("radius", radius, low=0.0, low_open=True, high=1.0)
    lim = dict(DEFAULT_LIMITS)
    for key, value in (limits or {}).items():
        if key not in lim:
            raise ParameterError(f"limits: unknown axis {key!r}; known: {', '.join(lim)}")
        lim[key] = real(f"limits[{key!r}]", value, low=0.0, low_open=True)
    w = 2 * math.pi * f
    a = min(lim["x"], lim["y"])
    v_amp = a / w

    # the small-modulation closed form: each column (t1, t2) = (V / g) (-Im S, Re S)
    def phasor(t: NDArray[np.float64]) -> tuple[float, float]:
        return gg * t[1] / v_amp, -gg * t[0] / v_amp

    p0 = np.array([*phasor(b - a_mat @ c), *phasor(a_mat[:, 1]), *phasor(-a_mat[:, 0])])
    p, hit = _clip(p0, lim)
    angles = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    pts = np.vstack([c, c + r * np.stack([np.cos(angles), np.sin(angles)], axis=1)])
    want = (pts - c) @ a_mat.T + b
    scale = max(float(np.sqrt(np.mean(np.sum(want**2, axis=1)))), 1e-6)

    def residual(q: NDArray[np.float64]) -> NDArray[np.float64]:
        d = drift_field(_motion(f, a, q), pts, mu=m, g=gg, steps=800, tol=1e-6)
        out: NDArray[np.float64] = (d.velocity - want).reshape(-1) / scale
        return out

    res = residual(p)
    done = 0
    damping = 1e-3
    while done < iterations:
        done += 1
        step = 1e-3 * max(float(np.max(np.abs(p))), 1.0)
        jac = np.stack([(residual(p + step * e) - res) / step for e in np.eye(6)], axis=1)
        lhs = jac.T @ jac
        rhs = -jac.T @ res
        improved = False
        for _ in range(6):
            delta = np.linalg.solve(lhs + damping * np.diag(np.diag(lhs) + 1e-12), rhs)
            trial, trial_hit = _clip(p + delta, lim)
            r_trial = residual(trial)
            if r_trial @ r_trial < res @ res:
                p, res, hit, improved = trial, r_trial, trial_hit, True
                damping = max(damping / 3, 1e-6)
                break
            damping *= 10
        if not improved or float(np.sqrt(np.mean(res**2))) < 1e-3:
            break
    motion = _motion(f, a, p)
    achieved = drift_field(motion, pts, mu=m, g=gg)
    err = float(np.sqrt(np.mean(np.sum((achieved.velocity - want) ** 2, axis=1)))) / scale
    moving = np.linalg.norm(want, axis=1) > 1e-9
    angle = (
        float(np.nanmax(np.abs(field_angle(achieved.velocity[moving], want[moving]))))
        if moving.any()
        else 0.0
    )
    return FieldDesign(motion, a_mat, b, c, want, achieved, err, angle, hit, done)
