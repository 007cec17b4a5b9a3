"""``upm demo`` (``upm demo feeding``): the two-harmonic Coulomb pump's tables of feed rate and
force at rest over ``(b, phi)``, the optimum on a fine grid, and Fig. 3.6 (thesis §3.2)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._core import __version__
from ..physics import theory
from ..physics.feeding import feed_rate, mean_force
from ..physics.waveforms import TwoHarmonic

__all__ = ["feeding"]


def _table(title: str, bs: np.ndarray, phis: np.ndarray, values: np.ndarray, mark: tuple[int, int]) -> str:
    head = "b \\ phi".ljust(9) + "".join(f"{p / np.pi:>8.3f}π" for p in phis)
    lines = [title, head]
    values = np.round(values, 12) + 0.0  # exact to rounding: show -1e-17 as 0.0000, not -0.0000
    for i, b in enumerate(bs):
        cells = []
        for j in range(len(phis)):
            star = "*" if (i, j) == mark else " "
            cells.append(f"{values[i, j]:>8.4f}{star}")
        lines.append(f"{b:<9.3f}" + "".join(cells))
    return "\n".join(lines)


def feeding(out: Path, plots: bool = True) -> int:
    """Feed rate and force at rest of the two-harmonic drive over (b, phi); Fig. 3.6 to ``out``."""
    bs = np.array([0.0, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0])
    phis = np.pi * np.array([0.0, 0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 1.0])
    wave = TwoHarmonic(bs[:, None], phis[None, :])
    v_eq, force = feed_rate(wave), mean_force(wave)
    bi, bj = np.unravel_index(np.argmax(v_eq), v_eq.shape)
    best = (int(bi), int(bj))
    print(f"upm {__version__}: the two-harmonic Coulomb pump v(t) = sin t + b sin(2t + phi)  (thesis §3.2)")
    print("Exact values from the roots of v(t) = v_p; * marks the table's maximum feed rate.\n")
    print(
        _table(
            "Feed rate v_eq (median of v; units of the first-harmonic amplitude)",
            bs,
            phis,
            v_eq,
            best,
        )
    )
    print()
    print(_table("Average force at rest / (mu m g)", bs, phis, force, best))

    # A fine grid locates the optimum independently of the table's coarse spacing.
    fb = np.linspace(0.0, 2.0, 401)
    fp = np.linspace(-np.pi, np.pi, 721)
    fine = feed_rate(TwoHarmonic(fb[:, None], fp[None, :]))
    i, j = np.unravel_index(np.argmax(fine), fine.shape)
    print(
        f"\nOptimum on a {fb.size}x{fp.size} grid: b = {fb[i]:.3f}, phi = {fp[j] / np.pi:.3f} pi, "
        f"v_eq = {fine[i, j]:.6f}  (thesis: b = 1/2, phi = pi/2, v_eq = 0.5 = 2/3 v_max)"
    )
    bb = theory.bang_bang_efficiency(0.5)
    print(f"Bang-bang optimum z = 1/2: eta1 = {bb[0]:.4f}, eta2 = {bb[1]:.4f}  (thesis: 0.0625, 1/3)")
    nd = theory.normalized_drive(0.5)
    print(
        f"Normalised two-harmonic drive: gamma = {nd.gamma:.4f}, eta1 = {nd.eta1:.4f}, eta2 = {nd.eta2:.4f}"
    )

    if plots:
        from ..viz import plot

        out.mkdir(parents=True, exist_ok=True)
        for name, fig in [
            ("fig3_6.png", plot.feeding_versus_b()),
            ("feed_rate_map.png", plot.feed_rate_map(fb[::4], fp[::6])),
        ]:
            fig.savefig(out / name, dpi=120)
            print(f"wrote {out / name}")
    return 0
