"""Exact one-dimensional Coulomb feeding: average forces, feed rates, two-sinusoid force tables.

All forces are dimensionless, ``force / (mu m g)``. They are computed from the exact roots of
``v(t) = v_p`` (one per monotone piece of the waveform), never by sampling, so results are exact
to about 1e-12 (docs/spec.md §1–3).
"""

from __future__ import annotations

from typing import Any

from numpy.typing import ArrayLike

from .. import _core
from .._arrays import as_float, broadcast_shape, flat, integer, shaped
from .._arrays import threads as pool
from .._errors import ParameterError
from .waveforms import Waveform

__all__ = ["feed_rate", "force_table", "mean_force", "theorem1_force"]


def _waveform(waveform: Any) -> Waveform:
    if not isinstance(waveform, Waveform):
        raise ParameterError(
            "waveform must be a upm.TwoHarmonic, upm.BangBang or upm.Harmonics; "
            f"got {type(waveform).__name__}"
        )
    return waveform


def feed_rate(waveform: Waveform, *, threads: int | None = None) -> Any:
    """Quasi-static feed rate [m/s]: the median of the plate velocity over one period (docs/spec.md §2).

    It is the part velocity at which the average Coulomb force vanishes. Computed exactly by
    bracketing the level crossings of every monotone piece and refining them with a root finder.

    Parameters
    ----------
    waveform : Waveform
        A single waveform or a broadcast array of them.
    threads : int, optional
        Run on a pool of this many threads (default: one per core, or ``RAYON_NUM_THREADS``).

    Returns
    -------
    float or ndarray of shape ``waveform.shape``

    Examples
    --------
    >>> import upm
    >>> upm.feed_rate(upm.BangBang(z=0.5))  # a_max T / 16 at the optimum z = 1/2
    0.0625
    """
    w = _waveform(waveform)
    return shaped(w._batch.feed_rate(threads=pool(threads)), w.shape)


def mean_force(waveform: Waveform, part_velocity: ArrayLike = 0.0, *, threads: int | None = None) -> Any:
    """Average Coulomb force / (mu m g) on a part sliding at ``part_velocity`` (3.4, 6.7).

    ``mean over one period of sgn(v(t) - part_velocity)``: +1 below the plate's lowest velocity,
    -1 above its highest, decreasing in between and zero at :func:`feed_rate`.

    Parameters
    ----------
    waveform : Waveform
        A single waveform or a broadcast array of them.
    part_velocity : array_like, optional
        Part velocity [m/s]; broadcasts against ``waveform.shape``.
    threads : int, optional
        Run on a pool of this many threads (default: one per core, or ``RAYON_NUM_THREADS``).

    Returns
    -------
    float or ndarray of shape ``broadcast(waveform.shape, part_velocity.shape)``
    """
    w = _waveform(waveform)
    batch, table, shape = w._rows("part_velocity", as_float("part_velocity", part_velocity))
    return shaped(batch.mean_force(table, threads=pool(threads)), shape)


#: The largest harmonic number of :func:`force_table`: its cost grows as ``n2**2`` per element
#: (the velocity has up to ``2 n2`` roots a period): about 0.2 s an element at this bound.
FORCE_TABLE_MAX_N2 = 1000
#: The largest harmonic number of :func:`theorem1_force` (a closed form; ``n1 n2`` must fit).
THEOREM1_MAX_N = 2**31 - 1


def _pair(n1: Any, n2: Any, high: int) -> tuple[int, int]:
    return integer("n1", n1, high=high), integer("n2", n2, high=high)


def theorem1_force(n1: int, n2: int, psi: ArrayLike) -> Any:
    """Theorem 1 (6.12–6.13): force / (mu m g) at rest under ``cos(n1 t) - cos(n2 (t - psi))``.

    ``Tri(n1 n2 psi) / (n2^2 - n1^2)``, with ``Tri`` the unit triangle wave of period ``2 pi``.
    The theorem assumes exactly one of ``n1, n2`` even; for two odd harmonics the force is 0 for
    every ``psi`` (Lemma 1) and 0 is returned.

    Parameters
    ----------
    n1, n2 : int
        Coprime harmonic numbers, ``1 <= n1 < n2``.
    psi : array_like
        Phase [rad].

    Returns
    -------
    float or ndarray of ``psi``'s shape
    """
    a, b = _pair(n1, n2, THEOREM1_MAX_N)
    p = as_float("psi", psi)
    return shaped(_core.theorem1_force(a, b, flat(p, p.shape)), p.shape)


def force_table(n1: int, n2: int, psi: ArrayLike, b: ArrayLike = 1.0, *, threads: int | None = None) -> Any:
    """Exact force / (mu m g) at rest under ``cos(n1 t) - b cos(n2 (t - psi))`` (6.12).

    The numerical counterpart of :func:`theorem1_force` (equal to it when ``b = 1``), computed
    from the exact roots of the velocity; fast over large arrays of ``psi`` (parallel, GIL
    released).

    Parameters
    ----------
    n1, n2 : int
        Coprime harmonic numbers, ``1 <= n1 < n2 <= 1000`` (`FORCE_TABLE_MAX_N2`: the cost of an
        element grows as ``n2**2``).
    psi : array_like
        Phase [rad].
    b : array_like, optional
        Relative amplitude of harmonic ``n2``; broadcasts with ``psi``.
    threads : int, optional
        Run on a pool of this many threads (default: one per core, or ``RAYON_NUM_THREADS``).

    Returns
    -------
    float or ndarray of shape ``broadcast(psi.shape, b.shape)``
    """
    a, c = _pair(n1, n2, FORCE_TABLE_MAX_N2)
    p, amp = as_float("psi", psi), as_float("b", b)
    shape = broadcast_shape(psi=p, b=amp)
    out = _core.force_table(a, c, flat(p, shape), flat(amp, shape), threads=pool(threads))
    return shaped(out, shape)
