"""Rerun recordings: a recorded loop read back through rerun's own reader, recording changes no
result, simulations and the M-Chip as recordings, bad input refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("rerun")

import upm
from upm import control, viz
from upm.physics.waveforms import Harmonics
from upm.plate.actuation import Plate
from upm.plate.drive import flexures
from upm.plate.plant import SimulatedUPM
from upm.plate.pulses import Pulse

PLATE = Plate(1.0, 0.0275, 0.2)
AXES = flexures(PLATE.mass, PLATE.inertia)
CHIP = 0.0195
STARTS = np.array([[0.05, 0.05], [-0.03, -0.06], [0.02, -0.01], [-0.06, 0.04]])
LABELS = ["red", "red", "blue", "blue"]


def sort_run(tmp_path, recording=None, cycles=6):
    plant = SimulatedUPM(plate=PLATE, axes=AXES, parts=STARTS, snr_db=None)
    task = control.SortTask({"red": -1, "blue": 1}, line=0.09, margin=0.08, spacing=0.046, max_step=0.025)
    planner = control.JetPlanner(mu=0.3, amplitude=0.1, rho=0.03, plate=PLATE, axes=AXES)
    loop = control.Loop(plant, plant.camera(LABELS), planner, task, part_radius=CHIP)
    log = loop.run(cycles, recording=recording)
    return log, plant


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("rec")
    log, plant = sort_run(tmp, tmp / "sort.rrd")
    return log, plant, viz.read_recording(tmp / "sort.rrd")


def test_a_recorded_loop_reads_back_with_every_entity(recorded):
    log, _, rec = recorded
    every = (
        "camera/image camera/parts plate/parts plate/steps/desired plate/steps/achieved plate/field "
        "plate/centers plate/task series/plate/speed series/plate/motion series/motors "
        "series/timing series/task/error events"
    )
    for entity in every.split():
        assert entity in rec, entity
    cycles = len(log.rows)
    assert rec.rows("plate/parts") == cycles  # one row per cycle, the last (no pulses) included
    assert rec["plate/parts"]["frame"] == list(range(cycles))
    assert rec.rows("series/timing") == cycles
    timings = np.array(rec["series/timing"]["Scalars:scalars"]) / 1e3
    np.testing.assert_allclose(
        timings, np.stack([log.vision, log.planning, log.execution], axis=1), rtol=1e-12
    )
    # every pulse played has its series row; every cycle that played pulses has a field
    assert rec.rows("series/plate/speed") == sum(log.pulses)
    assert rec.rows("plate/field") == sum(1 for n in log.pulses if n)
    assert 1 <= rec.rows("camera/image") <= cycles
    assert rec.static["/plate/outline"]["LineStrips2D:strips"]  # the plate's edge, static
    assert any("run ended" in str(t) for t in rec["events"]["TextLog:text"])


def test_recorded_positions_are_the_logs(recorded):
    log, _, rec = recorded
    rows = rec["plate/parts"]
    for c in range(len(log.rows)):
        ids = rows["Points2D:class_ids"][c]
        got = np.array(rows["Points2D:positions"][c], dtype=np.float64)
        want = np.array([log.rows[c][int(i)][0] for i in ids])
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-7)  # stored as float32
        # plate times on the timeline are the log's
        assert rows["plate_time"][c].total_seconds() == pytest.approx(log.time[c], abs=1e-6)
    labels = rows["Points2D:labels"][0]
    assert sorted(lab.split()[1] for lab in labels) == sorted(LABELS)


def test_recorded_steps_are_the_logs(recorded):
    log, _, rec = recorded
    desired = rec["plate/steps/desired"]
    for c in range(len(log.rows) - 1):
        want = np.array([d for _, d, _ in log.rows[c].values() if np.all(np.isfinite(d))])
        got = np.array(desired["Arrows2D:vectors"][c], dtype=np.float64).reshape(-1, 2)
        np.testing.assert_allclose(np.sort(got, axis=0), np.sort(want, axis=0), atol=1e-7)
    achieved = rec["plate/steps/achieved"]
    for c in range(1, len(log.rows)):
        want = np.array(list(log.achieved_rows[c - 1].values())).reshape(-1, 2)
        got = np.array(achieved["Arrows2D:vectors"][c], dtype=np.float64).reshape(-1, 2)
        np.testing.assert_allclose(np.sort(got, axis=0), np.sort(want, axis=0), atol=1e-7)


def test_recording_changes_none_of_the_runs_results(recorded, tmp_path):
    log, plant, _ = recorded
    plain, plain_plant = sort_run(tmp_path)
    np.testing.assert_array_equal(plain.positions, log.positions)
    np.testing.assert_array_equal(plain.desired, log.desired)
    assert plain.time == log.time
    np.testing.assert_array_equal(plain_plant.parts, plant.parts)


def test_pulse_series_match_an_independent_sampling():
    wave = Harmonics([0.05, 0.0], [0.0, 0.02], frequency=50.0)
    p = Pulse.rotation((0.1, -0.05), wave, 0.02, 0.2, 0.02)
    got = viz.pulse_series(p, plate_size=0.4, plate=PLATE)
    t = np.linspace(0, 1 / p.frequency, 20001)
    motion = p.motion(rest=False)
    steady = t + p.attack  # envelope is 1 from attack to attack + sustain
    u = motion.velocity(steady[steady < p.attack + p.sustain])
    assert got["speed"] == pytest.approx(1e3 * np.max(np.hypot(u[:, 0], u[:, 1])), rel=1e-3)
    assert got["rotation"] == pytest.approx(np.max(np.abs(u[:, 2])), rel=1e-3)
    # a rotation about C: the corner farthest from C moves most, |theta| * distance
    theta = np.max(np.abs(np.cumsum(u[:, 2]) * (t[1] - t[0])))
    assert got["excursion"] > 0 and math.isfinite(got["excursion"])
    far = max(math.dist((0.1, -0.05), (sx * 0.2, sy * 0.2)) for sx in (-1, 1) for sy in (-1, 1))
    assert got["excursion"] == pytest.approx(1e3 * theta * far, rel=0.2)  # theta's drift bounds it loosely
    assert set(got) >= {"X1", "X2", "Y1", "Y2"} and all(got[m] > 0 for m in ("X1", "X2", "Y1", "Y2"))


def test_sim_result_to_rerun(tmp_path):
    parts = [upm.Disk((0.0, 0.0), radius=0.01), upm.Disk((0.05, 0.02), radius=0.01)]
    motion = upm.PlateMotion.rotation((0.1, 0.0), Harmonics([4.0, 0.0], [0.0, 2.0], frequency=50.0))
    r = upm.simulate(motion, parts, duration=0.2, dt=2e-4, mu=0.3, record_every=100)
    path = r.to_rerun(tmp_path / "sim.rrd", radius=0.01)
    rec = viz.read_recording(path)
    assert rec.rows("sim/parts") == len(r.t)
    for k in range(len(r.t)):
        got = np.array(rec["sim/parts"]["Points2D:positions"][k], dtype=np.float64)
        np.testing.assert_allclose(got, r.positions[k], atol=1e-7)
    assert rec.rows("sim/orientation") == len(r.t)
    assert rec.rows("series/sim/stuck") == len(r.t)


def test_bad_recordings_are_refused(tmp_path):
    with pytest.raises(upm.ParameterError, match=r"recording must be a \.rrd"):
        viz.Recorder(tmp_path / "x.txt")
    with pytest.raises(upm.ParameterError, match="recording must be"):
        sort_run(tmp_path, recording=42, cycles=1)
    with pytest.raises(upm.ParameterError, match="max_queue"):
        viz.Recorder(tmp_path / "x.rrd", max_queue=1)
    with pytest.raises(upm.ParameterError, match="no recording"):
        viz.read_recording(tmp_path / "missing.rrd")
    # `upm replay` on a file that is not a recording exited 0 with a picture of the welcome page
    fake = tmp_path / "not-a-recording.rrd"
    fake.write_bytes(b"just some bytes, not rerun's")
    from upm.viz.replay import replay

    with pytest.raises(upm.ParameterError, match="not a rerun recording"):
        replay(fake, png=tmp_path / "x.png")
    assert not (tmp_path / "x.png").exists()


def test_a_slow_recorder_drops_and_says_so(tmp_path, monkeypatch):
    import threading

    gate = threading.Event()
    rec = viz.Recorder(tmp_path / "slow.rrd", max_queue=4, frame_rate=1e6)
    original = rec._log  # the background thread's worker: held until released

    def slow(c):
        gate.wait(10)
        original(c)

    monkeypatch.setattr(rec, "_log", slow)
    log, _ = sort_run(tmp_path, recording=rec, cycles=8)
    gate.set()
    rec.close()
    assert rec.dropped_cycles > 0 and rec.dropped_frames > 0
    assert rec.cycles + rec.dropped_cycles == len(log.rows)
    back = viz.read_recording(tmp_path / "slow.rrd")
    assert any("fell behind" in str(t) for t in back["events"]["TextLog:text"])


def test_mchip_result_to_rerun(tmp_path):
    from upm import mchip

    run = mchip.simulate(duration=0.004, record_every=200)
    rec = viz.read_recording(run.to_rerun(tmp_path / "mchip.rrd"))
    assert rec.rows("mchip/part") == len(run.t)
    centres = np.array([c[0] for c in rec["mchip/part"]["Boxes3D:centers"]], dtype=np.float64)
    np.testing.assert_allclose(centres, run.position, atol=1e-9)
    n = run.design.rows * run.design.cols
    assert all(f"series/mchip/resonators/{k}" in rec for k in range(n))
    got = np.array([v[0] for v in rec["series/mchip/resonators/3"]["Scalars:scalars"]])
    np.testing.assert_allclose(got, 1e3 * run.angles[:, 3], rtol=1e-12)
    hits = rec["events"]["TextLog:text"] if "events" in rec else []
    assert len(hits) == int(np.sum(run.collisions["time"] <= run.t[-1]))


def test_replay_serves_the_web_viewer_on_localhost(tmp_path):
    import urllib.request

    path = upm.simulate(
        upm.PlateMotion.rotation((0.1, 0.0), Harmonics([4.0, 0.0], [0.0, 2.0], frequency=50.0)),
        [[0.0, 0.0]],
        duration=0.05,
        dt=2e-4,
        mu=0.3,
    ).to_rerun(tmp_path / "r.rrd")
    with viz.serve_web(path) as url:
        assert url.startswith("http://127.0.0.1:") and "rerun%2Bhttp%3A%2F%2F127.0.0.1" in url
        with urllib.request.urlopen(url.split("?")[0], timeout=10) as page:
            assert page.status == 200 and b"rerun" in page.read().lower()
    with pytest.raises(OSError):  # the viewer and its launcher are gone with the context
        urllib.request.urlopen(url.split("?")[0], timeout=2)
    with pytest.raises(upm.ParameterError, match="no recording"):
        viz.replay(tmp_path / "nothing.rrd")


@pytest.mark.slow
def test_replay_screenshot_draws_the_recording(recorded, tmp_path):
    pytest.importorskip("playwright.sync_api")
    try:
        viz.chromium()
    except upm.MissingExtraError as error:
        pytest.skip(str(error))
    import subprocess
    import sys

    source = tmp_path / "sort.rrd"
    sort_run(tmp_path, source, cycles=3)
    png = tmp_path / "shot.png"
    out = subprocess.run(
        [sys.executable, "-m", "upm.cli", "replay", str(source), "--screenshot", str(png), "--wait", "8"],
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert out.returncode == 0, out.stderr
    import cv2

    img = cv2.imread(str(png))
    assert img is not None and img.shape[1] >= 1200
    # the plate view draws the parts in their labels' colours: red and blue pixels are there
    b, g, r = (img[..., k].astype(int) for k in range(3))
    assert np.sum((r > 180) & (g < 130) & (b < 130)) > 200  # red chips
    assert np.sum((b > 180) & (r < 120)) > 200  # blue chips


def test_the_drawn_field_is_the_average_force_at_rest():
    # independent reference: upm.average_field's adaptive quadrature on the same steady motion
    wave = Harmonics([0.05, 0.02], [0.0, 0.0], frequency=50.0)  # a Coulomb pump: a net rotation field
    pulses = [
        Pulse.rotation((0.03, -0.02), wave, 0.02, 0.3, 0.02),
        Pulse.jet((-0.05, 0.04), (1.0, 0.0), 0.03, 0.1, 40.0, 0.02, 0.2, 0.02),
    ]
    grid = np.stack(np.meshgrid(np.linspace(-0.17, 0.17, 5), np.linspace(-0.16, 0.18, 5)), -1).reshape(-1, 2)
    got = viz.field_on_grid(pulses, grid, samples=2048)
    raw = sum(p.on_time * upm.average_field(p.steady(), grid, tol=1e-8) for p in pulses)
    top = np.max(np.hypot(raw[:, 0], raw[:, 1]))
    assert top / sum(p.on_time for p in pulses) > 0.05  # a field worth drawing, in units of mu m g
    want = raw / top
    np.testing.assert_allclose(got, want, atol=2e-3)
    assert viz.field_on_grid([Pulse.pause(0.1)], grid) is None


@pytest.mark.slow
def test_upm_demo_rrd_records_the_mchip_feed(tmp_path):
    from upm import cli

    assert cli.main(["demo", "mchip-feed", "--quick", "--rrd", "--out", str(tmp_path)]) == 0
    rec = viz.read_recording(tmp_path / "mchip-feed" / "run.rrd")
    assert rec.rows("mchip/part") > 100 and "series/mchip/z" in rec
