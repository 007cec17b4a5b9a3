"""PartsTask: goals and paths by tracker id, their steps, cost and completion, bad input."""

from __future__ import annotations

import numpy as np
import pytest

import upm
from upm.control import PartsTask, State


def state(positions, ids=None, time=0.0, cycle=0, last=0.0):
    p = np.asarray(positions, dtype=np.float64)
    ids = np.arange(len(p)) if ids is None else np.asarray(ids)
    return State(cycle, time, ids, p, tuple("penny" for _ in p), last)


def test_goto_asks_for_gain_of_the_error_and_holds_the_others():
    t = PartsTask(gain=0.5, max_step=0.05)
    t.goto(7, (0.04, 0.0))
    s = state([[0.0, 0.0], [0.1, 0.1]], ids=[7, 3])
    np.testing.assert_allclose(t.steps(s), [[0.02, 0.0], [0.0, 0.0]])
    np.testing.assert_allclose(t.targets(s)[0], [0.04, 0.0])
    assert np.all(np.isnan(t.targets(s)[1]))
    # cost: the commanded part's distance less half the tolerance, plus hold x the idle part's move
    moved = np.array([[[0.03, 0.0], [0.1, 0.12]]])
    assert t.cost(s, moved)[0] == pytest.approx((0.01 - 0.0015) + 0.3 * 0.02)
    assert not t.done(s)
    assert t.done(state([[0.039, 0.001], [0.1, 0.1]], ids=[7, 3]))
    assert t.finished == [7] and not t.active


def test_a_path_reference_moves_at_its_speed_and_waits_for_a_lagging_part():
    t = PartsTask(speed=0.01, lag=0.015)
    t.follow(1, [[0.0, 0.0], [0.05, 0.0], [0.05, 0.05]])
    t.steps(state([[0.0, 0.0]], ids=[1], time=0.0))
    t.steps(state([[0.0, 0.0]], ids=[1], time=1.0))  # 1 s on: the reference 10 mm along
    np.testing.assert_allclose(t.targets(state([[0.0, 0.0]], ids=[1]))[0], [0.01, 0.0])
    t.steps(state([[-0.01, 0.0]], ids=[1], time=3.0))  # 20 mm behind its reference: it waits
    np.testing.assert_allclose(t.targets(state([[0.0, 0.0]], ids=[1]))[0], [0.01, 0.0])
    # the cost looks ahead along the path: in 2 s the reference is at 30 mm
    q = np.array([[[0.03, 0.0]]])
    assert t.cost(state([[0.01, 0.0]], ids=[1]), q, np.array([2.0]))[0] == pytest.approx(0.0)
    assert t.lines()[0].shape == (3, 2)
    assert not t.done(state([[0.05, 0.05]], ids=[1]))  # the reference has not reached the end


def test_bad_commands_are_refused():
    t = PartsTask()
    with pytest.raises(upm.ParameterError, match="part_id"):
        t.goto(-1, (0, 0))
    with pytest.raises(upm.ParameterError, match="part_id"):
        t.goto(True, (0, 0))
    with pytest.raises(upm.ParameterError, match="no length"):
        t.follow(1, [[0.0, 0.0], [0.0, 0.0]])
    with pytest.raises(upm.ParameterError, match="speed"):
        t.follow(1, [[0.0, 0.0], [0.01, 0.0]], speed=-1.0)
    with pytest.raises(upm.ParameterError, match="tolerance"):
        PartsTask(tolerance=0.0)
    assert not t.active


def test_a_placed_part_is_held_at_its_goal_while_later_commands_run():
    t = PartsTask(gain=0.5, max_step=0.05, tolerance=0.003)
    t.goto(1, (0.04, 0.0))
    assert t.done(state([[0.04, 0.0], [0.1, 0.0]], ids=[1, 2]))
    assert t.placed.keys() == {1} and not t.active
    s = state([[0.03, 0.0], [0.1, 0.0]], ids=[1, 2])  # part 1 pushed 10 mm off its place
    np.testing.assert_array_equal(t.steps(s), 0.0)  # nothing runs: nothing is steered
    t.goto(2, (0.06, 0.0))
    np.testing.assert_allclose(t.steps(s), [[0.005, 0.0], [-0.02, 0.0]])  # steered back, and 2 goes
    np.testing.assert_allclose(t.targets(s), [[0.04, 0.0], [0.06, 0.0]])
    # its cost counts as a commanded part's, not as hold x how far it moves
    q = np.array([[[0.03, 0.0], [0.06, 0.0]]])
    assert t.cost(s, q)[0] == pytest.approx(0.01 - 0.0015)
    assert not t.done(state([[0.03, 0.0], [0.06, 0.0]], ids=[1, 2]))  # 2 arrived, 1 is not back
    assert t.done(state([[0.041, 0.0], [0.06, 0.0]], ids=[1, 2]))
    assert t.finished == [1, 2] and t.placed.keys() == {1, 2}
    t.goto(3, (0.0, 0.0))
    assert t.done(state([[0.0, 0.0], [0.06, 0.0]], ids=[3, 2]))  # a placed part not seen does not block
    t.goto(2, (0.0, 0.05))  # a new command replaces the placement
    assert 2 not in t.placed
    t.clear()
    assert not t.placed and not t.active
