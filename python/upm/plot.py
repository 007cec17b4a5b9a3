"""Figures (matplotlib, imported only when a figure is drawn: ``pip install upm[plot]``)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from . import theory
from ._arrays import as_float
from .feeding import feed_rate, mean_force
from .waveforms import Harmonics, TwoHarmonic

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["feed_rate_map", "feeding_versus_b"]


def _pyplot() -> Any:
    try:
        import matplotlib

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt
    except ImportError as error:  # pragma: no cover - depends on the environment
        raise ImportError("upm.plot needs matplotlib: pip install 'upm[plot]'") from error
    return plt


def feeding_versus_b(b: ArrayLike | None = None) -> Figure:
    """Fig. 3.6: force at rest and feed rate against ``b`` for ``v = sin t + b cos 2t``.

    Lines are the exact root-based values (:func:`upm.mean_force`, :func:`upm.feed_rate`);
    markers are the thesis's closed forms (3.15) and (3.17). The force peaks at ``b = 1``
    (1/3), the feed rate at ``b = 1/2`` (0.5).
    """
    plt = _pyplot()
    bs = np.linspace(0.0, 3.0, 601) if b is None else as_float("b", b)
    wave = Harmonics(np.stack([np.zeros_like(bs), bs], axis=-1), [1.0])
    force, v_eq = mean_force(wave), feed_rate(wave)
    marks = np.linspace(0.0, 3.0, 25)[1:]
    fig, ax = plt.subplots(figsize=(6.4, 4.0), layout="constrained")
    ax.plot(bs, force, color="C0", label=r"$\bar f / \mu m g$ at rest (exact)")
    ax.plot(bs, v_eq, color="C1", label=r"$v_{eq}$ (exact median)")
    ax.plot(
        marks,
        theory.two_harmonic_force_at_rest(marks),
        "o",
        color="C0",
        ms=4,
        mfc="none",
        label="(3.15)",
    )
    ax.plot(
        marks,
        theory.two_harmonic_feed_rate(marks, np.pi / 2),
        "s",
        color="C1",
        ms=4,
        mfc="none",
        label="(3.17)",
    )
    ax.axvline(0.5, color="0.7", lw=0.8, ls=":")
    ax.axvline(1.0, color="0.7", lw=0.8, ls=":")
    ax.set_xlabel(r"$b$ in $v_s(t) = \sin t + b \cos 2t$")
    ax.set_ylabel("force / $\\mu m g$, feed rate")
    ax.set_title("Fig. 3.6: two-harmonic Coulomb pump")
    ax.legend(frameon=False)
    figure: Figure = fig
    return figure


def feed_rate_map(b: ArrayLike, phi: ArrayLike) -> Figure:
    """Heat map of the exact feed rate of ``sin t + b sin(2t + phi)`` over a ``(b, phi)`` grid."""
    plt = _pyplot()
    bs, ps = as_float("b", b), as_float("phi", phi)
    v = feed_rate(TwoHarmonic(bs[:, None], ps[None, :]))
    fig, ax = plt.subplots(figsize=(6.4, 4.4), layout="constrained")
    mesh = ax.pcolormesh(ps, bs, v, shading="nearest", cmap="viridis")
    fig.colorbar(mesh, ax=ax, label=r"$v_{eq}$ / amplitude")
    i, j = np.unravel_index(np.argmax(v), v.shape)
    ax.plot(ps[j], bs[i], "r+", ms=12, mew=2, label=f"max {v[i, j]:.4f} at b={bs[i]:.3f}, φ={ps[j]:.3f}")
    ax.set_xlabel(r"$\varphi$ [rad]")
    ax.set_ylabel(r"$b$")
    ax.set_title(r"Feed rate of $\sin t + b \sin(2t + \varphi)$")
    ax.legend(loc="lower right", fontsize=8)
    figure: Figure = fig
    return figure
