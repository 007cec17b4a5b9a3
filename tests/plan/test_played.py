"""A pulse as the drive plays it (``upm.plan.played``), against the plant that plays it: the board
envelopes the motors' forces and the plate answers through its flexures."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from upm.control.devices import SimulatedDevice
from upm.experiments.demos import LIMITS
from upm.plan import PredictivePlanner
from upm.plan.played import drive_shift, drive_velocity
from upm.plate.plant import Envelope, SimulatedUPM
from upm.plate.pulses import Pulse

PARTS = np.random.default_rng(0).uniform(-0.1, 0.1, (8, 2))


def plant() -> SimulatedUPM:
    return SimulatedUPM(
        plate=LIMITS.plate, axes=LIMITS.axes, stroke=LIMITS.stroke, parts=PARTS.copy(), seed=1
    )


def test_the_drive_velocity_is_the_plants_own():
    pulse = Pulse.jet((0.05, 0.02), (1.0, 0.0), 0.04, 0.1, 70.0, 0.057, 0.236, 0.057)
    t, vel = drive_velocity(LIMITS, pulse)
    here = plant()
    channels = pulse.channels(here.plate, here.axes, here.motor_force)
    _, played = here.pulse_ahead(channels, Envelope(pulse.attack, pulse.sustain, pulse.decay))
    assert vel.shape == played.vel.shape == (len(t), 3)
    np.testing.assert_allclose(vel, played.vel, rtol=0, atol=1e-9 * np.abs(played.vel).max())
    # and it is not the velocity Pulse.motion() asks for: on the ramps the force is enveloped
    ideal = pulse.motion(rest=False).velocity(t)
    assert np.abs(vel - ideal)[:, 2].max() > 0.05 * np.abs(ideal[:, 2]).max()


def test_a_jet_is_foreseen_as_the_plant_plays_it():
    # a full-amplitude jet at 70 Hz: its far parts move millimetres that Pulse.motion() misses
    pulse = Pulse.jet(PARTS[0], (1.0, 0.0), 0.04, 0.101, 70.0, 0.057, 0.236, 0.057)
    planner = PredictivePlanner(LIMITS, mu=0.3, adapt=False)
    final, durations = planner.predict([pulse], PARTS)
    here = plant()
    SimulatedDevice(here).execute([replace(pulse, rest=float(durations[0] - pulse.on_time + 0.05))])
    truth = np.asarray(here.parts)
    plain = np.hypot(*(final[0] - truth).T)
    driven = np.hypot(*(final[0] + drive_shift(LIMITS, [pulse], PARTS, mu=0.3)[0] - truth).T)
    assert np.median(plain) > 1.5e-3  # the plain prediction is millimetres off
    assert np.median(driven) < 0.5e-3 and driven.max() < 1.0e-3


def test_a_pause_is_not_shifted_and_no_parts_are_none():
    pause = Pulse.pause(0.2)
    jet = Pulse.jet((0.0, 0.0), (0.0, 1.0), 0.08, 0.02, 50.0, 0.06, 0.1, 0.06)
    shift = drive_shift(LIMITS, [pause, jet], PARTS[:3], mu=0.3)
    assert shift.shape == (2, 3, 2)
    assert np.all(shift[0] == 0.0) and np.all(np.isfinite(shift[1]))
    assert drive_shift(LIMITS, [jet], np.zeros((0, 2)), mu=0.3).shape == (1, 0, 2)


def test_the_planner_expects_its_pulse_where_the_drive_leaves_the_parts():
    from upm.control import GotoTask, State

    parts = PARTS[:4]
    now = State(0, 0.0, np.arange(4), parts, ("penny",) * 4, 0.0)
    task = GotoTask(parts + np.array([0.02, 0.0]))
    kw = {"mu": 0.3, "part_radius": 0.005, "lookahead": None, "pairs": None, "adapt": False}
    plain = PredictivePlanner(LIMITS, drive=False, **kw)
    (pulse,) = plain.plan_task(now, task)
    np.testing.assert_allclose(plain.expected[1], plain._last[3], atol=0)
    planner = PredictivePlanner(LIMITS, **kw)
    assert planner.plan_task(now, task) == [pulse]  # the same choice, drive or not
    expected = planner.expected[1]
    ideal = planner._last[3]  # what the planner learns from: its own model's prediction
    shift = drive_shift(LIMITS, [pulse], parts, mu=0.3)[0]
    np.testing.assert_allclose(expected - ideal, shift, atol=1e-12)
    assert np.abs(shift).max() > 0  # a pulse the plate plays: the drive moves the parts otherwise
