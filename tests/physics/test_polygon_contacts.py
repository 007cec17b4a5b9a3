"""Contacts of polygon parts through rapier2d's convex polygon colliders, checked with a separating
axis test written here (independent of rapier and parry): parts never sink into each other or
into a wall, a push moves and turns what it hits, and parts that never touch move as they do
without contacts."""

from __future__ import annotations

import numpy as np
import pytest

import upm

REST = upm.PlateMotion.rest(1.0)
KW = dict(dt=1e-4, mu=0.3, record_every=5, contacts=True)


def outline(part: upm.Polygon | upm.Disk, position: np.ndarray, angle: float) -> np.ndarray:
    if isinstance(part, upm.Disk):
        a = np.linspace(0, 2 * np.pi, 128, endpoint=False)
        return position + part.radius * np.stack([np.cos(a), np.sin(a)], 1)
    return upm.Polygon(part.vertices, position, angle).outline()


def depth(p: np.ndarray, q: np.ndarray) -> float:
    """How far two convex outlines overlap (<= 0: apart): the least overlap of their projections
    on every edge normal of either."""
    least = np.inf
    for poly in (p, q):
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.stack([edges[:, 1], -edges[:, 0]], 1) / np.hypot(*edges.T)[:, None]
        a, b = p @ normals.T, q @ normals.T
        overlap = np.minimum(a.max(0), b.max(0)) - np.maximum(a.min(0), b.min(0))
        least = min(least, float(overlap.min()))
    return least


def deepest(run: upm.SimResult, parts: list) -> float:
    outlines = [[outline(p, run.positions[k, j], run.angles[k, j]) for j, p in enumerate(parts)]
                for k in range(len(run.t))]  # fmt: skip
    return max(depth(a, b) for a, b in outlines)


@pytest.mark.parametrize("hit", ["square", "disk"])
def test_a_part_sliding_into_a_square_pushes_and_turns_it_without_sinking_in(hit):
    target = upm.Polygon.rectangle(0.02, 0.02, position=(0.0, 0.004), angle=0.3)
    mover = (
        upm.Polygon.rectangle(0.02, 0.02, position=(-0.05, 0.0), velocity=(0.8, 0.0))
        if hit == "square"
        else upm.Disk((-0.05, 0.0), radius=0.01, velocity=(0.8, 0.0))
    )
    parts = [mover, target]
    run = upm.simulate(REST, parts, duration=0.3, **KW)
    assert run.positions[-1, 1, 0] > 0.02 and abs(run.angles[-1, 1] - 0.3) > 0.1  # pushed and turned
    assert deepest(run, parts) < 2e-4  # 1 % of the side
    apart = upm.simulate(REST, parts, duration=0.3, **{**KW, "contacts": False})
    assert np.array_equal(apart.positions[:, 1], run.positions[:1, 1].repeat(len(run.t), 0))  # not hit


def test_a_spinning_triangle_stops_at_a_wall_and_separated_parts_move_as_without_contacts():
    tri = upm.Polygon.regular(3, 0.012, position=(0.1, 0.0), velocity=(0.5, 0.0), spin=3.0)
    quad = np.array([[0.0, 0.0], [0.03, -0.004], [0.041, 0.016], [0.022, 0.031]])
    far = upm.Polygon(quad, position=(-0.1, 0.0), velocity=(-0.1, 0.2), spin=-4.0)
    wall = [[[0.12, -0.1], [0.12, 0.1]]]
    run = upm.simulate(REST, [tri, far], duration=0.3, walls=wall, **KW)
    reach = max(upm.Polygon(tri.vertices, run.positions[k, 0], run.angles[k, 0]).outline()[:, 0].max()
                for k in range(len(run.t)))  # fmt: skip
    assert 0.1195 < reach < 0.12 + 1e-5  # it got to the wall and no further
    free = upm.simulate(REST, [tri, far], duration=0.3, **{**KW, "contacts": False})
    assert free.positions[-1, 0, 0] > 0.125  # without the wall it would have gone through
    assert np.array_equal(run.positions[:, 1], free.positions[:, 1])
    assert np.array_equal(run.angles[:, 1], free.angles[:, 1])


def test_overlapping_parts_at_the_start_are_refused_naming_them():
    a = upm.Polygon.rectangle(0.02, 0.02, position=(0.0, 0.0))
    b = upm.Polygon.rectangle(0.02, 0.02, position=(0.015, 0.0), angle=0.5)
    with pytest.raises(upm.ParameterError, match="polygons 0 and 1 overlap"):
        upm.simulate(REST, [a, b], duration=0.01, **KW)
    d = upm.Disk((0.0, 0.019), radius=0.01)
    with pytest.raises(upm.ParameterError, match="polygon 0 and disk 1 overlap"):
        upm.simulate(REST, [a, d], duration=0.01, **KW)
    with pytest.raises(upm.ParameterError, match="wall 0 and polygon 0"):
        upm.simulate(REST, [a], duration=0.01, walls=[[[0.005, -1], [0.005, 1]]], **KW)
    with pytest.raises(upm.ParameterError, match=r"parts\[1\] is a point"):
        upm.simulate(REST, [a, upm.Point((0.1, 0.1))], duration=0.01, **KW)
