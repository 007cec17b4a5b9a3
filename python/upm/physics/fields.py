"""Average force fields on resting or slowly moving parts (docs/spec.md §1, §4, §7; thesis 4.5-4.11, 6.1).

Every field is dimensionless, ``force / (mu m g)``, at points in the plate frame [m]. ``points``
may have any shape ``(..., 2)``; results keep the leading shape.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from .._arrays import as_float, point, real
from .._arrays import threads as pool
from .._errors import ParameterError, ShapeError
from .motion import PlateMotion

__all__ = ["average_field", "jet_field", "rotation_curl", "rotation_field"]

_TOL = 1e-10


def _points(name: str, points: ArrayLike) -> tuple[NDArray[np.float64], tuple[int, ...]]:
    p = as_float(name, points)
    if p.ndim == 0 or p.shape[-1] != 2:
        raise ShapeError(f"{name} must have shape (..., 2); got {p.shape}")
    return np.ascontiguousarray(p.reshape(-1, 2)), p.shape[:-1]


def _tol(tol: float) -> float:
    return real("tol", tol, low=0.0, low_open=True)


def rotation_field(points: ArrayLike, center: ArrayLike) -> NDArray[np.float64]:
    """Unit tangential field of a rotation about ``center`` (4.8, 5.1): ``R90(P - C) / |P - C|``.

    A rotation of strength ``k`` gives the average force ``k mu m g`` times this field. At the
    centre itself the plate does not move and a resting part feels no force: ``(0, 0)``.

    Returns an array of shape ``(..., 2)`` like ``points``.
    """
    p, lead = _points("points", points)
    return np.asarray(_core.rotation_field(p, point("center", center))).reshape(*lead, 2)


def rotation_curl(points: ArrayLike, center: ArrayLike) -> Any:
    """Curl of :func:`rotation_field`, ``1 / |P - C|`` [1/m] (4.11); ``inf`` at the centre."""
    p, lead = _points("points", points)
    out = np.asarray(_core.rotation_curl(p, point("center", center))).reshape(lead)
    return float(out) if out.ndim == 0 else out


def jet_field(
    points: ArrayLike,
    center: ArrayLike,
    direction: ArrayLike,
    rho: float,
    *,
    tol: float = _TOL,
    threads: int | None = None,
) -> NDArray[np.float64]:
    """Average force / (mu m g) of the jet (6.4) focused at ``center`` feeding along ``direction``.

    Exact to ``tol``: the period ``6 pi`` is split at the roots of the relative velocity's
    components (isolated rigorously) and each piece is integrated adaptively. ``(1/3)`` along
    ``direction`` at the focus (Corollary 1); vanishes far away; ``rho`` [m] sets the size.
    Only the direction of ``direction`` matters. ``threads``: a pool of that many threads
    (default: one per core).

    Returns an array of shape ``(..., 2)`` like ``points``.
    """
    p, lead = _points("points", points)
    c, d = point("center", center), point("direction", direction)
    out = _core.jet_field(p, c, d, real("rho", rho), _tol(tol), threads=pool(threads))
    return np.asarray(out).reshape(*lead, 2)


def average_field(
    motion: PlateMotion,
    points: ArrayLike,
    part_velocity: ArrayLike | None = None,
    *,
    tol: float = _TOL,
    threads: int | None = None,
) -> NDArray[np.float64]:
    """Average friction force / (mu m g) that ``motion`` exerts at ``points`` (4.5, 6.2).

    The average is over one pass of the program (its duration, or one period of a motion that
    repeats forever) of the unit relative velocity, by adaptive Gauss-Kronrod quadrature to
    absolute accuracy ``tol``, split at the program's item and envelope boundaries.

    Parameters
    ----------
    motion : PlateMotion
    points : array_like, shape (..., 2)
        Part positions [m].
    part_velocity : array_like, shape (2,) or (..., 2), optional
        Velocity of the parts [m/s] (default at rest); the force then depends on it (3.4).
    threads : int, optional
        Run on a pool of this many threads (default: one per core, or ``RAYON_NUM_THREADS``).

    Returns
    -------
    ndarray, shape (..., 2)
    """
    if not isinstance(motion, PlateMotion):
        raise ParameterError(f"motion must be a upm.PlateMotion; got {type(motion).__name__}")
    p, lead = _points("points", points)
    if part_velocity is None:
        v = np.zeros_like(p)
    else:
        va = as_float("part_velocity", part_velocity)
        try:
            v = np.ascontiguousarray(np.broadcast_to(va, (*lead, 2)).reshape(-1, 2))
        except ValueError as error:
            raise ShapeError(
                f"part_velocity must broadcast to the points' shape {(*lead, 2)}; got {va.shape}"
            ) from error
    out = _core.average_field(motion._inner, p, v, _tol(tol), threads=pool(threads))
    return np.asarray(out).reshape(*lead, 2)
