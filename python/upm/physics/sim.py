"""Simulating parts on the plate: the exact stick–slip integrator (docs/spec.md §1).

``simulate`` runs point and disk parts on a plate driven by a :class:`upm.PlateMotion`, in Rust, parallel
over parts with the GIL released; ``simulate_batch`` runs many independent worlds at once.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from operator import attrgetter
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from .._arrays import as_float, integer, items, real
from .._arrays import threads as pool
from .._errors import ParameterError, ShapeError
from .._extras import need
from .._memory import check_memory as _check_memory
from .motion import PlateMotion
from .surface import friction_grid, gravity

__all__ = ["Disk", "Point", "SimResult", "simulate", "simulate_batch"]

#: What differs per world, as the extension reads it: ``mu`` and ``mu_s`` ``(B, M)``, the start
#: positions ``(B M, 2)`` and angles ``(B M,)`` (or None).
_Worlds = tuple[
    NDArray[np.float64], NDArray[np.float64], NDArray[np.float64] | None, NDArray[np.float64] | None
]


class Point(NamedTuple):
    """A point part: ``position`` [m] and ``velocity`` [m/s], both ``(x, y)``."""

    position: tuple[float, float]
    velocity: tuple[float, float] = (0.0, 0.0)


class Disk(NamedTuple):
    """A flat disk part of ``radius`` [m] pressing uniformly on the plate: it slides and spins.

    ``position`` [m], ``velocity`` [m/s], ``angle`` [rad], ``spin`` [rad/s]. Friction force and
    torque are integrated over the footprint (see ``docs/simulation.md``). ``mass`` (any unit, only
    ratios matter) is used by contacts only; by default it is proportional to the disk's area. Give
    it for every disk or for none.
    """

    position: tuple[float, float]
    radius: float
    velocity: tuple[float, float] = (0.0, 0.0)
    angle: float = 0.0
    spin: float = 0.0
    mass: float | None = None


@dataclass(frozen=True, eq=False, repr=False)
class SimResult:
    """What a simulation recorded (the initial state, every ``record_every``-th step, and always the
    final state).

    ``simulate_batch`` adds a leading batch axis ``B`` to every array but ``t``.
    """

    t: NDArray[np.float64]
    """Recorded times [s], ``(T,)``."""
    positions: NDArray[np.float64]
    """Positions [m], ``(T, M, 2)``."""
    velocities: NDArray[np.float64]
    """Velocities [m/s], ``(T, M, 2)``."""
    stuck: NDArray[np.bool_]
    """Whether each part moved with the plate surface, ``(T, M)``."""
    angles: NDArray[np.float64]
    """Orientations [rad], ``(T, M)`` (0 for points, which have none)."""
    spins: NDArray[np.float64]
    """Angular velocities [rad/s], ``(T, M)`` (0 for points)."""
    left_plate: NDArray[np.bool_]
    """Parts whose centre left the square plate, ``(M,)``; they stop being simulated."""
    left_time: NDArray[np.float64]
    """When each part left the plate [s] (NaN: it did not), ``(M,)``."""
    flight_time: NDArray[np.float64]
    """Time each part spent in the air [s], ``(M,)``: non-zero only on a plate that moves out of its
    plane hard enough that the normal force vanishes (docs/ppod.md)."""

    def __repr__(self) -> str:
        lead = self.positions.shape[:-3]
        batch = f"worlds={lead[0]}, " if lead else ""
        span = f"{self.t[0]:g}..{self.t[-1]:g} s" if len(self.t) else "empty"
        return (
            f"SimResult({batch}records={len(self.t)} ({span}), parts={self.positions.shape[-2]}, "
            f"left_plate={int(np.sum(self.left_plate))})"
        )

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, SimResult):
            return NotImplemented

        def same(a: NDArray[Any], b: NDArray[Any]) -> bool:
            return bool(np.array_equal(a, b, equal_nan=bool(np.issubdtype(a.dtype, np.floating))))

        return all(same(getattr(self, f.name), getattr(other, f.name)) for f in fields(self))

    __hash__ = None  # type: ignore[assignment]  # arrays: mutable contents

    def save(self, path: str | Path) -> Path:
        """Write every array to ``path`` (``.npz``, compressed); :meth:`load` reads it back."""
        target = Path(path)
        target = target if target.suffix == ".npz" else target.with_name(target.name + ".npz")
        target.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(target, **{f.name: getattr(self, f.name) for f in fields(self)})
        return target

    @classmethod
    def load(cls, path: str | Path) -> SimResult:
        """A result written by :meth:`save`."""
        with np.load(Path(path), allow_pickle=False) as data:
            arrays = {f.name: data[f.name] for f in fields(cls) if f.name in data.files}
        if "flight_time" not in arrays and "left_time" in arrays:  # saved before flight times existed
            arrays["flight_time"] = np.zeros_like(arrays["left_time"])
        missing = [f.name for f in fields(cls) if f.name not in arrays]
        if missing:
            raise ParameterError(f"{path} is not a saved SimResult: it lacks {missing}")
        return cls(**arrays)

    def to_rerun(self, path: str | Path, *, radius: float | None = None, labels: Any = None) -> Path:
        """Write the result as a rerun recording (``.rrd``; extra ``viz``): parts, velocities and,
        with ``radius``, disks' orientations over the ``frame`` and ``plate_time`` timelines
        (:func:`upm.viz.sim_to_rerun`)."""
        from ..viz import sim_to_rerun

        return sim_to_rerun(self, path, radius=radius, labels=labels)

    def to_xarray(self) -> Any:
        """The result as a labelled :class:`xarray.Dataset` (dimensions ``world`` for a batch,
        ``time``, ``part``, ``axis``; units in each variable's ``attrs``). Needs the ``sweep`` extra."""
        xr = need("xarray", "sweep", "SimResult.to_xarray")
        lead = ("world",) if self.positions.ndim == 4 else ()
        units = {
            "positions": "m",
            "velocities": "m/s",
            "angles": "rad",
            "spins": "rad/s",
            "left_time": "s",
            "flight_time": "s",
        }
        dims = {
            "positions": (*lead, "time", "part", "axis"),
            "velocities": (*lead, "time", "part", "axis"),
            "stuck": (*lead, "time", "part"),
            "angles": (*lead, "time", "part"),
            "spins": (*lead, "time", "part"),
            "left_plate": (*lead, "part"),
            "left_time": (*lead, "part"),
            "flight_time": (*lead, "part"),
        }
        variables = {
            name: (dim, getattr(self, name), {"units": units[name]} if name in units else {})
            for name, dim in dims.items()
        }
        coords = {"time": ("time", self.t, {"units": "s"}), "axis": ["x", "y"]}
        return xr.Dataset(variables, coords=coords)


def _masses(parts: Any) -> np.ndarray | None:
    """The disks' and polygons' masses (M,) if every one gives one, None if none does (points
    count 1)."""
    from .polygon import Polygon

    sized = (Disk, Polygon)
    if not (
        isinstance(parts, (list, tuple)) and parts and all(isinstance(p, (Point, *sized)) for p in parts)
    ):
        return None
    given = [p.mass is not None for p in parts if isinstance(p, sized)]
    if not any(given):
        return None
    if not all(given):
        missing = next(i for i, p in enumerate(parts) if isinstance(p, sized) and p.mass is None)
        raise ParameterError(
            f"mass must be given for every Disk or for none (every Polygon likewise); part {missing} "
            "has none "
            "(without masses, contacts take them proportional to the area)"
        )
    masses = [p.mass if isinstance(p, sized) and p.mass is not None else 1.0 for p in parts]
    return as_float("parts[i].mass", masses)


def _walls(walls: Any, plate_size: float | None) -> np.ndarray | None:
    """Walls as a (K, 4) array of segment end points, from None, "plate" or (K, 2, 2)."""
    if walls is None:
        return None
    if isinstance(walls, str):
        if walls != "plate":
            raise ParameterError(f'walls must be None, "plate" or an array (K, 2, 2); got {walls!r}')
        if plate_size is None:
            raise ParameterError('walls="plate" needs plate_size (the side of the square plate, m)')
        h = 0.5 * real("plate_size", plate_size, low=0.0, low_open=True)
        c = [(-h, -h), (h, -h), (h, h), (-h, h)]
        return np.array([[*c[k], *c[(k + 1) % 4]] for k in range(4)], dtype=np.float64)
    w = as_float("walls", walls)
    if w.ndim != 3 or w.shape[1:] != (2, 2) or w.shape[0] == 0:
        raise ShapeError(f"walls must have shape (K, 2, 2) (K segments, two ends each); got {w.shape}")
    return np.ascontiguousarray(w.reshape(-1, 4))


def _positions(name: str, value: Any, *, finite: bool = False) -> np.ndarray:
    """``value`` as an ``(M, 2)`` float64 array of positions (M >= 1), contiguous; finite if
    ``finite`` (else the core checks that every position is finite and names the first part that
    is not)."""
    pos = as_float(name, value, finite=finite)
    if pos.ndim != 2 or pos.shape[1] != 2 or pos.shape[0] == 0:
        allowed = "an (M, 2) array of positions or a list of upm.Point/upm.Disk/upm.Polygon"
        raise ShapeError(f"parts must be {allowed}; got shape {pos.shape}")
    return np.ascontiguousarray(pos)


def _parts(parts: Any) -> tuple[Any, ...]:
    """Positions, velocities (M, 2) and radius, angle, spin (M,) of points, disks and polygons,
    and the polygons as ``[(part, vertices (K, 2), feet (3, 2) or None)]`` (None without any); for an array of
    positions (point parts at rest) the others are None (zero, never built)."""
    if isinstance(parts, np.ndarray):  # (the common small call, first)
        return _positions("parts", parts), None, None, None, None, None
    from .polygon import Polygon

    kinds = (Point, Disk, Polygon)
    if not (isinstance(parts, (list, tuple)) and parts and all(isinstance(p, kinds) for p in parts)):
        return _positions("parts", parts), None, None, None, None, None
    turning = (Disk, Polygon)
    pos = _positions("parts[i].position", [p.position for p in parts], finite=True)
    vel = as_float("parts[i].velocity", [p.velocity for p in parts])
    if vel.shape != pos.shape:
        raise ShapeError(f"part velocities must have shape {pos.shape}; got {vel.shape}")
    radius = as_float("parts[i].radius", [p.radius if isinstance(p, Disk) else 0.0 for p in parts])
    angle = as_float("parts[i].angle", [p.angle if isinstance(p, turning) else 0.0 for p in parts])
    spin = as_float("parts[i].spin", [p.spin if isinstance(p, turning) else 0.0 for p in parts])
    bad = [i for i, p in enumerate(parts) if isinstance(p, Disk) and not p.radius > 0]
    if bad:
        raise ParameterError(f"radius must be > 0 for a Disk; got {parts[bad[0]].radius} for part {bad[0]}")
    polygons = [(i, p.vertices, p.support) for i, p in enumerate(parts) if isinstance(p, Polygon)] or None
    return pos, vel, radius, angle, spin, polygons


def _per_part(name: str, value: ArrayLike, m: int) -> np.ndarray:
    """``value`` as shape ``(M,)``, or ``(1,)`` for one value shared by every part (never
    broadcast into M copies)."""
    a = as_float(name, value)
    if a.ndim > 1 or (a.ndim == 1 and a.size != m):
        raise ShapeError(f"{name} must be a scalar or have shape ({m},); got {a.shape}")
    return np.ascontiguousarray(a.reshape(-1), dtype=np.float64)


#: The most integrator steps one call may take (about ten minutes for one part at 50 ns a step).
MAX_STEPS = 10**10


_inner = attrgetter("_inner")


def _cores(motions: Any) -> list[Any]:
    """The core motions of ``motions`` (a sequence of at least one `upm.PlateMotion`), in one pass
    in C when every item is one (a batch of many worlds paid two: 0.04 µs a world, half of it the
    type check); `ParameterError` naming the first item that is not. A list of the core's own
    motions passes as it is (the environments build a batch's in one call and wrap none)."""
    if type(motions) is list or type(motions) is tuple:
        try:
            cores = list(map(_inner, motions))  # (only a upm.PlateMotion has `_inner`)
        except AttributeError:
            if motions and set(map(type, motions)) == {_core.PlateMotion}:
                return list(motions)
        else:
            if cores:
                return cores
    ms = items("motions", motions, PlateMotion, "a upm.PlateMotion")
    if not ms:
        raise ParameterError("motions must contain at least one upm.PlateMotion")
    return list(map(_inner, ms))


def _run(
    cores: list[Any],
    parts: Any,
    duration: float,
    dt: float,
    mu: ArrayLike,
    mu_s: ArrayLike | None,
    g: float,
    plate_size: float | None,
    record_every: int,
    threads: int | None = None,
    contacts: dict[str, Any] | None = None,
    progress: Callable[[float], object] | None = None,
    worlds: _Worlds | None = None,
    tilt: ArrayLike = (0.0, 0.0),
    friction_map: Any = None,
) -> _core.Run:
    step = real("dt", dt, low=0.0, low_open=True)
    span = real("duration", duration, low=0.0, low_open=True)
    if span < step * (1 - 1e-9):
        raise ParameterError(f"duration must be at least one step dt = {step:g} s; got {span:g}")
    pos, vel, radius, angle, spin, polygons = _parts(parts)
    if contacts:
        sized = np.zeros(pos.shape[0], bool) if radius is None else radius > 0
        for i, *_ in polygons or ():
            sized[i] = True
        if not sized.all():
            first = int(np.flatnonzero(~sized)[0])
            raise ParameterError(
                "contacts=True needs every part to be a upm.Disk or a upm.Polygon (points have no size to "
                f"collide or meet a wall); parts[{first}] is a point: give it a size, or simulate "
                "without contacts"
            )
    steps = math.ceil(span / step - 1e-9)
    if steps > MAX_STEPS:
        raise ParameterError(
            f"duration / dt must be at most {MAX_STEPS:.0e} steps (minutes of work a part); got "
            f"{steps:.3g} ({span:g} s at dt = {step:g} s): raise dt, or run the span in pieces, each "
            "starting from the last one's final state"
        )
    m = pos.shape[0]
    mu_a = _per_part("mu", mu, m)
    mu_s_a = mu_a if mu_s is None else _per_part("mu_s", mu_s, m)
    every = integer("record_every", record_every, low=1, high=2**62)
    _check_memory(len(cores), m, span, step, every)
    report = None
    if progress is not None:
        steps = max(1, math.ceil(span / step - 1e-9))

        def report(done: int) -> None:
            progress(min(1.0, done / steps))

    return _core.simulate(
        cores,
        pos,
        vel,
        mu_a,
        mu_s_a,
        radius,
        angle,
        spin,
        dt=step,
        duration=span,
        **gravity(g, tilt),
        friction_map=friction_grid(friction_map, plate_size),
        plate_size=None if plate_size is None else real("plate_size", plate_size, low=0.0, low_open=True),
        record_every=every,
        threads=pool(threads),
        progress=report,
        world_mu=None if worlds is None else worlds[0],
        world_mu_s=None if worlds is None else worlds[1],
        world_positions=None if worlds is None else worlds[2],
        world_angles=None if worlds is None else worlds[3],
        polygons=polygons,
        **(contacts or {}),
    )


def _contact(
    parts: Any,
    plate_size: float | None,
    contacts: bool,
    restitution: float,
    part_friction: float,
    walls: Any,
    walls_move_with_plate: bool,
    contact_iterations: int,
) -> dict[str, Any]:
    """The extension's contact keyword arguments (none when ``contacts`` is off)."""
    if not isinstance(contacts, (bool, np.bool_)):
        raise ParameterError(f"contacts must be True or False; got {contacts!r}")
    if not contacts:
        if walls is not None:
            raise ParameterError("walls need contacts=True")
        return {}
    return {
        "contacts": True,
        "restitution": real("restitution", restitution),
        "part_friction": real("part_friction", part_friction),
        "walls": _walls(walls, plate_size),
        "walls_move_with_plate": bool(walls_move_with_plate),
        "mass": _masses(parts),
        "contact_iterations": integer("contact_iterations", contact_iterations, low=1, high=1000),
    }


def simulate(
    motion: PlateMotion,
    parts: Any,
    *,
    duration: float,
    dt: float,
    mu: ArrayLike,
    mu_s: ArrayLike | None = None,
    g: float = 9.81,
    plate_size: float | None = None,
    record_every: int = 1,
    contacts: bool = False,
    restitution: float = 0.5,
    part_friction: float = 0.3,
    walls: ArrayLike | str | None = None,
    walls_move_with_plate: bool = False,
    contact_iterations: int = 4,
    threads: int | None = None,
    progress: Callable[[float], object] | None = None,
    tilt: ArrayLike = (0.0, 0.0),
    friction_map: Any = None,
) -> SimResult:
    """Simulate parts sliding (points) or sliding and spinning (disks, polygons) on the plate under
    ``motion``.

    Each step is the exact implicit Coulomb step of docs/spec.md §1: a part sticks when the force needed
    to keep it with the plate is within ``mu_s m g``, otherwise it slides at ``mu m g``; no
    regularisation, so parts on a still plate stop and never creep. A disk's or a polygon's force and
    torque are integrated over its footprint under uniform pressure and its translation and spin
    stick or slide together (a polygon sticks exactly when the wrench that keeps it with the plate
    lies in its limit set: docs/polygons.md). A polygon's recorded position is its frame's origin
    (with ``angles``, the pose: ``Polygon(vertices, position, angle)`` redraws it), its velocity
    its centroid's. On a plate that moves out of its plane the normal force at a polygon's centroid
    scales its friction, its pressure varies across the footprint as ``g + a_z`` does (a disk's
    stays uniform), and it flies while that force is negative.

    Parameters
    ----------
    motion : PlateMotion
    parts : array_like of shape (M, 2), or list of upm.Point, upm.Disk and upm.Polygon
        Positions [m] of point parts at rest, or points, disks and polygons with their state.
    duration : float
        Simulated time [s]; the run takes ``ceil(duration / dt)`` steps.
    dt : float
        Time step [s]; at most ``1 / (20 motion.max_frequency)``.
    mu, mu_s : float or array_like of shape (M,)
        Sliding and static friction coefficients; ``mu_s >= mu`` (default ``mu``).
    g : float
        Gravity [m/s^2].
    tilt : (float, float)
        The plate's slope [rad] along x and along y (a plate that is not level; at most 0.5 rad
        each): it rises toward +x by ``tilt[0]`` and toward +y by ``tilt[1]``, so gravity pulls
        every part by ``-g sin tilt`` in the plate's plane, and presses it by ``g sqrt(1 -
        sin² tilt[0] - sin² tilt[1])``. 0.5° pulls 86 mm/s² downhill. Planar motions only.
    friction_map : array_like of shape (ny, nx), or callable, optional
        The plate's friction over its surface, as a factor on every part's ``mu`` and ``mu_s``
        where it is: a grid over the plate of side ``plate_size`` (row 0 along its lower edge),
        or ``f(x, y) -> factor`` (:func:`upm.physics.surface.friction_grid`).
    plate_size : float, optional
        Side of the square plate centred at the origin [m]; parts whose centre leaves it are
        flagged in ``left_plate`` and frozen.
    record_every : int
        Record every this many steps (and the last step); memory is about ``steps / record_every + 2``
        rows, whatever the number of steps.
    contacts : bool
        Resolve disk–disk and disk–wall contacts with the rapier2d physics engine after every
        friction step (``docs/simulation.md``, "Contacts"). Every part must be a `upm.Disk` or a
        `upm.Polygon` (a point has no extent to collide or meet a wall) and parts must not overlap
        at the start.
        With ``False`` parts pass through each other.
    restitution : float
        Coefficient of restitution of every contact, in ``[0, 1]``.
    part_friction : float
        Coulomb friction coefficient between parts and between a part and a wall, ``>= 0``.
    walls : array_like of shape (K, 2, 2), or "plate", optional
        Fences as segments ``[[x0, y0], [x1, y1]]`` [m]; ``"plate"``: the four edges of the square
        plate of side ``plate_size``. Without walls the plate edge is no wall: parts fall off it.
    walls_move_with_plate : bool
        Walls fixed to the plate (they vibrate with it) instead of to the frame.
    contact_iterations : int
        rapier solver iterations per step.
    threads : int, optional
        Run on a pool of this many threads (default: one per core, or ``RAYON_NUM_THREADS``);
        ``1`` runs on the calling thread alone, with no pool to hand the work to.
    progress : callable, optional
        Called with the fraction of the run done (0 to 1) at most about every 0.17 s of one
        core's work, on the thread running the simulation; an exception it raises stops the run
        and is raised here (as Ctrl-C is).

    Returns
    -------
    SimResult
    """
    if not isinstance(motion, PlateMotion):
        raise ParameterError(f"motion must be a upm.PlateMotion; got {type(motion).__name__}")
    contact = _contact(parts, plate_size, contacts, restitution, part_friction, walls, walls_move_with_plate,
                       contact_iterations)  # fmt: skip
    r = _run(
        [motion._inner], parts, duration, dt, mu, mu_s, g, plate_size, record_every, threads, contact,
        _progress(progress), tilt=tilt, friction_map=friction_map,
    )  # fmt: skip
    return SimResult(r.t, r.positions[0], r.velocities[0], r.stuck[0], r.angles[0], r.spins[0],
                     r.left_plate[0], r.left_time[0], r.flight[0])  # fmt: skip


def simulate_batch(
    motions: Sequence[PlateMotion],
    parts: Any,
    *,
    duration: float,
    dt: float,
    mu: ArrayLike,
    mu_s: ArrayLike | None = None,
    g: float = 9.81,
    plate_size: float | None = None,
    record_every: int = 1,
    threads: int | None = None,
    contacts: bool = False,
    restitution: float = 0.5,
    part_friction: float = 0.3,
    walls: ArrayLike | str | None = None,
    walls_move_with_plate: bool = False,
    contact_iterations: int = 4,
    progress: Callable[[float], object] | None = None,
    starts: ArrayLike | None = None,
    tilt: ArrayLike = (0.0, 0.0),
    friction_map: Any = None,
) -> SimResult:
    """:func:`simulate` for ``B`` independent worlds (one motion each, the same parts), in parallel.

    Every array of the result but ``t`` gains a leading axis ``B``. Results are bitwise identical
    to ``B`` separate calls and to any thread count. ``threads``: run on a pool of that many
    threads (default: rayon's global pool, one thread per core; ``1``: the calling thread alone);
    :func:`upm.sweep` runs each chunk on one and parallelises over chunks (``RAYON_NUM_THREADS``
    sets the global pool's size). The contact, ``progress``, ``tilt`` and ``friction_map`` arguments are
    :func:`simulate`'s.

    ``mu`` and ``mu_s`` may differ from world to world (a friction sweep): shape ``(B, M)``, or
    ``(B, 1)`` for one value per world; all the worlds still run in one parallel call.

    ``starts (B, M, 2)`` [m]: each world starts its parts there instead of at ``parts``' positions
    (a vector of environments, each with its own layout; ``parts`` still gives their kinds, sizes
    and velocities); ``(B, M, 3)``: and at these angles [rad] (polygons' poses: each frame's origin
    and angle, as :meth:`upm.Polygon.moved` takes them).
    """
    cores = _cores(motions)
    contact = _contact(parts, plate_size, contacts, restitution, part_friction, walls, walls_move_with_plate,
                       contact_iterations)  # fmt: skip
    worlds = _per_world(len(cores), parts, mu, mu_s, starts)
    if worlds is not None:  # every world in the same parallel run, each with its own rows
        mu, mu_s = worlds[0][0], worlds[1][0]
    r = _run(
        cores, parts, duration, dt, mu, mu_s, g, plate_size, record_every, threads, contact,
        _progress(progress), worlds=worlds, tilt=tilt, friction_map=friction_map,
    )  # fmt: skip
    return SimResult(r.t, r.positions, r.velocities, r.stuck, r.angles, r.spins, r.left_plate, r.left_time,
                     r.flight)  # fmt: skip


def _progress(progress: Any) -> Callable[[float], object] | None:
    if progress is not None and not callable(progress):
        raise ParameterError(
            f"progress must be a callable taking the fraction done, or None; got {progress!r}"
        )
    return progress  # type: ignore[no-any-return]


def _per_world(
    b: int, parts: Any, mu: ArrayLike, mu_s: ArrayLike | None, starts: ArrayLike | None
) -> _Worlds | None:
    """What differs from world to world, as the core reads it: ``(mu, mu_s)`` as ``(B, M)`` for
    ``b`` worlds and the ``starts`` as ``(B M, 2)`` (or None), when either friction is given per
    world (shape ``(B, M)`` or ``(B, 1)``) or ``starts`` is, with the start angles ``(B M,)`` when
    ``starts`` holds them; None when the worlds share it all."""
    mu_a = as_float("mu", mu)
    mu_s_a = None if mu_s is None else as_float("mu_s", mu_s)
    if starts is None and mu_a.ndim < 2 and (mu_s_a is None or mu_s_a.ndim < 2):
        return None
    m = _parts(parts)[0].shape[0]

    def worlds(name: str, a: NDArray[np.float64]) -> NDArray[np.float64]:
        if a.ndim < 2:
            return np.broadcast_to(_per_part(name, a, m), (b, m))
        if a.ndim != 2 or a.shape[0] != b or a.shape[1] not in (1, m):
            raise ShapeError(f"{name} per world must have shape ({b}, {m}) or ({b}, 1); got {a.shape}")
        return np.broadcast_to(a, (b, m))

    kinetic = worlds("mu", mu_a)
    static = kinetic if mu_s_a is None else worlds("mu_s", mu_s_a)
    at = turn = None
    if starts is not None:
        at = as_float("starts", starts)
        if at.shape not in ((b, m, 2), (b, m, 3)):
            raise ShapeError(
                f"starts must have shape ({b}, {m}, 2) (world, part, xy) or ({b}, {m}, 3) (and the "
                f"angle); got {at.shape}"
            )
        turn = np.ascontiguousarray(at[..., 2].reshape(-1)) if at.shape[-1] > 2 else None
        at = np.ascontiguousarray(at[..., :2].reshape(-1, 2))  # (B M, 2)
    return np.ascontiguousarray(kinetic), np.ascontiguousarray(static), at, turn
