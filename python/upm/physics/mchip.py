"""The M-Chip resonator array of thesis chapter 2 (docs/spec.md §9), simulated with rapier3d.

A design tool for impact-driven microactuator arrays: an interleaved array of torsional resonators
(silicon slabs with a ridge at the rear end, on revolute joints with a torsional spring and damper)
driven by a positive square-wave torque feeds a rectangular part lying on the ridges. The model
and its unit scaling are described in ``docs/mchip.md``; the Rust side is ``upm_core::mchip``.

>>> from upm import mchip
>>> run = mchip.simulate(duration=0.02)                    # the default 8 x 5 array, 5 kHz
>>> run.feed_rate()                                        # m/s along the feed axis x
>>> mchip.simulate(mchip.Design(), mchip.Drive(scheme="strobe", tau=50, delta=4), duration=0.2)
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from .._errors import ParameterError

__all__ = ["Design", "Drive", "MChipResult", "conveyor_fit", "free_swing", "simulate"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Design:
    """Geometry and materials (SI units). Defaults: the thesis's 8 x 5 sub-array of 280 x 180 x
    5 µm silicon slabs with a 5 µm ridge, resonating at 5 kHz, and a 1150 x 400 x 50 µm silicon
    part (54 µg, the thesis's nominal 55 µg); friction 1.0, restitution 0.5 (docs/spec.md §9)."""

    rows: int = 8
    cols: int = 5
    slab: tuple[float, float, float] = (280e-6, 180e-6, 5e-6)
    gap: float = 20e-6
    ridge_distance: float = 130e-6
    """``L``: the ridge's distance behind the slab's midpoint (the joint) [m]."""
    ridge_height: float = 5e-6
    """``H`` [m]."""
    ridge_width: float = 10e-6
    density: float = 2330.0
    natural_frequency: float = 5000.0
    quality: float = 0.8
    """Quality factor of a resonator on its joint (damping ratio ``1 / (2 Q)``)."""
    part_size: tuple[float, float, float] = (1150e-6, 400e-6, 50e-6)
    part_mass: float | None = None
    """[kg]; default: silicon of ``part_size``."""
    friction: float = 1.0
    restitution: float = 0.5

    def mass(self) -> float:
        """The part's mass [kg]."""
        return self.part_mass if self.part_mass is not None else self.density * math.prod(self.part_size)


@dataclass(frozen=True)
class Drive:
    """The square-wave drive torque: ``frequency`` [Hz], ``duty`` (fraction on), amplitude
    ``torque`` [N m] or (default) the one whose free steady oscillation peaks at ``peak_angle``
    [rad]; ``scheme``: ``"all"`` rows on, ``"strobe"`` (rows off for ``tau`` cycles in wavefronts
    ``delta`` rows apart, travelling against the feed), ``"phases"`` (per-row offsets
    ``phases`` [cycles]) or ``"off"``."""

    frequency: float = 5000.0
    duty: float = 0.5
    torque: float | None = None
    peak_angle: float = 0.08
    scheme: str = "all"
    tau: int = 50
    delta: int = 4
    phases: tuple[float, ...] = field(default_factory=tuple)


_COLLISION = np.dtype(
    [
        ("time", "f8"),
        ("resonator", "i8"),
        ("angle", "f8"),
        ("angular_speed", "f8"),
        ("impulse_x", "f8"),
        ("impulse_normal", "f8"),
    ]
)


@dataclass(frozen=True)
class MChipResult:
    """What :func:`simulate` recorded (SI units)."""

    design: Design
    drive: Drive
    t: FloatArray
    """Recorded times [s], ``(T,)``."""
    position: FloatArray
    """Part centre [m], ``(T, 3)``; x along the feed, z up (z = 0: the slabs' top at rest)."""
    velocity: FloatArray
    """Part velocity [m/s], ``(T, 3)``."""
    orientation: FloatArray
    """Part orientation, ``(T, 4)``: the unit quaternion ``(x, y, z, w)`` of its rotation from the
    start (scalar last, as ``scipy.spatial.transform.Rotation.from_quat`` takes it)."""
    angular_velocity: FloatArray
    """Part angular velocity [rad/s], ``(T, 3)``."""
    angles: FloatArray
    """Resonator angles [rad], ``(T, rows * cols)`` (index ``row * cols + col``)."""
    collisions: NDArray[Any]
    """One record per part–resonator collision, in time order: ``time`` (when it began),
    ``resonator``, ``angle`` and ``angular_speed`` (the resonator's as it came in, before the
    impact), ``impulse_x``, ``impulse_normal`` [N s]. Contact that breaks off and resumes within
    5 µs is the same collision (``REJOIN`` in ``docs/mchip.md``)."""
    energy: dict[str, float]
    """Time-averaged energy per degree of freedom [J]: ``part_x``, ``part_y``, ``part_z``,
    ``part_rotation``, ``resonators_kinetic``, ``resonators_spring``."""
    torque: float
    """Drive torque amplitude used [N m]."""
    stiffness: float
    """Joint spring [N m/rad]."""
    damping: float
    """Joint damper [N m s/rad]."""
    inertia: float
    """Resonator inertia about its joint [kg m^2]."""

    def pitch(self) -> FloatArray:
        """The part's pitch [rad] at the recorded times, ``(T,)``: its rotation about y, positive
        nose down (front edge, +x, lowered)."""
        x, y, z, w = self.orientation.T
        pitch: FloatArray = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
        return pitch

    def to_rerun(self, path: str | Path) -> Path:
        """Write the run as a rerun recording (``.rrd``; extra ``viz``): the posed part over the
        array, resonator angles and collisions (:func:`upm.viz.mchip_to_rerun`)."""
        from ..viz import mchip_to_rerun

        return mchip_to_rerun(self, path)

    def feed_rate(self, skip: float = 0.01) -> float:
        """Mean feed velocity along x [m/s]: the least-squares slope of ``x(t)`` after ``skip`` [s]
        (the part's landing)."""
        keep = self.t >= min(skip, 0.5 * self.t[-1])
        if keep.sum() < 2:
            raise ParameterError("feed_rate needs at least two recorded rows after skip")
        return float(np.polyfit(self.t[keep], self.position[keep, 0], 1)[0])

    def jams(
        self, window: float = 0.01, fraction: float = 0.25, skip: float = 0.01
    ) -> list[tuple[float, float]]:
        """Intervals ``(start, end)`` [s] after ``skip`` in which the part advanced, over every
        ``window`` [s], less than ``fraction`` of its free feed rate (a jam, or a stall).

        The free rate is the 80th percentile of the rates over all such windows: the part's speed
        when it is not jammed, even if it is jammed for much of the run (the run's average would
        then be a jam's rate itself). If that percentile is itself under half the 95th (the part
        was jammed for more than four fifths of the run), the free rate is the median of the
        windows at least that fast, so a part blocked early is still found jammed as long as it
        moved freely for one window in twenty. A part that never moved forward has no free rate
        and no jams: check :meth:`feed_rate` first."""
        for name, value in (("window", window), ("fraction", fraction)):
            if not (math.isfinite(value) and value > 0):
                raise ParameterError(f"{name} must be a positive number; got {value!r}")
        if not (math.isfinite(skip) and skip >= 0):
            raise ParameterError(f"skip must be >= 0 s; got {skip!r}")
        t, x = self.t, self.position[:, 0]
        ends = np.flatnonzero(t >= t[0] + skip + window)
        if len(ends) == 0:
            raise ParameterError(
                f"jams needs a run longer than skip + window = {skip + window:g} s; got {t[-1] - t[0]:g} s"
            )
        begins = np.searchsorted(t, t[ends] - window)
        rates = (x[ends] - x[begins]) / (t[ends] - t[begins])
        free, fast = (float(v) for v in np.percentile(rates, [80, 95]))
        if fast <= 0:
            return []
        if free < 0.5 * fast:
            free = float(np.median(rates[rates >= 0.5 * fast]))
        out: list[tuple[float, float]] = []
        # The union of the slow windows (they start in time order).
        for k in np.flatnonzero(rates < fraction * free):
            a, b = float(t[begins[k]]), float(t[ends[k]])
            if out and a <= out[-1][1]:
                out[-1] = (out[-1][0], b)
            else:
                out.append((a, b))
        return out

    def collision_gaps(self) -> FloatArray:
        """For each collision, the time [s] since the same resonator's previous one (its
        inter-arrival time, thesis Fig. 2.7; NaN for each resonator's first), ``(len(collisions),)``."""
        c = self.collisions
        gaps = np.full(len(c), np.nan)
        for r in np.unique(c["resonator"]):
            index = np.flatnonzero(c["resonator"] == r)  # already in time order
            gaps[index[1:]] = np.diff(c["time"][index])
        return gaps

    def inter_arrival(self) -> FloatArray:
        """Times between successive collisions of the same resonator [s] (all resonators, in the
        order of the later collision)."""
        gaps = self.collision_gaps()
        return gaps[~np.isnan(gaps)]

    def rebound_share(self, within: float = 0.05e-3) -> float:
        """Share of collisions that came within ``within`` [s] of the same resonator's previous
        one: the double bounces of thesis 2.2.2 (0 without collisions)."""
        gaps = self.inter_arrival()
        return float(np.mean(gaps < within)) if len(gaps) else 0.0

    def rebounds(self, within: float = 0.05e-3) -> NDArray[np.bool_]:
        """Which collisions are rebounds: those within ``within`` [s] of the same resonator's
        previous one, ``(len(collisions),)`` (the double bounces counted by :meth:`rebound_share`)."""
        rebounds: NDArray[np.bool_] = self.collision_gaps() < within
        return rebounds

    def impacts(self) -> NDArray[np.bool_]:
        """Which collisions are the once-a-cycle impacts: those a drive period (within 15%) after
        the same resonator's previous one, ``(len(collisions),)`` (rebounds come within 0.05 ms,
        thesis Fig. 2.7; a resonator's first collision is neither)."""
        period = 1.0 / self.drive.frequency
        impacts: NDArray[np.bool_] = np.abs(self.collision_gaps() - period) < 0.15 * period
        return impacts

    def impact_median(self, field: str) -> float:
        """The median of a collision ``field`` (``"angle"``, ``"angular_speed"``, ...) over the
        once-a-cycle impacts (Fig. 2.9's theta and theta-dot); NaN without impacts."""
        if field not in (self.collisions.dtype.names or ()):
            raise ParameterError(f"field must be one of {self.collisions.dtype.names}; got {field!r}")
        values = self.collisions[field][self.impacts()]
        return float(np.median(values)) if len(values) else float("nan")

    def part_height(self, skip: float = 0.01) -> float:
        """Mean height [m] of the part's underside above the slabs' tops at rest after ``skip``
        [s] (the thesis's PartZ less half the part's thickness, Fig. 2.9): how deep the part
        sinks into the array."""
        keep = self.t >= min(skip, 0.5 * self.t[-1])
        return float(np.mean(self.position[keep, 2]) - 0.5 * self.design.part_size[2])

    def row_impulse(self) -> FloatArray:
        """Net x impulse [N s] each resonator row gave the part over the run, ``(rows,)``, rows
        numbered along the feed. A row that brakes the part (the blocking row of a jam, thesis
        2.2.1) has a negative entry; rows the part never touched have 0."""
        rows = self.collisions["resonator"] // self.design.cols
        per_row = np.bincount(rows, weights=self.collisions["impulse_x"], minlength=self.design.rows)
        return per_row.astype(np.float64)

    def hop_energy_share(self) -> float:
        """Share of the part's kinetic energy in its vertical motion (thesis 2.2.4, Table 2.1)."""
        e = self.energy
        part = e["part_x"] + e["part_y"] + e["part_z"] + e["part_rotation"]
        return e["part_z"] / part if part > 0 else float("nan")

    def hop_frequency(self, skip: float = 0.01, cycles: float = 10.0) -> float:
        """Dominant frequency [Hz] of the part's vertical motion below half the drive frequency
        (the array as a spring under the part, thesis 2.3.1), after ``skip`` [s].

        The height is detrended (a straight line) and only frequencies the run holds at least
        ``cycles`` periods of are searched: slower changes of height (the part settling, or
        sinking as it crosses onto fewer rows) are not a hop, and over a short window they would
        outweigh it."""
        keep = self.t >= skip
        t = self.t[keep]
        if len(t) < 8:
            raise ParameterError("hop_frequency needs a longer run (at least 8 rows after skip)")
        z = self.position[keep, 2]
        z = z - np.polyval(np.polyfit(t, z, 1), t)
        dt = float(np.median(np.diff(t)))
        spectrum = np.abs(np.fft.rfft(z * np.hanning(len(z))))
        f = np.fft.rfftfreq(len(z), dt)
        band = (f >= cycles / (t[-1] - t[0])) & (f < 0.5 * self.drive.frequency)
        if not band.any():
            raise ParameterError(
                f"hop_frequency needs a longer run: {t[-1] - t[0]:.3g} s after skip hold {cycles:g} "
                f"cycles of nothing below half the drive frequency"
            )
        return float(f[band][np.argmax(spectrum[band])])

    def array_stiffness(self, skip: float = 0.01, cycles: float = 10.0) -> float:
        """The array's vertical stiffness under the part [N/m]: ``m (2 pi f_hop)^2``."""
        return self.design.mass() * (2 * math.pi * self.hop_frequency(skip, cycles)) ** 2


def simulate(
    design: Design | None = None,
    drive: Drive | None = None,
    *,
    duration: float,
    dt: float = 1e-6,
    record_every: int = 10,
    external_force: ArrayLike = (0.0, 0.0),
    iterations: int = 4,
    part_start: ArrayLike = (600e-6, 400e-6),
    drop_height: float = 2e-6,
    initial_angle: float = 0.0,
    part: bool = True,
) -> MChipResult:
    """Simulate the resonator array and the part for ``duration`` [s] with steps of ``dt`` [s]
    (at most 1/50 of the drive and resonance periods).

    ``external_force`` (x, y) [N] acts on the part; ``part_start`` is its centre (x, y) [m] (x = 0
    at the first row's joints); it starts ``drop_height`` [m] above the ridges. ``initial_angle``
    sets every resonator's angle at the start (ring-down checks); ``part=False`` simulates the
    array alone. Releases the GIL; Ctrl-C stops it.
    """
    design = design or Design()
    drive = drive or Drive()
    if not isinstance(design, Design) or not isinstance(drive, Drive):
        raise ParameterError("design must be a upm.mchip.Design and drive a upm.mchip.Drive")
    d = asdict(design)
    d["part_mass"] = design.mass()
    v = asdict(drive)
    phases = [float(p) for p in v.pop("phases")]
    force = np.asarray(external_force, dtype=float).reshape(-1)
    start = np.asarray(part_start, dtype=float).reshape(-1)
    if force.size != 2 or start.size != 2:
        raise ParameterError("external_force and part_start must be (x, y) pairs")
    run = _core.mchip_simulate(
        **d,
        **v,
        phases=phases,
        dt=float(dt),
        duration=float(duration),
        record_every=int(record_every),
        external_force=(float(force[0]), float(force[1])),
        iterations=int(iterations),
        part_start=(float(start[0]), float(start[1])),
        drop_height=float(drop_height),
        initial_angle=float(initial_angle),
        part=bool(part),
    )
    records = np.zeros(len(run.collisions), dtype=_COLLISION)
    for k, name in enumerate(_COLLISION.names or ()):
        records[name] = run.collisions[:, k]
    names = ("part_x", "part_y", "part_z", "part_rotation", "resonators_kinetic", "resonators_spring")
    energies = dict(zip(names, map(float, run.energy), strict=True))
    return MChipResult(design, drive, run.t, run.positions, run.velocities, run.orientations,
                       run.angular_velocities, run.angles, records, energies, *run.joint)  # fmt: skip


def free_swing(
    design: Design | None = None, drive: Drive | None = None, *, dt: float = 1e-6
) -> tuple[float, float]:
    """The lowest and highest angle [rad] of a free resonator's steady swing with all rows on
    (the array without the part; read over the second half of a run of at least 20 drive periods
    and 20 decay times ``Q / (pi f0)``).

    A joint tuned to the drive swings from about 0; one resonating below it rides on the torque's
    mean, and its free ridges never come down to rest. A part riding lower than their lowest top,
    about ``ridge_height + ridge_distance * low`` above the slabs (compare
    :meth:`MChipResult.part_height`), cannot pass over the next row: it jams there (thesis 2.2.1,
    ``docs/mchip.md``)."""
    design = design or Design()
    drive = drive or Drive()
    if not isinstance(design, Design) or not isinstance(drive, Drive):
        raise ParameterError("design must be a upm.mchip.Design and drive a upm.mchip.Drive")
    drive = replace(drive, scheme="all")
    decay = design.quality / (math.pi * design.natural_frequency) if design.natural_frequency > 0 else 0.0
    duration = max(20.0 / drive.frequency, 20.0 * decay) if drive.frequency > 0 else 0.0
    # simulate() checks the design, the drive and the step (and a duration of 0 from bad input).
    run = simulate(design, drive, duration=duration, dt=dt, record_every=1, part=False)
    swing = run.angles[run.t >= 0.5 * run.t[-1], 0]
    return float(swing.min()), float(swing.max())


def conveyor_fit(forces: ArrayLike, feed_rates: ArrayLike) -> tuple[float, float]:
    """Fit the abstract spring–conveyor model's viscous law ``v = v_belt - F / c`` (thesis 2.2.4)
    to feed rates [m/s] measured under external forces [N]: returns ``(v_belt [m/s], c [N s/m])``."""
    f = np.asarray(forces, dtype=float).reshape(-1)
    v = np.asarray(feed_rates, dtype=float).reshape(-1)
    if f.size != v.size or f.size < 2:
        raise ParameterError("conveyor_fit needs at least two (force, feed rate) pairs of equal length")
    slope, belt = np.polyfit(f, v, 1)
    if slope >= 0:
        raise ParameterError("the feed rate does not fall with the force: no viscous fit")
    return float(belt), float(-1.0 / slope)
