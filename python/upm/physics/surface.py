"""The plate under the parts, beyond its motion: its slope (:func:`gravity`) and its friction
over the surface (:func:`friction_grid`), for :func:`upm.simulate`, ``SimulatedUPM`` and the
board emulator.

A friction map is a factor on every part's own ``mu`` and ``mu_s`` at each point of the plate (1: the
part's own friction). The integrator looks it up under each part every millisecond of plate time
(``FrictionMap::REFRESH`` in the core): a part moves micrometres in that time, a map varies over
centimetres. Give it as a grid, or as a function the plate is sampled with.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import as_float, real
from .._errors import ParameterError, ShapeError

__all__ = ["SAMPLES", "friction_grid", "gravity", "smooth_map"]

#: Nodes along each side when a map given as a function is sampled.
SAMPLES = 65


def friction_grid(friction_map: Any, plate_size: float | None) -> NDArray[np.float64] | None:
    """The grid of factors a ``friction_map`` stands for over a plate of side ``plate_size``
    [m]: ``None`` (the same friction everywhere); an array ``(ny, nx)`` (each at least 2), row
    ``j`` at ``y = -size/2 + j size/(ny-1)`` and column ``i`` likewise in ``x``, bilinear between
    them and the edge's value beyond; or a function ``f(x, y) -> factor`` of coordinate arrays
    [m], sampled on a :data:`SAMPLES` x :data:`SAMPLES` grid. Every factor finite and > 0."""
    if friction_map is None:
        return None
    if plate_size is None:
        raise ParameterError("friction_map covers the plate: give plate_size (the plate's side [m])")
    if callable(friction_map):
        return _sampled(friction_map, plate_size)
    try:
        grid = np.array(friction_map, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ParameterError(
            "friction_map must be a 2-D grid of factors or a function f(x, y); got "
            f"{type(friction_map).__name__}"
        ) from error
    if grid.ndim != 2 or min(grid.shape) < 2:
        raise ShapeError(
            f"friction_map must be a grid of at least 2 x 2 factors (ny, nx); got shape {grid.shape}"
        )
    if grid.size > 4096**2:
        raise ParameterError(f"friction_map must hold at most 4096 x 4096 factors; got {grid.shape}")
    return _checked(grid)


def _sampled(f: Callable[..., Any], plate_size: float) -> NDArray[np.float64]:
    axis = np.linspace(-plate_size / 2, plate_size / 2, SAMPLES)
    x, y = np.meshgrid(axis, axis)  # row j: y = axis[j]
    values = f(x, y)  # the user's own errors pass through as they are
    try:
        grid = np.broadcast_to(np.asarray(values, dtype=np.float64), x.shape).copy()
    except (TypeError, ValueError) as error:
        raise ParameterError(
            f"friction_map(x, y) must return a factor for every point of x and y (arrays of shape "
            f"{x.shape}); got {np.shape(values)}"
        ) from error
    return _checked(grid)


def _checked(grid: NDArray[np.float64]) -> NDArray[np.float64]:
    bad = ~(np.isfinite(grid) & (grid > 0))
    if np.any(bad):
        j, i = np.argwhere(bad)[0]
        raise ParameterError(
            f"friction_map factors must be finite and > 0; got {float(grid[j, i])!r} at row {j}, column {i}"
        )
    return np.ascontiguousarray(grid)


def smooth_map(low: float, high: float, seed: int = 0, n: int = 17) -> NDArray[np.float64]:
    """A random smooth map of factors from ``low`` to ``high`` (a few bumps across the plate,
    on an ``n`` x ``n`` grid over it): a surface worn or soiled unevenly, for robustness studies."""
    if not (0 < low <= high and np.isfinite(high)):
        raise ParameterError(f"smooth_map needs 0 < low <= high (finite); got low={low!r}, high={high!r}")
    rng = np.random.default_rng(seed)
    axis = np.linspace(-0.5, 0.5, n)
    x, y = np.meshgrid(axis, axis)
    field = np.zeros_like(x)
    for _ in range(4):  # a few plane waves of about one to two per plate side
        k = rng.uniform(1.0, 2.0) * 2 * np.pi
        angle, phase = rng.uniform(0, 2 * np.pi, 2)
        field += np.cos(k * (x * np.cos(angle) + y * np.sin(angle)) + phase)
    span = field.max() - field.min()
    unit = (field - field.min()) / span if span > 0 else np.full_like(field, 0.5)
    return low + (high - low) * unit


def gravity(g: float, tilt: ArrayLike) -> dict[str, Any]:
    """Gravity's normal part and its part in the plate's plane [m/s^2] of a plate of slope
    ``tilt`` [rad] (:func:`simulate`), as the extension takes them."""
    full = real("g", g, low=0.0, low_open=True)
    a = as_float("tilt", tilt)
    if a.shape != (2,) or not np.all(np.isfinite(a)) or np.any(np.abs(a) > 0.5):
        raise ParameterError(
            f"tilt must be two slopes [rad] (along x, along y), each within 0.5; got {tilt!r}"
        )
    s = np.sin(a)
    return {"g": full * math.sqrt(1.0 - float(s @ s)), "tilt": (-full * float(s[0]), -full * float(s[1]))}
