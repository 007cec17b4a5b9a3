"""An imperfect machine (issue 60): a plate that is not level (``tilt``: gravity's in-plane part
in the core integrator, for points, disks and polygons, against closed forms and an independent 1-D
stick-slip reference), friction per part, and motors whose gain and phase are not the model's."""

from __future__ import annotations

import math

import numpy as np
import pytest

import upm

G = 9.81


def _still(parts, tilt, duration=0.5, mu=0.3, mu_s=None):
    return upm.simulate(upm.PlateMotion.rest(duration), parts, duration=duration, dt=1e-3, mu=mu, mu_s=mu_s,
                        record_every=10, tilt=tilt)  # fmt: skip


@pytest.mark.parametrize(
    "make", [lambda: [[0.0, 0.0]], lambda: [upm.Disk((0.0, 0.0), 0.01)],
             lambda: [upm.Polygon.rectangle(0.04, 0.02)]],
    ids=["point", "disk", "polygon"],
)  # fmt: skip
def test_on_a_still_plate_steeper_than_friction_a_part_slides_at_g_sin_less_mu_g_cos(make):
    # tan 0.35 = 0.365 > mu = 0.3: it slides downhill (toward -x) at g (sin - mu cos), from rest
    theta, mu = 0.35, 0.3
    run = _still(make(), (theta, 0.0), mu=mu)
    a = G * (math.sin(theta) - mu * math.cos(theta))
    t = run.t
    np.testing.assert_allclose(run.positions[:, 0, 0], -0.5 * a * t**2, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(run.positions[:, 0, 1], 0.0, atol=1e-12)
    if run.angles.size:
        np.testing.assert_allclose(run.angles[:, 0], 0.0, atol=1e-12)  # a symmetric part does not turn
    # the same slope along y
    run_y = _still(make(), (0.0, -theta), mu=mu)
    np.testing.assert_allclose(run_y.positions[:, 0, 1], 0.5 * a * t**2, rtol=1e-9, atol=1e-12)


def test_below_the_friction_angle_a_part_stays_and_static_friction_holds_it_longer():
    parts = [[0.0, 0.0], [0.05, 0.0]]
    still = _still(parts, (0.2, 0.1), mu=0.3)  # tan of the slope about 0.22 < 0.3
    np.testing.assert_array_equal(still.positions[-1], parts)
    assert still.stuck[-1].all()
    held = _still(parts, (0.35, 0.0), mu=0.3, mu_s=0.4)  # 0.365 < mu_s: it never starts
    np.testing.assert_array_equal(held.positions[-1], parts)


def reference_1d(a, f, mu, slope, periods, steps_per_period):
    """Independent 1-D stick-slip reference on a plate rising toward +x by ``slope``: explicit
    Coulomb sliding at ``-g sin slope -+ mu g cos slope``, exact stick when the relative velocity
    changes sign within a step, release when keeping the part with the plate needs more than
    ``mu g cos slope``. Plate velocity ``a (sin wt + cos(2wt)/2)``."""
    w = 2 * math.pi * f
    dt = 1.0 / f / steps_per_period
    pull, grip = -G * math.sin(slope), mu * G * math.cos(slope)
    x = v = 0.0
    stuck = True
    for n in range(int(periods * steps_per_period)):
        t1 = (n + 1) * dt
        vs1 = a * (math.sin(w * t1) + 0.5 * math.cos(2 * w * t1))
        as1 = a * w * (math.cos(w * t1) - math.sin(2 * w * t1))
        if stuck and abs(as1 - pull) <= grip:
            v_new = vs1
        else:
            rel = v - vs1
            v_new = v + (pull - math.copysign(grip, rel)) * dt
            stuck = (v_new - vs1) * rel <= 0
            if stuck:
                v_new = vs1
        x += 0.5 * (v + v_new) * dt
        v = v_new
    return x


@pytest.mark.parametrize("slope", [math.radians(0.5), math.radians(-2.0)])
def test_a_vibrating_tilted_plate_feeds_as_an_independent_reference(slope):
    # the thesis's two-harmonic feed (about half the amplitude a second), uphill and downhill
    a, f, mu, periods = 0.02, 35.0, 0.1, 12
    ref = reference_1d(a, f, mu, slope, periods, 8000)
    level = reference_1d(a, f, mu, 0.0, periods, 8000)
    drive = upm.TwoHarmonic(0.5, np.pi / 2, amplitude=a, frequency=f)
    motion = upm.PlateMotion.translation((1, 0), drive)
    run = upm.simulate(motion, [[0.0, 0.0]], duration=periods / f, dt=1 / f / 4000, mu=mu,
                       record_every=4000, tilt=(slope, 0.0))  # fmt: skip
    assert run.positions[-1, 0, 0] == pytest.approx(ref, rel=3e-3)
    assert abs(ref - level) > 0.05 * abs(level)  # the slope matters at this size


def test_a_batch_and_its_vector_builds_carry_the_tilt_alike_and_bad_tilts_are_refused():
    rng = np.random.default_rng(1)
    parts = rng.uniform(-0.1, 0.1, (37, 2))  # vectors of 4 and 8 and a remainder
    jets = [upm.Pulse.jet(rng.uniform(-0.05, 0.05, 2), (1.0, 0.0), 0.04, 0.1, 35.0, 0.05, 0.1, 0.05)
            for _ in range(3)]  # fmt: skip
    motions = [j.motion() for j in jets]
    kw = {"duration": 0.3, "dt": 1 / 1680, "mu": 0.3, "record_every": 50, "tilt": (0.01, -0.02)}
    batch = upm.simulate_batch(motions, parts, **kw)
    for w, m in enumerate(motions):
        alone = upm.simulate(m, parts, **kw)
        np.testing.assert_array_equal(batch.positions[w], alone.positions)
        level = upm.simulate(m, parts, **{**kw, "tilt": (0.0, 0.0)})
        assert not np.allclose(alone.positions[-1], level.positions[-1], atol=1e-5)
    for bad in [(0.6, 0.0), (np.nan, 0.0), (0.1,), "x"]:
        with pytest.raises(upm.UpmError, match="tilt"):
            upm.simulate(motions[0], parts, **{**kw, "tilt": bad})


def test_a_plate_that_moves_out_of_its_plane_refuses_a_tilt_it_does_not_model():
    motion = upm.PlateMotion.harmonic(50.0, x=[(1, 5.0, 0.0)], z=[(1, 5.0, 0.0)])
    assert motion.is_spatial
    with pytest.raises(upm.ParameterError, match="tilt"):
        upm.simulate(motion, [[0.0, 0.0]], duration=0.01, dt=1e-4, mu=0.3, tilt=(0.01, 0.0))
    upm.simulate(motion, [[0.0, 0.0]], duration=0.01, dt=1e-4, mu=0.3)  # level: as before


def test_the_simulated_plate_tilts_its_parts_each_of_its_own_friction():
    from upm.plate.plant import SimulatedUPM

    # one part of low friction (0.05) and one of 0.3 on a plate sloping 0.03 rad: a still plate
    # holds both, a vibrating one carries the slippery part downhill (toward -x) the farther
    parts = np.array([[0.0, 0.05], [0.0, -0.05]])
    plant = SimulatedUPM(parts=parts.copy(), mu=[0.05, 0.3], tilt=(0.03, 0.0))
    level = SimulatedUPM(parts=parts.copy(), mu=[0.05, 0.3])
    shake = upm.PlateMotion.translation((0.0, 1.0), upm.Harmonics([0.3], [0.0], frequency=30.0)).for_duration(
        0.5
    )
    for p in (plant, level):
        p.play(shake)
    drift = plant.parts[:, 0] - level.parts[:, 0]
    assert drift[0] < -1e-3 and abs(drift[1]) < 0.2 * abs(drift[0])
    with pytest.raises(upm.ParameterError, match="tilt"):
        SimulatedUPM(parts=parts, mu=0.05, tilt=(0.06, 0.0))  # steeper than friction: they slide off
    with pytest.raises(upm.ShapeError, match="mu"):
        SimulatedUPM(parts=parts, mu=[0.3, 0.3, 0.3])


def test_the_loop_sorts_four_chips_on_a_plate_half_a_degree_off_level():
    from upm import control
    from upm.plan import PredictivePlanner
    from upm.plate.plant import SimulatedUPM

    chip = 0.0195
    parts = np.array([[-0.07, 0.06], [0.06, 0.05], [-0.05, -0.06], [0.07, -0.05]])
    labels = ["red", "blue", "red", "blue"]
    plant = SimulatedUPM(parts=parts, part_radius=chip, seed=3, tilt=(math.radians(0.5), math.radians(-0.3)))
    planner = PredictivePlanner(plant.limits, mu=0.3, part_radius=chip)  # it is not told of the tilt
    task = control.SortTask({"red": -1, "blue": 1}, line=0.09, margin=0.08)
    log = control.Loop(plant, plant.camera(labels, seed=3), planner, task, part_radius=chip).run(40)
    assert log.done and plant.fallen == 0
    assert np.all(plant.parts[[0, 2], 0] < -0.09) and np.all(plant.parts[[1, 3], 0] > 0.09)


def test_motor_gains_scale_and_motor_phases_delay_each_motors_force():
    from upm.plate.plant import Channel, Envelope, SimulatedUPM

    t = np.arange(400) / 5000.0
    env = Envelope(0.02, 0.04, 0.02)(t)
    asked = [Channel(50.0, 35.0, h1_phase=0.3, h2_phase=1.1), Channel(-40.0, 35.0), Channel(30.0, 50.0),
             Channel(0.0, 35.0)]  # fmt: skip
    gain, phase = np.array([1.15, 0.85, 1.0, 1.1]), np.radians([10.0, -10.0, 5.0, 0.0])
    plant = SimulatedUPM(motor_gain=gain, motor_phase=phase)
    # the same waveforms with each harmonic k's phase lagging k phase, gains applied: a perfect plant
    lagged = [Channel(c.amplitude * g, c.frequency, c.h1_amplitude, c.h1_phase - p, c.h2_amplitude,
                      c.h2_phase - 2 * p) for c, g, p in zip(asked, gain, phase, strict=True)]  # fmt: skip
    np.testing.assert_allclose(plant.forces(asked, t, env), SimulatedUPM().forces(lagged, t, env),
                               rtol=0, atol=1e-9)  # fmt: skip
    bads = [{"motor_gain": [1.0, 1.0, 1.0]}, {"motor_gain": [0.0, 1, 1, 1]}, {"motor_phase": [2.0, 0, 0, 0]}]
    for bad in bads:
        with pytest.raises(upm.ParameterError, match=next(iter(bad))):
            SimulatedUPM(**bad)


def test_the_loop_survives_motors_stronger_than_the_model_by_sizing_its_pulses_lower():
    # motors 30 % stronger swing the plate past its stroke on the pulses the model sizes to 90 %
    # of it: the plant refuses them (nothing plays), the planner sizes lower, the task gets done
    from upm import control
    from upm.plan import PredictivePlanner
    from upm.plate.plant import SimulatedUPM

    penny = 0.009525
    starts = np.array([[-0.08, 0.05], [0.07, -0.06]])
    goals = np.array([[0.06, 0.04], [-0.05, -0.07]])
    plant = SimulatedUPM(parts=starts, part_radius=penny, seed=2, motor_gain=[1.3] * 4)
    planner = PredictivePlanner(plant.limits, mu=0.3, part_radius=penny)
    task = control.GotoTask(goals, starts=starts, tolerance=0.004)
    with pytest.warns(upm.PlanWarning, match="sizes its pulses lower"):
        log = control.Loop(plant, plant.camera("penny", seed=2), planner, task, part_radius=penny).run(60)
    assert log.meta["refused"] >= 1 and planner.headroom < 1.0
    assert log.done and plant.fallen == 0
    gaps = np.hypot(*(plant.parts[:, None] - goals[None]).transpose(2, 0, 1))  # the task assigns goals
    assert np.all(gaps.min(axis=0) < 0.004 + 0.001)
    # a planner that cannot size lower passes the refusal on
    plant = SimulatedUPM(parts=starts, part_radius=penny, seed=2, motor_gain=[1.3] * 4)
    wave = upm.Harmonics([1.28, -0.64], [0.0, 0.0], 25.0)  # 9.5 mm of stroke on the model's motors
    fixed = control.FixedPlanner([upm.Pulse.translation((1.0, 0.0), wave, 0.12, 0.26, 0.12)])
    with pytest.raises(upm.StrokeError):
        control.Loop(
            plant, plant.camera("penny", seed=2), fixed, control.WatchTask(3), part_radius=penny
        ).run()


def test_a_lagging_camera_shows_the_parts_where_they_were_that_long_ago():
    # a point pushed by a translation pulse: the frame read with latency shows it where the plant's
    # own record (an independent simulate of the same motion) has it that long before the end
    from upm.plate.plant import SimulatedUPM

    motion = upm.PlateMotion.translation((1.0, 0.0), upm.Harmonics([0.3, -0.15], [0.0, 0.0], 25.0))
    motion = motion.with_envelope(0.1, 0.3, 0.1)
    plant = SimulatedUPM(parts=[[0.0, 0.0]], camera_latency=0.05)
    plant.play(motion)
    assert plant.clock == pytest.approx(0.5)
    coast = 0.5 * 1.0 + 0.01
    ref = upm.simulate(upm.PlateMotion.sequence([motion, upm.PlateMotion.rest(coast)]), [[0.0, 0.0]],
                       duration=0.5 + coast, dt=1.0 / (200 * 50.0), mu=0.3, record_every=1)  # fmt: skip
    at = np.interp(0.45, ref.t, ref.positions[:, 0, 0])
    assert plant.parts_at(0.45)[0, 0] == pytest.approx(at, abs=2e-5)
    assert abs(plant.parts_at(0.45)[0, 0] - plant.parts[0, 0]) > 1e-4  # the part was still sliding
    assert plant.parts_at(-1.0)[0, 0] == 0.0 and plant.parts_at(10.0)[0, 0] == plant.parts[0, 0]
    seen = plant.camera("penny", seed=1, noise=0.0)
    seen.read()
    np.testing.assert_allclose(seen.last.truth.positions, plant.parts_at(0.45), atol=1e-12)
    plant.move_parts([[0.05, 0.0]])  # put by hand: seen where it is
    np.testing.assert_allclose(plant.parts_at(0.45), [[0.05, 0.0]])


def test_pixel_jitter_and_lighting_drift_change_the_frames_as_their_models_say():
    from upm.plate.plant import SimulatedUPM
    from upm.vision import find_parts, find_table

    parts = np.array([[-0.05, 0.0], [0.05, 0.02]])
    clean = SimulatedUPM(parts=parts.copy()).camera("penny", seed=4)
    shaky = SimulatedUPM(parts=parts.copy(), pixel_noise=2.0).camera("penny", seed=4)
    shown = np.array([(shaky.read(), shaky.last.truth.positions)[1] for _ in range(200)])
    ends = upm.vision.synthetic.project(clean.camera.camera_from_plate, [[0.0, 0.0], [0.01, 0.0]])
    px = float(np.hypot(*(ends[1] - ends[0]))) / 0.01  # camera pixels per metre
    jitter = (shown - parts[None]) * px
    assert np.mean(jitter) == pytest.approx(0.0, abs=0.3)
    assert np.std(jitter) == pytest.approx(2.0, rel=0.1)
    # the drift brightens and dims the whole frame, within its bounds; vision still finds the parts
    lit = SimulatedUPM(parts=parts.copy(), lighting_drift=0.05).camera("penny", seed=4)
    base = float(np.mean(clean.read()[1]))
    means = np.array([np.mean(lit.read()[1]) for _ in range(40)])
    assert np.ptp(means) > 0.05 * base and np.all((means > 0.55 * base) & (means < 1.45 * base))
    frame = lit.read()[1]
    found = find_parts(frame, find_table(frame, 0.4064), 0.009525)
    assert len(found) == 2
    for bad in ({"camera_latency": -0.1}, {"camera_latency": 2.0}, {"pixel_noise": float("nan")}):
        with pytest.raises(upm.ParameterError, match=next(iter(bad))):
            SimulatedUPM(parts=parts, **bad)


def test_the_planner_learns_the_slope_from_where_a_pulse_leaves_the_parts():
    # the parts' end positions under a rotation pulse on a plate sloping (0.3, -0.2) degrees, from
    # upm.simulate of the whole motion (not the planner's batched prediction and closed-form
    # slide): fitted over a few pulses, the estimate comes within 0.05 degrees of the truth
    from upm.plan import PredictivePlanner
    from upm.plan.fitting import fit_tilt
    from upm.plate.plant import SimulatedUPM

    planner = PredictivePlanner(SimulatedUPM().limits, mu=0.3)
    pulse = upm.Pulse.rotation((0.02, -0.01), upm.Harmonics([6.0, -3.0], [0.0, 0.0], 35.0), 0.086, 0.3, 0.086)
    start = np.array([[0.08, 0.0], [-0.06, 0.07], [0.0, -0.1], [0.1, 0.09], [-0.1, -0.05]])
    truth = (math.radians(0.3), math.radians(-0.2))
    motion = upm.PlateMotion.sequence([pulse.motion(rest=False), upm.PlateMotion.rest(0.4)])
    run = upm.simulate(motion, start, duration=pulse.on_time + 0.4, dt=1.0 / (200 * 70.0), mu=0.3, tilt=truth)
    seen = run.positions[-1]
    assert np.all(np.hypot(*(seen - start).T) > 0.01)  # the pulse moves every part
    level, _ = planner.predict([pulse], start)
    assert np.max(np.hypot(*(level[0] - seen).T)) > 1e-3  # the slope shows
    for _ in range(20):
        fit_tilt(planner, pulse, start, seen)
    np.testing.assert_allclose(planner.tilt_estimate, truth, atol=math.radians(0.05))
    # a level plate: the estimate stays level
    flat = PredictivePlanner(SimulatedUPM().limits, mu=0.3)
    seen = upm.simulate(motion, start, duration=pulse.on_time + 0.4, dt=1.0 / (200 * 70.0), mu=0.3).positions[
        -1
    ]
    for _ in range(20):
        fit_tilt(flat, pulse, start, seen)
    assert np.hypot(*flat.tilt_estimate) < math.radians(0.02)


def test_the_tracker_follows_the_parts_through_a_light_that_drifts():
    # the light's brightness wanders +-40 % over the frames: the tracker scales the plate's stored
    # colour to each frame (Rectifier.light_gain) and keeps every part, each within 0.5 mm
    from upm.control.loop import loop_tracker
    from upm.plate.plant import SimulatedUPM
    from upm.vision import THESIS_PALETTE, find_table

    rng = np.random.default_rng(7)
    parts = np.array([[-0.08, 0.05], [0.06, 0.07], [0.0, -0.09], [0.1, -0.03], [-0.05, -0.06]])
    plant = SimulatedUPM(parts=parts.copy(), lighting_drift=0.08, seed=7)
    camera = plant.camera(["red", "blue", "red", "blue", "red"], seed=7)
    frame = camera.read()[1]
    tracker = loop_tracker(find_table(frame, plant.plate_size), 0.0195, THESIS_PALETTE, 0.02)
    tracks = tracker.update(frame)
    ids = tracks.ids.copy()
    owner = [int(np.argmin(np.hypot(*(parts - p).T))) for p in tracks.positions]  # each track's part
    assert sorted(owner) == list(range(5))
    lights = []
    for _ in range(30):
        plant.move_parts(plant.parts + rng.uniform(-0.004, 0.004, parts.shape))
        tracks = tracker.update(camera.read()[1])
        lights.append(camera._light)
        np.testing.assert_array_equal(tracks.ids, ids)
        assert np.max(np.hypot(*(tracks.positions - plant.parts[owner]).T)) < 0.5e-3
    assert np.ptp(lights) > 0.3  # the light did wander
