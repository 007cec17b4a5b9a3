"""The guard of the public API: every entry point, fed a wrong type, shape or value in any one of
its arguments, either works or raises a `upm.UpmError` subclass, never a built-in exception, a
Rust panic or a hang.

Each entry point is called once with arguments that work, then once per (argument, bad value)
with that one argument replaced; hypothesis then mixes several bad arguments at once.
"""

from __future__ import annotations

import math
import signal
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import upm
from upm import actuation, theory
from upm.board import protocol as p
from upm.vision import find_parts, find_table, plate_corners
from upm.vision.synthetic import Camera, render

SPIN = upm.PlateMotion.rotation((0.0, 0.0), upm.Harmonics([2.0, -1.0], frequency=35.0))
CORNERS = upm.corner_centers((-1, -0.5, 1, 0.5))


class _Opaque:
    def __repr__(self) -> str:
        return "<opaque>"


#: One bad value of each kind a user passes by mistake.
BAD: list[Any] = [
    None,
    "abc",
    math.nan,
    math.inf,
    -math.inf,
    -1,
    0,
    1.5,
    -1e300,
    1e300,
    2**70,
    True,
    1 + 1j,
    [],
    np.zeros(0),
    np.zeros((0, 2)),
    np.zeros((2, 3, 4)),
    [[1.0, "x"]],
    np.array([np.nan, 1.0]),
    _Opaque(),
]


def _frame_and_table() -> tuple[Any, Any]:
    frame = render(Camera(), [(0.0, 0.0)], ["red"], rng=1).image
    return frame, find_table(frame)


FRAME, TABLE = _frame_and_table()
PLATE = actuation.Plate(mass=1.0, inertia=0.0275, lever=0.2)
AXIS = actuation.Axis(mass=1.0, damping=2.0, stiffness=350.0)

#: name -> (callable, arguments that work). Every argument is passed by name.
ENTRIES: dict[str, tuple[Callable[..., Any], dict[str, Any]]] = {
    "TwoHarmonic": (upm.TwoHarmonic, {"b": 0.5, "phi": 1.0, "amplitude": 1.0, "frequency": 35.0}),
    "Harmonics": (upm.Harmonics, {"cos": [1.0, 0.5], "sin": [0.0, 0.2], "frequency": 35.0}),
    "BangBang": (upm.BangBang, {"z": 0.5, "a_max": 1.0, "period": 1.0}),
    "feed_rate": (upm.feed_rate, {"waveform": upm.TwoHarmonic(0.5, 1.0)}),
    "mean_force": (upm.mean_force, {"waveform": upm.TwoHarmonic(0.5, 1.0), "part_velocity": 0.1}),
    "theorem1_force": (upm.theorem1_force, {"n1": 1, "n2": 2, "psi": 0.3}),
    "force_table": (upm.force_table, {"n1": 1, "n2": 3, "psi": [0.1, 0.2], "b": 1.0}),
    "PlateMotion.rotation": (
        upm.PlateMotion.rotation,
        {"center": (0.0, 0.0), "waveform": upm.Harmonics([1.0], frequency=35.0)},
    ),
    "PlateMotion.translation": (
        upm.PlateMotion.translation,
        {"direction": (1.0, 0.0), "waveform": upm.Harmonics([1.0], frequency=35.0)},
    ),
    "PlateMotion.jet": (
        upm.PlateMotion.jet,
        {"center": (0.0, 0.0), "direction": (0.0, 1.0), "rho": 0.1, "amplitude": 0.1, "frequency": 35.0},
    ),
    "PlateMotion.rest": (upm.PlateMotion.rest, {"duration": 0.1}),
    "PlateMotion.sequence": (upm.PlateMotion.sequence, {"motions": [SPIN.for_duration(0.1), SPIN]}),
    "PlateMotion.from_samples": (
        upm.PlateMotion.from_samples,
        {"t": [0.0, 0.1, 0.2], "u1": [0.0, 1.0, 0.0], "u2": [0.0, 0.0, 0.0], "u3": [0.0, 0.0, 0.0]},
    ),
    "PlateMotion.for_duration": (SPIN.for_duration, {"seconds": 0.1}),
    "PlateMotion.with_envelope": (SPIN.with_envelope, {"attack": 0.01, "sustain": 0.1, "decay": 0.01}),
    "PlateMotion.velocity": (SPIN.velocity, {"t": [0.0, 0.01]}),
    "PlateMotion.acceleration": (SPIN.acceleration, {"t": [0.0, 0.01]}),
    "PlateMotion.is_closed": (SPIN.is_closed, {"tol": 1e-9}),
    "rotation_field": (upm.rotation_field, {"points": [(0.1, 0.0)], "center": (0.0, 0.0)}),
    "rotation_curl": (upm.rotation_curl, {"points": [(0.1, 0.0)], "center": (0.0, 0.0)}),
    "jet_field": (
        upm.jet_field,
        {"points": [(0.1, 0.0)], "center": (0.0, 0.0), "direction": (0.0, 1.0), "rho": 1.0, "tol": 1e-10},
    ),
    "average_field": (
        upm.average_field,
        {"motion": SPIN.for_duration(0.1), "points": [(0.1, 0.0)], "part_velocity": None, "tol": 1e-10},
    ),
    "simulate": (
        upm.simulate,
        {
            "motion": SPIN,
            "parts": np.zeros((2, 2)),
            "duration": 0.02,
            "dt": 5e-4,
            "mu": 0.3,
            "mu_s": 0.4,
            "g": 9.81,
            "record_every": 1,
        },
    ),
    "simulate disks": (
        upm.simulate,
        {
            "motion": SPIN,
            "parts": [upm.Disk((0.0, 0.0), 0.01), upm.Disk((0.05, 0.0), 0.01)],
            "duration": 0.02,
            "dt": 5e-4,
            "mu": 0.3,
            "contacts": True,
            "walls": "plate",
            "plate_size": 0.4,
            "restitution": 0.5,
            "part_friction": 0.3,
            "contact_iterations": 4,
        },
    ),
    "simulate_batch": (
        upm.simulate_batch,
        {
            "motions": [SPIN, SPIN],
            "parts": np.zeros((2, 2)),
            "duration": 0.02,
            "dt": 5e-4,
            "mu": 0.3,
            "record_every": 5,
            "threads": 1,
        },
    ),
    "Disk": (upm.Disk, {"position": (0.0, 0.0), "radius": 0.01, "velocity": (0.0, 0.0)}),
    "Point": (upm.Point, {"position": (0.0, 0.0), "velocity": (0.0, 0.0)}),
    "corner_centers": (upm.corner_centers, {"workspace": (-1, -0.5, 1, 0.5)}),
    "grid_centers": (upm.grid_centers, {"shape": (2, 2), "workspace": (-1, -1, 1, 1)}),
    "ring_centers": (upm.ring_centers, {"count": 4, "radius": 0.1, "center": (0.0, 0.0), "phase": 0.0}),
    "solve_rotations": (
        upm.solve_rotations,
        {
            "parts": [(0.5, 0), (-0.75, 0.25)],
            "forces": [(0.01, 0.01), (-0.01, 0)],
            "centers": CORNERS,
            "mu_m_g": 0.1,
            "order": "priority",
        },
    ),
    "solve_rotations_batch": (
        upm.solve_rotations_batch,
        {
            "parts": np.array([[(0.5, 0), (-0.75, 0.25)]]),
            "forces": np.array([[(0.01, 0.01), (-0.01, 0)]]),
            "centers": CORNERS,
            "mu_m_g": 0.1,
        },
    ),
    "solve_displacements": (
        upm.solve_displacements,
        {"parts": [(0.1, 0.0), (-0.1, 0.05)], "steps": [(0.01, 0.0), (0.0, 0.01)], "centers": CORNERS},
    ),
    "rotation_order": (
        upm.rotation_order,
        {"strengths": [0.5, -0.4, 0.3, -0.1], "parts": [(0.5, 0.0)], "centers": CORNERS, "rule": "priority"},
    ),
    "jet_pulses": (
        upm.jet_pulses,
        {"parts": [(0.05, 0.0)], "steps": [(0.01, 0.0)], "mu": 0.3},
    ),
    "sustain_for_displacement": (
        upm.sustain_for_displacement,
        {"d": 0.01, "radius": 0.05, "mu": 0.3},
    ),
    "theory.bang_bang_feed_rate": (theory.bang_bang_feed_rate, {"z": 0.5, "a_max": 1.0, "period": 1.0}),
    "theory.bang_bang_force": (theory.bang_bang_force, {"z": 0.5, "part_velocity": 0.0}),
    "theory.gamma": (theory.gamma, {"b": 0.5}),
    "theory.normalized_drive": (theory.normalized_drive, {"b": 0.5, "a_max": 1.0, "period": 1.0}),
    "theory.two_harmonic_feed_rate": (theory.two_harmonic_feed_rate, {"b": 0.5, "phi": 1.0}),
    "theory.viscous_gain": (theory.viscous_gain, {"a_max": 1.0, "period": 1.0, "mu_m_g": 1.0}),
    "actuation.Plate": (actuation.Plate, {"mass": 1.0, "inertia": 0.0275, "lever": 0.2}),
    "actuation.Axis": (actuation.Axis, {"mass": 1.0, "damping": 2.0, "stiffness": 350.0}),
    "actuation.wrench": (actuation.wrench, {"motors": [1.0, 0.0, 0.0, 1.0], "lever": 0.2}),
    "actuation.check_drive": (actuation.check_drive, {"frequency": 35.0, "axes": [AXIS], "margin": 3.0}),
    "actuation.positive_force": (actuation.positive_force, {"coefficients": [1.0, 0.0, 0.5, 0.0]}),
    "actuation.center_of_rotation": (actuation.center_of_rotation, {"u": [1.0, 0.0, 2.0]}),
    "actuation.synthetic_accelerometers": (
        actuation.synthetic_accelerometers,
        {
            "plate": PLATE,
            "motors": [1.0, 0.0, 0.0, 1.0],
            "r1": (0.1, 0.1),
            "frequency": 35.0,
            "duration": 0.05,
            "seed": 1,
        },
    ),
    "actuation.harmonic_fit": (
        actuation.harmonic_fit,
        {"samples": np.sin(np.linspace(0, 2 * np.pi, 200)), "sample_rate": 200.0, "frequency": 1.0},
    ),
    "vision.find_parts": (
        find_parts,
        {"frame": FRAME, "table": TABLE, "part_radius": 0.0195, "max_parts": 4, "min_contrast": 30.0},
    ),
    "vision.find_table": (find_table, {"frame": FRAME, "plate_size": 0.4064}),
    "vision.plate_corners": (plate_corners, {"plate_size": 0.4064}),
    "protocol.encode": (p.encode, {"message": p.SetWatchdog(100), "seq": 1}),
    "protocol.SetChannel": (p.SetChannel, {"channel": 0, "amplitude": 1.0, "frequency": 35.0}),
    "protocol.SetEnvelope": (p.SetEnvelope, {"attack": 0.01, "sustain": 0.1, "decay": 0.01}),
    "protocol.SetWatchdog": (p.SetWatchdog, {"milliseconds": 100}),
    "protocol.Pulse": (p.Pulse, {"id": 3}),
    "protocol.Samples": (p.Samples, {"first": 0, "values": ((1, 2, 3, 4),)}),
    "protocol.decode_frame": (p.decode_frame, {"frame": p.encode(p.Stop(), 1)[:-1]}),
    "DriveLimits": (upm.DriveLimits, {"force": 200.0, "stroke": 0.01}),
}

#: Protocol messages are checked when they are built or encoded (the wire format is fixed-width).
_MESSAGES = {name for name in ENTRIES if name.startswith("protocol.") and name[9].isupper()}


class Hang(Exception):
    pass


def _call(name: str, arguments: dict[str, Any]) -> None:
    function, _ = ENTRIES[name]

    def alarm(signum: int, frame: Any) -> None:
        raise Hang(f"{name} did not return within 20 s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(20)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = function(**arguments)
            if name in _MESSAGES:
                p.encode(result, 1)
    except upm.UpmError:
        pass
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def _describe(value: Any) -> str:
    if isinstance(value, np.ndarray):
        return f"ndarray{value.shape}"
    return repr(value)[:40]


@pytest.mark.parametrize("name", sorted(ENTRIES))
def test_entry_point_works_with_good_arguments(name):
    function, arguments = ENTRIES[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = function(**arguments)
    if name in _MESSAGES:
        p.encode(result, 1)


@pytest.mark.parametrize("name", sorted(ENTRIES))
def test_one_bad_argument_raises_an_upm_error(name):
    _, good = ENTRIES[name]
    failures = []
    for key in good:
        for bad in BAD:
            try:
                _call(name, {**good, key: bad})
            except BaseException as error:  # anything but UpmError is a defect
                failures.append(f"{key}={_describe(bad)}: {type(error).__name__}: {str(error)[:100]}")
    assert not failures, f"{name}: {len(failures)} built-in errors\n" + "\n".join(failures)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_several_bad_arguments_at_once(data):
    name = data.draw(st.sampled_from(sorted(ENTRIES)))
    good = ENTRIES[name][1]
    keys = data.draw(st.lists(st.sampled_from(sorted(good)), min_size=1, max_size=3, unique=True))
    arguments = dict(good)
    for key in keys:
        arguments[key] = data.draw(st.sampled_from(BAD))
    _call(name, arguments)
