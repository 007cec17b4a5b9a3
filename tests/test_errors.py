"""Bad input raises upm.UpmError subclasses naming the parameter; no Rust panic reaches Python."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import upm
from upm import _core, theory


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
