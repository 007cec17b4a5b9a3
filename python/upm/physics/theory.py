"""Closed forms of the Coulomb pump (thesis ch. 3) and two-sinusoid feeding (section 6.4).

Velocities in m/s, accelerations in m/s^2, periods in s; forces are ``force / (mu m g)``. Every
function broadcasts its array-like arguments and returns a float for scalar input. The exact
numerical counterparts are :func:`upm.feed_rate` and :func:`upm.mean_force`; docs/spec.md lists the
checked values and errata (E1–E3) these reproduce.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

from numpy.typing import ArrayLike

from .. import _core
from .._arrays import as_float, broadcast_shape, flat, shaped
from .feeding import theorem1_force

__all__ = [
    "NormalizedDrive",
    "bang_bang_efficiency",
    "bang_bang_feed_rate",
    "bang_bang_force",
    "bang_bang_velocity_range",
    "gamma",
    "normalized_drive",
    "theorem1_force",
    "two_harmonic_feed_rate",
    "two_harmonic_force_at_rest",
    "viscous_gain",
]


def _apply(function: Callable[..., Any], **arguments: ArrayLike) -> Any:
    """Broadcast the named arguments, call the Rust kernel on flat columns, restore the shape."""
    arrays = {name: as_float(name, value, finite=False) for name, value in arguments.items()}
    shape = broadcast_shape(**arrays)
    out = function(*(flat(a, shape) for a in arrays.values()))
    if isinstance(out, tuple):
        return tuple(shaped(o, shape) for o in out)
    return shaped(out, shape)


def bang_bang_feed_rate(z: ArrayLike, a_max: ArrayLike = 1.0, period: ArrayLike = 1.0) -> Any:
    """Bang-bang feed rate (3.11) [m/s]: ``a_max T z^2 / 4`` for ``z <= 1/2``, else ``v_max``.

    ``v_max = a_max T (z - 1)^2 / 4``: beyond ``z = 1/2`` the part cannot outrun the plate.
    Maximum ``a_max T / 16`` at ``z = 1/2``. ``z`` in ``[0, 1)``.
    """
    return _apply(_core.bang_bang_feed_rate, z=z, a_max=a_max, period=period)


def bang_bang_force(
    z: ArrayLike, part_velocity: ArrayLike = 0.0, a_max: ArrayLike = 1.0, period: ArrayLike = 1.0
) -> Any:
    """Bang-bang average force / (mu m g) on a part at ``part_velocity`` [m/s] (3.10).

    ``z^2 - 4 v_p / (a_max T)`` for ``v_min <= v_p < v_max``; ``+1`` below ``v_min``, ``-1``
    above ``v_max`` (and ``z - 1`` exactly at ``v_max``, where the part rides the dwell).
    """
    return _apply(_core.bang_bang_force, z=z, part_velocity=part_velocity, a_max=a_max, period=period)


def bang_bang_velocity_range(z: ArrayLike, a_max: ArrayLike = 1.0, period: ArrayLike = 1.0) -> Any:
    """``(v_min, v_max)`` of the bang-bang velocity (3.8).

    ``v_min = a_max T (z^2 - 1) / 4`` and ``v_max = a_max T (z - 1)^2 / 4``.
    """
    return _apply(_core.bang_bang_velocity_range, z=z, a_max=a_max, period=period)


def bang_bang_efficiency(z: ArrayLike) -> Any:
    """``(eta1, eta2)`` (3.5): ``v_eq / (a_max T)`` and ``v_eq / |v_min|``; ``(1/16, 1/3)`` at ``z = 1/2``."""
    return _apply(_core.bang_bang_efficiency, z=z)


def viscous_gain(a_max: ArrayLike, period: ArrayLike, mu_m_g: ArrayLike = 1.0) -> Any:
    """Gain ``K`` of the viscous model (3.12) ``f = K (v_eq - v_p)``: ``4 mu m g / (a_max T)`` [N s/m].

    With the default ``mu_m_g = 1`` the result is ``K / (mu m g)`` [s/m].
    """
    return _apply(_core.viscous_gain, a_max=a_max, period=period, mu_m_g=mu_m_g)


def two_harmonic_feed_rate(b: ArrayLike, phi: ArrayLike, amplitude: ArrayLike = 1.0) -> Any:
    """Feed rate of ``amplitude (sin t + b sin(2t + phi))`` from (3.16)–(3.17) [m/s].

    ``amplitude b sin(phi)`` for ``|b| <= 1/2``; for ``phi = +-pi/2`` and ``|b| > 1/2``,
    ``+-amplitude / (4 |b|)``. Other ``(b, phi)`` have no closed form in the thesis and raise
    `upm.ParameterError`: use :func:`upm.feed_rate`. Optimum ``0.5`` at ``b = 1/2, phi = pi/2``.
    (Erratum E1: Fig. 3.7's caption misstates three of these values.)
    """
    return _apply(_core.two_harmonic_feed_rate, b=b, phi=phi, amplitude=amplitude)


def two_harmonic_force_at_rest(b: ArrayLike) -> Any:
    """Force / (mu m g) at rest under ``sin t + b cos 2t``, eq. (3.15); maximum ``1/3`` at ``b = 1``.

    The thesis's branch for ``b < -1`` is misprinted (as printed it exceeds 1 in magnitude); the
    force is odd in ``b`` and that is what is returned. (Erratum E3: ``f ~ b/3`` is a loose
    approximation.)
    """
    return _apply(_core.two_harmonic_force_at_rest, b=b)


def gamma(b: ArrayLike) -> Any:
    """``max_t |cos t - 2b sin 2t|``, the normaliser of (3.18), computed exactly (erratum E2)."""
    return _apply(_core.gamma, b=b)


class NormalizedDrive(NamedTuple):
    """What the normalised two-harmonic drive (3.18–3.20) achieves (floats or arrays)."""

    gamma: Any
    """``max_t |cos t - 2b sin 2t|``."""
    v_min: Any
    """Lowest plate velocity [m/s]."""
    v_max: Any
    """Highest plate velocity [m/s]."""
    v_eq: Any
    """Feed rate [m/s]."""
    eta1: Any
    """``v_eq / (a_max T)``."""
    eta2: Any
    """``v_eq / |v_min|``."""


def normalized_drive(b: ArrayLike = 0.5, a_max: ArrayLike = 1.0, period: ArrayLike = 1.0) -> NormalizedDrive:
    """The drive ``a_s = (a_max / gamma) [cos wt - 2b sin 2wt]`` (3.18–3.20), peak acceleration ``a_max``.

    At ``b = 1/2``: ``v_min = -3 a_max T/(4 pi gamma)``, ``v_max = 3 a_max T/(8 pi gamma)``,
    ``v_eq = a_max T/(4 pi gamma)``, ``eta1 = 0.0452``, ``eta2 = 1/3``. ``b >= 0``.
    """
    return NormalizedDrive(*_apply(_core.normalized_drive, b=b, a_max=a_max, period=period))
