"""Issue 60's bad calls: each refused up front with a UpmError naming the parameter, none crashing,
hanging or returning a silently wrong result."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

import upm
from upm import control
from upm.control.state import State
from upm.plate.drive import MAX_FREQUENCY
from upm.plate.plant import Envelope, SimulatedUPM
from upm.plate.pulses import Pulse

H = upm.Harmonics([1.0, -0.5], [0.0, 0.0], 35.0)


def refused(match: str, call, kind: type[Exception] = upm.UpmError) -> upm.UpmError:
    with pytest.raises(kind, match=match) as info:
        call()
    assert isinstance(info.value, upm.UpmError)
    return info.value


def test_a_long_average_is_refused_before_it_allocates():
    # it used to abort the process: "memory allocation of 53760000000 bytes failed"
    drive = upm.TwoHarmonic(0.5, 1.57, amplitude=0.02, frequency=35.0)
    motion = upm.PlateMotion.translation((1, 0), drive).for_duration(3e6)
    refused("motion.*too long to average", lambda: upm.average_field(motion, [(0.1, 0.0)]))
    # one period still averages
    one = upm.PlateMotion.translation((1, 0), drive)
    assert np.all(np.isfinite(upm.average_field(one, [(0.1, 0.0)])))


def test_frequencies_a_board_cannot_play_are_refused_not_simulated():
    start = time.perf_counter()
    refused("frequency", lambda: upm.jet_pulses([(0.0, 0.0)], [(0.01, 0.0)], mu=0.3, frequency=1e9))
    refused("frequency", lambda: upm.jet_pulses([(0.0, 0.0)], [(0.01, 0.0)], mu=0.3, frequency=1e5))
    limits = SimulatedUPM().limits
    refused("frequencies", lambda: upm.PredictivePlanner(limits, frequencies=(1e9,)))
    refused("frequency", lambda: Pulse.jet((0, 0), (1, 0), 0.05, 0.1, 2 * MAX_FREQUENCY, 0.1, 0.1, 0.1))
    assert time.perf_counter() - start < 60  # refusals, not runs (a loose bound: a hang took minutes)


def test_a_simulation_of_a_trillion_steps_is_refused():
    motion = upm.PlateMotion.rest(1.0)
    refused("duration / dt", lambda: upm.simulate(motion, [(0.0, 0.0)], duration=1e3, dt=1e-9, mu=0.3))


def test_a_pulse_is_checked_however_it_is_built():
    refused("frequency", lambda: Pulse("rotation", (0.0, 0.0), 0.0, 0.1, 0.1, 0.1, waveform=H))
    refused("kind", lambda: Pulse("spin", (0.0, 0.0), 35.0, 0.1, 0.1, 0.1))  # type: ignore[arg-type]
    refused("waveform", lambda: Pulse("rotation", (0.0, 0.0), 35.0, 0.1, 0.1, 0.1))
    refused("attack", lambda: Pulse("rotation", (0.0, 0.0), 35.0, -0.1, 0.1, 0.1, waveform=H))
    refused("attack \\+ sustain", lambda: Pulse("rotation", (0.0, 0.0), 35.0, 0.0, 0.0, 0.0, waveform=H))
    refused("direction", lambda: Pulse("jet", (0.0, 0.0), 35.0, 0.1, 0.1, 0.1, direction=(0.0, 0.0), rho=0.05,
                                       amplitude=0.1))  # fmt: skip
    refused("rho", lambda: Pulse("jet", (0.0, 0.0), 35.0, 0.1, 0.1, 0.1, direction=(1.0, 0.0), amplitude=0.1))
    refused("plate_motion", lambda: Pulse("field", (0.0, 0.0), 35.0, 0.1, 0.1, 0.1))
    # what the limits' check met as a bare AssertionError or ZeroDivisionError
    refused("pulse", lambda: SimulatedUPM().limits.check("rotation"))  # type: ignore[arg-type]
    # the builders still build
    good = Pulse.rotation((0.0, 0.0), H, 0.1, 0.1, 0.1, rest=0.2)
    assert good.duration == pytest.approx(0.5)


def test_motions_from_anything_but_their_builders_are_refused():
    refused("inner", lambda: upm.PlateMotion(None))  # type: ignore[arg-type]
    refused("inner", lambda: upm.PlateMotion(3))  # type: ignore[arg-type]
    refused("phasors\\[1\\] must hold 6", lambda: upm.PlateMotion.from_phasors(20.0, {1: np.zeros(5)}))
    refused("keys must be harmonics", lambda: upm.PlateMotion.from_phasors(20.0, {0: np.zeros(6)}))
    refused("phasors\\[1\\]", lambda: upm.PlateMotion.from_phasors(20.0, {1: "six"}))


def test_the_simulated_plant_refuses_what_it_cannot_simulate():
    refused("parts", lambda: SimulatedUPM(parts=[[0.0, 0.0, 0.0]]))
    refused("parts", lambda: SimulatedUPM(parts=np.zeros((2, 4))))
    refused("seed", lambda: SimulatedUPM(parts=[[0.0, 0.0]], seed=-1))
    refused("mu", lambda: SimulatedUPM(parts=[[0.0, 0.0]], mu=float("nan")))
    refused("mu_s", lambda: SimulatedUPM(parts=[[0.0, 0.0]], mu=0.3, mu_s=0.2))
    refused("restitution", lambda: SimulatedUPM(parts=[[0.0, 0.0]], restitution=3))
    refused("overlap", lambda: SimulatedUPM(parts=[[0.0, 0.0], [0.01, 0.0]], part_radius=0.01))
    touching = SimulatedUPM(parts=[[0.0, 0.0], [0.02, 0.0]], part_radius=0.01)  # rims touch: allowed
    assert touching.parts.shape == (2, 2)
    refused("labels", lambda: touching.camera(["red"]))
    refused("attack", lambda: Envelope(attack=-1))


def test_a_sort_refuses_parts_whose_label_has_no_side():
    refused("sides", lambda: control.SortTask(["red", "blue"]))  # type: ignore[arg-type]
    task = control.SortTask({"red": -1, "green": 1})
    state = State(0, 0.0, np.arange(3), np.array([[-0.15, 0.0], [0.15, 0.0], [0.0, 0.0]]),
                  ("red", "green", "blue"), 0.0)  # fmt: skip
    # it used to report done with the blue chip unsorted in the middle
    refused("blue", lambda: task.done(state))
    ignoring = control.SortTask({"red": -1, "green": 1}, ignore=["blue"])
    assert ignoring.done(state)
    refused("share", lambda: control.SortTask({"red": -1, "blue": 1}, ignore=["blue"]))


def test_jets_refuse_a_part_listed_twice():
    refused("distinct", lambda: upm.jet_pulses([(0.0, 0.0), (0.1, 0.0)], [(0.01, 0.0), (0.01, 0.0)], mu=0.3,
                                               order=[0, 0]))  # fmt: skip


def test_rests_trimmed_only_from_pulses():
    refused("pulses", lambda: upm.trim_rests([1, 2], np.zeros((1, 2)), mu=0.3))  # type: ignore[list-item]


def test_a_corrupt_log_is_named_as_such(tmp_path: Path):
    bad = tmp_path / "log.npz"
    bad.write_bytes(np.random.default_rng(0).bytes(300))
    refused("not a log", lambda: control.load_log(bad))
    refused("no log", lambda: control.load_log(tmp_path / "missing.npz"))
    np.save(tmp_path / "array.npy", np.zeros(3))
    refused("not a log", lambda: control.load_log(tmp_path / "array.npy"))


def test_a_palette_with_one_colour_for_two_labels_is_refused():
    from upm.vision.parts import Palette

    refused("same colour", lambda: Palette({"red": (110, 125, 220), "pink": (110, 125, 220)}))
    refused("tolerance", lambda: Palette({"red": (110, 125, 220)}, tolerance=float("nan")))


def test_noise_is_not_a_table():
    pytest.importorskip("cv2")
    from upm.vision import find_table

    rng = np.random.default_rng(0)
    for shape in ((480, 640, 3), (960, 1280)):
        refused("no table found", lambda shape=shape: find_table(rng.integers(0, 256, shape, dtype=np.uint8)))
    plant = SimulatedUPM(parts=[[0.05, 0.02], [-0.08, 0.1]])
    _, frame = plant.camera("red").read()
    found = find_table(frame)  # a real plate is still found, its edges to a pixel
    assert found.residual < 1.0 and np.ptp(found.corners, axis=0).min() > 0.3 * min(frame.shape[:2])


def test_a_sweep_parameter_given_twice_is_refused():
    refused("both as grid axes and as fixed", lambda: upm.sweep(lambda a, b: a + b, {"a": [1, 2]}, a=3, b=1,
                                                               progress=False))  # fmt: skip


def test_board_settings_are_checked_before_anything_opens():
    pytest.importorskip("serial")
    from upm.board import Board

    refused("timeout", lambda: Board("loop://", timeout=-1))
    refused("timeout", lambda: Board("loop://", timeout=float("inf")))
    refused("retries", lambda: Board("loop://", retries=-1))
    refused("retries", lambda: Board("loop://", retries=1.5))  # type: ignore[arg-type]
    refused("heartbeat", lambda: Board("loop://", heartbeat=0))
    refused("url", lambda: Board(None))  # type: ignore[arg-type]


def test_inputs_that_broadcast_beyond_memory_are_refused_up_front():
    big = np.zeros((10**6, 1))
    refused("broadcast to", lambda: upm.TwoHarmonic(big, np.zeros((1, 10**6)), amplitude=1.0, frequency=35.0))


def test_a_sweep_without_progress_needs_no_tqdm(monkeypatch: pytest.MonkeyPatch):
    pytest.importorskip("xarray")
    monkeypatch.setitem(__import__("sys").modules, "tqdm", None)
    monkeypatch.setitem(__import__("sys").modules, "tqdm.auto", None)
    out = upm.sweep(lambda a, b: a + b, {"a": [1.0, 2.0]}, b=1.0, progress=False, n_jobs=1)
    (values,) = out.data_vars.values()
    np.testing.assert_allclose(values.values, [2.0, 3.0])
    refused("tqdm", lambda: upm.sweep(lambda a, b: a + b, {"a": [1.0]}, b=1.0, progress=True, n_jobs=1),
            upm.MissingExtraError)  # fmt: skip


def test_subpackages_load_on_first_use_as_the_docs_call_them():
    # docs/sweeps.md calls upm.plot.sweep after a bare `import upm` (it raised AttributeError)
    import subprocess
    import sys

    code = "import upm; print(upm.plot.sweep.__name__, upm.control.Loop.__name__); upm.nothing"
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.stdout.split() == ["sweep", "Loop"]
    assert "module 'upm' has no attribute 'nothing'" in run.stderr
