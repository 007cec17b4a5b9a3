"""Public value objects pickle, deep-copy and compare by value, with compact reprs (issue 23, item 6),
and SimResult saves, loads and labels itself (item 7)."""

from __future__ import annotations

import copy
import pickle
from concurrent.futures import ProcessPoolExecutor

import cloudpickle
import numpy as np
import pytest

import upm
from upm.plate.pulses import Pulse

H = upm.Harmonics([2.0, -1.0], frequency=35.0)
SPIN = upm.PlateMotion.rotation((0.0, 0.0), H)
T = np.linspace(0.0, 1.2, 97)


def motions() -> dict[str, upm.PlateMotion]:
    jet = upm.PlateMotion.jet((0.01, 0.0), (0.0, 1.0), 0.1, 0.1, 35.0)
    return {
        "rotation": SPIN,
        "translation": upm.PlateMotion.translation((1.0, 1.0), upm.TwoHarmonic(0.5, np.pi / 2, 0.3, 35.0)),
        "jet": jet,
        "rest": upm.PlateMotion.rest(0.25),
        "bang_bang": upm.PlateMotion.translation((0.0, 1.0), upm.BangBang(0.3, 2.0, 0.05)),
        "samples": upm.PlateMotion.from_samples([0.0, 0.5, 1.0], [0.0, 0.1, 0.0], [0.0] * 3, [0.0, 0.0, 1.0]),
        "program": upm.PlateMotion.sequence(
            [SPIN.with_envelope(0.02, 0.2, 0.02), upm.PlateMotion.rest(0.1), jet.for_duration(0.5)]
        ),
    }


@pytest.mark.parametrize("name", sorted(motions()))
@pytest.mark.parametrize("dumps", [pickle.dumps, cloudpickle.dumps], ids=["pickle", "cloudpickle"])
def test_motions_round_trip_and_compare_by_value(name, dumps):
    motion = motions()[name]
    back = pickle.loads(dumps(motion))
    assert back == motion and hash(back) == hash(motion)
    assert copy.deepcopy(motion) == motion
    np.testing.assert_array_equal(back.velocity(T), motion.velocity(T))  # the same program, bitwise
    assert back.duration == motion.duration
    assert motions()[name] == motion  # two identical builds are equal (they were not)
    shown = {"bang_bang": "BangBang", "samples": "from_samples", "program": "sequence"}.get(name, name)
    assert len(repr(motion)) < 250 and shown in repr(motion)


def test_different_motions_are_unequal():
    assert SPIN != SPIN.for_duration(1.0)
    assert SPIN != upm.PlateMotion.rotation((0.0, 0.001), H)
    assert upm.PlateMotion.rest(0.1) != upm.PlateMotion.rest(0.2)


@pytest.mark.parametrize(
    "waveform",
    [H, upm.TwoHarmonic([0.1, 0.5], np.pi / 2), upm.BangBang(0.4, 1.0, 2.0)],
    ids=lambda w: type(w).__name__,
)
def test_waveforms_round_trip(waveform):
    back = pickle.loads(pickle.dumps(waveform))
    assert back == waveform and hash(back) == hash(waveform)
    np.testing.assert_array_equal(upm.mean_force(back, 0.1), upm.mean_force(waveform, 0.1))
    assert copy.deepcopy(waveform) == waveform


def _simulate(motion: upm.PlateMotion) -> np.ndarray:
    return upm.simulate(motion, [[0.05, 0.0]], duration=0.1, dt=1e-4, mu=0.3).positions[-1]


def test_a_motion_runs_in_another_process():
    # What multiprocessing, joblib and dask with user functions need.
    motion = motions()["program"]
    with ProcessPoolExecutor(1) as pool:
        there = pool.submit(_simulate, motion).result(timeout=120)
    np.testing.assert_array_equal(there, _simulate(motion))


def test_plans_results_limits_and_pulses_round_trip(tmp_path):
    plan = upm.solve_rotations(
        [(0.5, 0), (-0.75, 0.25)],
        [(0.01, 0.01), (-0.01, 0)],
        upm.corner_centers((-1, -0.5, 1, 0.5)),
        mu_m_g=0.1,
    )
    run = upm.simulate(SPIN, np.array([[0.05, 0.0], [0.0, 0.08]]), duration=0.05, dt=1e-4, mu=0.3)
    pulse = Pulse.rotation((0.0, 0.0), H, 0.02, 0.2, 0.02)
    for value in (plan, run, upm.DriveLimits(), pulse):
        back = pickle.loads(pickle.dumps(value))
        assert back == value, type(value).__name__
        assert len(repr(value)) < 400, (type(value).__name__, len(repr(value)))
    assert plan != upm.solve_rotations(
        [(0.5, 0), (-0.75, 0.2)],
        [(0.01, 0.01), (-0.01, 0)],
        upm.corner_centers((-1, -0.5, 1, 0.5)),
        mu_m_g=0.1,
    )
    # SimResult: saved and loaded bitwise; labelled with units.
    path = run.save(tmp_path / "run")
    assert path.name == "run.npz" and upm.SimResult.load(path) == run
    ds = run.to_xarray()
    assert ds.positions.dims == ("time", "part", "axis") and ds.positions.attrs["units"] == "m"
    np.testing.assert_array_equal(ds.positions.values, run.positions)
    np.testing.assert_array_equal(ds.time.values, run.t)
    (tmp_path / "other.npz").write_bytes(b"")
    np.savez(tmp_path / "other.npz", x=np.zeros(1))
    with pytest.raises(upm.ParameterError, match="not a saved SimResult"):
        upm.SimResult.load(tmp_path / "other.npz")
