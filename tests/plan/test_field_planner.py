"""Velocity fields in the closed loop: field pulses, the gather task and the FieldPlanner
(docs/ppod.md)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import upm
from upm.control.tasks import GatherTask, State
from upm.plan.fields import FieldPlanner, _focus
from upm.plate.pulses import Pulse


def test_a_field_pulse_is_its_enveloped_motion_and_its_in_plane_phasors() -> None:
    m = upm.PlateMotion.ppod("Whirlpool")
    p = Pulse.field(m, 0.1, 0.4, 0.1, rest=0.2, center=(0.01, 0.0))
    assert p.kind == "field" and p.frequency == 20.0 and p.duration == pytest.approx(0.8)
    t = np.linspace(0.1, 0.5, 17)  # the hold: the pulse moves exactly as the field
    assert np.allclose(p.motion().velocity(t), m.velocity(t), atol=1e-15)
    assert np.all(p.motion().velocity([0.7]) == 0)  # its rest
    ph = p.phasors()[1.0]
    assert np.allclose(np.real(ph[None, :] * np.exp(2j * np.pi * 20 * t)[:, None]), m.velocity(t), atol=1e-12)
    with pytest.raises(upm.ParameterError, match=r"out of its plane.*6-DOF plate"):
        p.channels(upm.drive.DEFAULT_PLATE)
    flat = Pulse.field(upm.PlateMotion.harmonic(20.0, x=[(1, 10.0, 0.0)]), 0.1, 0.2, 0.1)
    assert len(flat.channels(upm.drive.DEFAULT_PLATE)) == 4  # in the plane: the motors play it
    with pytest.raises(upm.ParameterError, match=r"PlateMotion\.harmonic"):
        Pulse.field(upm.PlateMotion.rest(1.0), 0.1, 0.2, 0.1)


def state(q: np.ndarray) -> State:
    return State(0, 0.0, np.arange(len(q)), q, ("penny",) * len(q), 0.0)


def test_the_gather_task() -> None:
    task = GatherTask((0.04, -0.03), radius=0.04)
    q = np.array([[0.04, -0.03], [0.14, -0.03], [np.nan, np.nan]])
    s = state(q)
    assert np.allclose(task.errors(s)[:2], [0.0, 0.06])
    steps = task.steps(s)
    assert np.allclose(steps[0], 0) and steps[1, 0] < 0 and steps[1, 1] == 0 and np.all(steps[2] == 0)
    assert task.cost(s) == pytest.approx(0.06 + 1.0)  # the lost part counts 1 m
    assert not task.done(s) and task.done(state(q[:1]))
    with pytest.raises(upm.ParameterError, match="radius"):
        GatherTask(radius=0.0)


def test_the_focus_of_steps() -> None:
    q = np.array([[0.1, 0.0], [0.0, 0.1], [-0.05, -0.05]])
    c = np.array([0.02, -0.01])
    assert np.allclose(_focus(q, 0.3 * (c - q)), c)
    assert np.allclose(_focus(q[:1], np.array([[0.01, 0.0]])), [0.11, 0.0])  # one part: its goal
    assert _focus(q, np.array([[0.01, 0.0], [0.01, 0.0], [0.0, 0.01]])) is None  # no common point


def test_the_field_planner_gathers_parts_through_the_loop() -> None:
    pytest.importorskip("cv2")
    from upm import control
    from upm.experiments.demos import LIMITS, PENNY, scatter
    from upm.plate.plant import SimulatedUPM

    parts = scatter(np.random.default_rng(2), 6, 0.11, 0.04)
    plant = SimulatedUPM(plate=LIMITS.plate, axes=LIMITS.axes, parts=parts, seed=2, part_radius=None)
    planner = FieldPlanner(("Sink", "TransX", "TransNegX"), mu=0.3, grid=15)
    task = control.GatherTask((0.04, -0.03), radius=0.04)
    loop = control.Loop(control.SimulatedDevice(plant, ideal=True), plant.camera("penny", seed=2), planner,
                        task, part_radius=PENNY)  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        log = loop.run(30)
    assert log.done and plant.fallen == 0
    assert np.all(np.hypot(*(plant.parts - [0.04, -0.03]).T) <= 0.04)
    assert any(name.startswith("sink@(0.040, -0.030)") for name in planner.chosen)  # designed there
    assert log.meta["plate_time"] < 15.0
    # on the four-motor plate the same planner's pulses are refused, not silently flattened
    plant2 = SimulatedUPM(plate=LIMITS.plate, axes=LIMITS.axes, parts=parts, seed=2, part_radius=None)
    with pytest.raises(upm.ParameterError, match="out of its plane"):
        control.SimulatedDevice(plant2).execute(planner.plan(plant2.parts, task.steps(state(plant2.parts))))


def test_field_planner_input_checks() -> None:
    with pytest.raises(upm.ParameterError, match="unknown"):
        FieldPlanner(("Sinc",))
    with pytest.raises(upm.ParameterError, match="durations"):
        FieldPlanner(("Sink",), durations=())
    p = FieldPlanner(("TransX",), grid=7, design=False)
    assert p.plan(np.zeros((2, 2)), np.full((2, 2), np.nan)) == []  # nothing asked, nothing played
    moved = p.plan(np.array([[0.0, 0.0]]), np.array([[0.03, np.nan]]))
    assert moved and moved[0].kind == "field" and p.chosen == ["TransX"]
