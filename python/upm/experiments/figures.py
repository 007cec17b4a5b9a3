"""``upm figures``: the thesis's analytic figures (3.5, 3.6, 4.7, 6.2, 6.9) drawn from the library."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["figures"]


def figures(out: Path) -> list[Path]:
    """The thesis's analytic figures (3.5, 3.6, 4.7, 6.2, 6.9) from the library, into ``out``."""
    from ..plan.solvers import corner_centers, solve_rotations
    from ..viz import plot

    out.mkdir(parents=True, exist_ok=True)
    written = []
    # Fig. 4.7 left: 4 rotations about the square's corners (4.2.1); right: 3 rotations, zero force and
    # curl -0.05 at the part (4.2.3), a clockwise whirlpool. Known answers in docs/spec.md §4.
    centers = corner_centers((-1.0, -0.5, 1.0, 0.5))
    parts = np.array([[0.5, 0.0], [-0.75, 0.25]])
    left = solve_rotations(parts, [[0.01, 0.01], [-0.01, 0.0]], centers, mu_m_g=0.1)
    right = solve_rotations([[0.5, 0.0]], [[0.0, 0.0]], centers[:3], curls=[-0.05], mu_m_g=0.1)
    plt = plot._pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10.5, 4.6), layout="constrained")
    plot.field(
        "plan", (-1.2, -1.2, 1.2, 1.2), strengths=left.strengths, centers=centers, parts=parts, ax=axes[0]
    )
    plot.field("plan", (-1.2, -1.2, 1.2, 1.2), strengths=right.strengths, centers=centers[:3],
               parts=[[0.5, 0.0]], ax=axes[1])  # fmt: skip
    axes[0].set_title(f"Fig. 4.7 left: K = {np.round(left.strengths, 3)}", fontsize=9)
    axes[1].set_title(f"Fig. 4.7 right: K = {np.round(right.strengths, 3)}", fontsize=9)
    jet = plot.field("jet", (-2.0, -2.0, 2.0, 2.0), rho=1.0, direction=(0.0, 1.0), resolution=25)
    jet.axes[0].add_patch(plt.Circle((0, 0), 2.0, fill=False, ls=":", color="0.3"))
    jet.axes[0].set_title("Fig. 6.2: the jet (6.4), rho = 1; dotted: radius 2 rho", fontsize=10)
    for name, f in (("fig3_5.png", plot.bang_bang_feed_rate()), ("fig3_6.png", plot.feeding_versus_b()),
                    ("fig4_7.png", fig), ("fig6_2.png", jet), ("fig6_9.png", plot.theorem1())):  # fmt: skip
        f.savefig(out / name, dpi=120)
        plt.close(f)
        written.append(out / name)
    return written
