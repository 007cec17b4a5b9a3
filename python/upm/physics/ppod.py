"""Velocity fields of a plate that moves out of its plane (docs/ppod.md, docs/spec.md §10).

With vertical and rocking vibration the normal force varies over the plate and the cycle, and
parts follow velocity fields with sinks, sources, whirlpools and shear: the Northwestern PPOD line
(Vose, Umbanhowar and Lynch, IJRR 2009 and 2012). Here:

* the PPOD2 controller's field library as :class:`upm.PlateMotion` (``PlateMotion.ppod(name)``);
* :func:`drift_field`: the mean velocity of a part held at each point, in the periodic steady state
  of the exact stick–slip dynamics at a given friction coefficient;
* :func:`asymptotic_field`: ``argmin_v <(g + a_z)|v - v_h(t)|>``, the limit of the drift for a
  plate whose acceleration is large against ``mu g``, independent of ``mu`` and mass;
* :func:`divergence_curl` of either on a grid.

Both fields are computed in Rust, in parallel over points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from .._arrays import as_float, integer, real
from .._arrays import threads as pool
from .._errors import ParameterError, ShapeError
from .motion import PlateMotion
from .ppod_library import PPOD_FIELDS, PPOD_SEQUENCES

__all__ = [
    "PPOD_FIELDS",
    "PPOD_SEQUENCES",
    "FieldResult",
    "asymptotic_field",
    "divergence_curl",
    "drift_field",
    "field_angle",
]

_AXES = ("x", "y", "z", "rx", "ry", "rz")


def library_motion(name: str) -> PlateMotion:
    """The library field ``name`` as a :class:`PlateMotion` (``PlateMotion.ppod``)."""
    return PlateMotion.ppod(name)


@dataclass(frozen=True, eq=False)
class FieldResult:
    """A velocity field at points: what :func:`drift_field` and :func:`asymptotic_field` return."""

    kind: str
    """``"drift"`` or ``"asymptotic"``."""
    points: NDArray[np.float64]
    """Where [m], ``(..., 2)``."""
    velocity: NDArray[np.float64]
    """The field [m/s], ``(..., 2)``."""
    max_acceleration: NDArray[np.float64]
    """Largest horizontal acceleration of the plate surface over a cycle at each point [m/s²]."""
    validity: NDArray[np.float64]
    """``mu g / max_acceleration``: the asymptotic field describes the drift where this is small
    (NaN for an asymptotic field computed without ``mu``)."""
    lift_off: NDArray[np.float64]
    """Fraction of the cycle with ``g + a_z < 0`` at each point (a part there leaves the plate)."""
    converged: NDArray[np.bool_]
    """Whether each point met the tolerance."""
    iterations: NDArray[np.int64]
    """Periods simulated (drift) or median iterations (asymptotic) at each point."""
    mu: float | None
    """The friction coefficient the field was computed for (None: the asymptotic field)."""

    @property
    def speed(self) -> NDArray[np.float64]:
        """``|velocity|`` [m/s]."""
        return np.hypot(self.velocity[..., 0], self.velocity[..., 1])


def _points(points: ArrayLike) -> tuple[NDArray[np.float64], tuple[int, ...]]:
    p = as_float("points", points)
    if p.ndim == 0 or p.shape[-1] != 2:
        raise ShapeError(f"points must have shape (..., 2); got {p.shape}")
    return np.ascontiguousarray(p.reshape(-1, 2)), p.shape[:-1]


def _motion(motion: PlateMotion) -> PlateMotion:
    if not isinstance(motion, PlateMotion):
        raise ParameterError(f"motion must be a upm.PlateMotion; got {type(motion).__name__}")
    return motion


def drift_field(
    motion: PlateMotion,
    points: ArrayLike,
    *,
    mu: float,
    mu_s: float | None = None,
    g: float = 9.81,
    steps: int = 2000,
    tol: float = 1e-5,
    max_periods: int = 5000,
    threads: int | None = None,
) -> FieldResult:
    """The drift field of a periodic ``motion``: the mean velocity [m/s] of a part held at each of
    ``points`` in the periodic steady state of the exact stick–slip dynamics (the integrator's own
    step, lift-off included) at friction ``mu`` (``mu_s``, default ``mu``).

    Each point starts at rest and runs whole periods of ``steps`` steps until the mean velocity of
    a period differs from the previous period's by at most ``tol`` [m/s] twice in a row (at most
    ``max_periods``; ``converged`` tells). ``motion`` must repeat forever (one motion, no
    duration), e.g. ``PlateMotion.ppod("Sink")``.
    """
    p, shape = _points(points)
    m = real("mu", mu, low=0.0, low_open=True)
    ms = m if mu_s is None else real("mu_s", mu_s, low=m)
    gg = real("g", g, low=0.0, low_open=True)
    r = _core.drift_field(
        _motion(motion)._inner, p, mu=m, mu_s=ms, g=gg, steps=integer("steps", steps, low=16, high=1_000_000),
        tol=real("tol", tol, low=0.0, low_open=True), max_periods=integer("max_periods", max_periods, low=1),
        threads=pool(threads),
    )  # fmt: skip
    return _result("drift", p, shape, r.velocity, r.max_accel, r.lift, r.converged, r.work, m, gg)


def asymptotic_field(
    motion: PlateMotion,
    points: ArrayLike,
    *,
    mu: float | None = None,
    g: float = 9.81,
    samples: int = 4096,
    threads: int | None = None,
) -> FieldResult:
    """The asymptotic field ``v* = argmin_v <(g + a_z)^+ |v - v_h(t)|>`` [m/s] of a periodic
    ``motion`` at ``points``: the weighted geometric median of the surface velocity's hodograph
    over ``samples`` times of a cycle (weights: the normal force, none in flight). Independent of
    friction and mass; ``mu``, if given, only sets the ``validity`` index."""
    p, shape = _points(points)
    gg = real("g", g, low=0.0, low_open=True)
    m = None if mu is None else real("mu", mu, low=0.0, low_open=True)
    r = _core.asymptotic_field(
        _motion(motion)._inner, p, g=gg, samples=integer("samples", samples, low=16, high=1_000_000),
        threads=pool(threads),
    )  # fmt: skip
    return _result("asymptotic", p, shape, r.velocity, r.max_accel, r.lift, r.converged, r.work, m, gg)


def _result(
    kind: str,
    p: NDArray[np.float64],
    shape: tuple[int, ...],
    v: NDArray[np.float64],
    acc: NDArray[np.float64],
    lift: NDArray[np.float64],
    ok: NDArray[np.bool_],
    work: NDArray[np.uint64],
    mu: float | None,
    g: float,
) -> FieldResult:
    with np.errstate(divide="ignore"):
        validity = np.full(acc.shape, np.nan) if mu is None else mu * g / acc
    return FieldResult(
        kind=kind,
        points=p.reshape(*shape, 2),
        velocity=v.reshape(*shape, 2),
        max_acceleration=acc.reshape(shape),
        validity=validity.reshape(shape),
        lift_off=lift.reshape(shape),
        converged=ok.reshape(shape),
        iterations=work.astype(np.int64).reshape(shape),
        mu=mu,
    )


def field_angle(a: FieldResult | ArrayLike, b: FieldResult | ArrayLike) -> NDArray[np.float64]:
    """The angle [deg] from field ``a`` to field ``b`` at each point, in (-180, 180] (NaN where
    either vanishes)."""
    va = a.velocity if isinstance(a, FieldResult) else as_float("a", a)
    vb = b.velocity if isinstance(b, FieldResult) else as_float("b", b)
    if va.shape != vb.shape or va.shape[-1:] != (2,):
        raise ShapeError(f"the fields must have the same shape (..., 2); got {va.shape} and {vb.shape}")
    cross = va[..., 0] * vb[..., 1] - va[..., 1] * vb[..., 0]
    dot = va[..., 0] * vb[..., 0] + va[..., 1] * vb[..., 1]
    angle = np.degrees(np.arctan2(cross, dot))
    zero = (np.hypot(va[..., 0], va[..., 1]) == 0) | (np.hypot(vb[..., 0], vb[..., 1]) == 0)
    return np.where(zero, np.nan, angle)


def divergence_curl(
    velocity: ArrayLike, xs: ArrayLike, ys: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Divergence and curl [1/s] of a field sampled on the grid ``velocity[j, i] = v(xs[i], ys[j])``
    (shape ``(len(ys), len(xs), 2)``), by second-order finite differences (one-sided at the edges).
    A sink has negative divergence, a counter-clockwise whirl positive curl."""
    v = as_float("velocity", velocity)
    x = as_float("xs", xs).reshape(-1)
    y = as_float("ys", ys).reshape(-1)
    if v.shape != (y.size, x.size, 2):
        raise ShapeError(
            f"velocity must have shape (len(ys), len(xs), 2) = ({y.size}, {x.size}, 2); got {v.shape}"
        )
    if x.size < 3 or y.size < 3 or np.any(np.diff(x) <= 0) or np.any(np.diff(y) <= 0):
        raise ParameterError("xs and ys must be strictly increasing with at least 3 values each")
    dvx_dy, dvx_dx = np.gradient(v[..., 0], y, x, edge_order=2)
    dvy_dy, dvy_dx = np.gradient(v[..., 1], y, x, edge_order=2)
    div: NDArray[np.float64] = np.asarray(dvx_dx + dvy_dy)
    curl: NDArray[np.float64] = np.asarray(dvy_dx - dvx_dy)
    return div, curl
