"""The closed loop: pulses and their motor channels, tasks, planners, the loop end to end (in this
process and through the board emulator), logs, and the demos' command line."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

import upm
from upm import control
from upm.plate.actuation import Plate
from upm.plate.drive import flexures
from upm.plate.plant import Channel, Envelope, SimulatedUPM
from upm.plate.pulses import Pulse, program

PLATE = Plate(1.0, 0.0275, 0.2)
AXES = flexures(PLATE.mass, PLATE.inertia)
W = upm.Harmonics([1.0, -0.5], [0.0, 0.0], 35.0)
PENNY = 0.009525
CHIP = 0.0195


def plant_with(parts, **kw):
    return SimulatedUPM(plate=PLATE, axes=AXES, parts=parts, snr_db=None, **kw)


# -- pulses -----------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["rotation", "jet"])
def test_phasors_reproduce_the_commanded_velocity(kind):
    # Independent of the integrator: the phasor sum equals the PlateMotion's velocity while the
    # envelope is 1.
    if kind == "rotation":
        p = Pulse.rotation((0.05, -0.08), upm.Harmonics([1.3, -0.4], [0.2, 0.7], 35.0), 0.1, 0.5, 0.1)
    else:
        p = Pulse.jet((0.04, 0.02), (1.0, 2.0), 0.03, 0.07, 35.0, 0.1, 0.5, 0.1)
    t = np.linspace(0.12, 0.58, 97)
    w = 2 * np.pi * p.frequency
    expected = sum(np.real(np.outer(np.exp(1j * h * w * t), v)) for h, v in p.phasors().items())
    np.testing.assert_allclose(p.motion().velocity(t), expected, atol=1e-12)


def test_channels_give_the_inertial_wrench_of_every_harmonic():
    # 5.8 and 5.10 written out here: wrench phasor = i h w diag(M, M, I) V_h for a free plate.
    p = Pulse.jet((-0.05, 0.03), (0.3, -1.0), 0.04, 0.05, 35.0, 0.1, 0.2, 0.1)
    chans = p.channels(PLATE, None)
    r = PLATE.lever
    w = 2 * np.pi * p.frequency
    for h, key in ((1.0, "h1"), (2.0, "h2"), (2.0 / 3.0, "h23")):
        m = np.array([c[f"{key}_amplitude"] * np.exp(1j * c[f"{key}_phase"]) for c in chans])
        wrench = np.array([m[0] - m[1], m[2] - m[3], r * ((m[2] + m[3]) - (m[0] + m[1]))])
        want = 1j * h * w * np.array([PLATE.mass, PLATE.mass, PLATE.inertia]) * p.phasors()[h]
        np.testing.assert_allclose(wrench, want, atol=1e-9 * np.abs(want).max())


def test_a_motor_channel_has_one_shape_everywhere():
    # Four motors (Pulse.channels) and six actuators (Plate6.channels) give the same class the plant
    # plays; it still reads as the dict of SET_CHANNEL fields it used to be.
    p = Pulse.jet((-0.05, 0.03), (0.3, -1.0), 0.04, 0.05, 35.0, 0.1, 0.2, 0.1)
    four = p.channels(PLATE, None)
    six = upm.plate6.Plate6().channels(
        upm.PlateMotion.harmonic(20.0, x=[(1, 15.0, 0.0)], z=[(1, 5.0, 4.712)])
    )
    assert all(type(c) is Channel for c in four + six) and len(six) == 6
    c = four[0]
    assert Channel(**c) == c and c["h2_phase"] == c.h2_phase and set(c.keys()) >= {"amplitude", "h23_phase"}
    with pytest.raises(KeyError):
        c["h4_amplitude"]
    # the peak bounds the force it asks at any time (sampled densely over a period of the 2/3 harmonic)
    t = np.linspace(0.0, 3 / p.frequency, 20001)
    for ch in four:
        assert np.max(np.abs(ch.force(t))) <= ch.peak * (1 + 1e-12)
    assert p.peak_force(PLATE) == max(ch.h1_amplitude + ch.h2_amplitude + ch.h23_amplitude for ch in four)


def test_motors_play_a_pulse_like_the_ideal_plate():
    # The simulated plate on flexures, driven by the precompensated channels, against the exact motion.
    p = Pulse.rotation((0.05, -0.1), W, 4 / 35, 0.3, 4 / 35)
    plant = plant_with(np.zeros((0, 2)))
    n = round(p.on_time * plant.sample_rate)
    t = np.arange(n) / plant.sample_rate
    env = Envelope(p.attack, p.sustain, p.decay)
    _, vel = plant.plate_state(plant.forces([Channel(**c) for c in p.channels(PLATE, AXES)], t, env(t)))
    ref = p.motion(rest=False).velocity(t)
    assert np.max(np.abs(vel - ref)) < 0.08 * np.max(np.abs(ref))
    parts = np.array([[0.0, 0.0], [0.06, -0.08], [-0.1, 0.1]])
    ideal, motors = plant_with(parts.copy()), plant_with(parts.copy())
    control.SimulatedDevice(ideal, ideal=True).execute([p])
    control.SimulatedDevice(motors).execute([p])
    steps = ideal.parts - parts
    assert np.linalg.norm(motors.parts - ideal.parts) < 0.1 * np.linalg.norm(steps)


def test_a_pulse_beyond_the_motor_limit_is_refused_with_the_force_it_needs():
    p = Pulse.rotation((0.2, 0.2), upm.Harmonics([20.0, -10.0], [], 35.0), 0.1, 0.1, 0.1)
    with pytest.raises(upm.ParameterError, match="motor force"):
        p.channels(PLATE, AXES, limit=200.0)
    with pytest.raises(upm.ParameterError, match="attack"):
        Pulse.rotation((0, 0), W, -1.0, 0.1, 0.1)
    with pytest.raises(upm.ParameterError, match="direction"):
        Pulse.jet((0, 0), (0, 0), 0.03, 0.05, 35.0, 0.1, 0.1, 0.1)


def test_trimmed_rests_still_let_every_part_stop():
    parts = np.array([[0.02, 0.0], [-0.05, 0.04]])
    pulses = upm.jet_pulses(parts, [[0.01, 0.0], [0.0, -0.01]], mu=0.3, amplitude=0.08)
    trimmed = upm.trim_rests(pulses, parts, mu=0.3)
    assert sum(p.rest for p in trimmed) < 0.5 * sum(p.rest for p in pulses)
    # independently: after each trimmed pulse and its rest, nothing moves any more
    pos = parts.copy()
    for p in trimmed:
        m = p.motion()
        run = upm.simulate(m, pos, duration=m.duration, dt=1 / (200 * 70), mu=0.3, record_every=1)
        assert np.all(run.stuck[-1])
        np.testing.assert_allclose(np.abs(run.velocities[-1]), 0.0, atol=1e-9)
        pos = run.positions[-1]


def test_plan_to_motion_is_its_pulses_played_in_turn():
    plan = upm.solve_displacements([[0.05, 0.0]], [[0.0, 0.004]], upm.corner_centers((-0.1, -0.1, 0.1, 0.1)))
    pulses = upm.plan_pulses(plan, mu=0.3, refine=0)
    motion = upm.plan_to_motion(plan, mu=0.3, refine=0)
    assert math.isclose(motion.duration, sum(p.duration for p in pulses))
    t = np.linspace(0, motion.duration, 501)
    np.testing.assert_allclose(motion.velocity(t), program(pulses).velocity(t), atol=1e-12)


# -- tasks ------------------------------------------------------------------------------------------


def state(cycle, positions, ids=None, labels=None, time=0.0, last=0.0):
    pos = np.asarray(positions, float)
    ids = np.arange(len(pos)) if ids is None else np.asarray(ids)
    labels = tuple(labels or ["penny"] * len(pos))
    return control.State(cycle, time, ids, pos, labels, last)


def test_goto_binds_parts_to_goals_by_least_total_distance_and_clips_steps():
    task = control.GotoTask([[0.1, 0.0], [-0.1, 0.0]], max_step=0.02, gain=1.0, tolerance=0.002)
    s = state(0, [[-0.09, 0.01], [0.095, 0.0]], ids=[7, 3])
    steps = task.steps(s)
    np.testing.assert_allclose(steps, [[-0.01, -0.01], [0.005, 0.0]], atol=1e-12)
    assert not task.done(s)
    assert task.done(state(1, [[-0.1, 0.0005], [0.1, 0.0]], ids=[7, 3]))
    # a part that leaves for good frees its goal for one that appears
    s2 = state(2, [[0.1, 0.0], [-0.12, 0.0]], ids=[3, 9])
    np.testing.assert_allclose(task.errors(s2), [0.0, 0.02], atol=1e-12)


def test_trajectory_references_wait_for_a_lagging_part_and_keep_spacing():
    ring = np.array([[0.1, 0.0], [0.0, 0.1], [-0.1, 0.0], [0.0, -0.1]])
    task = control.TrajectoryTask([ring], speed=0.01, closed=True, equidistant=True, count=2, hold=0.005)
    length = 4 * math.hypot(0.1, 0.1)
    refs = [task.reference(k, 0.0) for k in range(2)]
    np.testing.assert_allclose(refs[0], [0.1, 0.0], atol=1e-12)
    np.testing.assert_allclose(refs[1], [-0.1, 0.0], atol=1e-12)  # half the loop behind
    task.steps(state(0, refs))
    task.steps(state(1, refs, time=1.0, last=1.0))
    assert math.isclose(task.progress, 0.01)
    lagging = [refs[0], refs[1] + 0.02]
    task.steps(state(2, lagging, time=2.0, last=1.0))
    assert math.isclose(task.progress, 0.01) and task.waited == 1.0
    assert task.end == pytest.approx(length)


def test_sort_pushes_by_label_spreads_close_pairs_and_knows_when_done():
    task = control.SortTask({"red": -1, "blue": 1}, line=0.1, margin=0.05, spacing=0.04, max_step=0.02)
    s = state(0, [[0.0, 0.0], [0.0, 0.01], [-0.16, 0.1]], labels=["red", "blue", "red"])
    steps = task.steps(s)
    assert steps[0, 0] < 0 < steps[1, 0] and steps[0, 1] < 0 < steps[1, 1]  # pushed apart along y
    assert steps[2, 0] == 0.0  # already at its side's goal (edge - margin)
    assert not task.done(s)
    assert task.done(state(1, [[-0.11, 0.0], [0.12, 0.0], [-0.15, 0.1]], labels=["red", "blue", "red"]))
    with pytest.raises(upm.ParameterError, match="sides"):
        control.SortTask({"red": 2})


# -- the loop end to end ------------------------------------------------------------------------------


def min_gap(log):
    pos = log.positions
    out = np.inf
    for row in pos:
        ok = row[np.all(np.isfinite(row), axis=1)]
        if len(ok) > 1:
            d = np.linalg.norm(ok[:, None] - ok[None], axis=2)
            out = min(out, d[np.triu_indices(len(ok), 1)].min())
    return out


def test_jets_sort_four_chips_through_the_loop_without_overlap(tmp_path):
    parts = np.array([[0.05, 0.05], [-0.03, -0.06], [0.02, -0.01], [-0.06, 0.04]])
    labels = ["red", "red", "blue", "blue"]
    plant = plant_with(parts)
    task = control.SortTask({"red": -1, "blue": 1}, line=0.09, margin=0.08, spacing=0.046, max_step=0.025)
    planner = control.JetPlanner(mu=0.3, amplitude=0.1, rho=0.03, plate=PLATE, axes=AXES)
    loop = control.Loop(plant, plant.camera(labels), planner, task, part_radius=CHIP)
    log = loop.run(25, log=tmp_path / "sort.npz")
    assert log.done and plant.fallen == 0
    truth = plant.parts
    assert np.all(truth[:2, 0] < -0.09) and np.all(truth[2:, 0] > 0.09)
    assert min_gap(log) > 2 * CHIP - 0.004  # chips never overlap by more than 4 mm
    tracking = log.tracking_error()
    assert np.nanmedian(tracking) < 0.015  # per-cycle steps land within 15 mm of what was asked
    # the log reads back with one call
    back = control.load_log(tmp_path / "sort.npz")
    np.testing.assert_array_equal(back.positions, log.positions)
    assert back.meta["done"] and back.meta["planner"] == "JetPlanner"
    assert back.frames.shape[0] == len(log.frames) and back.frames.shape[-1] == 3


def test_an_interrupted_run_keeps_its_log(tmp_path):
    # Before: the log was written only at the end, so Ctrl-C threw the whole run away.
    parts = np.array([[0.05, 0.05], [-0.03, -0.06]])
    plant = plant_with(parts)
    task = control.SortTask({"red": -1, "blue": 1}, line=0.09, margin=0.08, spacing=0.046, max_step=0.025)
    planner = control.JetPlanner(mu=0.3, amplitude=0.1, rho=0.03, plate=PLATE, axes=AXES)
    loop = control.Loop(plant, plant.camera(["red", "blue"]), planner, task, part_radius=CHIP)
    play, calls = loop.device.execute, []

    def interrupted(pulses):
        calls.append(len(pulses))
        if len(calls) == 4:
            raise KeyboardInterrupt
        play(pulses)

    loop.device.execute = interrupted
    with pytest.raises(KeyboardInterrupt):
        loop.run(25, log=tmp_path / "run.npz", flush_every=1e-6)
    back = control.load_log(tmp_path / "run.npz")
    assert back.stopped.startswith("KeyboardInterrupt") and not back.done
    assert back.positions.shape[0] == 3  # the three cycles played before the interrupt
    assert back.tracking_error().shape == back.positions.shape[:2]
    assert not list(tmp_path.glob(".*"))  # no partial files left behind


def test_a_log_path_that_cannot_be_written_is_refused_before_the_run(tmp_path):
    plant = plant_with([[0.0, 0.0]])
    loop = control.Loop(plant, plant.camera(), control.JetPlanner(), control.WatchTask(1), part_radius=PENNY)
    (tmp_path / "file").write_text("")
    with pytest.raises(upm.ParameterError, match="log: cannot write"):
        loop.run(1, log=tmp_path / "file" / "log.npz")
    assert loop.plate_time == 0.0


def test_displacements_bring_two_parts_to_their_goals():
    # parts that do not cross each other's way: two close parts make the system ill-conditioned (4.2.5)
    starts = np.array([[-0.05, -0.03], [0.05, -0.03]])
    goals = np.array([[-0.03, 0.04], [0.04, 0.05]])
    plant = plant_with(starts)
    planner = control.DisplacementPlanner(
        upm.corner_centers((-0.15, -0.15, 0.15, 0.15)), mu=0.3, plate=PLATE, axes=AXES
    )
    task = control.GotoTask(goals, starts=starts, gain=0.7, max_step=0.015, tolerance=0.004)
    log = control.Loop(plant, plant.camera("penny"), planner, task, part_radius=PENNY).run(30)
    assert log.done
    assert np.all(np.linalg.norm(plant.parts - goals, axis=1) < 0.004 + 0.001)  # vision within 1 mm
    assert np.nanmax(log.tracking_error()) < 0.03


def test_rotations_follow_a_segment():
    path = np.array([[-0.05, 0.0], [0.03, 0.0]])
    plant = plant_with([[-0.05, 0.0]])
    task = control.TrajectoryTask([path], speed=0.008, max_step=0.012, tolerance=0.004)
    planner = control.RotationsPlanner(upm.ring_centers(5, 0.17), cycle=0.6, limits=plant.limits)
    log = control.Loop(plant, plant.camera("penny"), planner, task, part_radius=PENNY).run(60)
    assert log.done
    assert np.nanmax(log.errors) < 0.02  # never more than 2 cm off the moving reference
    assert abs(plant.parts[0, 0] - 0.03) < 0.005


def test_the_loop_refuses_what_it_cannot_use():
    plant = plant_with([[0.0, 0.0]])
    with pytest.raises(upm.ParameterError, match="device"):
        control.Loop(object(), plant.camera(), control.JetPlanner(), control.WatchTask(1), part_radius=PENNY)
    with pytest.raises(upm.ParameterError, match="part_radius"):
        control.Loop(plant, plant.camera(), control.JetPlanner(), control.WatchTask(1), part_radius=-1.0)
    with pytest.raises(upm.ParameterError, match="planner"):
        control.Loop(plant, plant.camera(), object(), control.WatchTask(1), part_radius=PENNY)


def test_a_part_pushed_over_the_edge_falls_off_and_leaves_the_picture():
    plant = plant_with([[0.19, 0.0], [0.0, 0.0]])
    pulse = Pulse.jet((0.19, 0.0), (1.0, 0.0), 0.05, 0.1, 35.0, 0.25, 2.0, 0.25)
    control.SimulatedDevice(plant, ideal=True).execute([pulse])
    assert plant.fallen == 1 and np.all(np.isnan(plant.parts[0]))
    cam = plant.camera(["red", "blue"])
    ok, _ = cam.read()
    assert ok and len(cam.last.truth.centers) == 1 and cam.last.truth.labels == ("blue",)


# -- through the board emulator -----------------------------------------------------------------------


def test_sort_through_the_board_protocol_and_the_emulator_process(tmp_path):
    from upm import demos

    # make demo's job, cut short: the predictive planner planning while the emulated plate plays
    # (the thesis's jet planner plays 20 s programs a cycle: 3 cycles of it took a minute)
    m = demos.run_demo("sort8", tmp_path / "board", board=True, quick=True, cycles=6, verbose=False,
                       planner="predictive", pipeline=0.006)  # fmt: skip
    assert m["board"] and m["cycles"] == 6 and m["fallen"] == 0 and m["pulses"] == 6
    # the parts went where the planner's model said, through the protocol and the emulator's
    # own plate and contacts (1.2 mm measured)
    assert m["prediction_error_median"] < 0.004
    # the emulated plate's largest corner excursion, read back from the emulator process
    assert 0.0 < m["max_stroke"] <= 0.010


def test_remote_camera_refuses_bad_addresses():
    with pytest.raises(upm.VisionError, match="tcp://host:port"):
        from upm.vision import RemoteCamera

        RemoteCamera("nowhere")


# -- the command line ---------------------------------------------------------------------------------


def test_demo_list_names_every_demo(capsys):
    from upm import cli, demos, mchip_demos, orient_demos, ppod_demos, scale_demos

    assert cli.main(["demo", "list"]) == 0
    listed = [line.split()[0] for line in capsys.readouterr().out.splitlines()]
    every = [
        "feeding",
        *demos.DEMOS,
        *mchip_demos.DEMOS,
        *ppod_demos.DEMOS,
        *orient_demos.DEMOS,
        *scale_demos.DEMOS,
    ]
    assert listed == every


def test_figures_are_written(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "upm.cli", "figures", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    for name in ("fig3_5.png", "fig3_6.png", "fig4_7.png", "fig6_2.png", "fig6_9.png"):
        assert (tmp_path / name).stat().st_size > 10_000 and name in out


def test_a_short_demo_writes_its_outputs(tmp_path):
    from upm import demos

    m = demos.run_demo("racetrack", tmp_path, quick=True, verbose=False)
    for name in ("animation.gif", "paths.png", "errors.png", "log.npz"):
        assert (tmp_path / "racetrack" / name).stat().st_size > 1000
    assert json.loads((tmp_path / "racetrack" / "metrics.json").read_text())["cycles"] == 3
    # every part moved forward along the flow, the inner ones turning through larger angles
    assert all(a > 0 for a in m["angles"]) and m["angles"][0] > m["angles"][-1]


def test_the_displacement_planner_plays_no_program_that_carries_parts_away():
    # large steps in different directions about four corner centres: sequential rotations far from
    # linear once carried a part away from its goal (the corners demo then diverged, 136 -> 103 mm)
    from upm.experiments.demos import DEMOS
    from upm.plan.displacements import MAX_MISS
    from upm.plate.pulses import program

    planner = DEMOS["corners"].build(False, 1).planner
    goals = np.array([[0.02, 0.06], [-0.06, 0.03]])
    rng = np.random.default_rng(0)
    for _ in range(6):
        pos = rng.uniform(-0.08, 0.08, (2, 2))
        way = goals - pos
        steps = way * np.minimum(1, 0.015 / np.linalg.norm(way, axis=1, keepdims=True))
        motion = program(planner.plan(pos, steps))
        run = upm.simulate(motion, pos, duration=motion.duration, dt=1 / (200 * motion.max_frequency), mu=0.3,
                           record_every=10**9)  # fmt: skip
        moved = run.positions[-1] - pos
        # each part ends nearer its goal, and the steps played are a fraction of those asked,
        # missed by at most MAX_MISS of their own size
        assert np.all(np.linalg.norm(goals - run.positions[-1], axis=1) < np.linalg.norm(way, axis=1))
        scale = float(np.sum(moved * steps) / np.sum(steps * steps))
        assert np.linalg.norm(moved - scale * steps) <= MAX_MISS * np.linalg.norm(scale * steps) + 1e-4
