"""Sensorless orienting in a squeeze field: the turn function and its stable roots against a
brute-force grid over the footprint written here, and the rod-like result for a rectangle; in a
radial field with a bias: the unique pose against a brute-force minimum of the field's potential
over a grid of cells."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize

import upm
from footprint import cells
from upm.physics.orienting import RadialField, SqueezeField, orientation_equilibria

PENTAGON = np.array([[0.0, 0.0], [0.030, -0.004], [0.041, 0.016], [0.022, 0.031], [-0.006, 0.019]])


def turned_cells(part: upm.Polygon, theta: float, h: float) -> np.ndarray:
    """:func:`cells` of side ``h`` turned by ``theta``, about their own centroid."""
    c, s = math.cos(theta), math.sin(theta)
    p = cells(part, h) @ np.array([[c, s], [-s, c]])
    return p - p.mean(axis=0)


def brute_turn(part: upm.Polygon, theta: float, line: float, h: float = 4e-5) -> tuple[float, float]:
    """The moment per mu N at force balance, and the centroid's distance from the line (to its
    right), from a grid of cells over the footprint: the line (direction ``line``) through the
    cells' median across it, each cell pushed towards it."""
    v = upm.Polygon(part.vertices, (0.0, 0.0), theta).outline()
    v = v - v.mean(axis=0)
    lo, hi = v.min(axis=0), v.max(axis=0)
    x, y = np.meshgrid(np.arange(lo[0], hi[0], h) + h / 2, np.arange(lo[1], hi[1], h) + h / 2)
    inside = np.ones_like(x, bool)
    for a, b in zip(v, np.roll(v, -1, axis=0), strict=True):
        inside &= (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]) >= 0
    p = np.stack([x[inside], y[inside]], axis=1)
    p -= p.mean(axis=0)  # about the (grid) centroid
    n = np.array([math.sin(line), -math.cos(line)])  # across the line
    across = p @ n
    side = np.where(across < np.median(across), 1.0, -1.0)  # pushed towards the median line
    force = side[:, None] * n
    return float(np.mean(p[:, 0] * force[:, 1] - p[:, 1] * force[:, 0])), -float(np.median(across))


def test_a_rectangle_lies_along_the_line_and_a_square_across_its_diagonal():
    for line in (0.0, 0.7):
        rect = orientation_equilibria(upm.Polygon.rectangle(0.04, 0.02), SqueezeField(angle=line))
        assert rect.period == pytest.approx(math.pi)
        assert np.allclose(rect.stable, [np.mod(line, math.pi)], atol=1e-10)  # long axis along the line
        assert np.allclose(rect.unstable, [np.mod(line + math.pi / 2, math.pi)], atol=1e-10)
    square = orientation_equilibria(upm.Polygon.rectangle(0.02, 0.02), SqueezeField())
    assert square.period == pytest.approx(math.pi / 2)
    assert np.allclose(square.stable, [math.pi / 4]) and np.allclose(square.unstable, [0.0])
    tri = orientation_equilibria(upm.Polygon.regular(3, 0.015), SqueezeField())
    assert tri.period == pytest.approx(math.pi / 3) and len(tri.stable) == len(tri.unstable) == 1


@pytest.mark.parametrize("line", [0.0, 1.1])
def test_the_turn_function_matches_a_brute_force_grid(line):
    part = upm.Polygon(PENTAGON)
    eq = orientation_equilibria(part, SqueezeField(point=(0.01, -0.02), angle=line), samples=180)
    scale = np.abs(eq.turn[:, 1]).max()
    for theta, m in eq.turn[::30]:
        assert m == pytest.approx(brute_turn(part, theta, line)[0], abs=2e-3 * scale)
    # the irregular pentagon has one stable orientation a half turn
    assert len(eq.stable) == 1 and len(eq.unstable) == 1
    at, offset = brute_turn(part, eq.stable[0], line)
    assert abs(at) < 3e-3 * scale
    assert brute_turn(part, eq.stable[0] - 0.05, line)[0] > 0 > brute_turn(part, eq.stable[0] + 0.05, line)[0]
    # at rest the line bisects it, off its centroid; the frame's origin goes with the angle
    assert eq.offsets[0] == pytest.approx(offset, abs=1e-4) and abs(offset) > 1e-4
    c, s = math.cos(eq.stable[0]), math.sin(eq.stable[0])
    centroid = eq.positions[0] + np.array([[c, -s], [s, c]]) @ part.centroid
    right = np.array([math.sin(line), -math.cos(line)])
    assert (centroid - (0.01, -0.02)) @ right == pytest.approx(eq.offsets[0], abs=1e-15)


def test_bad_input():
    with pytest.raises(upm.ParameterError, match="point"):
        SqueezeField(point=(0.0, np.nan))
    with pytest.raises(upm.ParameterError, match=r"part must be a upm\.Polygon"):
        orientation_equilibria(np.zeros((3, 2)), SqueezeField())
    with pytest.raises(upm.ParameterError, match=r"field must be a upm\.SqueezeField or a upm\.RadialField"):
        orientation_equilibria(upm.Polygon.regular(4, 0.01), "squeeze")
    with pytest.raises(upm.ParameterError, match=r"bias must have a length in \(0, 1\).*got 0"):
        RadialField(bias=(0.0, 0.0))
    with pytest.raises(upm.ParameterError, match=r"bias must have a length in \(0, 1\).*got 1.2"):
        RadialField(bias=(1.2, 0.0))
    with pytest.raises(upm.ParameterError, match="center must be finite"):
        RadialField(center=(np.inf, 0.0))


def brute_potential(
    r: np.ndarray, theta: float, center: np.ndarray, bias: np.ndarray
) -> tuple[float, np.ndarray]:
    """The least potential of the pose at angle ``theta`` over the centroid's position, and that
    position: the field (unit pull towards ``center`` plus ``bias``) is minus the gradient of
    ``|x - center| - bias . x``, summed over the cells ``r``."""
    c, s = math.cos(theta), math.sin(theta)
    turned = r @ np.array([[c, s], [-s, c]])

    def energy(g: np.ndarray) -> float:
        return float(np.mean(np.hypot(*(turned + g - center).T)) - bias @ g)

    best = minimize(energy, center, method="Nelder-Mead", options=dict(xatol=1e-10, fatol=1e-15))
    return float(best.fun), best.x


@pytest.mark.parametrize(
    ("vertices", "bias", "poses"),
    [
        ([(0.0, 0.0), (0.03, 0.0), (0.0, 0.015)], (0.1, 0.0), 1),
        ([(0.0, 0.0), (0.04, 0.0), (0.03, 0.02), (0.006, 0.02)], (-0.03, 0.04), 1),
        # its centroid is 0.07 mm from the point it pivots about: a stronger bias finds a second pose
        (PENTAGON, (0.05, -0.12), 2),
    ],
    ids=["right triangle", "trapezoid", "pentagon, strong bias"],
)
def test_a_biased_radial_field_brings_a_part_to_the_least_potential(vertices, bias, poses):
    part = upm.Polygon(np.asarray(vertices))
    center, u = np.array([0.01, -0.02]), np.asarray(bias)
    eq = orientation_equilibria(part, RadialField(center=tuple(center), bias=bias), samples=120)
    assert len(eq.stable) == len(eq.unstable) == poses and eq.period == pytest.approx(2 * math.pi)
    r = cells(part)
    # the potential, least over position, over a sweep of angles: its global minimum is at one
    # of the predicted poses, and each pose is a local minimum (0.25 degree steps about it)
    sweep = np.radians(np.arange(0, 360, 6))
    coarse = sweep[np.argmin([brute_potential(r, t, center, u)[0] for t in sweep])]

    def gap(a: float, b: float) -> float:
        return abs(math.degrees((a - b + math.pi) % (2 * math.pi) - math.pi))

    assert min(gap(coarse, t) for t in eq.stable) < 6
    for j, theta in enumerate(eq.stable):
        fine = theta + np.radians(np.arange(-3, 3.01, 0.25))
        least = fine[np.argmin([brute_potential(r, t, center, u)[0] for t in fine])]
        # (within 1 degree: the grid's 0.25 mm cells are coarse against the pentagon's 0.07 mm
        # between centroid and pivot, which sets its pose)
        assert gap(least, theta) < 1.0
        # the part rests there: its centroid where the grid's balance puts it, downstream of
        # the centre along the bias
        c, s = math.cos(theta), math.sin(theta)
        centroid = eq.positions[j] + np.array([[c, -s], [s, c]]) @ part.centroid
        at = brute_potential(r, theta, center, u)[1]
        assert np.hypot(*(centroid - at)) < 2e-4
        assert eq.offsets[j] == pytest.approx(np.hypot(*(centroid - center)), abs=1e-12)
    if poses == 1:
        theta = eq.stable[0]
        c, s = math.cos(theta), math.sin(theta)
        centroid = eq.positions[0] + np.array([[c, -s], [s, c]]) @ part.centroid
        assert (centroid - center) @ u > 0


def brute_linear_turn(part: upm.Polygon, theta: float, line: float, h: float = 4e-5) -> float:
    """The moment per mu N about the centroid in a linear squeeze field of unit gradient, from a
    grid of cells over the footprint: each cell pushed towards the line through the centroid in
    proportion to its distance from it."""
    p = turned_cells(part, theta, h)
    n = np.array([math.sin(line), -math.cos(line)])
    force = -(p @ n)[:, None] * n
    return float(np.mean(p[:, 0] * force[:, 1] - p[:, 1] * force[:, 0]))


@pytest.mark.parametrize("vertices", [PENTAGON, [[0.0, 0.0], [0.03, 0.0], [0.0, 0.015]]])
def test_the_linear_squeeze_turn_function_matches_a_brute_force_grid(vertices):
    part = upm.Polygon(vertices)
    eq = orientation_equilibria(part, SqueezeField(angle=0.4, profile="linear"), samples=90)
    scale = np.max(np.abs(eq.turn[:, 1]))
    for theta, m in eq.turn[::9]:
        assert abs(m - brute_linear_turn(part, theta, 0.4)) < 2e-3 * scale
    # one stable and one unstable orientation a half turn, a quarter turn apart
    assert len(eq.stable) == 1 and len(eq.unstable) == 1
    assert abs((eq.stable[0] - eq.unstable[0]) % math.pi - math.pi / 2) < 1e-9
    assert eq.offsets[0] == 0.0


def test_a_linear_squeeze_lays_a_rectangle_along_the_line_and_leaves_a_square_neutral():
    rect = upm.Polygon.rectangle(0.04, 0.02)
    eq = orientation_equilibria(rect, SqueezeField(angle=0.3, profile="linear"))
    np.testing.assert_allclose(eq.stable, [0.3], atol=1e-9)
    np.testing.assert_allclose(eq.unstable, [0.3 + math.pi / 2], atol=1e-9)
    square = orientation_equilibria(upm.Polygon.rectangle(0.02, 0.02), SqueezeField(profile="linear"))
    assert len(square.stable) == 0 and len(square.unstable) == 0
    with pytest.raises(upm.ParameterError, match="profile must be 'unit' or 'linear'"):
        SqueezeField(profile="quadratic")


@pytest.mark.parametrize(
    ("vertices", "start"),
    [
        (None, 1.0),  # a 2:1 rectangle, from either side of its stable pose
        (None, 2.5),
        ([[0.0, 0.0], [0.03, 0.0], [0.0, 0.015]], 1.0),  # a right triangle
    ],
)
def test_the_ppod_line_sink_turns_parts_to_the_predicted_orientation_within_3_degrees(vertices, start):
    # Simulated on the 6-DOF plate: the rocking presses each element of the part by g + a_z where
    # it lies, which is what turns it; the prediction knows nothing of the integrator.
    part = upm.Polygon.rectangle(0.03, 0.015) if vertices is None else upm.Polygon(vertices)
    line = SqueezeField(point=(0.0, 0.0), angle=math.pi / 2, profile="linear")  # LineSinkX: x = 0
    (want,) = orientation_equilibria(part, line).stable
    run = upm.simulate(
        upm.PlateMotion.ppod("LineSinkX"),
        [upm.Polygon(part.vertices, position=(0.02, 0.01), angle=start)],
        duration=25.0,
        dt=1 / 20 / 400,
        mu=0.3,
        record_every=10_000,
    )
    err = (run.angles[-1, 0] - want + math.pi / 2) % math.pi - math.pi / 2
    assert abs(math.degrees(err)) < 3.0, f"ended at {math.degrees(run.angles[-1, 0]) % 180:.2f} deg"
    # it turned there (it did not start there), and its centroid came to the line
    first = (start - want + math.pi / 2) % math.pi - math.pi / 2
    assert abs(math.degrees(first)) > 20.0
    centroid = run.positions[-1, 0] + part.centroid_offset(run.angles[-1, 0])
    assert abs(centroid[0]) < 2e-3
