"""Sensorless orienting in a squeeze field: the turn function and its stable roots against a
brute-force grid over the footprint written here, and the rod-like result for a rectangle."""

from __future__ import annotations

import math

import numpy as np
import pytest

import upm
from upm.orienting import SqueezeField, orientation_equilibria

PENTAGON = np.array([[0.0, 0.0], [0.030, -0.004], [0.041, 0.016], [0.022, 0.031], [-0.006, 0.019]])


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
    with pytest.raises(upm.ParameterError, match=r"field must be a upm\.SqueezeField"):
        orientation_equilibria(upm.Polygon.regular(4, 0.01), "squeeze")
