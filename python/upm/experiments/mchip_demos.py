"""``upm demo mchip-NAME``: the M-Chip experiments of thesis chapter 2 (Figs. 2.5–2.10, Table 2.1),
each writing plots and ``metrics.json`` to ``out/mchip-NAME/``. Needs matplotlib."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from .._errors import ParameterError
from ..physics.mchip import Design, Drive, MChipResult, conveyor_fit, free_swing, simulate
from .runner import keep, run_named

# The thesis's part (Fig. 2.3): 1.15 x 0.4 x 0.25 mm; the demos give it a mass of their own.
_THESIS_PART = (1150e-6, 400e-6, 250e-6)
# Joints resonating at 1.5 kHz, below the 5 kHz drive: the free ridges never come down to rest,
# and the next row blocks the default part (docs/mchip.md, Jamming).
_BELOW_DRIVE = replace(Design(), natural_frequency=1500.0)


def _run(design: Design, drive: Drive, duration: float, **kw: Any) -> MChipResult:
    return simulate(design, drive, duration=duration, record_every=20, **kw)


def _median(values: np.ndarray) -> float:
    return float(np.median(values)) if len(values) else float("nan")


def _mean(values: np.ndarray) -> float:
    return float(np.mean(values)) if len(values) else float("nan")


def _phase(r: MChipResult) -> np.ndarray:
    """Each collision's phase in its row's square wave, in [0, 1)."""
    c, drive = r.collisions, r.drive
    offset = np.asarray(drive.phases)[c["resonator"] // r.design.cols] if drive.scheme == "phases" else 0.0
    return np.asarray((c["time"] * drive.frequency - offset) % 1.0)


def _summary(r: MChipResult) -> dict[str, Any]:
    c = r.collisions
    cycle, rebound = r.impacts(), r.rebounds()
    jams = r.jams()
    landed = (c["time"] >= 0.02) & ~np.isnan(r.collision_gaps())  # the landing's bounces left out
    return {
        "feed_rate_mm_s": 1e3 * r.feed_rate(),
        "collisions": len(r.collisions),
        "double_bounce_share": r.rebound_share(),
        "double_bounce_share_after_20ms": _mean(rebound[landed]),
        # Fig. 2.7: the once-a-cycle impacts against the rebounds just after them.
        "impact_angular_speed_median_rad_s": r.impact_median("angular_speed"),
        # Where in its row's drive cycle each impact falls (the torque is on up to `duty`).
        "impact_phase_median": _median(_phase(r)[cycle]),
        "rebound_angular_speed_median_rad_s": _median(c["angular_speed"][rebound]),
        "impact_impulse_x_mean_n_s": _mean(c["impulse_x"][cycle]),
        "rebound_impulse_x_mean_n_s": _mean(c["impulse_x"][rebound]),
        "jams_s": jams,
        "jam_time_s": float(sum(b - a for a, b in jams)),
        "energy_share_vertical_hop": r.hop_energy_share(),
        "row_impulse_x_n_s": r.row_impulse().tolist(),
    }


def _feed(quick: bool, out: Path) -> dict[str, Any]:
    import matplotlib.pyplot as plt

    duration = 0.04 if quick else 0.2
    r = _run(Design(), Drive(), duration)
    keep(r, out)
    m = _summary(r)
    m["hop_frequency_hz"] = r.hop_frequency()
    m["array_stiffness_n_m"] = r.array_stiffness()
    m["energy_j"] = r.energy
    fig, ax = plt.subplots(3, 1, figsize=(7, 9))
    ax[0].plot(1e3 * r.t, 1e6 * (r.position[:, 0] - r.position[0, 0]), label="x (feed)")
    ax[0].plot(1e3 * r.t, 1e6 * r.position[:, 2], label="z (hop)")
    ax[0].set(xlabel="t [ms]", ylabel="part [µm]", title="Part displacement (Fig. 2.5)")
    ax[0].legend()
    c = r.collisions
    ax[1].scatter(c["angle"], c["angular_speed"], s=3)
    ax[1].set(xlabel="angle [rad]", ylabel="angular speed [rad/s]", title="Collisions (Fig. 2.6)")
    gaps = r.inter_arrival()
    ax[2].hist(1e3 * gaps[gaps < 0.5e-3], bins=100)
    ax[2].set(xlabel="inter-arrival time [ms]", ylabel="collisions", title="Fig. 2.7")
    fig.tight_layout()
    fig.savefig(out / "feed.png", dpi=110)
    plt.close(fig)
    return m


def _compare(
    runs: dict[str, tuple[Design, Drive]], duration: float, out: Path, name: str
) -> tuple[dict[str, Any], dict[str, MChipResult]]:
    import matplotlib.pyplot as plt

    m: dict[str, Any] = {}
    results = {}
    fig, ax = plt.subplots(figsize=(7, 4))
    for label, (design, drive) in runs.items():
        r = results[label] = _run(design, drive, duration)
        m[label] = _summary(r)
        ax.plot(1e3 * r.t, 1e6 * (r.position[:, 0] - r.position[0, 0]), label=label)
    ax.set(xlabel="t [ms]", ylabel="x [µm]")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / f"{name}.png", dpi=110)
    plt.close(fig)
    return m, results


def _strobe(quick: bool, out: Path) -> dict[str, Any]:
    """Fig. 2.5: the part's advance with all rows on and strobed, on the default joints (the free
    ridges come down to rest once a cycle: no jam) and on joints resonating at 1.5 kHz, below the
    drive (the next row's ridges never come down: they block the part, and strobing clears it)."""
    strobe = Drive(scheme="strobe", tau=50, delta=4)
    runs = {
        "all rows on": (Design(), Drive()),
        "row strobing (tau 50, delta 4)": (Design(), strobe),
        "1.5 kHz joints, all rows on": (_BELOW_DRIVE, Drive()),
        "1.5 kHz joints, row strobing": (_BELOW_DRIVE, strobe),
    }
    return _compare(runs, 0.06 if quick else 0.4, out, "strobe")[0]


def _duty(quick: bool, out: Path) -> dict[str, Any]:
    """Fig. 2.7: each collision's angle, angular speed and x impulse against its inter-arrival
    time, at duty 50% (a-c) and 36% (d-f): the default part; the thesis's 1.15 x 0.4 x 0.25 mm
    part at 125 µg (heavier: the impacts come earlier in the drive's on-time, and the lower duty
    cycle removes its double bounces); the default part on stiffer resonators (10 kHz, Q = 3),
    whose impacts come early too; and the default part on joints resonating at 1.5 kHz, over
    0.1 s (the next row blocks it soon after)."""
    import matplotlib.pyplot as plt

    stiff = replace(Design(), natural_frequency=10_000.0, quality=3.0)
    thesis = replace(Design(), part_size=_THESIS_PART, part_mass=125e-9)
    runs = {
        "duty 50%": (Design(), Drive()),
        "duty 36%": (Design(), Drive(duty=0.36)),
        "125 µg thick part, duty 50%": (thesis, Drive()),
        "125 µg thick part, duty 36%": (thesis, Drive(duty=0.36)),
        "10 kHz, Q 3, duty 50%": (stiff, Drive()),
        "10 kHz, Q 3, duty 36%": (stiff, Drive(duty=0.36)),
    }
    m, results = _compare(runs, 0.04 if quick else 0.2, out, "duty")
    soft_runs = {
        "1.5 kHz, duty 50%": (_BELOW_DRIVE, Drive()),
        "1.5 kHz, duty 36%": (_BELOW_DRIVE, Drive(duty=0.36)),
    }
    more, more_results = _compare(soft_runs, 0.04 if quick else 0.1, out, "duty_1500hz")
    m.update(more)
    results.update(more_results)
    fig, ax = plt.subplots(3, len(results), figsize=(3.2 * len(results), 9), sharex=True, sharey="row")
    for j, (label, r) in enumerate(results.items()):
        c, gaps = r.collisions, 1e3 * r.collision_gaps()
        # After the landing's bounces (the thesis plots 0.05 < t < 0.2 s).
        keep = (gaps < 0.5) & (c["time"] >= (0.01 if quick else 0.02))
        for i, (key, scale, unit) in enumerate(
            [("angle", 1.0, "angle [rad]"), ("angular_speed", 1.0, "angular speed [rad/s]"),
             ("impulse_x", 1e12, "x impulse [1e-12 N s]")]
        ):  # fmt: skip
            ax[i, j].scatter(gaps[keep], scale * c[key][keep], s=3)
            ax[i, j].set(ylabel=unit if j == 0 else "")
        ax[0, j].set(title=label)
        ax[2, j].set(xlabel="inter-arrival time [ms]")
    fig.tight_layout()
    fig.savefig(out / "collisions.png", dpi=110)
    plt.close(fig)
    return m


def _sweep_plot(x: list[float], ys: dict[str, list[float]], xlabel: str, out: Path, name: str) -> None:
    """Feed rate against ``x``, one line per entry of ``ys`` (its key the legend, if several)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for label, y in ys.items():
        ax.plot(x, y, "o-", label=label)
    if len(ys) > 1:
        ax.legend()
    ax.set(xlabel=xlabel, ylabel="feed rate [mm/s]")
    fig.tight_layout()
    fig.savefig(out / f"{name}.png", dpi=110)
    plt.close(fig)


def _mass(quick: bool, out: Path) -> dict[str, Any]:
    """Fig. 2.9(a): feed rate against part mass, with the part's mean height (PartZ), the impacts'
    median angle and angular speed. Two series: the thesis's 1.15 x 0.4 x 0.25 mm part on the
    default joints, 0.3 s runs from the default start, long enough to cross a row, where heavy
    parts stall; and the default 1150 x 400 x 50 µm part over the thesis's 20-110 µg on joints
    resonating at 1.5 kHz, 0.1 s runs, which end before the next row (it blocks the part there)."""
    import matplotlib.pyplot as plt

    series = {
        "thesis's part, 5 kHz joints": (
            replace(Design(), part_size=_THESIS_PART),
            [50.0, 100.0, 200.0] if quick else [25.0, 50.0, 75.0, 100.0, 125.0, 150.0, 200.0, 250.0, 300.0],
            0.03 if quick else 0.3,
        ),
        "default part, 1.5 kHz joints": (
            _BELOW_DRIVE,
            [35.0, 75.0, 110.0] if quick else [20.0, 35.0, 55.0, 75.0, 95.0, 110.0],
            0.03 if quick else 0.1,
        ),
    }
    m: dict[str, Any] = {}
    fig, ax = plt.subplots(1, len(series), figsize=(6 * len(series), 4))
    for k, (label, (base, masses, duration)) in enumerate(series.items()):
        rates, heights, speeds, angles = [], [], [], []
        for mass in masses:
            r = _run(replace(base, part_mass=mass * 1e-9), Drive(), duration)
            rates.append(1e3 * r.feed_rate())
            heights.append(1e6 * r.part_height())
            speeds.append(r.impact_median("angular_speed"))
            angles.append(r.impact_median("angle"))
        ax[k].plot(masses, rates, "o-", color="C0")
        ax[k].set(xlabel="part mass [µg]", ylabel="feed rate [mm/s]", title=label)
        right = ax[k].twinx()
        right.plot(masses, heights, "s--", color="C1", label="underside height [µm]")
        right.plot(masses, np.array(speeds) / 100, "^:", color="C2", label="impact speed [100 rad/s]")
        right.plot(masses, 100 * np.array(angles), "v-.", color="C3", label="impact angle [0.01 rad]")
        right.legend(loc="upper right", fontsize=8)
        # The array as a spring under the part (thesis 2.3.1): its height falls linearly with the
        # mass.
        slope = np.polyfit(1e-9 * np.array(masses), 1e-6 * np.array(heights), 1)[0]
        stiffness = float(-9.81 / slope) if slope < 0 else float("nan")
        m[label] = {"part_mass_ug": masses, "feed_rate_mm_s": rates, "underside_height_um": heights,
                    "impact_angular_speed_median_rad_s": speeds, "impact_angle_median_rad": angles,
                    "stiffness_from_height_n_m": stiffness}  # fmt: skip
    fig.tight_layout()
    fig.savefig(out / "mass.png", dpi=110)
    plt.close(fig)
    return m


def _shape(quick: bool, out: Path) -> dict[str, Any]:
    """Figs. 2.9(b, c): feed rate, the part's height and the impacts' angular speed against the
    ridge distance L for the default part and for the thesis's 1.15 x 0.4 x 0.25 mm part at
    175 µg (heavier: an interior optimum in L), and against the ridge height H for the default
    part (0.15 s runs)."""
    import matplotlib.pyplot as plt

    heavy = replace(Design(), part_size=_THESIS_PART, part_mass=175e-9)
    ls = [70e-6, 130e-6] if quick else [70e-6, 85e-6, 100e-6, 115e-6, 130e-6]
    hs = [5e-6, 10e-6] if quick else [2.5e-6, 5e-6, 10e-6, 16e-6, 20e-6]
    series = {
        ("L", "default part, 54 µg"): [replace(Design(), ridge_distance=v) for v in ls],
        ("L", "175 µg thick part"): [replace(heavy, ridge_distance=v) for v in ls],
        ("H", "default part, 54 µg"): [replace(Design(), ridge_height=v) for v in hs],
    }
    m: dict[str, Any] = {"ridge_distance_um": [1e6 * v for v in ls], "ridge_height_um": [1e6 * v for v in hs]}
    fig, ax = plt.subplots(3, 2, figsize=(10, 9), sharex="col")
    done: dict[Design, MChipResult] = {}  # the default design is on both the L and the H line
    for (axis, label), designs in series.items():
        for d in designs:
            if d not in done:
                done[d] = _run(d, Drive(), 0.03 if quick else 0.15)
        runs = [done[d] for d in designs]
        curves = {
            "feed_rate_mm_s": [1e3 * r.feed_rate() for r in runs],
            "underside_height_um": [1e6 * r.part_height() for r in runs],
            "impact_angular_speed_median_rad_s": [r.impact_median("angular_speed") for r in runs],
            "double_bounce_share": [r.rebound_share() for r in runs],
        }
        m[f"{axis}: {label}"] = curves
        col, x = (0, m["ridge_distance_um"]) if axis == "L" else (1, m["ridge_height_um"])
        for i, key in enumerate(list(curves)[:3]):
            ax[i, col].plot(x, curves[key], "o-", label=label)
    for col, name in enumerate(["ridge distance L [µm] (H = 5 µm)", "ridge height H [µm] (L = 130 µm)"]):
        ax[0, col].set(ylabel="feed rate [mm/s]")
        ax[1, col].set(ylabel="part underside [µm]")
        ax[2, col].set(ylabel="impact angular speed [rad/s]", xlabel=name)
        ax[0, col].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "shape.png", dpi=110)
    plt.close(fig)
    return m


def _jam(quick: bool, out: Path) -> dict[str, Any]:
    """The next row's ridge (2.2.1): the default part started with its front 20 µm behind row 5's
    ridge, at the simulated 0.08 rad and the device's nominal 2°, all rows on and strobed; the
    thesis's 1.15 x 0.4 x 0.25 mm part at 300 µg (where it feeds at the thesis's 0.8 mm/s) from
    the default start, which stalls for a while as it crosses the ridges (0.6 s runs); and the
    default part on joints resonating at 1.5 kHz, below the drive, from the default start (0.4 s
    runs): the free ridges ride on the torque's mean, row 5 blocks the part and strobing clears
    it."""
    import matplotlib.pyplot as plt

    design = Design()
    heavy = replace(design, part_size=_THESIS_PART, part_mass=300e-9)
    pitch = design.slab[0] + design.gap
    ridge = 5 * pitch - design.ridge_distance - 0.5 * design.ridge_width  # row 5's ridge, rear face
    near = (ridge - 20e-6 - 0.5 * design.part_size[0], 400e-6)
    short, long = (0.03, 0.03) if quick else (0.1, 0.6)
    # Strobed, row 5 is off 20-30 ms into every 40 ms: the quick run lasts past that.
    soft_start, soft_duration = (near, 0.04) if quick else ((600e-6, 400e-6), 0.4)
    m: dict[str, Any] = {"part_start_near_m": near[0], "row5_ridge_m": ridge}
    # The free resonators' swing (no part): a joint tuned to the drive swings from about 0, one
    # resonating below it rides on the torque's mean.
    for label, d in (("tuned 5 kHz joint", design), ("1.5 kHz joint", _BELOW_DRIVE)):
        low, high = free_swing(d)
        m[f"free_swing_rad, {label}"] = [low, high]
        m[f"free_ridge_lowest_m, {label}"] = d.ridge_height + d.ridge_distance * low
    runs = {
        "0.08 rad, all rows": (design, Drive(), near, short),
        "0.08 rad, strobed": (design, Drive(scheme="strobe"), near, short),
        "2°, all rows": (design, Drive(peak_angle=0.035), near, short),
        "2°, strobed": (design, Drive(peak_angle=0.035, scheme="strobe"), near, short),
        "300 µg thick part, all rows": (heavy, Drive(), (600e-6, 400e-6), long),
        "300 µg thick part, strobed": (heavy, Drive(scheme="strobe"), (600e-6, 400e-6), long),
        "1.5 kHz joint, all rows": (_BELOW_DRIVE, Drive(), soft_start, soft_duration),
        "1.5 kHz joint, strobed": (_BELOW_DRIVE, Drive(scheme="strobe"), soft_start, soft_duration),
    }
    fig, ax = plt.subplots(3, 1, figsize=(7, 10))
    for k, (label, (d, drive, start, duration)) in enumerate(runs.items()):
        r = _run(d, drive, duration, part_start=start)
        front = r.position[:, 0] + 0.5 * d.part_size[0]
        edges = np.minimum(np.searchsorted(r.t, np.arange(0.0, r.t[-1] + 1e-9, 0.02) - 1e-9), len(r.t) - 1)
        m[label] = _summary(r) | {
            "crossed_row5_ridge": bool(front.max() > ridge + d.ridge_width),
            "underside_height_m": r.part_height(),
            # The feed rate over successive 20 ms windows: a stall shows as a run of low values.
            "rate_per_20ms_mm_s": (np.diff(1e3 * front[edges]) / np.diff(r.t[edges])).tolist(),
        }  # fmt: skip
        ax[0].plot(1e3 * r.t, 1e6 * (front - ridge), label=label)
        ax[1].plot(1e3 * r.t, 1e3 * r.pitch(), lw=0.8, label=label)
        width = 0.8 / len(runs)
        # Each row's mean x force on the part as a share of its weight (runs of unequal parts and
        # lengths side by side).
        share = r.row_impulse() / (d.mass() * 9.81 * r.t[-1])
        ax[2].bar(np.arange(d.rows) + width * (k - (len(runs) - 1) / 2), share, width=width, label=label)
    ax[0].axhline(0, color="k", lw=0.8)
    ax[0].set(xlabel="t [ms]", ylabel="part front - row 5 ridge [µm]", title="Approaching the next row")
    ax[0].legend(fontsize=7)
    ax[1].set(xlabel="t [ms]", ylabel="part pitch [mrad] (nose down > 0)")
    ax[2].set(xlabel="resonator row (along the feed)", ylabel="mean x force / part weight")
    fig.tight_layout()
    fig.savefig(out / "jam.png", dpi=110)
    plt.close(fig)
    return m


def _force(quick: bool, out: Path) -> dict[str, Any]:
    weight = Design().mass() * 9.81
    fractions = [0.0, 0.05, 0.1] if quick else [0.0, 0.025, 0.05, 0.075, 0.1, 0.15]
    forces = [-f * weight for f in fractions]  # pushing against the feed
    rates = [
        _run(Design(), Drive(), 0.03 if quick else 0.1, external_force=(f, 0.0)).feed_rate() for f in forces
    ]
    m: dict[str, Any] = {"force_n": forces, "feed_rate_mm_s": [1e3 * v for v in rates]}
    try:
        belt, c = conveyor_fit(np.negative(forces), rates)
        fit = np.polyval(np.polyfit(forces, rates, 1), forces)
        m.update(belt_speed_mm_s=1e3 * belt, viscous_n_s_m=c,
                 linear_fit_rms_mm_s=float(1e3 * np.sqrt(np.mean((np.array(rates) - fit) ** 2))))  # fmt: skip
    except ParameterError as error:
        m["fit"] = str(error)
    newtons = [1e9 * -f for f in forces]
    _sweep_plot(newtons, {"": m["feed_rate_mm_s"]}, "force against the feed [nN]", out, "force")
    return m


DEMOS: dict[str, tuple[str, Callable[[bool, Path], dict[str, Any]]]] = {
    "mchip-feed": ("the part fed by the array; collisions and inter-arrival times (Figs. 2.5–2.7)", _feed),
    "mchip-strobe": ("all rows on against row strobing (2.2.1, Figs. 2.4, 2.5)", _strobe),
    "mchip-jam": ("crossing into the next row: blocking, stalls and strobing (2.2.1)", _jam),
    "mchip-duty": ("torque duty cycle 50% against 36%: double bounces (2.2.2, Fig. 2.7)", _duty),
    "mchip-mass": ("feed rate against part mass, the thesis's part size (Fig. 2.9a)", _mass),
    "mchip-shape": ("feed rate against ridge distance L and height H (Figs. 2.8, 2.9)", _shape),
    "mchip-force": ("feed rate under an external force: the viscous model (Fig. 2.10, Table 2.1)", _force),
}


def run_mchip_demo(
    name: str, out: Path | str = "out", quick: bool = False, verbose: bool = True
) -> dict[str, Any]:
    """Run M-Chip experiment ``name`` (see :data:`DEMOS`); write ``out/name/`` and return the metrics."""
    return run_named(DEMOS, name, out, quick, verbose)
