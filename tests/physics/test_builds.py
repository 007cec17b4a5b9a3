"""The point-part step's builds (docs/simulation.md, "Performance"): the chosen one is reported,
``UPM_SIMD`` picks another, and every build the CPU has reproduces the portable (correctly
rounded) build and an independent NumPy implementation of the step."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np

import upm

RUN = """
import json, sys
import numpy as np
import upm
wave = upm.TwoHarmonic(0.5, np.pi / 2, amplitude=0.05, frequency=35)
trans = upm.PlateMotion.translation((0.6, 0.8), wave).for_duration(2 / 35)
rot = upm.PlateMotion.rotation((0.03, -0.02), upm.Harmonics([0.5, -0.25], frequency=35)).for_duration(2 / 35)
motion = upm.PlateMotion.sequence([trans, rot])
pos = np.random.default_rng(1).uniform(-0.1, 0.1, (203, 2))
kw = dict(duration=4 / 35, dt=1 / 35 / 400, mu=0.3, mu_s=0.4, plate_size=0.19, record_every=40)
run = upm.simulate(motion, pos, **kw)
print(json.dumps({"simd": upm.build_info()["simd"], "pos": run.positions.tolist(),
                  "stuck": run.stuck.tolist(), "left": run.left_time.tolist()}))
"""


# A plate that moves out of its plane (the lift-off step, docs/ppod.md): hard enough that parts fly.
SPATIAL = """
import json
import numpy as np
import upm
m = upm.PlateMotion.harmonic(20.0, x=[(1, 10.0, 0.0)], y=[(1, 10.0, 1.57)], z=[(1, 6.0, 0.3)],
                             rx=[(1, 80.0, 3.7)], ry=[(1, 80.0, 5.2)])
pos = np.random.default_rng(2).uniform(-0.1, 0.1, (203, 2))
kw = dict(duration=0.2, dt=0.05 / 400, mu=0.3, mu_s=0.4, plate_size=0.19, record_every=40)
out = {"simd": upm.build_info()["simd"]}
for th in (1, 2):
    r = upm.simulate(m, pos, threads=th, **kw)
    left = np.nan_to_num(r.left_time, nan=-1.0).tolist()
    out[th] = [r.positions.tolist(), r.stuck.tolist(), r.flight_time.tolist(), left]
print(json.dumps(out))
"""


def _run(build: str, script: str = RUN) -> dict:
    env = dict(os.environ, UPM_SIMD=build)
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def test_every_build_of_the_out_of_plane_step_matches_the_portable_one() -> None:
    # bitwise the same for any thread count on one build; within rounding across builds (the
    # AVX-512 build's refined reciprocal square root), with the same decisions and flights
    reference = _run("portable", SPATIAL)
    assert reference["1"] == reference["2"]
    assert max(reference["1"][2]) > 0  # parts flew
    for build in upm.build_info()["available"][1:]:
        got = _run(build, SPATIAL)
        assert got["simd"] == build and got["1"] == got["2"]
        pos, stuck, flight, left = got["1"]
        assert np.abs(np.array(pos) - np.array(reference["1"][0])).max() < 1e-12
        assert stuck == reference["1"][1] and left == reference["1"][3]
        assert np.allclose(flight, reference["1"][2], rtol=0, atol=1e-9)


def test_build_info_reports_the_chosen_build() -> None:
    info = upm.build_info()
    assert info["simd"] in info["available"]
    assert info["available"][0] == "portable"
    assert set(info) >= {"version", "simd", "available", "cpu", "cores", "machine"}
    assert isinstance(info["cpu"], str) and info["cpu"]


def test_every_build_matches_the_portable_one() -> None:
    reference = _run("portable")
    assert reference["simd"] == "portable"
    for build in upm.build_info()["available"][1:]:
        got = _run(build)
        assert got["simd"] == build
        assert np.abs(np.array(got["pos"]) - np.array(reference["pos"])).max() < 1e-12
        assert got["stuck"] == reference["stuck"]
        assert np.array_equal(np.array(got["left"]), np.array(reference["left"]), equal_nan=True)


def test_an_unknown_build_falls_back_to_the_best() -> None:
    assert _run("no-such-build")["simd"] == upm.build_info()["available"][-1]


def test_the_step_matches_an_independent_numpy_step() -> None:
    # One step from 50,000 random states (velocities from far above the stick threshold to
    # within it), with the rule of docs/spec.md §1 written here.
    rng = np.random.default_rng(7)
    n, dt, mu, g = 50_000, 1e-4, 0.3, 9.81
    motion = upm.PlateMotion.rotation((0.01, 0.02), upm.Harmonics([0.5], frequency=35))
    pos = rng.uniform(-0.1, 0.1, (n, 2))
    slide = mu * g * dt
    vel = rng.normal(size=(n, 2)) * slide * 10 ** rng.uniform(-0.5, 3.5, (n, 1))
    parts = [upm.Point(tuple(p), velocity=tuple(v)) for p, v in zip(pos, vel, strict=True)]
    run = upm.simulate(motion, parts, duration=dt, dt=dt, mu=mu)
    u1, u2, u3 = motion.velocity(np.array([(1 - 1e-6) * dt]))[0]
    p, v = pos, vel
    s = np.stack([u1 - u3 * p[:, 1], u2 + u3 * p[:, 0]], 1)
    w = v - s
    wn = np.hypot(w[:, 0], w[:, 1])
    stick = wn <= slide
    keep = np.where(stick, 0.0, 1 - slide / np.where(stick, 1.0, wn))
    nv = s + w * keep[:, None]
    assert np.abs(run.velocities[-1] - nv).max() < 1e-15
    assert np.abs(run.positions[-1] - (p + 0.5 * (v + nv) * dt)).max() < 1e-15
    assert np.array_equal(run.stuck[-1], stick)
