"""Parallel-manipulation solvers (docs/spec.md §4, §5; thesis 4.2, 5.1): rotation strengths about fixed
centres that give many parts the forces, curls or small steps you ask for, at once.

Columns of every system are the unit tangential fields ``R90(P - C_j) / |P - C_j|`` of the centres
``C_j``, ``x`` rows first, then ``y`` rows (4.10, 5.3), then curl rows ``1 / |Q - C_j|`` (4.12).
Square systems are solved exactly; with redundant centres the SVD gives the minimum-norm solution;
``rcond`` truncates small singular values, ``damping`` adds Tikhonov regularisation and
``max_strength`` bounds every strength (bounded least squares). The SVD runs in Rust.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from .._arrays import as_float, integer, real, show, vector
from .._errors import ParameterError, PlanWarning, RankWarning, ShapeError

__all__ = [
    "DisplacementPlan",
    "RotationPlan",
    "corner_centers",
    "flow_error",
    "grid_centers",
    "ring_centers",
    "rotation_order",
    "solve_displacements",
    "solve_rotations",
    "solve_rotations_batch",
]

FloatArray = NDArray[np.float64]
#: The most centres ring_centers lays out (a plate has a few dozen at most).
MAX_CENTERS = 100_000
OrderRule = str | Callable[[FloatArray, FloatArray, FloatArray], ArrayLike]


@dataclass(frozen=True, slots=True, eq=False, repr=False)
class _Plan:
    strengths: FloatArray
    """Strength per centre ``(N,)``: see the subclass."""
    order: NDArray[np.int64]
    """Execution order ``(N,)`` (indices into ``strengths``), by the priority rule of 4.2.4."""
    residual: Any
    """Norm of (achieved - requested) over all constraints, in the caller's units."""
    bound_cost: Any
    """How much ``max_strength`` raised ``residual`` (0 when it does not bind)."""
    singular_values: FloatArray
    """Singular values of the system, descending."""
    rank: Any
    """Numerical rank; full rank equals the number of constraints."""
    condition_number: Any
    """``s_max / s_min`` of the system (4.2.5): large when parts crowd or are far from every centre."""
    parts: FloatArray
    """Part positions ``(M, 2)`` [m] the plan was solved for."""
    centers: FloatArray
    """Centres of rotation ``(N, 2)`` [m]."""

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(
            np.array_equal(
                np.asarray(getattr(self, f.name)), np.asarray(getattr(other, f.name)), equal_nan=True
            )
            for f in fields(self)
        )

    __hash__ = None  # type: ignore[assignment]  # arrays: mutable contents

    def __repr__(self) -> str:
        k = np.asarray(self.strengths)
        if k.ndim == 1:
            shown = np.array2string(k, precision=4, threshold=8)
            return (
                f"{type(self).__name__}(strengths={shown}, parts={len(self.parts)}, rank={self.rank}, "
                f"condition_number={float(self.condition_number):.3g}, residual={float(self.residual):.3g})"
            )
        return f"{type(self).__name__}(batch={k.shape[0]}, centers={k.shape[-1]})"


@dataclass(frozen=True, slots=True, eq=False, repr=False)
class RotationPlan(_Plan):
    """Rotation strengths ``k_j`` (dimensionless) that give requested average forces (4.9, 4.10).

    The plan's average force on a part at ``P`` is ``(mu_m_g / N) sum_j k_j R90(P - C_j)/|P - C_j|``.
    Arrays gain a leading batch axis when produced by :func:`solve_rotations_batch`.
    """

    predicted_forces: FloatArray
    """Average force the plan gives at each part ``(M, 2)`` [N]."""
    predicted_curls: FloatArray
    """Curl it gives at each curl point ``(Q,)`` [N/m]."""
    mu_m_g: float
    """Friction scale ``mu m g`` [N] the forces are measured in."""


@dataclass(frozen=True, slots=True, eq=False, repr=False)
class DisplacementPlan(_Plan):
    """Arc lengths ``d_j`` [m] along the tangential flows of the centres that move the parts by the
    requested small steps, to first order (5.3); rotate about each centre in :attr:`order`."""

    predicted_steps: FloatArray
    """First-order step the plan gives each part ``(M, 2)`` [m]."""


def _pairs(name: str, value: ArrayLike, ndim: int = 2) -> FloatArray:
    a = np.ascontiguousarray(as_float(name, value))
    if a.ndim != ndim or a.shape[-1] != 2:
        want = "(K, 2)" if ndim == 2 else "(B, K, 2)"
        raise ShapeError(f"{name} must have shape {want}; got {a.shape}")
    return a


def _options(rcond: float | None, damping: float | None, max_strength: float | None) -> tuple[Any, ...]:
    return (
        None if rcond is None else real("rcond", rcond, low=0.0),
        0.0 if damping is None else real("damping", damping, low=0.0),
        None if max_strength is None else real("max_strength", max_strength, low=0.0, low_open=True),
    )


def _mu_m_g(value: Any) -> float:
    return real("mu_m_g", value, low=0.0, low_open=True)


_NO_POINTS = np.zeros((0, 2))
_NO_VALUES = np.zeros(0)


def _curls(
    curls: ArrayLike | None, curl_points: ArrayLike | None, parts: FloatArray
) -> tuple[FloatArray, FloatArray]:
    if curls is None:
        if curl_points is not None:
            raise ParameterError("curl_points needs curls (the curl wanted at each point)")
        return _NO_POINTS, _NO_VALUES
    values = np.ascontiguousarray(as_float("curls", curls)).reshape(-1)
    points = parts if curl_points is None else _pairs("curl_points", curl_points)
    if points.shape[0] != values.size:
        raise ShapeError(
            f"curls has {values.size} entries; curl_points has {points.shape[0]} (default: one per part)"
        )
    return points, values


def _warn_rank(low: int, constraints: int) -> None:
    """Warn when the lowest rank of the plans solved is below the number of constraints."""
    if low < constraints:
        warnings.warn(
            f"the system is rank deficient (rank {low} < {constraints} constraints): parts coincide "
            "or sit where the centres' fields are parallel; the plan is the least-squares "
            "minimum-norm compromise, see plan.residual",
            RankWarning,
            stacklevel=3,
        )


#: Condition numbers above this make a plan's strengths amplify rounding and position errors.
ILL_CONDITIONED = 1e8


def _warn_plan(forces: FloatArray, mu_m_g: float, condition: float, strengths: FloatArray) -> None:
    """Warn on forces no friction can give and on a system so ill-conditioned that the strengths
    mean little."""
    biggest = float(np.max(np.hypot(forces[..., 0], forces[..., 1]), initial=0.0))
    if biggest > mu_m_g:
        warnings.warn(
            f"a requested force is {biggest / mu_m_g:.3g} mu m g, but the average friction force never "
            "exceeds mu m g (forces are in the unit of mu_m_g): no plate motion gives this plan",
            PlanWarning,
            stacklevel=3,
        )
    if condition > ILL_CONDITIONED:
        warnings.warn(
            f"the system is ill-conditioned (condition number {condition:.3g}): strengths up to "
            f"{float(np.max(np.abs(strengths), initial=0.0)):.3g} amplify every error in the positions; "
            "move the centres, set rcond or damping, or bound them with max_strength",
            RankWarning,
            stacklevel=3,
        )


def _order(
    plan_order: NDArray[np.int64],
    strengths: FloatArray,
    parts: FloatArray,
    centers: FloatArray,
    order: OrderRule,
) -> NDArray[np.int64]:
    if isinstance(order, str) and order == "priority":
        return plan_order
    return _by_rule(strengths, parts, centers, order, "order")


def solve_rotations(
    parts: ArrayLike,
    forces: ArrayLike,
    centers: ArrayLike,
    *,
    curls: ArrayLike | None = None,
    curl_points: ArrayLike | None = None,
    mu_m_g: float = 1.0,
    rcond: float | None = None,
    damping: float | None = None,
    max_strength: float | None = None,
    order: OrderRule = "priority",
) -> RotationPlan:
    """Rotation strengths about ``centers`` giving average ``forces`` at ``parts`` (4.10, 4.12).

    Parameters
    ----------
    parts : array_like, shape (M, 2)
        Part positions [m]; none may lie on a centre.
    forces : array_like, shape (M, 2)
        Desired average force on each part, in the unit of ``mu_m_g``: with the default
        ``mu_m_g=1`` as ``force / (mu m g)`` (upm's rule for every force), or in newtons with
        ``mu_m_g`` in newtons. None may exceed ``mu_m_g`` (warns `upm.PlanWarning`).
    centers : array_like, shape (N, 2)
        Distinct centres of rotation [m]; ``N >= 2M + Q``.
    curls : array_like, shape (Q,), optional
        Desired curl of the force field [N/m] at ``curl_points`` (default: at the parts).
    mu_m_g : float
        Friction scale ``mu m g``: 1 (the default) for forces as ``force / (mu m g)``, or [N].
    rcond : float, optional
        Singular values below ``rcond * s_max`` are dropped (default ``eps * max(2M+Q, N)``).
    damping : float, optional
        Tikhonov ``lambda``: minimises ``|A k - b|^2 + lambda^2 |k|^2``.
    max_strength : float, optional
        Bound on every ``|k_j|``; the plan reports the force error it costs in ``bound_cost``.
    order : "priority", "magnitude", "given" or callable
        Rule for :attr:`RotationPlan.order` (see :func:`rotation_order`).

    Returns
    -------
    RotationPlan
        Warns :class:`upm.RankWarning` when the system is rank deficient or ill-conditioned
        (condition number above 1e8).

    Examples
    --------
    The worked example of thesis 4.2.1:

    >>> import upm
    >>> plan = upm.solve_rotations(
    ...     [(0.5, 0), (-0.75, 0.25)], [(0.01, 0.01), (-0.01, 0)],
    ...     [(-1, -0.5), (1, -0.5), (1, 0.5), (-1, 0.5)], mu_m_g=0.1)
    >>> plan.strengths.round(3)
    array([ 0.584, -0.389,  0.48 , -0.095])
    """
    p = _pairs("parts", parts)
    f = _pairs("forces", forces)
    c = _pairs("centers", centers)
    q, k = _curls(curls, curl_points, p)
    scale = _mu_m_g(mu_m_g)
    r = _core.solve(p, f, c, q, k, scale, *_options(rcond, damping, max_strength))
    s, r0, cond = r.strengths[0], int(r.rank[0]), float(r.condition_number[0])
    _warn_rank(r0, 2 * p.shape[0] + k.size)
    _warn_plan(f, scale, cond, s)
    return RotationPlan(
        s, _order(r.order[0], s, p, c, order), float(r.residual[0]), float(r.bound_cost[0]),
        r.singular_values[0], r0, cond, p, c, r.predicted[0], r.predicted_curls[0], scale,
    )  # fmt: skip


def solve_displacements(
    parts: ArrayLike,
    steps: ArrayLike,
    centers: ArrayLike,
    *,
    rcond: float | None = None,
    damping: float | None = None,
    max_strength: float | None = None,
    order: OrderRule = "priority",
) -> DisplacementPlan:
    """Arc lengths about ``centers`` that move ``parts`` by small ``steps`` [m] to first order (5.3).

    Same options as :func:`solve_rotations`; ``max_strength`` bounds every ``|d_j|`` [m]. Execute
    with :func:`upm.plan_to_motion`; :func:`flow_error` estimates the second-order error of doing
    the rotations one after another.
    """
    p = _pairs("parts", parts)
    d = _pairs("steps", steps)
    c = _pairs("centers", centers)
    r = _core.solve(p, d, c, _NO_POINTS, _NO_VALUES, None, *_options(rcond, damping, max_strength))
    s, r0 = r.strengths[0], int(r.rank[0])
    _warn_rank(r0, 2 * p.shape[0])
    return DisplacementPlan(
        s, _order(r.order[0], s, p, c, order), float(r.residual[0]), float(r.bound_cost[0]),
        r.singular_values[0], r0, float(r.condition_number[0]), p, c, r.predicted[0],
    )  # fmt: skip


def solve_rotations_batch(
    parts: ArrayLike,
    forces: ArrayLike,
    centers: ArrayLike,
    *,
    curls: ArrayLike | None = None,
    curl_points: ArrayLike | None = None,
    mu_m_g: float = 1.0,
    rcond: float | None = None,
    damping: float | None = None,
    max_strength: float | None = None,
) -> RotationPlan:
    """:func:`solve_rotations` for ``B`` systems at once, in parallel in Rust with the GIL released.

    ``parts`` and ``forces`` have shape ``(B, M, 2)``; ``centers`` ``(N, 2)`` (shared) or
    ``(B, N, 2)``; ``curls`` ``(B, Q)`` with ``curl_points`` ``(Q, 2)`` or ``(B, Q, 2)`` (default:
    at the parts). Every array of the returned plan gains a leading axis ``B``; ``order`` is by
    priority. Results are identical to ``B`` separate calls, for any thread count.
    """
    p = _pairs("parts", parts, 3)
    f = _pairs("forces", forces, 3)
    b = p.shape[0]
    c = as_float("centers", centers)
    c = _pairs("centers", np.broadcast_to(c, (b, *c.shape)) if c.ndim == 2 else c, 3)
    if curls is None:
        if curl_points is not None:
            raise ParameterError("curl_points needs curls (the curl wanted at each point)")
        q = np.zeros((b, 0, 2))
        k = np.zeros((b, 0))
    else:
        k = np.ascontiguousarray(as_float("curls", curls))
        if k.ndim != 2 or k.shape[0] != b:
            raise ShapeError(f"curls must have shape ({b}, Q); got {k.shape}")
        qa = p if curl_points is None else as_float("curl_points", curl_points)
        q = _pairs("curl_points", np.broadcast_to(qa, (b, *qa.shape)) if qa.ndim == 2 else qa, 3)
    r = _core.solve_batch(
        p, f, np.ascontiguousarray(c), np.ascontiguousarray(q), k, _mu_m_g(mu_m_g),
        *_options(rcond, damping, max_strength),
    )  # fmt: skip
    if b:
        _warn_rank(int(np.min(r.rank)), 2 * p.shape[1] + k.shape[1])
    return RotationPlan(r.strengths, r.order, r.residual, r.bound_cost, r.singular_values, r.rank,
                        r.condition_number, p, c, r.predicted, r.predicted_curls, float(mu_m_g))  # fmt: skip


def rotation_order(
    strengths: ArrayLike, parts: ArrayLike, centers: ArrayLike, rule: OrderRule = "priority"
) -> NDArray[np.int64]:
    """The order to execute rotations in (4.2.4); returns indices into ``strengths``.

    Rules: ``"priority"`` sorts by ``rho_j = |k_j| / min_i |P_i - C_j|``, largest first (the
    thesis's rule; erratum E4: its printed priorities do not follow from it, the formula is
    implemented); ``"magnitude"`` by ``|k_j|``; ``"given"`` keeps the centres' order; a callable
    ``rule(strengths, parts, centers)`` returns one priority per centre (largest runs first).
    Ties keep the centres' order.
    """
    k = np.ascontiguousarray(as_float("strengths", strengths)).reshape(-1)
    p = _pairs("parts", parts)
    c = _pairs("centers", centers)
    if k.size != c.shape[0]:
        raise ShapeError(f"strengths has {k.size} entries; centers has {c.shape[0]}")
    return _by_rule(k, p, c, rule, "rule")


def _by_rule(k: FloatArray, p: FloatArray, c: FloatArray, rule: Any, name: str) -> NDArray[np.int64]:
    """The order of ``rule`` (passed as parameter ``name``) for strengths ``k``."""
    if isinstance(rule, np.ndarray):
        raise ParameterError(
            f"{name} must be 'priority', 'magnitude', 'given' or a callable; got {show(rule)}"
        )
    if callable(rule):
        rho = np.asarray(rule(k, p, c), dtype=np.float64)
        if rho.shape != k.shape:
            raise ShapeError(f"the order rule must return one priority per centre {k.shape}; got {rho.shape}")
    elif rule == "priority":
        rho = _core.priorities(k, p, c)
    elif rule == "magnitude":
        rho = np.abs(k)
    elif rule == "given":
        return np.arange(k.size, dtype=np.int64)
    else:
        raise ParameterError(
            f"{name} must be 'priority', 'magnitude', 'given' or a callable; got {show(rule)}"
        )
    return np.argsort(-rho, kind="stable").astype(np.int64)


def flow_error(
    plan: DisplacementPlan | ArrayLike,
    parts: ArrayLike | None = None,
    centers: ArrayLike | None = None,
    order: ArrayLike | None = None,
    *,
    exact: bool = False,
) -> FloatArray:
    """Error [m] of rotating about the centres one after another instead of along the sum (5.4.4).

    The second-order (Lie-bracket) estimate at each part (5.28-5.30):
    ``sum_j d_j^2/2 DX_j X_j + sum_{a before b} d_a d_b DX_b X_a`` with ``X_j`` the unit tangential
    field of ``C_j``. It grows near the centres and depends on the order. With ``exact=True``,
    returns the exact error instead: end point of the sequence of exact rotations (by
    ``d_j / |P - C_j|`` about ``C_j``) minus the first-order prediction.

    Pass a :class:`DisplacementPlan`, or arc lengths ``(N,)`` with ``parts``, ``centers`` and
    optionally ``order`` (default: the centres' order).

    Returns
    -------
    ndarray, shape (M, 2)
    """
    if isinstance(plan, RotationPlan):
        raise ParameterError(
            "plan must be a DisplacementPlan (arc lengths); a RotationPlan's strengths are forces"
        )
    if isinstance(plan, DisplacementPlan):
        d, p, c = plan.strengths, plan.parts, plan.centers
        o = plan.order if order is None else order
    else:
        if parts is None or centers is None:
            raise ParameterError("parts and centers are required when plan is an array of arc lengths")
        d = np.ascontiguousarray(plan, dtype=np.float64).reshape(-1)
        p, c = _pairs("parts", parts), _pairs("centers", centers)
        o = np.arange(d.size) if order is None else order
    idx = [int(i) for i in np.asarray(o).reshape(-1)]
    end = np.asarray(_core.flow_error(d, p, c, idx, bool(exact)))
    if not exact:
        return end
    rows = np.stack([_core.rotation_field(p, (float(x), float(y))) for x, y in c], axis=1)
    linear: FloatArray = p + np.einsum("mnk,n->mk", rows, d)
    return np.asarray(end - linear, dtype=np.float64)


def corner_centers(workspace: ArrayLike) -> FloatArray:
    """The four corners of a rectangular workspace ``(xmin, ymin, xmax, ymax)`` [m], as in 4.2.1:
    lower-left, lower-right, upper-right, upper-left. Shape ``(4, 2)``."""
    w = as_float("workspace", workspace)
    if w.shape != (4,) or not (w[2] > w[0] and w[3] > w[1]):
        raise ParameterError(
            f"workspace must be finite (xmin, ymin, xmax, ymax) with max > min; got {workspace!r}"
        )
    x0, y0, x1, y1 = w
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])


def ring_centers(count: int, radius: float, center: ArrayLike = (0.0, 0.0), phase: float = 0.0) -> FloatArray:
    """``count`` centres evenly spaced on a circle of ``radius`` [m] about ``center``, the first at
    angle ``phase`` [rad]. Shape ``(count, 2)``."""
    n = integer("count", count, low=1, high=MAX_CENTERS)
    r = real("radius", radius, low=0.0, low_open=True)
    c = vector("center", center, 2)
    a = real("phase", phase) + 2 * np.pi * np.arange(n) / n
    return c + r * np.stack([np.cos(a), np.sin(a)], axis=1)


def grid_centers(shape: tuple[int, int], workspace: ArrayLike) -> FloatArray:
    """A ``shape = (nx, ny)`` grid of centres spanning ``workspace = (xmin, ymin, xmax, ymax)`` [m],
    corners included, x fastest. Shape ``(nx * ny, 2)``."""
    if isinstance(shape, (str, bytes)) or not isinstance(shape, (tuple, list, np.ndarray)) or len(shape) != 2:
        raise ParameterError(f"shape must be two integers (nx, ny) >= 2; got {show(shape)}")
    nx, ny = (integer(f"shape[{k}]", n, low=2, high=1000) for k, n in enumerate(shape))
    x0, y0, x1, y1 = corner_centers(workspace)[[0, 2]].reshape(-1)
    gx, gy = np.meshgrid(np.linspace(x0, x1, nx), np.linspace(y0, y1, ny))
    return np.stack([gx.reshape(-1), gy.reshape(-1)], axis=1)
