"""Convex polygon parts: their geometry and the exact friction wrench of any relative motion
(docs/spec.md §11, docs/polygons.md).

Under uniform pressure the friction of a part that slides with relative twist ``(V, omega)`` at its
centroid is ``F = -mu p ∫ u/|u| dA`` and ``M = -mu p ∫ r x u/|u| dA`` with ``u(r) = V + omega z x
r``. :meth:`Polygon.wrench` evaluates both exactly (closed forms over triangles fanning from the
instantaneous centre of rotation, computed in Rust), in parallel over many twists.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from .._arrays import as_float, real
from .._arrays import threads as pool
from .._errors import ParameterError, ShapeError

__all__ = ["Polygon"]

FloatArray = NDArray[np.float64]


def _pair(name: str, value: Any) -> tuple[float, float]:
    a = as_float(name, value)
    if a.shape != (2,) or not np.all(np.isfinite(a)):
        raise ParameterError(f"{name} must be two finite numbers (x, y); got {value!r}")
    return float(a[0]), float(a[1])


def _load(load: ArrayLike | None) -> tuple[float, float]:
    """A pressure gradient ``(kx, ky)`` [1/m] (uniform pressure when None)."""
    if load is None:
        return (0.0, 0.0)
    k = as_float("load", load)
    if k.shape != (2,):
        raise ShapeError(f"load must be two numbers (kx, ky) [1/m]; got shape {k.shape}")
    return (float(k[0]), float(k[1]))


def _rows(pair_name: str, pair: Any, one_name: str, one: Any) -> tuple[tuple[int, ...], FloatArray]:
    """``pair (..., 2)`` and ``one (...)`` broadcast together: their shape and the ``(N, 3)`` rows."""
    p = as_float(pair_name, pair)
    o = as_float(one_name, one)
    if p.ndim == 0 or p.shape[-1] != 2:
        raise ShapeError(f"{pair_name} must have shape (..., 2); got {p.shape}")
    try:
        shape = np.broadcast_shapes(p.shape[:-1], o.shape)
    except ValueError:
        raise ShapeError(f"{pair_name} {p.shape} and {one_name} {o.shape} do not broadcast") from None
    rows = np.empty((*shape, 3))
    rows[..., :2] = p
    rows[..., 2] = o
    return shape, rows.reshape(-1, 3)


@dataclass(frozen=True, eq=False)
class Polygon:
    """A flat convex polygon part pressing uniformly on the plate, or resting on three feet.

    ``vertices`` ``(K, 2)`` [m] in the part's frame, counter-clockwise; ``position`` [m] of the
    frame's origin on the plate and ``angle`` [rad] of the frame; ``velocity`` [m/s] of the
    centroid and ``spin`` [rad/s]; ``mass`` (any unit, only ratios matter; by default
    proportional to the area). A polygon that is not convex, turns clockwise, repeats a vertex,
    has three collinear vertices or no area is refused with :class:`upm.ParameterError` naming
    the reason.

    ``support``: ``None`` (the default) for uniform pressure over the footprint, or three feet
    ``(3, 2)`` [m] in the part's frame that carry it instead (three-point support, as in Vose,
    Umbanhowar and Lynch 2012): the normal force splits over them so that they hold the part
    level (:attr:`shares`), friction acts at the feet alone, and the part may pivot about a
    foot. The feet must lie within the outline, span a triangle and surround the centroid (else
    the part would tip); :class:`upm.ParameterError` names the reason otherwise.

    :func:`upm.simulate` and :func:`upm.simulate_batch` step it with its exact stick–slip step
    (out of the plane too, pressed by ``g + a_z`` across its footprint or its feet), with contacts
    through rapier's convex polygon colliders; its friction is :meth:`wrench`.
    """

    vertices: Any
    position: tuple[float, float] = (0.0, 0.0)
    angle: float = 0.0
    velocity: tuple[float, float] = (0.0, 0.0)
    spin: float = 0.0
    mass: float | None = None
    support: Any = None
    _geometry: tuple[Any, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        v = as_float("vertices", self.vertices)
        if v.ndim != 2 or v.shape[1] != 2:
            raise ShapeError(f"vertices must have shape (K, 2) with K >= 3; got {v.shape}")
        v = np.ascontiguousarray(v)
        v.setflags(write=False)
        feet = None
        if self.support is not None:
            feet = np.ascontiguousarray(as_float("support", self.support))
            if feet.shape != (3, 2):
                raise ShapeError(f"support must have shape (3, 2): three feet (x, y); got {feet.shape}")
            feet.setflags(write=False)
        geometry = _core.polygon_geometry(v, "vertices", feet)
        set_ = object.__setattr__
        set_(self, "vertices", v)
        set_(self, "support", feet)
        set_(self, "_geometry", geometry)
        set_(self, "position", _pair("position", self.position))
        set_(self, "velocity", _pair("velocity", self.velocity))
        set_(self, "angle", real("angle", self.angle))
        set_(self, "spin", real("spin", self.spin))
        if self.mass is not None:
            set_(self, "mass", real("mass", self.mass, low=0.0, low_open=True))

    # -- shapes --------------------------------------------------------------------------------
    @classmethod
    def regular(cls, sides: int, circumradius: float, **state: Any) -> Polygon:
        """A regular polygon of ``sides`` sides centred on its frame's origin, a vertex on the
        frame's x axis."""
        if isinstance(sides, bool) or not isinstance(sides, (int, np.integer)) or not 3 <= sides <= 100_000:
            raise ParameterError(f"sides must be an integer from 3 to 100000; got {sides!r}")
        r = real("circumradius", circumradius, low=0.0, low_open=True)
        a = 2 * np.pi * np.arange(int(sides)) / int(sides)
        return cls(np.stack([r * np.cos(a), r * np.sin(a)], axis=1), **state)

    @classmethod
    def rectangle(cls, width: float, height: float, **state: Any) -> Polygon:
        """A ``width`` x ``height`` rectangle centred on its frame's origin, ``width`` along x."""
        w = real("width", width, low=0.0, low_open=True) / 2
        h = real("height", height, low=0.0, low_open=True) / 2
        return cls([(-w, -h), (w, -h), (w, h), (-w, h)], **state)

    # -- geometry ------------------------------------------------------------------------------
    @property
    def area(self) -> float:
        """[m²]."""
        return float(self._geometry[0])

    @property
    def centroid(self) -> FloatArray:
        """Centroid in the part's frame [m]."""
        out: FloatArray = self._geometry[1].copy()
        return out

    @property
    def gyration(self) -> float:
        """Radius of gyration about the centroid [m]: the moment of inertia is
        ``mass * gyration**2``."""
        return math.sqrt(self._geometry[2] / self._geometry[0])

    @property
    def second_moments(self) -> FloatArray:
        """``∫ r r^T dA / A`` about the centroid in the part's frame, ``(2, 2)`` [m²]: how the
        area spreads (its principal axes are the part's)."""
        xx, xy, yy = self._geometry[6]
        return np.array([[xx, xy], [xy, yy]])

    @property
    def radius(self) -> float:
        """Largest distance of a vertex from the centroid [m]."""
        return float(self._geometry[3])

    @property
    def mean_distance(self) -> float:
        """Mean distance of the footprint (or of the feet, weighted by their :attr:`shares`) from
        the centroid [m]: a part spinning in place on a still plate feels the moment ``mu N
        mean_distance``."""
        return float(self._geometry[4])

    @property
    def shares(self) -> FloatArray | None:
        """Each foot's share of the normal force on a level plate ``(3,)`` (summing to 1; the
        barycentric coordinates of the centroid in the feet's triangle), None without feet."""
        s = self._geometry[7]
        return None if s is None else np.array(s)

    def moved(
        self, position: ArrayLike, angle: float, velocity: ArrayLike = (0.0, 0.0), spin: float = 0.0
    ) -> Polygon:
        """The same part (outline, feet, mass) in another state: ``position`` [m] of its frame's
        origin, ``angle`` [rad], ``velocity`` [m/s] of its centroid and ``spin`` [rad/s]."""
        return Polygon(self.vertices, _pair("position", position), angle, _pair("velocity", velocity), spin,
                       self.mass, self.support)  # fmt: skip

    @property
    def symmetry(self) -> int:
        """The order ``k`` of the outline's rotational symmetry about its centroid (1: none; a
        square 4, a rectangle 2, a regular n-gon n): its pose's angle is known modulo ``2 pi / k``."""
        z = (self.vertices[:, 0] - self.centroid[0]) + 1j * (self.vertices[:, 1] - self.centroid[1])
        n, tol = len(z), 1e-9 * self.radius
        for k in range(n, 1, -1):
            if n % k == 0 and all(np.abs(z - t).min() <= tol for t in z * np.exp(2j * np.pi / k)):
                return k
        return 1

    def centroid_offset(self, angles: Any) -> FloatArray:
        """Where the centroid is from the frame's origin on the plate [m], ``(..., 2)``, with the
        frame turned by ``angles`` [rad] ``(...)``: a pose's centroid is its position plus this."""
        a = np.asarray(angles, dtype=np.float64)
        c, s = np.cos(a), np.sin(a)
        o = self.centroid
        out: FloatArray = np.stack([c * o[0] - s * o[1], s * o[0] + c * o[1]], axis=-1)
        return out

    def outline(self) -> FloatArray:
        """The vertices on the plate [m], ``(K, 2)``: turned by ``angle`` and moved to
        ``position``."""
        c, s = math.cos(self.angle), math.sin(self.angle)
        out: FloatArray = self.vertices @ np.array([[c, s], [-s, c]]) + np.asarray(self.position)
        return out

    # -- friction ------------------------------------------------------------------------------
    def wrench(
        self,
        velocity: ArrayLike,
        spin: ArrayLike,
        *,
        load: ArrayLike | None = None,
        threads: int | None = None,
    ) -> tuple[FloatArray, FloatArray]:
        """Friction force and moment about the centroid, divided by ``mu N``, on the part sliding
        with relative ``velocity`` [m/s] ``(..., 2)`` at its centroid and relative ``spin`` [rad/s]
        ``(...)`` (the part's less the plate surface's), in the part's frame. Returns
        ``(force (..., 2), moment (...) [m])``; zero where there is no relative motion (friction
        then holds the part with whatever it needs).

        ``load``: the pressure's gradient ``k`` [1/m] in the part's frame, the pressure being
        ``(N / A) (1 + k . r)`` with ``r`` from the centroid (a part on a rocking plate:
        docs/polygons.md, "Out of the plane"); uniform by default. It must leave the pressure
        nowhere negative. On three feet it moves their shares as it moves the footprint's centre
        of pressure (to ``S k``, ``S`` the :attr:`second_moments`), and must leave every foot
        pressed."""
        shape, twists = _rows("velocity", velocity, "spin", spin)
        out = _core.polygon_wrench(self._geometry[5], twists, pool(threads), _load(load), self._feet())
        out = out.reshape(*shape, 3)
        return out[..., :2], out[..., 2]

    def gauge(
        self,
        force: ArrayLike,
        moment: ArrayLike,
        *,
        load: ArrayLike | None = None,
        threads: int | None = None,
    ) -> tuple[FloatArray, FloatArray]:
        """Where the wrench ``(force (..., 2), moment (...) [m])`` per ``mu N`` lies against the
        limit surface (every wrench friction can give the part): its gauge ``(...)``, at most 1
        when static friction can supply it, and the relative twist ``(..., 3)`` ``(vx, vy,
        omega)`` (up to scale) whose sliding friction is the wrench divided by the gauge (the way
        the part starts to slide when the wrench it needs grows past the limit). Exact: a Newton
        ascent of ``<z, e> / D(e)`` over twist directions (on three feet, Dinkelbach's iteration
        over weighted Fermat–Weber problems; docs/polygons.md). ``load``: as for
        :meth:`wrench`."""
        shape, z = _rows("force", force, "moment", moment)
        values, twists = _core.polygon_gauge(self._geometry[5], z, pool(threads), _load(load), self._feet())
        return values.reshape(shape), twists.reshape(*shape, 3)

    def _feet(self) -> FloatArray | None:
        """The feet about the centroid (the frame of ``_geometry[5]``), None without feet."""
        if self.support is None:
            return None
        out: FloatArray = np.ascontiguousarray(self.support - self._geometry[1])
        return out

    def holds(
        self, force: ArrayLike, moment: ArrayLike, *, load: ArrayLike | None = None
    ) -> NDArray[np.bool_]:
        """Whether static friction can supply the wrench ``(force, moment)`` per ``mu N`` (its
        :meth:`gauge` is at most 1): a part that needs it to move with the plate sticks."""
        out: NDArray[np.bool_] = self.gauge(force, moment, load=load)[0] <= 1.0
        return out
