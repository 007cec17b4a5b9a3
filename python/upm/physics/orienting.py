"""Sensorless orienting: the orientations a squeeze field brings a polygon part to (issue 27,
docs/polygons.md, after Böhringer, Donald, Kavraki, Lamiraux, IEEE T-RA 2000).

A squeeze field pushes every point of the plate perpendicularly towards a line. Under friction
the force on an element of a part at rest is ``mu p dA`` along the field's *direction* there,
whatever its magnitude, so the part's wrench depends only on which side of the line each element
lies: it is at force balance where the line bisects its area, and its moment about the centroid
then depends on its angle alone: the *turn function* ``M(theta)``. Its roots are the equilibria;
those where it falls (``dM/dtheta < 0``) are stable: a part released near one turns to it. Both
come here exactly, from the two halves the line cuts the polygon into (areas and centroids in
closed form), the roots refined by bisection.

Rotating the whole picture by half a turn maps a squeeze field onto itself, so equilibria repeat
every half turn, and every ``2 pi / k`` for a part with ``k``-fold symmetry.

A :class:`RadialField` (a unit pull towards a centre plus a small constant bias) brings a part
whose centroid is off the point it pivots about to one pose (:func:`orientation_equilibria`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .._arrays import as_float, instance, integer, real
from .._errors import ConvergenceError, ParameterError
from .polygon import Polygon

__all__ = ["Equilibria", "RadialField", "SqueezeField", "orientation_equilibria"]

FloatArray = NDArray[np.float64]
_Turn = Callable[[float], float]
"""A turn function: the moment about the centroid per ``mu N`` at force balance, by angle."""
_Rest = Callable[[float], tuple[float, FloatArray]]
"""At an angle: the centroid's offset (from the line, or the centre) and where the frame rests."""


@dataclass(frozen=True)
class SqueezeField:
    """A field pushing every point perpendicularly towards the line through ``point`` [m] along
    ``angle`` [rad] (0: the x axis), on both sides.

    ``profile`` says how the push on an element of a part grows with its distance from the line:

    - ``"unit"`` (default): the same on either side, Böhringer et al.'s squeeze field (friction
      following the direction of a velocity field);
    - ``"linear"``: in proportion to the distance, the force field of the PPOD's line sinks
      (``PlateMotion.ppod("LineSinkX")``: line along y). There a part slides as a whole, all its
      elements along one direction, while the rocking plate presses each element by ``g + a_z``
      where it lies, which varies linearly across the footprint; the centroid rests on the line
      and the long principal axis of the part's area turns along it (a part whose second moments
      are the same in every direction, such as a square, is neutral: no equilibria).
    """

    point: tuple[float, float] = (0.0, 0.0)
    angle: float = 0.0
    profile: str = "unit"

    def __post_init__(self) -> None:
        p = as_float("point", self.point)
        if p.shape != (2,) or not np.all(np.isfinite(p)):
            raise ParameterError(f"point must be two finite numbers (x, y) [m]; got {self.point!r}")
        object.__setattr__(self, "point", (float(p[0]), float(p[1])))
        object.__setattr__(self, "angle", real("angle", self.angle))
        if self.profile not in ("unit", "linear"):
            raise ParameterError(f"profile must be 'unit' or 'linear'; got {self.profile!r}")


@dataclass(frozen=True)
class RadialField:
    """A field pushing every point towards ``center`` [m] with unit strength, plus the constant
    ``bias`` (a vector, ``|bias| < 1``, in units of the radial push): Böhringer et al.'s radial
    field with a small unit field, which brings a part to a unique pose where its centroid and
    the point it pivots about differ.

    Friction on a part at rest follows the *direction* of the plate's velocity field, so adding a
    constant velocity field to a linear sink only moves the sink. The forces add when the two
    fields take turns: a sink for a share ``1 - e`` of the time and a translation along ``u`` for
    ``e`` give, on average, the radial field plus ``bias = e u / (1 - e)``."""

    center: tuple[float, float] = (0.0, 0.0)
    bias: tuple[float, float] = (0.1, 0.0)

    def __post_init__(self) -> None:
        for name in ("center", "bias"):
            p = as_float(name, getattr(self, name))
            if p.shape != (2,) or not np.all(np.isfinite(p)):
                raise ParameterError(f"{name} must be two finite numbers (x, y); got {getattr(self, name)!r}")
            object.__setattr__(self, name, (float(p[0]), float(p[1])))
        size = math.hypot(*self.bias)
        if not 0.0 < size < 1.0:
            raise ParameterError(
                f"bias must have a length in (0, 1) (a radial field alone holds a part at every "
                f"angle; a bias of 1 or more outpulls it); got {size:g}"
            )


@dataclass(frozen=True)
class Equilibria:
    """Where a part comes to rest in a field.

    Attributes
    ----------
    stable, unstable : (S,) and (U,) ndarray
        The part's frame angles [rad] at its stable and unstable equilibria, in ``[0, period)``.
    period : float
        The equilibria repeat every this many radians (half a turn, or less for a symmetric part).
    offsets : (S,) ndarray
        At each stable angle, the signed distance [m] of the centroid from the line (positive to
        its right, looking along the line's direction): where the line bisects the part's area.
        In a radial field: the centroid's distance from the centre.
    positions : (S, 2) ndarray
        At each stable angle, where the part's frame origin comes to rest if its centroid starts
        on the line's normal through ``point`` (the field does not move a part along the line).
        In a radial field: where it comes to rest.
    turn : (T, 2) ndarray
        The turn function sampled: angle [rad] and moment about the centroid per ``mu N`` [m]
        (positive: counter-clockwise) at force balance.
    """

    stable: FloatArray
    unstable: FloatArray
    period: float
    offsets: FloatArray
    positions: FloatArray
    turn: FloatArray


def _clip_left(poly: FloatArray, s: float) -> FloatArray:
    """The part of a convex polygon (counter-clockwise) with ``x < s`` (Sutherland–Hodgman)."""
    out = []
    n = len(poly)
    for k in range(n):
        a, b = poly[k], poly[(k + 1) % n]
        ina, inb = a[0] < s, b[0] < s
        if ina:
            out.append(a)
        if ina != inb:
            t = (s - a[0]) / (b[0] - a[0])
            out.append(a + t * (b - a))
    return np.array(out) if out else np.zeros((0, 2))


def _area_centroid(poly: FloatArray) -> tuple[float, FloatArray]:
    if len(poly) < 3:
        return 0.0, np.zeros(2)
    x, y = poly[:, 0], poly[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    area = 0.5 * float(cross.sum())
    if area <= 0:
        return 0.0, np.zeros(2)
    c = np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6 * area)
    return area, c


def _balance(v: FloatArray, area: float) -> tuple[float, float]:
    """For the outline ``v`` about its centroid, in the line's frame (line: the y axis, field
    towards it along x): the centroid's x at force balance and the moment there per ``mu N``."""
    # The line at x = s cuts off area(x < s), rising from 0 to A; between two vertices' x the
    # cut's length is linear in s, so the area is a quadratic there: found exactly.
    half = 0.5 * area
    xs = np.unique(v[:, 0])
    cut = [_area_centroid(_clip_left(v, x))[0] for x in xs[1:-1]]
    areas = np.array([0.0, *cut, area])
    k = int(np.clip(np.searchsorted(areas, half) - 1, 0, len(xs) - 2))
    lo, hi = float(xs[k]), float(xs[k + 1])
    mid = 0.5 * (lo + hi)
    a0, a1, a2 = areas[k], _area_centroid(_clip_left(v, mid))[0], areas[k + 1]
    # a(t) = a0 + b t + c t², t in [0, 1] over [lo, hi]
    c = 2 * (a2 - 2 * a1 + a0)
    b = a2 - a0 - c
    d = a0 - half
    if abs(b) <= 1e-14 * area and abs(c) <= 1e-14 * area:
        t = 0.5  # a bracket of no width (two vertices at one x, to rounding)
    elif abs(c) <= 1e-14 * area:
        t = -d / b
    else:
        q = -0.5 * (b + math.copysign(math.sqrt(max(b * b - 4 * c * d, 0.0)), b))
        roots = [r for r in (q / c, d / q if q != 0 else math.inf) if -1e-9 <= r <= 1 + 1e-9]
        t = roots[0] if roots else (-d / b if b else 0.5)
    s = lo + min(max(t, 0.0), 1.0) * (hi - lo)
    a_left, c_left = _area_centroid(_clip_left(v, s))
    c_right = -c_left * a_left / max(area - a_left, 1e-300)  # the whole centroid is at 0
    # left half pushed +x, right half -x; (r x x_hat) = -r_y: M = (-c_left_y A_l + c_right_y A_r) / A
    moment = (-c_left[1] * a_left + c_right[1] * (area - a_left)) / area
    return -s, moment


def _turned(part: Polygon, theta: float, line: float) -> FloatArray:
    """The outline about its centroid, frame angle ``theta``, in the frame of a line at angle
    ``line`` turned onto the y axis."""
    v = np.asarray(part.vertices, np.float64) - part.centroid
    a = theta - (line - math.pi / 2)
    c, s = math.cos(a), math.sin(a)
    out: FloatArray = v @ np.array([[c, s], [-s, c]])
    return out


def _distinct(angles: list[float], period: float) -> FloatArray:
    """``angles`` in ``[0, period)``, sorted, the same root found twice (at a sample, or across
    the period's end) kept once."""
    out: list[float] = []
    for a in sorted(float(np.mod(a, period)) for a in angles):
        a = 0.0 if period - a < 1e-9 else a
        if not out or a - out[-1] > 1e-9:
            out.append(a)
    if len(out) > 1 and out[0] + period - out[-1] < 1e-9:
        out.pop()
    return np.array(out)


def _roots(moment: _Turn, period: float, samples: int) -> tuple[FloatArray, ...]:
    """The turn function ``moment`` sampled over a period and its roots refined by bisection to
    1e-12 rad: ``(grid, values, stable, unstable)``, stable where it falls."""
    grid = np.arange(samples) * period / samples
    m = np.array([moment(t) for t in grid])
    scale = float(np.abs(m).max())
    stable: list[float] = []
    unstable: list[float] = []
    for i in range(samples):
        a, b = grid[i], grid[i] + period / samples
        ma, mb = m[i], m[(i + 1) % samples]
        if abs(ma) <= 1e-12 * scale:
            root = a
        elif ma * mb < 0:
            for _ in range(60):
                mid = 0.5 * (a + b)
                if moment(mid) * ma > 0:
                    a = mid
                else:
                    b = mid
            root = 0.5 * (a + b)
        else:
            continue
        (stable if mb < ma else unstable).append(float(np.mod(root, period)))
    return grid, m, _distinct(stable, period), _distinct(unstable, period)


def _pull(part: Polygon, q: FloatArray) -> FloatArray:
    """The mean direction from ``q`` to the part's points, ``∫ (r - q)/|r - q| dA / A`` (part
    frame, about its centroid), from the friction of a unit spin about ``q`` (exact,
    :meth:`Polygon.wrench`: its force is this turned by a quarter turn clockwise)."""
    force, _ = part.wrench((q[1], -q[0]), 1.0)
    return np.array([-force[1], force[0]])


def _radial_balance(part: Polygon, bias: FloatArray, start: FloatArray) -> FloatArray:
    """Where the radial field's centre sits in the part's frame (from the centroid) at force
    balance, ``_pull(q) = bias``: the minimum of the convex ``∫|r - q| dA / A + bias . q``,
    by Newton's method on its gradient from ``start``."""
    q = np.array(start, np.float64)
    h = 1e-7 * part.radius
    for _ in range(100):
        g = _pull(part, q) - bias
        if np.hypot(*g) < 1e-13:
            break
        jac = np.column_stack([(_pull(part, q + d) - _pull(part, q - d)) / (2 * h) for d in np.eye(2) * h])
        step = np.linalg.solve(jac, -g)
        while np.hypot(*step) > 0.5 * part.radius:  # stay near the part, where the pull turns
            step = step / 2
        q = q + step
    else:
        raise ConvergenceError(
            f"the radial field's balance point did not converge for bias {tuple(bias)} (|pull - bias| = "
            f"{np.hypot(*g):.1e}); a bias this close to 1 may have none"
        )
    return q


def orientation_equilibria(
    part: Polygon, field: SqueezeField | RadialField, *, samples: int = 720
) -> Equilibria:
    """The stable and unstable orientations of ``part`` in ``field`` (module docs): roots of its
    turn function sampled at ``samples`` angles over a period and refined by bisection to 1e-12
    rad.

    In a :class:`RadialField` the part's centroid ``g`` comes to rest where the field's pull
    balances the bias, and the moment about ``g`` is then ``(g - c) x bias`` per ``mu N``
    (``c`` the centre: the radial pull on each element points at ``c``, so its moment about ``g``
    is that of a force through ``c``). The stable pose puts the centroid downstream of ``c``
    along the bias; ``offsets`` are then the centroid's distances from ``c``."""
    instance("part", part, Polygon, "a upm.Polygon")
    if not isinstance(field, (SqueezeField, RadialField)):
        raise ParameterError(
            f"field must be a upm.SqueezeField or a upm.RadialField; got {type(field).__name__}"
        )
    samples = integer("samples", samples, low=16, high=1_000_000)
    k = part.symmetry
    if isinstance(field, RadialField):
        period = 2 * math.pi / k
        moment, rest = _radial(part, field)
    elif field.profile == "linear":
        period = math.pi
        s0 = part.second_moments
        moment, rest = _linear_squeeze(part, field, s0)
        if _isotropic(s0):
            # every orientation is neutral: the turn function vanishes
            grid = np.linspace(0.0, period, samples, endpoint=False)
            empty = np.zeros(0)
            return Equilibria(
                empty, empty, period, empty, np.zeros((0, 2)), np.column_stack([grid, 0 * grid])
            )
    else:
        period = 2 * math.pi / math.lcm(2, k)
        moment, rest = _squeeze(part, field)
    grid, m, stable, unstable = _roots(moment, period, samples)
    rests = [rest(t) for t in stable]
    return Equilibria(
        stable=stable,
        unstable=unstable,
        period=period,
        offsets=np.array([off for off, _ in rests]),
        positions=np.array([at for _, at in rests]).reshape(-1, 2),
        turn=np.column_stack([grid, m]),
    )


def _squeeze(part: Polygon, field: SqueezeField) -> tuple[_Turn, _Rest]:
    """The turn function in a squeeze field, and at a stable angle the centroid's offset from
    the line and where the frame's origin rests."""
    area = part.area
    right = np.array([math.sin(field.angle), -math.cos(field.angle)])  # the line frame's +x

    def moment(theta: float) -> float:
        return _balance(_turned(part, theta, field.angle), area)[1]

    def rest(theta: float) -> tuple[float, FloatArray]:
        off = _balance(_turned(part, theta, field.angle), area)[0]
        return off, np.asarray(field.point) + off * right - part.centroid_offset(theta)

    return moment, rest


def _isotropic(s0: FloatArray) -> bool:
    """Whether second moments of area ``s0`` are the same in every direction."""
    lo, hi = np.linalg.eigvalsh(s0)
    return bool(hi - lo <= 1e-9 * hi)


def _linear_squeeze(part: Polygon, field: SqueezeField, s0: FloatArray) -> tuple[_Turn, _Rest]:
    """The turn function in a linear squeeze field of unit gradient (per metre): the push on an
    element at signed distance ``n . r`` from the line through the centroid is ``-(n . r) n``
    per ``mu N`` and unit area, so the moment about the centroid is ``n^T S t`` (``S`` the second
    moments of area over the area, ``s0`` in the part's frame, ``t`` the line's direction, ``n``
    its right normal)."""
    t = np.array([math.cos(field.angle), math.sin(field.angle)])
    n = np.array([t[1], -t[0]])

    def moment(theta: float) -> float:
        c, s = math.cos(theta), math.sin(theta)
        r = np.array([[c, -s], [s, c]])
        return float(n @ (r @ s0 @ r.T) @ t)

    def rest(theta: float) -> tuple[float, FloatArray]:
        # the pushes balance with the centroid on the line
        return 0.0, np.asarray(field.point) - part.centroid_offset(theta)

    return moment, rest


def _radial(part: Polygon, field: RadialField) -> tuple[_Turn, _Rest]:
    """The turn function in a radial field, and at a stable angle the centroid's distance from
    the centre and where the frame's origin rests."""
    bias = np.asarray(field.bias)
    last = {"q": np.zeros(2)}  # the balance point at the angle before: Newton's start

    def centre(theta: float) -> tuple[FloatArray, FloatArray]:
        """The centre from the centroid in the part's frame, and the bias there."""
        c, s = math.cos(theta), math.sin(theta)
        b = np.array([c * bias[0] + s * bias[1], -s * bias[0] + c * bias[1]])
        q = _radial_balance(part, b, last["q"])
        last["q"] = q
        return q, b

    def moment(theta: float) -> float:
        q, b = centre(theta)
        return float(-(q[0] * b[1] - q[1] * b[0]))  # (g - c) x bias, g - c = -q

    def rest(theta: float) -> tuple[float, FloatArray]:
        q, _ = centre(theta)
        c, s = math.cos(theta), math.sin(theta)
        g = np.asarray(field.center) - np.array([c * q[0] - s * q[1], s * q[0] + c * q[1]])
        return float(np.hypot(*q)), g - part.centroid_offset(theta)

    return moment, rest
