"""Bad input raises upm.UpmError subclasses naming the parameter; no Rust panic reaches Python."""

import math
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import upm
from upm import _core, actuation, theory


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: upm.BangBang(1.0), r"z must lie in \[0, 1\); got 1.0"),
        (lambda: upm.BangBang(-0.1), r"z must lie in \[0, 1\)"),
        (lambda: upm.BangBang(0.5, a_max=0.0), r"a_max must lie in \(0"),
        (lambda: upm.BangBang([0.1, np.nan]), r"z must be finite; got nan at index \(1,\)"),
        (lambda: upm.TwoHarmonic(np.inf, 0.0), "b must be finite"),
        (lambda: upm.TwoHarmonic(0.5, 0.0, frequency=-1.0), "frequency must lie in"),
        (lambda: upm.TwoHarmonic(0.5, 0.0, amplitude=0.0), "amplitude must be non-zero"),
        (lambda: upm.Harmonics([0.0, 0.0]), "identically zero"),
        (lambda: upm.TwoHarmonic(1e300, 0.0, amplitude=1e300), r"amplitude \* b must be finite"),
        (lambda: upm.Harmonics(["a"]), "cos must be a real number"),
        (lambda: upm.theorem1_force(2, 2, 0.0), "n2 must be greater than n1 = 2; got 2"),
        (lambda: upm.theorem1_force(3, 2, 0.0), "n2 must be greater than n1"),
        (lambda: upm.theorem1_force(0, 2, 0.0), "n1 must be an integer >= 1; got 0"),
        (lambda: upm.force_table(2, 4, 0.0), r"must be coprime; gcd\(2, 4\) = 2"),
        (lambda: upm.force_table(1.5, 4, 0.0), "n1 must be an integer; got 1.5"),
        (lambda: upm.force_table(1, 2, [0.0, np.nan]), "psi must be finite"),
        (lambda: upm.mean_force(upm.BangBang(0.5), np.nan), "part_velocity must be finite"),
        (lambda: upm.feed_rate(0.5), "waveform must be a upm.TwoHarmonic"),
        (lambda: theory.bang_bang_feed_rate(1.5), r"z must lie in \[0, 1\); got 1.5"),
        (
            lambda: theory.bang_bang_feed_rate([0.2, 0.3], period=[1.0, -2.0]),
            r"period .* got -2 \(at flat index 1\)",
        ),
        (lambda: theory.two_harmonic_feed_rate(0.8, 0.3), "no closed-form feed rate for"),
        (lambda: theory.normalized_drive(-0.5), "b must be finite and >= 0"),
        (lambda: theory.normalized_drive(0.5, 1e200, 1e200), r"a_max \* period must be a normal"),
        (lambda: upm.BangBang(0.5, 1e300, 1e300), r"a_max \* period must be a normal"),
        (lambda: theory.viscous_gain(1.0, 1.0, mu_m_g=0.0), "mu_m_g must be finite and > 0"),
        (lambda: theory.gamma(np.nan), "b must be finite"),
        # (scalars take a fast path past NumPy: the same checks and messages)
        (
            lambda: upm.simulate(
                upm.PlateMotion.rest(1.0), [[0.0, 0.0]], duration=0.01, dt=0.001, mu=math.nan
            ),
            "mu must be finite; got nan",
        ),
        (
            lambda: upm.simulate(
                upm.PlateMotion.rest(1.0), [[0.0, 0.0]], duration=0.01, dt=0.001, mu=10**400
            ),
            "mu is too large for a float",
        ),
        (
            lambda: upm.simulate(
                upm.PlateMotion.rest(1.0), [[0.0, 0.0]], duration=0.01, dt=0.001, mu=np.float64(np.inf)
            ),
            "mu must be finite; got inf",
        ),
        (
            lambda: upm.simulate(
                upm.PlateMotion.rest(1.0), [[0.0, 0.0]], duration=0.01, dt=0.001, mu=np.array(10**400)
            ),
            "mu is too large for a float",
        ),
        (
            lambda: upm.simulate(
                upm.PlateMotion.rest(1.0), [[0.0, 0.0]], duration=0.01, dt=0.001, mu=[0.3, 10**400]
            ),
            "mu is too large for a float",
        ),
        (
            lambda: upm.simulate("spin", [[0.0, 0.0]], duration=0.01, dt=0.001, mu=0.3),
            "motion must be a upm.PlateMotion; got str",
        ),
        (
            lambda: upm.simulate_batch(
                [upm.PlateMotion.rest(1.0), 3.0], [[0.0, 0.0]], duration=0.01, dt=0.001, mu=0.3
            ),
            r"motions\[1\] must be a upm.PlateMotion; got float",
        ),
    ],
)
def test_bad_input_names_the_parameter(call, match):
    with pytest.raises(upm.ParameterError, match=match) as info:
        call()
    assert isinstance(info.value, upm.UpmError)
    assert isinstance(info.value, ValueError)


def test_shapes_that_do_not_broadcast():
    with pytest.raises(upm.ShapeError, match=r"shapes do not broadcast together: psi \(2,\), b \(3,\)"):
        upm.force_table(1, 2, [0.0, 1.0], b=[1.0, 2.0, 3.0])
    with pytest.raises(upm.ShapeError, match=r"waveform \(2,\), part_velocity \(3,\)"):
        upm.mean_force(upm.TwoHarmonic([0.1, 0.2], 0.0), [1.0, 2.0, 3.0])


def test_shape_errors_from_the_binding():
    batch = upm.TwoHarmonic(0.5, 1.0)._batch
    with pytest.raises(upm.ShapeError, match="equal lengths"):
        batch.mean_force(np.zeros((2, 3)))
    with pytest.raises(upm.ShapeError, match="cos and sin must have the same shape"):
        _core.WaveformBatch.harmonics(np.zeros((2, 2)), np.zeros((2, 3)), np.ones(2))


def test_a_rust_panic_becomes_internal_error():
    with pytest.raises(upm.InternalError, match="deliberate test panic"):
        _core._panic_for_test()


def test_exception_tree():
    for cls in (upm.ParameterError, upm.ShapeError, upm.ConvergenceError, upm.InternalError):
        assert issubclass(cls, upm.UpmError)


_values = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e-300, -1e300, 5e-324, 0.5, 1.0 - 1e-16]),
)


@settings(max_examples=300, deadline=None)
@given(_values, _values, _values, _values)
def test_arbitrary_floats_give_a_result_or_an_upm_error(a, b, c, d):
    """Every entry point either returns finite numbers or raises an UpmError, never anything else."""
    calls = [
        lambda: upm.feed_rate(upm.TwoHarmonic(a, b, amplitude=c, frequency=d)),
        lambda: upm.mean_force(upm.BangBang(a, a_max=b, period=c), d),
        lambda: upm.mean_force(upm.Harmonics([a, b], [c]), d),
        lambda: upm.force_table(1, 2, a, b),
        lambda: theory.bang_bang_force(a, b, c, d),
        lambda: theory.two_harmonic_feed_rate(a, b, c),
        lambda: theory.two_harmonic_force_at_rest(a),
        lambda: theory.normalized_drive(a, b, c),
    ]
    for call in calls:
        try:
            out = call()
        except upm.UpmError:
            continue
        values = out if isinstance(out, tuple) else (out,)
        assert all(math.isfinite(float(v)) for v in values), (call, out)


SPIN = upm.PlateMotion.rotation((0.0, 0.0), upm.Harmonics([2.0, -1.0], frequency=35.0))
CORNERS = upm.corner_centers((-1, -0.5, 1, 0.5))
JET = {"center": (0, 0), "direction": (0, 1), "rho": 0.1, "amplitude": 0.1, "frequency": 35.0}
TWO = ([(0.5, 0), (-0.75, 0.25)], [(0.01, 0.01), (-0.01, 0)], CORNERS)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        # The cases a user met (issue 23, item 8): built-in exceptions before.
        (
            lambda: upm.PlateMotion.jet(**{**JET, "frequency": "abc"}),
            "frequency must be a real number; got 'abc'",
        ),
        (lambda: upm.PlateMotion.rest("1s"), "duration must be a real number; got '1s'"),
        (
            lambda: upm.PlateMotion.jet(**{**JET, "frequency": None}),
            "frequency must be a real number; got None",
        ),
        (lambda: upm.solve_rotations(*TWO, curls=["x", "y"]), "curls must be a real number"),
        (
            lambda: actuation.synthetic_accelerometers(
                actuation.Plate(1, 0.0275, 0.2), [1, 0, 0, 1], (0.1, 0.1), 35.0, duration=0
            ),
            r"duration must lie in \(0, inf\]; got 0",
        ),
        (lambda: actuation.check_drive(35.0, []), "axes must hold at least 1 item"),
        (lambda: actuation.check_drive(math.nan, [actuation.Axis(1, 2, 350)]), "frequency must be finite"),
        (lambda: actuation.wrench([1, 0, 0, 1], lever="x"), "lever must be a real number; got 'x'"),
        (
            lambda: upm.simulate_batch([SPIN], np.zeros((1, 2)), duration=0.01, dt=5e-4, mu=0.3, threads=-1),
            r"threads must be an integer in \[1, 4096\]; got -1",
        ),
        (
            lambda: upm.simulate(
                SPIN,
                [upm.Disk((0, 0), 0.01)],
                duration=0.01,
                dt=5e-4,
                mu=0.3,
                contacts=True,
                contact_iterations=-1,
            ),
            r"contact_iterations must be an integer in \[1, 1000\]",
        ),
        (lambda: upm.theorem1_force(1, 2**70, 0.0), r"n2 must be an integer <= 2147483647"),
        (lambda: upm.TwoHarmonic(b=None, phi=0.0), "b must be a real number or an array of them; got None"),
        (lambda: upm.solve_rotations(*TWO, order="bogus"), "order must be 'priority'"),
        # Silent or misleading before (item 10).
        (
            lambda: upm.simulate(SPIN, np.zeros((1, 2)), duration=1e-4, dt=5e-4, mu=0.3),
            r"duration must be at least one step dt = 0.0005 s; got 0.0001",
        ),
        (lambda: upm.PlateMotion.jet(**{**JET, "amplitude": 0}), "amplitude must be non-zero"),
        (lambda: upm.Harmonics([1 + 1j]), "cos must be a real number"),
        (
            lambda: upm.simulate(
                SPIN,
                np.array([[0.15, 0.0]]),
                duration=0.01,
                dt=5e-4,
                mu=0.3,
                contacts=True,
                walls="plate",
                plate_size=0.4,
            ),
            r"contacts=True needs every part to be a upm.Disk.*parts\[0\] is a point",
        ),
        # Bounded costs (item 3).
        (lambda: upm.force_table(1, 10001, 0.1), r"n2 must be an integer <= 1000; got 10001"),
        (lambda: upm.Harmonics(np.r_[1.0, np.zeros(1000)]), "at most 256 terms"),
        (lambda: upm.sustain_for_displacement(1.5, radius=0.05, mu=0.3), "at most half a turn"),
        (lambda: upm.jet_pulses([(0.05, 0.0)], [(0.01, 0.0)], mu=1e300), r"mu must lie in \(0, 10\]"),
    ],
)
def test_the_cases_users_met_name_the_parameter(call, match):
    with pytest.raises(upm.UpmError, match=match):
        call()


def test_a_numpy_integer_is_a_valid_number():
    # Before: "mass must be finite and > 0; got np.int64(1)".
    plate = actuation.Plate(mass=np.int64(1), inertia=0.0275, lever=0.2)
    assert plate.mass == 1.0 and isinstance(plate.mass, float)


def test_zero_parts_need_zero_strengths():
    # Before: a Rust panic turned into InternalError ("please report").
    plan = upm.solve_rotations(np.zeros((0, 2)), np.zeros((0, 2)), CORNERS)
    np.testing.assert_array_equal(plan.strengths, np.zeros(4))
    batch = upm.solve_rotations_batch(np.zeros((0, 2, 2)), np.zeros((0, 2, 2)), CORNERS)
    assert batch.strengths.shape[0] == 0


def test_a_far_part_does_not_merge_the_centres():
    # Before: "centres 0 and 3 are both at (-1, -0.5)" for a part 1e12 m away. The system is
    # solvable, and (rightly) ill-conditioned.
    with pytest.warns(upm.RankWarning, match="ill-conditioned"):
        plan = upm.solve_rotations([(1e12, 0.0)], [(0.1, 0.0)], CORNERS)
    assert np.all(np.isfinite(plan.strengths))


def test_solve_rotations_warns_on_infeasible_forces_and_ill_conditioning():
    with pytest.warns(upm.PlanWarning, match="100 mu m g"):
        upm.solve_rotations([(0.5, 0.0)], [(100.0, 0.0)], CORNERS, mu_m_g=1.0)
    with pytest.warns(upm.RankWarning, match="ill-conditioned"):
        upm.solve_rotations([(0.5, 0.0), (0.5 + 1e-9, 0.0)], [(0.1, 0.1), (-0.1, 0.0)], CORNERS)


def test_a_result_too_big_for_memory_is_refused_not_aborted():
    # Before: "memory allocation of 512 bytes failed" and SIGABRT under an 8 GB limit.
    script = (
        "import resource, numpy as np, upm\n"
        "resource.setrlimit(resource.RLIMIT_AS, (8 << 30, resource.RLIM_INFINITY))\n"
        "spin = upm.PlateMotion.rotation((0.0, 0.0), upm.Harmonics([2.0, -1.0], frequency=35.0))\n"
        "try:\n"
        "    upm.simulate(spin, np.zeros((30_000_000, 2)), duration=0.01, dt=1e-4, mu=0.3)\n"
        "except upm.ParameterError as error:\n"
        "    print(error)\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "raise record_every (now 1), simulate fewer parts, or split the batch" in out.stdout
