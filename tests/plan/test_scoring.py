"""The planner's scoring sums in the core (``distance_sum``, the edge penalty's spread) against
plain NumPy written here, on layouts with lost parts, parts without a target and broadcast inputs."""

from __future__ import annotations

import numpy as np
import pytest

import upm
from upm import _core
from upm.control._steps import distance_sum
from upm.plan.penalties import penalty


def _distance_sum(q: np.ndarray, targets: np.ndarray, slack: float, bend: float) -> np.ndarray:
    d = q - targets
    r = np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2)
    e = np.clip(r - slack, 0.0, None)
    if bend > 0:
        e = np.where(e < bend, e**2 / (2 * bend), e - bend / 2)
    e = np.where(np.isnan(r), 1.0, e)
    return np.where(np.isnan(targets).any(axis=-1), 0.0, e).sum(axis=-1)


def _layouts(rng: np.random.Generator, *shape: int) -> np.ndarray:
    q = rng.uniform(-0.2, 0.2, (*shape, 2))
    q.reshape(-1, 2)[rng.choice(q.size // 2, size=max(1, q.size // 20), replace=False), 0] = np.nan
    return q


@pytest.mark.parametrize(("slack", "bend"), [(0.0, 0.0), (0.002, 0.0), (0.0018, 0.0037)])
def test_distance_sum_is_numpys_for_shared_targets_and_per_layout(slack: float, bend: float) -> None:
    rng = np.random.default_rng(3)
    q = _layouts(rng, 6, 5, 9)
    targets = rng.uniform(-0.1, 0.1, (9, 2))
    targets[4] = np.nan  # a part without a target
    got = distance_sum(q, targets, slack, bend)
    assert got.shape == (6, 5)
    assert np.allclose(got, _distance_sum(q, targets, slack, bend), rtol=1e-14, atol=0)
    # targets that differ along the leading axes (a reference that moves with the elapsed time)
    each = rng.uniform(-0.1, 0.1, (6, 1, 9, 2))
    want = _distance_sum(q, each, slack, bend)
    assert np.allclose(distance_sum(q, each, slack, bend), want, rtol=1e-14, atol=0)
    # a resting layout broadcast over (K, R): summed once, the same numbers, a writable array
    still = np.broadcast_to(q[0, 0], (40, 7, 9, 2))
    rest = distance_sum(still, targets, slack, bend)
    assert rest.shape == (40, 7) and rest.flags.writeable
    assert np.all(rest == rest[0, 0])
    assert rest[0, 0] == pytest.approx(_distance_sum(q[0, 0], targets, slack, bend), rel=1e-14)
    # one layout against targets over several times (a trajectory's references)
    over_time = _distance_sum(q[0, 0], each[:, 0], slack, bend)
    assert np.allclose(distance_sum(q[0, 0], each[:, 0], slack, bend), over_time, rtol=1e-14, atol=0)
    # one layout, no batch axis
    assert distance_sum(q[1, 2], targets, slack, bend).shape == ()


def test_distance_sum_refuses_targets_of_another_count() -> None:
    with pytest.raises(ValueError):
        distance_sum(np.zeros((3, 4, 2)), np.zeros((5, 2)))
    with pytest.raises(upm.ShapeError, match="targets must hold layouts of 4 points"):
        _core.distance_sum(np.zeros((3, 4, 2)), np.zeros((1, 5, 2)), 0.0, 0.0)
    with pytest.raises(upm.ShapeError, match="S dividing the 3 layouts"):
        _core.distance_sum(np.zeros((3, 4, 2)), np.zeros((2, 4, 2)), 0.0, 0.0)
    with pytest.raises(upm.ParameterError, match="slack"):
        _core.distance_sum(np.zeros((3, 4, 2)), np.zeros((1, 4, 2)), -1.0, 0.0)


def _edge(q: np.ndarray, half: float, band: float, weight: float, lost: float, guard: float) -> np.ndarray:
    a = np.abs(q)
    off = ~np.all(a <= half, axis=-1)  # (NaN too)
    near = ~off & ~np.all(a <= half - guard, axis=-1)
    over = np.clip(a - (half - band), 0.0, None) + 5 * np.clip(a - (half - band / 2), 0.0, None)
    gone = off.sum(axis=-1) + 0.5 * near.sum(axis=-1)
    return lost * gone + weight * np.where(off[..., None], 0.0, over).sum(axis=(-1, -2))


def test_the_edge_penalty_scores_each_part_at_its_worst_case_from_its_own_start() -> None:
    rng = np.random.default_rng(5)
    k, r, m, spread = 4, 3, 10, 0.15
    starts = rng.uniform(-0.15, 0.15, (k, m, 2))
    after = starts[:, None] + rng.normal(0, 0.03, (k, r, m, 2))
    after[1, 2, 3] = np.nan
    kw = {"half": 0.2, "edge": 0.04, "edge_weight": 2.0, "lost_cost": 1.5, "guard": 0.008}
    # each start serves its R consecutive layouts (the look-ahead's first pulses)
    got = penalty(after.reshape(-1, m, 2), spread=spread, start=starts, **kw)
    way = np.hypot(*(after - starts[:, None]).transpose(3, 0, 1, 2))
    at = after + np.sign(after) * (spread * way)[..., None]
    want = _edge(at, 0.2, 0.04, 2.0, 1.5, 0.008).reshape(-1)
    assert got == pytest.approx(want, rel=1e-13, abs=1e-15)
    assert np.all(got[[1 * r + 2]] >= 1.5)
    # one start for every layout
    one = penalty(after.reshape(-1, m, 2), spread=spread, start=starts[0], **kw)
    at = after + np.sign(after) * (spread * np.hypot(*(after - starts[0]).transpose(3, 0, 1, 2)))[..., None]
    assert one == pytest.approx(_edge(at, 0.2, 0.04, 2.0, 1.5, 0.008).reshape(-1), rel=1e-13, abs=1e-15)
    with pytest.raises(upm.ShapeError, match="S dividing"):
        penalty(after.reshape(-1, m, 2), spread=spread, start=np.zeros((5, m, 2)), **kw)
