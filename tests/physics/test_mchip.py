"""The M-Chip array (``upm.mchip``, rapier3d): the Python contract, the collision log and the
spring–conveyor fit. The physics checks (ring-down Q, drive off/on, dt halving) are in
``crates/upm-core/tests/mchip.rs``."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

import upm
from upm import mchip


@pytest.fixture(scope="module")
def run() -> mchip.MChipResult:
    return mchip.simulate(duration=0.02)


def test_a_driven_part_feeds_forward_and_hops(run: mchip.MChipResult) -> None:
    assert run.feed_rate() > 5e-4  # m/s along +x
    assert run.position.shape == (len(run.t), 3) and run.angles.shape == (len(run.t), 40)
    # The resonators oscillate between about 0 and the 0.08 rad asked for.
    late = run.angles[len(run.t) // 2 :]
    assert 0.075 < late.max() < 0.09 and late.min() > -0.01
    # Most of the part's kinetic energy is the vertical hop.
    e = run.energy
    assert e["part_z"] > 5 * max(e["part_x"], e["part_y"])


def test_collisions_come_once_a_cycle_with_rebounds_just_after(run: mchip.MChipResult) -> None:
    c = run.collisions
    assert set(c.dtype.names or ()) >= {"time", "resonator", "angle", "angular_speed", "impulse_x"}
    assert np.all(np.diff(c["time"]) >= 0) and c["resonator"].max() < 40
    assert np.all(c["impulse_normal"] > 0)
    gaps = run.inter_arrival()
    period = 1 / 5000
    # One impact per resonator cycle (0.2 ms) and rebounds within a few hundredths of a ms.
    assert np.mean(np.abs(gaps - period) < 0.15 * period) > 0.1
    assert np.mean(gaps < 0.25 * period) > 0.05
    # Impacts push the part forward on balance.
    assert c["impulse_x"].sum() > 0


def test_the_part_pose_is_recorded(run: mchip.MChipResult) -> None:
    q, w = run.orientation, run.angular_velocity
    assert q.shape == (len(run.t), 4) and w.shape == (len(run.t), 3)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
    np.testing.assert_array_equal(q[0], [0.0, 0.0, 0.0, 1.0])
    # The part rocks by small angles, so the pitch's rate is the angular velocity about y.
    pitch = run.pitch()
    assert 1e-5 < np.abs(pitch).max() < 0.1
    rate = np.gradient(pitch, run.t)
    assert np.corrcoef(rate[5:-5], w[5:-5, 1])[0, 1] > 0.99


def test_double_bounces_come_in_slower_and_brake(run: mchip.MChipResult) -> None:
    # Thesis Fig. 2.7(a-c): the rebounds a few hundredths of a ms after an impact meet the part at
    # a lower angle and a much lower angular speed than the once-a-cycle impacts, and push it
    # backward on average.
    c, gaps = run.collisions, run.collision_gaps()
    assert gaps.shape == (len(c),) and np.isnan(gaps).sum() == len(np.unique(c["resonator"]))
    np.testing.assert_array_equal(np.sort(gaps[~np.isnan(gaps)]), np.sort(run.inter_arrival()))
    # Contact resumed within 5 µs is the same collision.
    assert np.nanmin(gaps) > 5e-6
    rebound = gaps < 0.05e-3
    cycle = np.abs(gaps - 0.2e-3) < 0.03e-3
    assert rebound.sum() > 10 and cycle.sum() > 10
    assert np.median(c["angular_speed"][rebound]) < 0.5 * np.median(c["angular_speed"][cycle])
    assert np.median(c["angle"][rebound]) < np.median(c["angle"][cycle])
    assert c["impulse_x"][rebound].mean() < 0 < c["impulse_x"][cycle].mean()
    # The once-a-cycle impacts catch the resonator on its way up (Fig. 2.6).
    assert np.median(c["angular_speed"][cycle]) > 0
    np.testing.assert_array_equal(run.impacts(), cycle)
    np.testing.assert_array_equal(run.rebounds(), rebound)
    assert run.impact_median("angular_speed") == np.median(c["angular_speed"][cycle])
    with pytest.raises(upm.ParameterError, match="field"):
        run.impact_median("speed")


def test_hop_frequency_finds_the_bounce_under_a_drift(run: mchip.MChipResult) -> None:
    # A synthetic height record: the part sinking (a slow drift much larger than the hop), a
    # 430 Hz bounce and the 5 kHz impacts. The estimator must find the bounce.
    t = np.arange(0.0, 0.2, 2e-5)
    z = 30e-6 - 1e-6 * np.sin(2 * np.pi * 20.0 * t) + 0.3e-6 * np.sin(2 * np.pi * 430.0 * t)
    z += 0.1e-6 * np.sin(2 * np.pi * 5000.0 * t)
    pos = np.zeros((len(t), 3))
    pos[:, 2] = z
    synthetic = dataclasses.replace(run, t=t, position=pos)
    assert abs(synthetic.hop_frequency() - 430.0) <= 1 / 0.19
    m = run.design.mass()
    np.testing.assert_allclose(synthetic.array_stiffness(), m * (2 * np.pi * synthetic.hop_frequency()) ** 2)
    # Too short a window to hold ten cycles of anything below 2.5 kHz.
    with pytest.raises(upm.ParameterError, match="longer run"):
        dataclasses.replace(run, t=t[:300], position=pos[:300]).hop_frequency(skip=0.0, cycles=1e4)


def test_jams_finds_stalls_against_the_free_rate(run: mchip.MChipResult) -> None:
    # A synthetic record: 1 mm/s, a stall at a fifth of that from 0.1 to 0.25 s (longer than
    # the free stretches together, so the run's average would itself be near a stall's rate),
    # then 1 mm/s again; the hop's wobble on top.
    t = np.arange(0.0, 0.3, 2e-5)
    v = np.where((t >= 0.1) & (t < 0.25), 0.2e-3, 1e-3)
    x = np.concatenate(([0.0], np.cumsum(v[:-1] * np.diff(t)))) + 0.02e-6 * np.sin(2 * np.pi * 5e3 * t)
    pos = np.zeros((len(t), 3))
    pos[:, 0] = x
    synthetic = dataclasses.replace(run, t=t, position=pos)
    jams = synthetic.jams(window=0.01)
    assert len(jams) == 1
    ((a, b),) = jams
    # The slow windows are those mostly inside the stall: it is found to within a window.
    assert abs(a - 0.1) < 0.01 and abs(b - 0.25) < 0.01
    # Two stalls closer than a window are one jam: the intervals never overlap.
    twice = np.where((t >= 0.1) & (t < 0.15) | (t >= 0.153) & (t < 0.2), 0.0, 1e-3)
    pos2 = np.zeros_like(pos)
    pos2[:, 0] = np.concatenate(([0.0], np.cumsum(twice[:-1] * np.diff(t))))
    merged = dataclasses.replace(run, t=t, position=pos2).jams(window=0.01)
    assert len(merged) == 1 and abs(merged[0][0] - 0.1) < 0.01 and abs(merged[0][1] - 0.2) < 0.01
    # A part blocked after 30 ms of a 0.3 s run (jammed for nine tenths of it: the 80th percentile
    # of the windowed rates is a jammed window's) is still found jammed, from the block on.
    blocked = np.where(t < 0.03, 1e-3, 0.0)
    pos3 = np.zeros_like(pos)
    pos3[:, 0] = np.concatenate(([0.0], np.cumsum(blocked[:-1] * np.diff(t))))
    stuck = dataclasses.replace(run, t=t, position=pos3).jams(window=0.01)
    assert len(stuck) == 1 and abs(stuck[0][0] - 0.03) < 0.01 and stuck[0][1] == pytest.approx(t[-1])
    # A steady feed has none; a part that never moves forward has no free rate and no jams.
    steady = dataclasses.replace(run, t=t, position=np.column_stack([1e-3 * t, 0 * t, 0 * t]))
    assert steady.jams() == []
    assert dataclasses.replace(run, t=t, position=np.zeros_like(pos)).jams() == []
    with pytest.raises(upm.ParameterError, match="fraction"):
        synthetic.jams(fraction=0.0)
    with pytest.raises(upm.ParameterError, match="longer"):
        synthetic.jams(window=1.0)


def test_row_impulse_splits_the_collision_log_by_row(run: mchip.MChipResult) -> None:
    per_row = run.row_impulse()
    assert per_row.shape == (8,)
    np.testing.assert_allclose(per_row.sum(), run.collisions["impulse_x"].sum(), rtol=1e-12)
    # The part starts over rows 0-3 (centre 600 µm, 1150 µm long; pitch 300 µm): in 20 ms it
    # cannot reach row 5's ridge at 1370 µm, so rows 5-7 gave nothing; the rows under it push
    # it forward on balance.
    assert np.all(per_row[5:] == 0)
    assert per_row[:5].sum() > 0
    rows = run.collisions["resonator"] // 5
    assert np.isclose(per_row[2], run.collisions["impulse_x"][rows == 2].sum(), rtol=1e-12)


def test_no_drive_no_feed() -> None:
    still = mchip.simulate(drive=mchip.Drive(scheme="off"), duration=0.01)
    # It drops 2 µm onto the ridges and rocks there (a few nm, damped) for a few ms; then it rests.
    landed = np.searchsorted(still.t, 0.006)
    assert np.ptp(still.position[landed:, 0]) < 5e-9
    # Its underside rests on the ridges' tops (5 µm above the slabs), which its weight tips down by
    # a few tenths of a µm (the joints' springs).
    assert 4.6e-6 < still.part_height(skip=0.006) < 5e-6


def test_strobe_and_phase_schemes_switch_rows() -> None:
    strobe = mchip.simulate(mchip.Design(rows=4, cols=1), mchip.Drive(scheme="strobe", tau=2, delta=2),
                            duration=2e-3, part=False, record_every=1)  # fmt: skip
    # Two rows (alternating) are off for two cycles at a time: their angles fall while the
    # others swing.
    swing = np.ptp(strobe.angles[-200:], axis=0)
    assert swing.min() < 0.5 * swing.max()
    phased = mchip.simulate(mchip.Design(rows=2, cols=1), mchip.Drive(scheme="phases", phases=(0.0, 0.5)),
                            duration=2e-3, part=False, record_every=1)  # fmt: skip
    a = phased.angles[-400:]
    assert np.corrcoef(a[:, 0], a[:, 1])[0, 1] < -0.5  # half a cycle apart


def test_conveyor_fit_recovers_a_viscous_law() -> None:
    forces = np.array([0.0, 1e-9, 2e-9, 3e-9])
    belt, c = mchip.conveyor_fit(forces, 1e-3 - forces / 2e-6)
    assert belt == pytest.approx(1e-3) and c == pytest.approx(2e-6)
    with pytest.raises(upm.ParameterError, match="does not fall"):
        mchip.conveyor_fit(forces, forces)


def test_bad_input_names_the_parameter() -> None:
    with pytest.raises(upm.ParameterError, match="scheme"):
        mchip.simulate(drive=mchip.Drive(scheme="wave"), duration=1e-3)
    with pytest.raises(upm.ParameterError, match="duty"):
        mchip.simulate(drive=mchip.Drive(duty=1.5), duration=1e-3)
    with pytest.raises(upm.ParameterError, match="dt"):
        mchip.simulate(duration=1e-3, dt=1e-5)
    with pytest.raises(upm.ParameterError, match="ridge_distance"):
        mchip.simulate(mchip.Design(ridge_distance=1e-3), duration=1e-3)
    with pytest.raises(upm.ParameterError, match="phases"):
        mchip.simulate(drive=mchip.Drive(scheme="phases", phases=(0.0,)), duration=1e-3)
    with pytest.raises(upm.ParameterError, match="design must be"):
        mchip.simulate("8x5", duration=1e-3)  # type: ignore[arg-type]


@pytest.mark.slow
def test_the_feed_demo_writes_its_figure_and_metrics(tmp_path: Path) -> None:

    pytest.importorskip("matplotlib")
    from upm.experiments.mchip_demos import run_mchip_demo

    metrics = run_mchip_demo("mchip-feed", out=tmp_path, quick=True, verbose=False)
    folder = tmp_path / "mchip-feed"
    assert (folder / "feed.png").stat().st_size > 10_000
    written = json.loads((folder / "metrics.json").read_text())
    assert written["feed_rate_mm_s"] == pytest.approx(metrics["feed_rate_mm_s"])
    # 40 ms (200 drive cycles) of the default part: it feeds forward without a jam, hit several
    # times a cycle but not more often than the 16 resonators under it could, most of its kinetic
    # energy in the hop.
    assert written["feed_rate_mm_s"] > 0.5 and written["jams_s"] == [] and written["jam_time_s"] == 0
    assert 2 * 200 < written["collisions"] < 16 * 200
    assert written["energy_share_vertical_hop"] > 0.5
    with pytest.raises(upm.ParameterError, match="mchip-feed"):
        run_mchip_demo("mchip-fed", out=tmp_path)


@pytest.mark.slow
def test_the_lower_duty_cycle_removes_a_heavy_parts_double_bounces() -> None:
    # Thesis 2.2.2 with its 1.15 x 0.4 x 0.25 mm part at 125 µg: at 50% duty its resonators
    # ricochet (the torque is still on when a ridge knocked back by the part comes up again); at
    # 36% the torque is off by then. The rebounds, after the landing, fall to a fraction, the
    # impacts come in faster and the part feeds faster.
    design = mchip.Design(part_size=(1150e-6, 400e-6, 250e-6), part_mass=125e-9)
    share, speed, feed = {}, {}, {}
    for duty in (0.5, 0.36):
        r = mchip.simulate(design, mchip.Drive(duty=duty), duration=0.045, record_every=20)
        gaps, late = r.collision_gaps(), r.collisions["time"] >= 0.015
        share[duty] = np.mean(gaps[late & ~np.isnan(gaps)] < 0.05e-3)
        speed[duty] = np.median(r.collisions["angular_speed"][r.impacts()])
        feed[duty] = r.feed_rate()
    assert share[0.5] > 0.05 and share[0.36] < 0.3 * share[0.5]
    assert speed[0.36] > 1.2 * speed[0.5] and feed[0.36] > feed[0.5]


def _square_wave_response(
    natural_frequency: float, quality: float, frequency: float, duty: float
) -> np.ndarray:
    """One period of a damped oscillator's steady response to a 0/1 square wave (its Fourier series,
    400 harmonics), in units of the torque over the stiffness."""
    w0, w = 2 * np.pi * natural_frequency, 2 * np.pi * frequency
    t = np.linspace(0.0, 1.0 / frequency, 2001)
    theta = np.full_like(t, duty)
    for m in range(1, 401):
        coefficient = (1 - np.exp(-2j * np.pi * m * duty)) / (2j * np.pi * m)
        gain = 1 / (1 - (m * w / w0) ** 2 + 1j * m * w / (w0 * quality))
        theta += 2 * np.real(coefficient * gain * np.exp(1j * m * w * t))
    return theta


@pytest.mark.slow
def test_a_joint_resonating_below_the_drive_lets_the_next_row_block_the_part() -> None:
    # Thesis 2.2.1. A joint resonating at 1.5 kHz, driven at 5 kHz, low-passes the square wave:
    # the free resonators ride on the torque's mean and swing between 0.063 and 0.08 rad (the
    # tuned default: 0 to 0.08), as the linear response predicts, so the free ridges never come
    # down to their rest height.
    design = mchip.Design(natural_frequency=1500.0)
    swings = {}
    for joint in (design, mchip.Design(), mchip.Design(natural_frequency=3000.0, quality=5.0)):
        low, high = swings[joint.natural_frequency] = mchip.free_swing(joint)
        predicted = _square_wave_response(joint.natural_frequency, joint.quality, 5000.0, 0.5)
        assert low / high == pytest.approx(predicted.min() / predicted.max(), abs=0.03)
        assert high == pytest.approx(0.08, rel=0.03)  # the drive is sized from the linear response
    assert swings[1500.0][0] > 0.7 * swings[1500.0][1] and swings[5000.0][0] < 0.01
    with pytest.raises(upm.ParameterError, match="design must be"):
        mchip.free_swing("8x5")  # type: ignore[arg-type]
    with pytest.raises(upm.ParameterError, match="and drive a"):
        mchip.free_swing(drive="strobe")  # type: ignore[arg-type]
    # The default part started with its front 30 µm behind row 5's ridge rides below the free
    # ridges' lowest height: it runs into the ridge's rear face and stays there, and row 5 pushes
    # it back on balance. Strobed, row 5 is switched off 20 ms in, its ridges drop, and the part
    # goes over them.
    pitch = design.slab[0] + design.gap
    ridge = 5 * pitch - design.ridge_distance - 0.5 * design.ridge_width  # the rear face
    start = (ridge - 30e-6 - 0.5 * design.part_size[0], 400e-6)
    front = {}
    for scheme in ("all", "strobe"):
        drive = mchip.Drive(scheme=scheme)
        r = mchip.simulate(design, drive, duration=0.06, record_every=20, part_start=start)
        front[scheme] = r.position[:, 0] + 0.5 * design.part_size[0]
        if scheme == "all":
            blocked = front["all"][r.t >= 0.035]
            # The tilted ridge's face stands about half a µm ahead of its place at rest.
            assert np.all((blocked > ridge) & (blocked < ridge + 1.5e-6))
            assert r.row_impulse()[5] < 0
    assert front["strobe"][-1] > ridge + design.ridge_width + 10e-6
