"""The six-actuator plate: Jacobian, limits, accelerometers and the estimator (docs/ppod.md)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import upm
from upm.plate.plate6 import PPOD_LIKE, Actuator, Plate6


def test_the_jacobian_by_hand() -> None:
    p = Plate6()
    # pure vertical acceleration: the three vertical actuators share m a equally, none in the plane
    f = p.forces([0, 0, 2.0, 0, 0, 0])
    assert np.allclose(f[:3], 0, atol=1e-12) and np.allclose(f[3:], 1.5 * 2.0 / 3)
    # rotation about z: the tangential ones each I alpha / (3 R)
    f = p.forces([0, 0, 0, 0, 0, 10.0])
    assert np.allclose(f[:3], 0.0225 * 10.0 / (3 * 0.18)) and np.allclose(f[3:], 0, atol=1e-12)
    # the wrench of each actuator: (d, p x d), built here independently
    for i, act in enumerate(PPOD_LIKE):
        d = np.array(act.direction)
        px, py = act.point
        moment = [py * d[2], -px * d[2], px * d[1] - py * d[0]]
        assert np.allclose(p.jacobian[:, i], [*d, *moment])
    rng = np.random.default_rng(0)
    a = rng.normal(size=(5, 6)) + 1j * rng.normal(size=(5, 6))
    assert np.allclose(p.accelerations(p.forces(a)), a)


def test_limits_name_the_actuator() -> None:
    p = Plate6()
    f, reach = p.demands(upm.PlateMotion.ppod("Sink"))
    # m a = 15 N turning on a circle, shared by three tangential actuators 120 degrees apart: each
    # carries (2/3) 15 N at its peak
    assert np.allclose(f[:3], 2 / 3 * 15.0)
    # the rocking 70 rad/s^2 at 20 Hz tilts by 70 / w^2 = 4.4 mrad: 0.8 mm at 0.18 m
    assert np.allclose(reach[3:], 0.18 * 70 / (2 * math.pi * 20) ** 2, rtol=1e-9)
    p.check(upm.PlateMotion.ppod("Sink"))
    hard = upm.PlateMotion.harmonic(5.0, z=[(1, 6.0, 0.0)])  # 6 mm at 5 Hz
    with pytest.raises(upm.StrokeError, match="actuator 3 would travel"):
        p.check(hard)
    strong = upm.PlateMotion.harmonic(20.0, x=[(1, 90.0, 0.0)])
    with pytest.raises(upm.ParameterError, match="actuator 0 needs"):
        p.check(strong)


def test_bad_geometries_are_refused() -> None:
    flat = tuple(Actuator((0.1 * k, 0.0), (1.0, 0.0, 0.0)) for k in range(6))
    with pytest.raises(upm.ParameterError, match="rank < 6"):
        Plate6(actuators=flat)
    with pytest.raises(upm.ParameterError, match="do not observe"):
        Plate6(accelerometers=((0.0, 0.0), (0.1, 0.0), (0.2, 0.0)))
    with pytest.raises(upm.ParameterError, match="6 actuators"):
        Plate6(actuators=PPOD_LIKE[:5])


def test_the_estimator_recovers_every_axis_from_noisy_readings() -> None:
    p = Plate6()
    for name in ("Sink", "Whirlpool", "SqueezeTransY", "Circle"):
        m = upm.PlateMotion.ppod(name)
        f, want = m.harmonic_phasors()
        t = np.arange(2500) / 5000
        seen = p.readings(m, t) + np.random.default_rng(1).normal(0, 0.2, (len(t), 9))
        got = p.estimate(seen, 5000, f, (1,))
        assert np.linalg.norm(got[1] - want[1]) / np.linalg.norm(want[1]) < 0.005, name
    # the readings themselves against the rigid-body formula at one sensor
    m = upm.PlateMotion.ppod("Sink")
    t = np.array([0.013])
    px, py = p.accelerometers[1]
    _, acc = m.velocity(t), m.acceleration(t)
    nz = m.normal_acceleration(t)[0]
    r = p.readings(m, t)[0, 3:6]
    assert np.allclose(
        r, [acc[0, 0] - acc[0, 2] * py, acc[0, 1] + acc[0, 2] * px, nz[0] + py * nz[1] - px * nz[2]]
    )


def test_a_calibration_error_changes_the_motion_and_the_estimate_sees_it() -> None:
    p = Plate6()
    m = upm.PlateMotion.ppod("Sink")
    same = p.achieved(m, np.ones(6))
    _, want = m.harmonic_phasors()
    assert np.allclose(same.harmonic_phasors()[1][1], want[1])
    off = p.achieved(m, [1.1, 1, 1, 1, 1, 1])
    assert not np.allclose(off.harmonic_phasors()[1][1], want[1])


def test_gathering_through_the_loop_on_the_six_actuator_plate() -> None:
    pytest.importorskip("cv2")
    from upm import control
    from upm.experiments.demos import LIMITS, PENNY, scatter
    from upm.plate.plant import SimulatedUPM

    parts = scatter(np.random.default_rng(3), 6, 0.11, 0.04)
    plant = SimulatedUPM(plate=LIMITS.plate, axes=LIMITS.axes, parts=parts, seed=3, part_radius=None)
    device = control.SimulatedDevice6(plant, seed=3)
    planner = control.FieldPlanner(("Sink", "TransX"), mu=0.3, grid=15)
    loop = control.Loop(device, plant.camera("penny", seed=3), planner, control.GatherTask((0.04, -0.03)),
                        part_radius=PENNY)  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        log = loop.run(30)
    assert log.done and plant.fallen == 0
    assert 0.01 < np.median(device.tracking) < 0.2  # 5 % actuator gains: about 10 % tracking error
    with pytest.raises(upm.ParameterError, match="plays field pulses"):
        device.execute([upm.Pulse.jet((0, 0), (1, 0), 0.03, 0.1, 35.0, 0.1, 0.1, 0.1)])
    assert math.isfinite(log.meta["plate_time"])
