"""Figures (matplotlib, imported only when a figure is drawn: ``pip install upm[plot]``)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from .._arrays import as_float
from .._errors import ParameterError
from .._extras import need
from ..physics import theory
from ..physics.feeding import feed_rate, mean_force
from ..physics.waveforms import Harmonics, TwoHarmonic
from ..plate.drive import PLATE_SIZE

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "bang_bang_feed_rate",
    "feed_rate_map",
    "feeding_versus_b",
    "field",
    "loop_errors",
    "loop_paths",
    "sweep",
    "theorem1",
]


def _pyplot() -> Any:
    matplotlib = need("matplotlib", "plot", "upm.plot (figures)")
    matplotlib.use("Agg", force=False)
    return need("matplotlib.pyplot", "plot", "upm.plot (figures)", "matplotlib")


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


def field(
    kind: str | Any,
    extent: ArrayLike,
    *,
    motion: Any = None,
    mu: float = 0.3,
    measured: bool = True,
    center: ArrayLike = (0.0, 0.0),
    direction: ArrayLike = (0.0, 1.0),
    rho: float = 1.0,
    strengths: ArrayLike | None = None,
    centers: ArrayLike | None = None,
    parts: ArrayLike | None = None,
    resolution: int = 21,
    ax: Any = None,
) -> Figure:
    """Quiver plot of an average force field / (mu m g), as in Figs. 4.7 and 6.2, or of the velocity
    fields of a plate that moves out of its plane (docs/ppod.md).

    Parameters
    ----------
    kind : "rotation", "jet", "plan", a PlateMotion, or "drift", "asymptotic", "both"
        ``"rotation"``: the unit tangential field about ``center``; ``"jet"``: the jet (6.4) at
        ``center`` along ``direction`` with ``rho``; ``"plan"``: the superposition
        ``(1/N) sum_j k_j R90(P - C_j)/|P - C_j|`` of ``strengths`` about ``centers`` (4.9);
        a :class:`upm.PlateMotion`: its :func:`upm.average_field`. ``"drift"``,
        ``"asymptotic"``: the velocity field of the periodic ``motion`` (:func:`upm.drift_field`
        at ``mu``, :func:`upm.asymptotic_field`); ``"both"``: the two side by side. With
        ``measured``, the mean velocity of simulated parts (red) is drawn on the drift.
    extent : (xmin, ymin, xmax, ymax)
        The plotted square of the plate [m], sampled on ``resolution x resolution`` arrows.
    parts, centers : array_like (K, 2), optional
        Marked as dots and crosses.
    """
    from ..physics.fields import average_field, jet_field, rotation_field
    from ..physics.motion import PlateMotion

    if isinstance(kind, str) and kind in ("drift", "asymptotic", "both"):
        return _velocity_field(kind, extent, motion, mu, measured, resolution, ax)
    plt = _pyplot()
    x0, y0, x1, y1 = as_float("extent", extent).reshape(4)
    gx, gy = np.meshgrid(np.linspace(x0, x1, resolution), np.linspace(y0, y1, resolution))
    points = np.stack([gx, gy], axis=-1)
    title: str
    if isinstance(kind, PlateMotion):
        f, title = average_field(kind, points, tol=1e-7), "average field of the motion"
    elif kind == "rotation":
        f, title = rotation_field(points, center), "rotation field (4.8)"
    elif kind == "jet":
        f, title = jet_field(points, center, direction, rho, tol=1e-7), "jet (6.4)"
    elif kind == "plan":
        if strengths is None or centers is None:
            raise ValueError("kind='plan' needs strengths and centers")
        k = as_float("strengths", strengths).reshape(-1)
        cs = as_float("centers", centers).reshape(-1, 2)
        f = np.sum([kj * rotation_field(points, c) for kj, c in zip(k, cs, strict=True)], axis=0) / len(k)
        title = "superposed rotations (4.9)"
    else:
        raise ValueError(f"kind must be 'rotation', 'jet', 'plan' or a upm.PlateMotion; got {kind!r}")
    if ax is None:
        fig, ax = plt.subplots(figsize=(5.2, 5.0), layout="constrained")
    else:
        fig = ax.figure
    ax.quiver(gx, gy, f[..., 0], f[..., 1], np.hypot(f[..., 0], f[..., 1]), cmap="viridis", pivot="mid")
    if centers is not None:
        cs = as_float("centers", centers).reshape(-1, 2)
        ax.plot(cs[:, 0], cs[:, 1], "r+", ms=10, mew=2, label="centres")
    if parts is not None:
        ps = as_float("parts", parts).reshape(-1, 2)
        ax.plot(ps[:, 0], ps[:, 1], "ko", ms=6, label="parts")
    if centers is not None or parts is not None:
        ax.legend(loc="upper right", fontsize=8)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"Force / $\\mu m g$: {title}")
    figure: Figure = fig
    return figure


def _velocity_field(
    kind: str, extent: ArrayLike, motion: Any, mu: float, measured: bool, resolution: int, ax: Any
) -> Figure:
    """The drift and/or asymptotic velocity field of ``motion`` (see :func:`field`)."""
    from ..physics.motion import PlateMotion
    from ..physics.ppod import asymptotic_field, drift_field, field_angle
    from ..physics.sim import simulate

    if not isinstance(motion, PlateMotion):
        raise ParameterError(f"kind={kind!r} needs motion=, a periodic upm.PlateMotion; got {motion!r}")
    plt = _pyplot()
    x0, y0, x1, y1 = as_float("extent", extent).reshape(4)
    n = min(resolution, 15)
    gx, gy = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n))
    points = np.stack([gx, gy], axis=-1)
    shown = ["drift", "asymptotic"] if kind == "both" else [kind]
    titles = {"drift": f"drift, $\\mu$ = {mu:g}", "asymptotic": "asymptotic"}
    if ax is None:
        fig, axes = plt.subplots(
            1, len(shown), figsize=(5.0 * len(shown), 5.0), layout="constrained", squeeze=False
        )
        axes = list(axes[0])
    else:
        fig, axes = ax.figure, [ax] * len(shown)
    computed = {}
    spacing = (x1 - x0) / max(n - 1, 1)
    for axis, name in zip(axes, shown, strict=True):
        result = drift_field(motion, points, mu=mu) if name == "drift" else asymptotic_field(motion, points)
        computed[name] = result
        v = result.velocity * 1e3
        top = max(float(np.max(np.hypot(v[..., 0], v[..., 1]))), 1e-9)
        arrows = dict(angles="xy", scale_units="xy", scale=top / (0.9 * spacing))  # longest: 0.9 spacing
        axis.quiver(gx, gy, v[..., 0], v[..., 1], np.hypot(v[..., 0], v[..., 1]), cmap="viridis", pivot="mid",
                    **arrows)  # fmt: skip
        title = titles[name]
        if name == "drift" and measured:
            t_end = 1.0
            pick = points[::2, ::2].reshape(-1, 2)
            dt = 1.0 / (400.0 * max(motion.max_frequency, 1.0))
            r = simulate(motion, pick, duration=t_end, dt=dt, mu=mu, record_every=10**9)
            moved = (r.positions[-1] - r.positions[0]) / t_end * 1e3
            label = "simulated parts, mean over 1 s"
            tip = dict(color="red", pivot="mid", width=0.004, label=label)
            axis.quiver(pick[:, 0], pick[:, 1], moved[:, 0], moved[:, 1], **tip, **arrows)
            axis.legend(loc="upper right", fontsize=8)
        axis.set_aspect("equal")
        axis.set_xlabel("x [m]")
        axis.set_ylabel("y [m]")
        axis.set_title(f"Velocity field [mm/s]: {title}")
    if len(computed) == 2:
        angle = np.nanmedian(np.abs(field_angle(computed["drift"], computed["asymptotic"])))
        fig.suptitle(f"median angle between drift and asymptotic: {angle:.0f}°")
    figure: Figure = fig
    return figure


def _log_spaced(values: Any) -> bool:
    """Whether an axis is positive and geometrically spaced over more than a decade (then it is
    drawn on a log scale)."""
    v = np.asarray(values, dtype=np.float64) if np.asarray(values).dtype.kind in "fiu" else np.zeros(0)
    if v.size < 3 or not np.all(v > 0) or v.max() / v.min() < 10:
        return False
    ratios = v[1:] / v[:-1]
    return bool(np.allclose(ratios, ratios[0], rtol=1e-6) and abs(ratios[0] - 1) > 1e-9)


def sweep(ds: Any, var: str | None = None, *, x: str | None = None, y: str | None = None) -> Figure:
    """A sweep's result (:func:`upm.sweep`) at a glance: a line plot over one dimension, a heat
    map over two (``y`` down the rows, ``x`` along the columns; by default the first two
    dimensions); further dimensions are fixed at their first value and named in the title.

    Parameters
    ----------
    ds : xarray.Dataset or xarray.DataArray
        The sweep's result.
    var : str, optional
        The variable to show (default: the first).
    x, y : str, optional
        Dimensions for the axes.
    """
    plt = _pyplot()
    da = ds if var is None and not hasattr(ds, "data_vars") else ds[var or next(iter(ds.data_vars))]
    dims = list(da.dims)
    if not dims:
        raise ParameterError(f"{da.name!r} has no dimensions to plot")
    for d in (x, y):
        if d is not None and d not in dims:
            raise ParameterError(f"{d!r} is not a dimension of {da.name!r}; its dimensions: {dims}")
    rest = [d for d in dims if d not in (x, y)]
    if len(dims) == 1:
        keep = dims
    else:
        rows = y if y is not None else rest.pop(0)
        cols = x if x is not None else rest.pop(0)
        keep = [rows, cols]
    fixed = {d: da[d].values[0] if d in da.coords else 0 for d in dims if d not in keep}
    da = da.isel({d: 0 for d in fixed})
    title = f"{da.name}" + ("" if not fixed else " at " + ", ".join(f"{d}={v}" for d, v in fixed.items()))
    fig, ax = plt.subplots(figsize=(6.4, 4.4), layout="constrained")
    if len(keep) == 1:
        d = keep[0]
        xs = da[d].values if d in da.coords else np.arange(da.sizes[d])
        ax.plot(xs, da.values, "o-")
        if _log_spaced(xs):
            ax.set_xscale("log")
        ax.set_xlabel(d)
        ax.set_ylabel(str(da.name))
    else:
        rows, cols = keep
        grid = da.transpose(rows, cols)
        xs = grid[cols].values if cols in grid.coords else np.arange(grid.sizes[cols])
        ys = grid[rows].values if rows in grid.coords else np.arange(grid.sizes[rows])
        mesh = ax.pcolormesh(xs, ys, grid.values, shading="nearest", cmap="viridis")
        if _log_spaced(xs):
            ax.set_xscale("log")
        if _log_spaced(ys):
            ax.set_yscale("log")
        fig.colorbar(mesh, ax=ax, label=str(da.attrs.get("description", da.name)))
        ax.set_xlabel(cols)
        ax.set_ylabel(rows)
    ax.set_title(title)
    figure: Figure = fig
    return figure


_LABEL_COLOURS = {"red": "tab:red", "blue": "tab:blue", "penny": "tab:orange"}


def loop_paths(
    log: Any,
    references: Any = (),
    centers: ArrayLike | None = None,
    labels: Any = None,
    plate_size: float = PLATE_SIZE,
) -> Figure:
    """The parts' tracked paths on the plate during a loop run (a :class:`upm.control.Log` or a
    loaded log), with reference paths and the centres of rotation."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(5.4, 5.2), layout="constrained")
    h = plate_size / 2
    ax.plot([-h, h, h, -h, -h], [-h, -h, h, h, -h], color="0.4", lw=1)
    for r in references:
        r = np.asarray(r)
        ax.plot(r[:, 0], r[:, 1], color="0.6", lw=1.2, ls="--")
    pos = np.asarray(log.positions)
    names = list(log.labels)
    for k in range(pos.shape[1]):
        colour = _LABEL_COLOURS.get(names[k] if k < len(names) else "", None)
        p = pos[:, k]
        ax.plot(p[:, 0], p[:, 1], "-", lw=1.2, color=colour)
        ok = np.nonzero(np.all(np.isfinite(p), axis=1))[0]
        if len(ok):
            ax.plot(*p[ok[0]], "o", mfc="none", color=colour or "k", ms=6)
            ax.plot(*p[ok[-1]], "o", color=colour or "k", ms=6)
    if centers is not None:
        cs = np.asarray(centers).reshape(-1, 2)
        ax.plot(cs[:, 0], cs[:, 1], "k+", ms=9, mew=1.5, label="centres of rotation")
        ax.legend(loc="upper right", fontsize=8)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("Tracked paths (open: start, filled: end)")
    figure: Figure = fig
    return figure


def loop_errors(log: Any) -> Figure:
    """Each part's task error and the step tracking error ``|achieved - desired|`` per cycle."""
    plt = _pyplot()
    fig, (a, b) = plt.subplots(2, 1, figsize=(6.0, 5.2), sharex=True, layout="constrained")
    t = np.asarray(log.time)
    errors = np.asarray(log.errors)
    for k in range(errors.shape[1] if errors.ndim == 2 else 0):
        a.plot(t, 1000 * errors[:, k], lw=1)
    a.set_ylabel("task error [mm]")
    d = np.asarray(log.achieved) - np.asarray(log.desired)
    track = np.hypot(d[..., 0], d[..., 1])
    if track.size:
        for k in range(track.shape[1]):
            b.plot(t, 1000 * track[:, k], ".", ms=3)
        finite = track[np.isfinite(track)]
        if finite.size:
            b.axhline(1000 * float(np.median(finite)), color="k", lw=1, ls="--", label="median")
            b.legend(fontsize=8)
    b.set_ylabel("|achieved - desired| [mm]")
    b.set_xlabel("plate time [s]")
    a.set_title("Closed loop: errors per cycle")
    figure: Figure = fig
    return figure


def bang_bang_feed_rate(a_max: float = 16.0, period: float = 1.0) -> Figure:
    """Fig. 3.5: the bang-bang feed rate ``v_eq``, the velocity range ``v_max`` and their ratio
    against ``z`` (3.10, 3.11), ``a_max = 16``, ``T = 1``."""
    plt = _pyplot()
    z = np.linspace(0.0, 0.999, 400)
    v_eq = theory.bang_bang_feed_rate(z, a_max, period)
    v_max = theory.bang_bang_velocity_range(z, a_max, period)[1]
    ratio = np.divide(v_eq, v_max, out=np.zeros_like(z), where=v_max > 0)
    fig, ax = plt.subplots(figsize=(5.6, 4.0), layout="constrained")
    ax.plot(z, v_eq, label=r"$v_{eq}$")
    ax.plot(z, v_max, "--", label=r"$v_{max}$")
    ax.plot(z, ratio, ":", label=r"$v_{eq}/v_{max}$")
    ax.axvline(0.5, color="0.7", lw=0.8)
    ax.set_xlabel("z")
    ax.set_ylabel("velocity")
    ax.set_title(rf"Fig. 3.5: bang-bang feed rate ($a_{{max}}$ = {a_max:g}, T = {period:g})")
    ax.legend()
    figure: Figure = fig
    return figure


def theorem1(pairs: Any = ((1, 2), (2, 3), (1, 4))) -> Figure:
    """Fig. 6.9: average force at rest ``f / (mu m g)`` under ``cos(n1 t) - cos(n2 (t - psi))``
    against ``psi`` for coprime pairs: triangular waves of period ``2 pi / (n1 n2)`` and amplitude
    ``1 / (n2^2 - n1^2)`` (Theorem 1, lines), with points from the exact root-based integral
    (:func:`upm.force_table`)."""
    from ..physics.feeding import force_table, theorem1_force

    plt = _pyplot()
    phi = np.linspace(0, 2 * np.pi, 721)
    fig, ax = plt.subplots(figsize=(6.0, 4.0), layout="constrained")
    for n1, n2 in pairs:
        line = ax.plot(phi, theorem1_force(n1, n2, phi), lw=1.2, label=f"({n1}, {n2})")[0]
        ax.plot(phi[::24], force_table(n1, n2, phi[::24]), "o", ms=3.5, color=line.get_color())
    ax.set_xlabel(r"$\psi$ [rad]")
    ax.set_ylabel(r"$f / \mu m g$")
    ax.set_title(r"Fig. 6.9: $\cos n_1 t - \cos n_2 (t - \psi)$ (lines: Theorem 1; dots: exact)", fontsize=10)
    ax.legend(title="(n1, n2)")
    figure: Figure = fig
    return figure
