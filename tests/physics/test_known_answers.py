"""SPEC.md §2–3 known answers through the public Python API (each value cited from SPEC.md)."""

import numpy as np
import pytest

import upm
from upm import theory

PI = np.pi


@pytest.mark.parametrize(
    ("z", "v_eq"),
    # SPEC §2.1 (checked; a_max = T = 1); z > 1/2 is clamped to v_max.
    [(0.1, 0.0025), (0.3, 0.0225), (0.5, 0.0625), (0.7, 0.0225), (0.9, 0.0025)],
)
def test_bang_bang_feed_rate(z, v_eq):
    assert upm.feed_rate(upm.BangBang(z)) == pytest.approx(v_eq, abs=1e-12)
    assert theory.bang_bang_feed_rate(z) == pytest.approx(v_eq, abs=1e-15)


def test_bang_bang_force_efficiency_and_gain():
    # SPEC §2.1: z = 0.3 -> f/(mu m g) 0.09 at rest; eta1 = 0.0625, eta2 = 1/3 at z = 1/2;
    # K = 4 mu m g / (a_max T).
    assert upm.mean_force(upm.BangBang(0.3)) == pytest.approx(0.09, abs=1e-12)
    assert theory.bang_bang_force(0.3) == pytest.approx(0.09, abs=1e-15)
    assert theory.bang_bang_efficiency(0.5) == pytest.approx((0.0625, 1 / 3), abs=1e-15)
    assert theory.viscous_gain(a_max=16.0, period=0.5, mu_m_g=0.2) == pytest.approx(0.1)
    assert theory.bang_bang_velocity_range(0.5, a_max=16.0, period=1.0) == pytest.approx((-3.0, 1.0))


@pytest.mark.parametrize(
    ("b", "phi", "v_eq", "force"),
    # SPEC §2.2 (checked). Erratum E1: Fig. 3.7's caption says 1/3 for (1, pi/2) and 1/4 for
    # (1/2, pi/4); (3.16)/(3.17) and simulation give 0.25 and 0.354.
    [
        (0.5, PI / 2, 0.5, 0.2386),
        (1.0, PI / 2, 0.25, 0.3333),
        (0.5, PI / 4, 0.3536, 0.2237),
        (0.25, PI / 2, 0.25, 0.1443),
        (0.3, PI / 3, 0.2598, None),
        (2.0, PI / 2, 0.125, None),
    ],
)
def test_two_harmonic(b, phi, v_eq, force):
    wave = upm.TwoHarmonic(b, phi)
    assert upm.feed_rate(wave) == pytest.approx(v_eq, abs=5e-5)
    assert theory.two_harmonic_feed_rate(b, phi) == pytest.approx(upm.feed_rate(wave), abs=1e-12)
    if force is not None:
        assert upm.mean_force(wave) == pytest.approx(force, abs=5e-5)


def test_eq_3_15_and_gamma():
    # SPEC §2.2: (3.15) b = 0.25 -> 0.1443, 0.9 -> 0.3201, 1.5 -> 0.0813; gamma(1/2) = 1.7602,
    # gamma(1) = 2.7358 (erratum E2: computed, not the printed closed form).
    b = np.array([0.25, 0.9, 1.5])
    np.testing.assert_allclose(theory.two_harmonic_force_at_rest(b), [0.1443, 0.3201, 0.0813], atol=5e-5)
    exact = upm.mean_force(upm.Harmonics(np.stack([0 * b, b], -1), [1.0]))
    np.testing.assert_allclose(theory.two_harmonic_force_at_rest(b), exact, atol=1e-12)
    np.testing.assert_allclose(theory.gamma([0.5, 1.0]), [1.7602, 2.7358], atol=5e-5)
    # Erratum E3: "f ~ b/3 for |b| < 1" is loose: b = 1/2 gives 0.2386, not 0.167.
    assert theory.two_harmonic_force_at_rest(0.5) - 0.5 / 3 > 0.07


def test_normalized_drive_at_the_optimum():
    # SPEC §2.2 (3.18-3.20): eta1 = 0.0452, eta2 = 1/3 at b = 1/2; v_eq = a_max T / (4 pi gamma).
    d = theory.normalized_drive(0.5, a_max=16.0, period=1 / 35)
    assert d.eta1 == pytest.approx(0.0452, abs=5e-5)
    assert d.eta2 == pytest.approx(1 / 3)
    assert d.v_eq == pytest.approx(16.0 / 35 / (4 * PI * d.gamma))
    assert d.v_min == pytest.approx(-3 * 16.0 / 35 / (4 * PI * d.gamma))


@pytest.mark.parametrize(
    ("n1", "n2", "peak"),
    # SPEC §3 known answers: peak 1/(n2^2 - n1^2), period in psi 2 pi/(n1 n2).
    [(1, 2, 1 / 3), (2, 3, 1 / 5), (1, 4, 1 / 15), (2, 5, 1 / 21), (3, 4, 1 / 7)],
)
def test_theorem1_peaks_and_periods(n1, n2, peak):
    assert upm.theorem1_force(n1, n2, 0.0) == pytest.approx(peak, abs=1e-15)
    assert upm.force_table(n1, n2, 0.0) == pytest.approx(peak, abs=1e-12)
    psi = np.linspace(-1, 1, 41)
    period = 2 * PI / (n1 * n2)
    np.testing.assert_allclose(
        upm.force_table(n1, n2, psi + period), upm.force_table(n1, n2, psi), atol=1e-12
    )


def _coprime_pairs(limit):
    return [(a, b) for b in range(2, limit + 1) for a in range(1, b) if np.gcd(a, b) == 1]


@pytest.mark.parametrize(("n1", "n2"), _coprime_pairs(7))
def test_theorem1_equals_the_exact_table(n1, n2):
    # SPEC §3: Theorem 1 checked to 1e-5; both odd -> 0 (Lemma 1).
    psi = np.linspace(-3.0, 9.0, 601)
    np.testing.assert_allclose(upm.theorem1_force(n1, n2, psi), upm.force_table(n1, n2, psi), atol=1e-9)


def test_half_amplitude_second_harmonic():
    # SPEC §3: cos t - cos(2t)/2 -> 0.2386 (the "0.24 mu m g" of 5.1.2 and 6.4).
    assert upm.force_table(1, 2, 0.0, b=0.5) == pytest.approx(0.2386, abs=5e-5)


def test_lemmas_over_random_parameters(rng):
    b = rng.uniform(-3, 3, 500)
    phi = rng.uniform(-4, 4, 500)
    # Lemma 1: sin t + b sin(3 (t - phi)) has both harmonics odd -> no feeding.
    cos = np.stack([0 * b, 0 * b, -b * np.sin(3 * phi)], -1)
    sin = np.stack([1 + 0 * b, 0 * b, b * np.cos(3 * phi)], -1)
    np.testing.assert_allclose(upm.mean_force(upm.Harmonics(cos, sin)), 0.0, atol=1e-12)
    # Lemma 2: phi = 0 -> sigma is odd in t -> no feeding, also for a feeding pair (1, 2).
    np.testing.assert_allclose(upm.mean_force(upm.TwoHarmonic(b, 0.0)), 0.0, atol=1e-12)
    np.testing.assert_allclose(upm.feed_rate(upm.TwoHarmonic(b, 0.0)), 0.0, atol=1e-12)


def test_mean_force_is_monotone_and_vanishes_at_the_feed_rate(rng):
    for b, phi in zip(rng.uniform(0, 3, 8), rng.uniform(-PI, PI, 8), strict=True):
        wave = upm.TwoHarmonic(b, phi, amplitude=0.02, frequency=35.0)
        lo, hi = wave.velocity_range()
        v = np.linspace(lo - 1e-3, hi + 1e-3, 301)
        f = upm.mean_force(wave, v)
        assert np.all(np.diff(f) <= 1e-15)
        assert f[0] == 1.0
        assert f[-1] == -1.0
        assert abs(upm.mean_force(wave, upm.feed_rate(wave))) < 1e-9


def test_against_an_independent_sampled_average(rng):
    # Reference written here: the mean of sign(v - v_p) on a fine midpoint grid (error ~ 1e-6).
    cos, sin = rng.normal(size=4), rng.normal(size=4)
    t = 2 * PI * (np.arange(2_000_000) + 0.5) / 2_000_000
    k = np.arange(1, 5)[:, None]
    v = (cos[:, None] * np.cos(k * t) + sin[:, None] * np.sin(k * t)).sum(0)
    wave = upm.Harmonics(cos, sin)
    for level in (-0.5, 0.0, 0.3):
        assert upm.mean_force(wave, level) == pytest.approx(np.mean(np.sign(v - level)), abs=5e-6)
    assert upm.feed_rate(wave) == pytest.approx(np.median(v), abs=1e-5)
