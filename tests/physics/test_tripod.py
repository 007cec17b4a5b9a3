"""Polygon parts on three feet (three-point support): the friction summed over the feet by hand,
the shares from the feet's triangle, the gauge of sliding wrenches, bad feet refused with the
reason, and through the integrator: spinning down on a still and on a heaving plate as the closed
form says, and pivoting about a heavy foot on a plate that turns about it."""

from __future__ import annotations

import math

import numpy as np
import pytest

import upm

G = 9.81
# a 4 x 3 cm plate on three feet, one of them (the first) near the centroid carrying most
BOX = np.array([[0.0, 0.0], [0.04, 0.0], [0.04, 0.03], [0.0, 0.03]])
FEET = np.array([[0.021, 0.019], [0.004, 0.004], [0.036, 0.004]])


def shares(feet: np.ndarray, centroid: np.ndarray) -> np.ndarray:
    """The barycentric coordinates of the centroid in the feet's triangle."""
    a = np.vstack([feet.T, np.ones(3)])
    return np.linalg.solve(a, [centroid[0], centroid[1], 1.0])


def by_hand(feet: np.ndarray, lam: np.ndarray, v: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``(Fx, Fy, M) / (mu N)`` of the feet ``feet`` (from the centroid) at twists ``(v, w)``."""
    out = np.zeros((len(w), 3))
    for s, share in zip(feet, lam, strict=True):
        u = v + w[:, None] * np.array([-s[1], s[0]])
        h = u / np.linalg.norm(u, axis=1)[:, None]
        out[:, :2] -= share * h
        out[:, 2] -= share * (s[0] * h[:, 1] - s[1] * h[:, 0])
    return out


def test_the_friction_is_the_feet_summed_and_the_shares_hold_the_part_level():
    part = upm.Polygon(BOX, support=FEET)
    want = shares(FEET, part.centroid)
    assert part.shares == pytest.approx(want, abs=1e-15)
    assert part.shares.sum() == pytest.approx(1.0, abs=1e-15)
    feet = FEET - part.centroid
    assert part.mean_distance == pytest.approx(float(want @ np.linalg.norm(feet, axis=1)), rel=1e-15)
    rng = np.random.default_rng(3)
    v = rng.normal(0, 0.01, (200, 2))
    w = rng.normal(0, 1.0, 200)
    force, moment = part.wrench(v, w)
    ref = by_hand(feet, want, v, w)
    assert np.abs(force - ref[:, :2]).max() < 1e-12
    assert np.abs(moment - ref[:, 2]).max() < 1e-14
    # the footprint's friction is another thing
    plain = upm.Polygon(BOX)
    assert plain.shares is None
    assert np.abs(plain.wrench(v, w)[1] - moment).max() > 1e-3


def test_every_sliding_wrench_has_gauge_one_on_feet():
    part = upm.Polygon(BOX, support=FEET)
    rng = np.random.default_rng(5)
    v = rng.normal(0, 0.01, (40, 2))
    w = rng.normal(0, 1.0, 40)
    force, moment = part.wrench(v, w)
    g, _ = part.gauge(force, moment)
    assert np.abs(g - 1.0).max() < 1e-9
    assert np.abs(part.gauge(0.5 * force, 0.5 * moment)[0] - 0.5).max() < 1e-9
    assert part.holds(0.99 * force, 0.99 * moment).all()
    assert not part.holds(1.01 * force, 1.01 * moment).any()


def test_bad_feet_are_refused_with_the_reason():
    with pytest.raises(upm.ShapeError, match="support must have shape"):
        upm.Polygon(BOX, support=FEET[:2])
    with pytest.raises(upm.ParameterError, match=r"support.*one line"):
        upm.Polygon(BOX, support=[[0.0, 0.0], [0.01, 0.01], [0.02, 0.02]])
    with pytest.raises(upm.ParameterError, match=r"support.*foot 2 lies outside"):
        upm.Polygon(BOX, support=[[0.0, 0.0], [0.04, 0.0], [0.05, 0.03]])
    with pytest.raises(upm.ParameterError, match=r"support.*tips"):
        upm.Polygon(BOX, support=[[0.0, 0.0], [0.01, 0.0], [0.0, 0.01]])
    part = upm.Polygon(BOX, support=FEET)
    with pytest.raises(upm.ParameterError, match=r"load.*every foot pressed"):
        part.wrench([0.01, 0.0], 0.0, load=(0.0, 500.0))
    with pytest.raises(upm.ParameterError, match=r"parts\[1\]\.support.*tips"):
        bad = upm.Polygon(BOX, position=(0.05, 0.0))
        object.__setattr__(bad, "support", np.array([[0.0, 0.0], [0.01, 0.0], [0.0, 0.01]]))
        upm.simulate(upm.PlateMotion.rest(0.01), [upm.Polygon(BOX), bad], duration=0.01, dt=1e-3, mu=0.3)


def even_feet(radius: float) -> np.ndarray:
    a = 0.4 + 2 * np.pi * np.arange(3) / 3
    return np.array([0.02, 0.015]) + radius * np.stack([np.cos(a), np.sin(a)], axis=1)


def test_on_three_even_feet_a_part_spins_down_at_mu_g_rho_over_k_squared():
    mu, rho, omega0, dt = 0.3, 0.008, 20.0, 1e-5
    part = upm.Polygon(BOX, support=even_feet(rho), position=(0.01, -0.02), angle=0.3, spin=omega0)
    alpha = mu * G * rho / part.gyration**2
    stop = omega0 / alpha
    run = upm.simulate(upm.PlateMotion.rest(1.0), [part], duration=1.5 * stop, dt=dt, mu=mu, record_every=10)
    assert run.angles[-1, 0] - 0.3 == pytest.approx(omega0**2 / (2 * alpha), rel=1e-4)
    centroid = run.positions[:, 0] + part.centroid_offset(run.angles[:, 0])
    assert np.abs(centroid - centroid[0]).max() < 1e-14
    after = run.t > stop + 2 * dt
    assert run.stuck[after, 0].all() and (run.spins[after, 0] == 0).all()
    # on its whole footprint the same part stops sooner (its mean distance is 1.2 cm)
    plain = upm.simulate(upm.PlateMotion.rest(1.0), [upm.Polygon(BOX, angle=0.3, spin=omega0)],
                         duration=1.5 * stop, dt=dt, mu=mu, record_every=10)  # fmt: skip
    assert plain.angles[-1, 0] - 0.3 < 0.8 * (run.angles[-1, 0] - 0.3)


def test_on_a_heaving_plate_the_feet_are_pressed_by_g_plus_the_heave():
    # z'' = A sin(w t): the spin falls at mu (g + z'') rho / k², so omega(t) = omega0 - alpha t -
    # (alpha A / g) (1 - cos w t) / w while it turns
    mu, rho, omega0, dt, f, amp = 0.3, 0.008, 20.0, 1e-5, 50.0, 5.0
    w = 2 * np.pi * f
    part = upm.Polygon(BOX, support=even_feet(rho), spin=omega0)
    alpha = mu * G * rho / part.gyration**2
    motion = upm.PlateMotion.harmonic(f, z=[(1, amp, 0.0)])
    run = upm.simulate(motion, [part], duration=0.5 * omega0 / alpha, dt=dt, mu=mu, record_every=10)
    want = omega0 - alpha * run.t - alpha * amp / G * (1 - np.cos(w * run.t)) / w
    assert np.abs(run.spins[:, 0] - want).max() < 2 * alpha * dt
    assert run.flight_time[0] == 0.0


def foot_at(angles: np.ndarray) -> np.ndarray:
    """The heavy foot from the frame's origin with the frame turned by ``angles``."""
    c, s = np.cos(angles), np.sin(angles)
    return np.stack([c * FEET[0, 0] - s * FEET[0, 1], s * FEET[0, 0] + c * FEET[0, 1]], axis=1)


def test_a_heavy_foot_is_a_pivot_on_a_plate_that_turns_about_it():
    # The plate turns about the heavy foot faster than friction can carry the part: the part
    # lags, turning about that foot, which stays where it stands (it carries 73 % of the load,
    # more than the other two can pull it with); on its whole footprint the part slides off it.
    mu, f = 0.3, 20.0
    pos, angle = np.array([0.01, 0.02]), 0.3
    c, s = math.cos(angle), math.sin(angle)
    turn = np.array([[c, -s], [s, c]])
    foot = pos + turn @ FEET[0]
    w = 2 * np.pi * f
    motion = upm.PlateMotion.rotation(tuple(foot), upm.Harmonics([0.0], [400.0 / w], frequency=f))
    runs = {}
    for name, support in (("feet", FEET), ("footprint", None)):
        part = upm.Polygon(BOX, position=tuple(pos), angle=angle, support=support)
        runs[name] = upm.simulate(motion, [part], duration=0.1, dt=1e-5, mu=mu, record_every=10)
    run = runs["feet"]
    a = run.angles[:, 0]
    where = run.positions[:, 0] + foot_at(a)
    # (to the trapezoid's error: the pose moves by its centroid's velocity and its spin)
    assert np.abs(where - foot).max() < 1e-8
    assert not run.stuck[:, 0].all()  # it slips: it lags the plate's turn (400/w² (1 - cos wt))
    plate = 400.0 / w**2 * (1 - np.cos(w * run.t))
    assert np.abs(a - angle).max() > 0.1 * plate.max()
    assert np.abs(a - angle - plate).max() > 0.1 * plate.max()
    other = runs["footprint"]
    b = other.angles[:, 0]
    moved = other.positions[:, 0] + foot_at(b)
    assert np.abs(moved - foot).max() > 1e-5


def test_moved_keeps_the_feet_and_the_mass():
    part = upm.Polygon(BOX, support=FEET, mass=2.0)
    there = part.moved((0.1, 0.2), 1.0, velocity=(0.01, 0.0), spin=2.0)
    assert np.array_equal(there.support, part.support) and there.mass == 2.0
    assert there.position == (0.1, 0.2) and there.angle == 1.0 and there.spin == 2.0
    assert np.array_equal(there.shares, part.shares)


def test_the_simulated_plant_moves_parts_on_their_feet():
    from upm.plate.plant import SimulatedUPM

    spin = upm.PlateMotion.rotation(
        (0.0, 0.0), upm.TwoHarmonic(0.5, np.pi / 2, amplitude=2.0, frequency=20.0)
    )
    turned = {}
    for name, support in (("feet", even_feet(0.004)), ("footprint", None)):
        shape = upm.Polygon(BOX, support=support)
        plant = SimulatedUPM(parts=[[-0.06, 0.02], [0.05, -0.03]], part_shape=shape, angles=[0.0, 1.0])
        plant.play(spin.for_duration(0.3))
        turned[name] = plant.angles - [0.0, 1.0]
    # on feet 4 mm from the centroid the spin's friction moment is a third of the footprint's:
    # the parts turn differently
    assert np.abs(turned["feet"]).max() > 0.01
    assert np.abs(turned["feet"] - turned["footprint"]).max() > 0.01
