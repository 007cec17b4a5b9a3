"""Waveform objects: evaluation against their definitions, broadcasting, shapes."""

import numpy as np
import pytest

import upm


def test_two_harmonic_evaluates_its_definition():
    b, phi, a, f = 0.7, 0.4, 0.02, 35.0
    wave = upm.TwoHarmonic(b, phi, amplitude=a, frequency=f)
    t = np.linspace(0, 0.1, 257)
    w = 2 * np.pi * f
    np.testing.assert_allclose(wave(t), a * (np.sin(w * t) + b * np.sin(2 * w * t + phi)), atol=1e-15)
    acc = a * w * (np.cos(w * t) + 2 * b * np.cos(2 * w * t + phi))
    np.testing.assert_allclose(wave.acceleration(t), acc, atol=1e-12)
    assert wave.period == pytest.approx(1 / 35)
    assert wave.shape == ()
    assert isinstance(wave(0.1), float)


def test_harmonics_pads_and_matches_two_harmonic():
    two = upm.TwoHarmonic(0.3, 1.1)
    h = two.to_harmonics()
    t = np.linspace(0, 7, 50)
    np.testing.assert_allclose(h(t), two(t), atol=1e-15)
    padded = upm.Harmonics([0.0, 0.5], [1.0])
    np.testing.assert_allclose(padded(t), np.sin(t) + 0.5 * np.cos(2 * t), atol=1e-15)


def test_bang_bang_velocity_is_the_spec_formula():
    z, a, T = 0.3, 2.0, 0.5
    wave = upm.BangBang(z, a_max=a, period=T)
    t1, t2 = (1 - z) * T / 2, (1 + z) * T / 2
    t = np.linspace(0, T, 1001, endpoint=False)
    want = np.where(
        t < t1,
        a * (T / 4 * (z * z - 1) + t),
        np.where(t < t2, a * T / 4 * (z - 1) ** 2, a * (T / 4 * (z * z + 3) - t)),
    )
    np.testing.assert_allclose(wave(t), want, atol=1e-15)
    np.testing.assert_allclose(wave.acceleration(t), np.where(t < t1, a, np.where(t < t2, 0, -a)))
    assert wave.velocity_range() == pytest.approx((a * T * (z * z - 1) / 4, a * T * (z - 1) ** 2 / 4))


def test_parameters_broadcast_into_a_grid():
    b = np.linspace(0, 1, 5)[:, None]
    phi = np.linspace(0, np.pi, 3)[None, :]
    grid = upm.TwoHarmonic(b, phi)
    assert grid.shape == (5, 3)
    rates = upm.feed_rate(grid)
    assert rates.shape == (5, 3)
    for i in range(5):
        for j in range(3):
            assert rates[i, j] == upm.feed_rate(upm.TwoHarmonic(b[i, 0], phi[0, j]))
    # A batch of waveforms against a matching batch of part velocities, and a broadcast.
    v = np.full((5, 3), 0.1)
    assert upm.mean_force(grid, v).shape == (5, 3)
    assert upm.mean_force(grid, np.zeros((2, 5, 3))).shape == (2, 5, 3)
    assert grid(np.zeros((4, 1, 1))).shape == (4, 5, 3)
    # One waveform, many velocities: the result takes the velocities' shape.
    single = upm.TwoHarmonic(0.5, np.pi / 2)
    f = upm.mean_force(single, np.linspace(-1, 1, 12).reshape(3, 4))
    assert f.shape == (3, 4)
    assert f[0, 0] == upm.mean_force(single, -1.0)


def test_repr_names_the_parameters():
    assert (
        repr(upm.TwoHarmonic(0.5, 1.0))
        == "TwoHarmonic(b=0.5, phi=1.0, amplitude=1.0, frequency=0.15915494309189535)"
    )
    assert "shape=(2,)" in repr(upm.BangBang([0.1, 0.2]))
