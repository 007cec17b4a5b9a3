"""Candidate pulses for the predictive planner, each at the largest amplitude the drive allows.

Families (all enveloped, 3 drive periods of attack and decay; jets 4 and fine jets 6, for their
2/3 harmonic):

* **translations** along ``directions`` evenly spread directions: the Coulomb pump (chapter 3),
  ``v (cos wt - cos(2wt)/2)``, the same force on every part;
* **rotations** about a grid of centres and about each part, both senses: the time-asymmetric
  rotation of 5.1.2 (every resting part the same tangential force);
* **jets** (6.4) focused on each part, in several directions and radii;
* **aligned rotations** about centres that serve the task best by a quick model
  (:func:`aligned_centers`): one pulse that moves many parts toward their goals at once.

Every family is built for each drive frequency and on-time. A pulse's motor forces and its
plate excursion are linear in its amplitude, so each candidate is sized once at unit amplitude by
:meth:`upm.drive.DriveLimits.reach` (one vectorised call) and scaled to ``use`` times the smaller of
the force and the stroke headroom. Higher frequencies need less stroke for the same plate velocity
and more motor force; the limits decide which wins for each shape.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..physics.waveforms import Harmonics
from ..plate.drive import DriveLimits
from ..plate.pulses import Pulse

__all__ = ["Candidates", "aligned_centers", "generate", "narrow_radii"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Candidates:
    """``K`` pulses and what the planner needs of them."""

    pulses: list[Pulse]
    family: NDArray[np.str_]
    """``"translation"``, ``"rotation"``, ``"part-rotation"``, ``"aligned-rotation"``, ``"jet"`` or
    ``"fine-jet"`` per pulse."""
    force: FloatArray
    """Peak motor force of each pulse as sized [N]."""
    excursion: FloatArray
    """Largest plate-corner excursion of each pulse as sized, played from home [m]."""

    def __len__(self) -> int:
        return len(self.pulses)

    def __add__(self, other: Candidates) -> Candidates:
        return Candidates(
            self.pulses + other.pulses,
            np.concatenate([self.family, other.family]),
            np.concatenate([self.force, other.force]),
            np.concatenate([self.excursion, other.excursion]),
        )


def _unit_phasors(kind: str, center: FloatArray, direction: FloatArray, rho: float) -> NDArray[np.complex128]:
    """Velocity phasors (harmonics 1, 2, 2/3; axes u1, u2, u3) at unit amplitude, as
    :meth:`upm.Pulse.phasors` gives them: rotations and translations ``cos wt - cos(2wt)/2``."""
    out = np.zeros((3, 3), complex)
    if kind == "jet":
        out[0, :2] = direction
        out[1, :2] = -direction
        rate = -2j / rho
        out[2] = [rate * center[1], -rate * center[0], rate]
        return out
    for j, c in enumerate((1.0, -0.5)):
        if kind == "translation":
            out[j, :2] = c * direction
        else:
            out[j] = [c * center[1], -c * center[0], c]
    return out


def aligned_centers(
    cost: Callable[[FloatArray], ArrayLike],
    positions: FloatArray,
    size: float,
    *,
    count: int = 8,
    step: float = 0.015,
    core: float = 0.02,
    spacing: float = 0.03,
    points: int = 37,
) -> tuple[FloatArray, FloatArray]:
    """Centres and senses (``+1`` counter-clockwise) of the ``count`` rotations that lower
    ``cost`` most by a quick model, at least ``spacing`` [m] apart, ``(n, 2)`` and ``(n,)``.

    The model: a time-asymmetric rotation about ``C`` pushes every resting part along its tangent
    about ``C`` alike (5.1.2), so it moves a part at ``P`` by ``step`` [m] along
    ``R90 (P - C) / |P - C|``, scaled down within ``core`` [m] of ``C`` (the plate barely moves
    there). Every centre of a ``points x points`` lattice over 1.8 plate sides (``size`` [m];
    centres off the plate give nearly parallel fields), both senses, is scored by ``cost`` of the
    layouts it would leave, ``cost((K, M, 2)) -> (K,)``; only centres that lower it are kept. The
    candidates built about them are then predicted exactly, like every other."""
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    lattice = np.linspace(-0.9 * size, 0.9 * size, points)
    centres = np.stack(np.meshgrid(lattice, lattice, indexing="ij"), axis=-1).reshape(-1, 2)
    rel = pos[None] - centres[:, None]  # (G, M, 2)
    r = np.hypot(rel[..., 0], rel[..., 1])
    tangent = np.stack([-rel[..., 1], rel[..., 0]], axis=-1) / np.maximum(r, 1e-12)[..., None]
    moved = step * np.minimum(1.0, r / core)[..., None] * tangent
    layouts = np.concatenate([pos[None] + moved, pos[None] - moved])
    now = float(np.asarray(cost(pos[None]), dtype=float).reshape(-1)[0])
    gain = now - np.asarray(cost(layouts), dtype=float).reshape(-1)
    picked: list[int] = []
    for k in np.argsort(-np.where(np.isfinite(gain), gain, -np.inf), kind="stable"):
        if len(picked) >= count or not gain[k] > 0:
            break
        c = centres[k % len(centres)]
        if all(np.hypot(*(c - centres[j % len(centres)])) >= spacing for j in picked):
            picked.append(int(k))
    at = np.array(picked, dtype=np.int64)
    return centres[at % len(centres)].reshape(-1, 2), np.where(at < len(centres), 1.0, -1.0)


def narrow_radii(near: FloatArray, crowd: FloatArray, part_radius: float, widest: float) -> FloatArray:
    """A jet radius [m] for each part at ``near (n, 2)`` packed among the parts ``crowd (M, 2)``:
    its nearest neighbour's distance (at least two part radii, to 2 mm), or NaN where that is
    ``widest`` or more. A jet's force falls from a third of ``mu m g`` at its focus to a slight
    reverse at ``rho`` (6.4, the SPEC's known answers), so at this radius it moves its part while
    the neighbour holds or eases back: the fine placing of a shape whose points are 14 mm apart,
    where a 40 mm jet moves the neighbours nearly as far as the part (shape8 stalled 5-12 mm out)."""
    near = np.asarray(near, dtype=np.float64).reshape(-1, 2)
    crowd = np.asarray(crowd, dtype=np.float64).reshape(-1, 2)
    crowd = crowd[np.all(np.isfinite(crowd), axis=1)]
    out = np.full(len(near), np.nan)
    if not len(near) or len(crowd) < 2:
        return out
    d = np.hypot(near[:, None, 0] - crowd[None, :, 0], near[:, None, 1] - crowd[None, :, 1])
    d[d < 1e-9] = np.inf  # the part itself
    rho = np.round(np.maximum(d.min(axis=1), 2 * part_radius) / 0.002) * 0.002
    return np.where(rho < widest, rho, np.nan)


#: The spelling of earlier releases (upm now spells ``centers`` throughout): the same function.
aligned_centres = aligned_centers


def generate(
    limits: DriveLimits,
    positions: FloatArray,
    *,
    frequencies: tuple[float, ...] = (25.0, 35.0, 50.0),
    on_times: tuple[float, ...] = (0.3, 0.55, 0.9),
    directions: int = 8,
    grid: int = 5,
    jet_radii: tuple[float, ...] = (0.03, 0.06),
    jet_directions: int = 8,
    use: float = 0.9,
    cache: dict[tuple[object, ...], tuple[float, float]] | None = None,
    carried: float = 0.0,
    jet_toward: FloatArray | None = None,
    pulse_cache: dict[tuple[object, ...], Pulse] | None = None,
    fine: tuple[float, ...] = (0.12, 0.35),
    jet_on_times: tuple[float, ...] | None = None,
    rotation_on_times: tuple[float, ...] | None = None,
    aligned: tuple[FloatArray, FloatArray] | None = None,
    aligned_on_times: tuple[float, ...] = (0.2, 0.4),
    narrow: FloatArray | None = None,
) -> Candidates:
    """Candidate pulses for parts at ``positions (M, 2)`` [m], sized within ``limits``.

    ``grid``: rotation centres on a ``grid x grid`` lattice over the middle half of the plate and
    on its middle lines (0: none);
    ``use``: the fraction of the force and stroke headroom a pulse may use (the rest is margin for
    what the plate carries over from the pulse before). ``cache`` keeps the unit-amplitude reach
    of shapes that do not depend on the parts (translations, grid rotations) across calls.
    ``pulse_cache`` keeps the pulses of those shapes by amplitude. ``fine``: fractions of the
    largest amplitude for short jets along ``jet_toward`` (the last millimetres of a step).
    ``jet_toward (M, 2)``: where each part should go (a direction; zero: no jet at that part);
    jets then feed along it and 35 degrees to either side instead of ``jet_directions`` evenly
    spread directions. ``jet_on_times``, ``rotation_on_times``: on-times of the jets and of the
    rotations about the grid (default the middle of ``on_times``, and ``on_times``).
    ``carried`` [m]: the largest corner excursion the plate's motion left from earlier pulses
    may still add; the stroke left for the candidate is ``stroke - carried``. ``aligned``: centres
    ``(n, 2)`` and senses ``(n,)`` of rotations to add at ``aligned_on_times`` (as
    :func:`aligned_centers` gives them). ``narrow (M,)``: a jet radius [m] for each part (NaN:
    none) added to ``jet_radii`` at that part and used for its detour and fine jets (a part
    packed among neighbours: :func:`narrow_radii`). Each shape is
    played at the one of ``frequencies`` that gives it the largest amplitude within the limits
    (rotations and jets: stroke-bound at low frequencies, force-bound at high ones).
    """
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    specs: list[tuple[str, str, FloatArray, FloatArray, float, float, float]] = []
    angles = 2 * np.pi * np.arange(directions) / directions
    half = limits.size / 4
    if grid > 0:
        lattice = np.linspace(-half, half, grid) if grid > 1 else np.zeros(1)
        centres = np.array([(x, y) for x in lattice for y in lattice])
        # and on the plate's two middle lines, out past its edges: a rotation about (0, c) pushes
        # the parts above c one way along x and the parts below it the other (likewise along y)
        line = np.linspace(-0.75 * limits.size, 0.75 * limits.size, 13)
        line = line[np.abs(line) > half + 1e-9]
        centres = np.vstack(
            [centres, np.stack([np.zeros_like(line), line], 1), np.stack([line, np.zeros_like(line)], 1)]
        )
    else:
        centres = np.zeros((0, 2))
    zero = np.zeros(2)
    shape: list[int] = []  # which shape each spec plays (one frequency of it is kept)
    n_shapes = 0

    fraction: list[float] = []  # of the largest amplitude the drive allows
    fixed: list[bool] = []  # shapes that do not follow the parts
    keys: list[tuple[object, ...]] = []  # each spec's key in ``cache``
    sized_at: list[FloatArray] = []  # where each spec is sized

    def add(
        kind: str,
        family: str,
        c: FloatArray,
        d: FloatArray,
        rho: float,
        on: float,
        freqs: tuple[float, ...],
        part: float = 1.0,
    ) -> None:
        nonlocal n_shapes
        # shapes at a part are sized at its position rounded to 5 mm (their reach changes by well
        # under 2 % over that), so they too are mostly found in the cache from cycle to cycle;
        # shapes that do not follow the parts (aligned centres lie on a fixed lattice) exactly
        cx, cy = float(c[0]), float(c[1])
        fix = family in ("translation", "rotation", "aligned-rotation")
        at = (round(cx, 9), round(cy, 9)) if fix else (round(cx / 0.005) * 0.005, round(cy / 0.005) * 0.005)
        where = np.array(at)
        prefix = (kind, *at, round(float(d[0]), 9), round(float(d[1]), 9), rho)
        for f in freqs:
            specs.append((kind, family, c, d, rho, f, on))
            shape.append(n_shapes)
            fraction.append(part)
            fixed.append(fix)
            keys.append((*prefix, f, on))
            sized_at.append(where)
        n_shapes += 1

    for on in on_times:
        for a in angles:
            add("translation", "translation", zero, np.array([np.cos(a), np.sin(a)]), 0.0, on, frequencies)
    for on in on_times if rotation_on_times is None else rotation_on_times:
        for c in centres:
            for sign in (1.0, -1.0):
                add("rotation", "rotation", c, np.array([sign, 0.0]), 0.0, on, frequencies)
    on_part = on_times[len(on_times) // 2]
    jet_angles = 2 * np.pi * np.arange(jet_directions) / jet_directions
    for i, p in enumerate(pos):
        radii = jet_radii
        if narrow is not None and math.isfinite(float(narrow[i])):
            radii = (float(narrow[i]), *jet_radii)
        for sign in (1.0, -1.0):
            add("rotation", "part-rotation", p, np.array([sign, 0.0]), 0.0, on_part, frequencies)
        if jet_toward is None:
            ways = [np.array([np.cos(a), np.sin(a)]) for a in jet_angles]
        else:
            g = np.asarray(jet_toward[i], dtype=float)
            n = float(np.hypot(*g))
            base = np.arctan2(g[1], g[0])
            ways = (
                []
                if not n > 0
                else [np.array([np.cos(base + b), np.sin(base + b)]) for b in (0.0, -0.61, 0.61)]
            )
        for on in (on_part,) if jet_on_times is None else jet_on_times:
            for rho in radii:
                for d in ways:
                    add("jet", "jet", p, d, rho, on, frequencies)
        short = min(jet_on_times or (on_part,))
        if jet_toward is not None and ways:
            # and short, narrow jets 70 degrees either side: a detour round a part in the way
            # (a part's goal behind a neighbour already at its own)
            for b in (-1.22, 1.22):
                d = np.array([np.cos(base + b), np.sin(base + b)])
                add("jet", "jet", p, d, radii[0], short, frequencies)
        # and gentle short jets for the last millimetres: a part's speed saturates at a velocity
        # proportional to the amplitude, so a weaker jet moves it less
        for part in fine:
            for d in ways:
                add("jet", "fine-jet", p, d, radii[0], short, frequencies[-1:], part)
    if aligned is not None:
        for c, sense in zip(np.asarray(aligned[0], float).reshape(-1, 2), aligned[1], strict=True):
            for on in aligned_on_times:
                add("rotation", "aligned-rotation", c, np.array([float(sense), 0.0]), 0.0, on, frequencies)
    k = len(specs)
    # drive periods of attack (and decay): 3 for translations and rotations; jets 4, long enough
    # for their 2/3 harmonic to ramp without much drift and short enough to leave a 0.35 s jet
    # most of its time at full amplitude (bowtie: 62.5 -> 57.8 s a loop); the gentle fine jets,
    # which place a part to the millimetre, keep 6 (less drift for the planner to predict)
    attack = np.array(
        [((6.0 if s[1] == "fine-jet" else 4.0) if s[0] == "jet" else 3.0) / s[5] for s in specs]
    )
    freq = np.array([s[5] for s in specs])
    on_arr = np.array([s[6] for s in specs])
    attack = np.minimum(attack, on_arr / 2)
    sustain = on_arr - 2 * attack
    force = np.full(k, np.nan)
    reach = np.full(k, np.nan)
    if cache is not None:
        for i, key in enumerate(keys):
            hit = cache.get(key)
            if hit is not None:
                force[i], reach[i] = hit
    todo = np.nonzero(np.isnan(force))[0]
    if len(todo):
        ph = np.stack([_unit_phasors(specs[i][0], sized_at[i], specs[i][3], specs[i][4]) for i in todo])
        fo, ex = limits.reach(ph, freq[todo], attack[todo], sustain[todo], attack[todo], samples=1536)
        force[todo], reach[todo] = fo, ex
        if cache is not None:
            for j in todo:
                cache[keys[int(j)]] = (float(force[j]), float(reach[j]))
    # the stroke left, down to a quarter millimetre: amplitudes then repeat from cycle to cycle
    # and the fixed shapes' pulses are found in ``pulse_cache``
    room = math.floor(max(limits.stroke - carried, 0.0) / 2.5e-4) * 2.5e-4
    scale = use * np.minimum(limits.force / np.maximum(force, 1e-300), room / np.maximum(reach, 1e-300))
    scale = scale * np.array(fraction)
    # per shape, the frequency with the largest amplitude (ties: the higher frequency)
    shape_a = np.array(shape)
    keep = np.zeros(len(specs), dtype=bool)
    # sorted by shape, then largest first (a stable sort: the first of equals, as argmax takes)
    order = np.lexsort((-(scale * (1 + 1e-9 * freq)), shape_a))
    first = np.r_[True, shape_a[order][1:] != shape_a[order][:-1]] if len(order) else order
    keep[order[first]] = True
    pulses: list[Pulse] = []
    for i, (kind, _, c, d, rho, f, _t) in enumerate(specs):
        if not keep[i]:
            continue
        a, s = float(attack[i]), float(sustain[i])
        amp = float(scale[i])
        if fixed[i] and pulse_cache is not None and (keys[i], amp) in pulse_cache:
            pulses.append(pulse_cache[(keys[i], amp)])
            continue
        if kind == "translation":
            pulses.append(Pulse.translation(d, Harmonics([amp, -amp / 2], [0.0, 0.0], f), a, s, a))
        elif kind == "rotation":
            w = amp * float(d[0])  # d[0] carries the sense of rotation
            pulses.append(Pulse.rotation(c, Harmonics([w, -w / 2], [0.0, 0.0], f), a, s, a))
        else:
            pulses.append(Pulse.jet(c, d, rho, amp, f, a, s, a))
        if fixed[i] and pulse_cache is not None:
            if len(pulse_cache) > 20000:
                pulse_cache.clear()
            pulse_cache[(keys[i], amp)] = pulses[-1]
    return Candidates(
        pulses,
        np.array([s[1] for s, k in zip(specs, keep, strict=True) if k]),
        (force * scale)[keep],
        (reach * scale)[keep],
    )
