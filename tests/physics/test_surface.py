"""A plate whose friction varies over its surface (``friction_map``), and parts that stick
(``SimulatedUPM(stuck=)``), against closed forms."""

import numpy as np
import pytest

import upm
from upm import PlateMotion
from upm.physics.surface import friction_grid, smooth_map
from upm.plate.plant import SimulatedUPM

G, MU, V0, X0 = 9.81, 0.3, 0.5, -0.1
REST = PlateMotion.rest(1.0)


def drive(peak, seconds=0.4, frequency=25.0):
    """An asymmetric translation along x whose acceleration peaks at about ``peak`` [m/s^2],
    ramped in and out (no jump in the plate's velocity)."""
    wave = upm.TwoHarmonic(b=0.5, phi=np.pi / 2, amplitude=1.0, frequency=frequency)
    t = np.linspace(0, 1 / frequency, 4001)
    unit = np.abs(np.gradient(np.asarray(wave(t)), t)).max()  # the peak of a 1 m/s drive
    wave = upm.TwoHarmonic(b=0.5, phi=np.pi / 2, amplitude=peak / unit, frequency=frequency)
    return PlateMotion.translation((1.0, 0.0), wave).with_envelope(0.05, seconds - 0.1, 0.05)


def spin(center, seconds):
    wave = upm.TwoHarmonic(b=0.5, phi=np.pi / 2, amplitude=4.0, frequency=30.0)
    return PlateMotion.rotation(center, wave).for_duration(seconds)


def stop(a, b):
    """Where a part sent along +x from X0 at V0 stops on a still plate whose friction is
    ``MU (a + b x)``: ``V0^2 / 2 = MU g (a (x - X0) + b (x^2 - X0^2) / 2)``."""
    c = V0**2 / (2 * MU * G) + a * X0 + b / 2 * X0**2
    return (-a + np.sqrt(a * a + 2 * b * c)) / b


@pytest.mark.parametrize("kind", ["point", "disk", "polygon"])
def test_a_part_sliding_over_rising_friction_stops_where_the_work_says(kind):
    part = {
        "point": upm.Point((X0, 0.0), (V0, 0.0)),
        "disk": upm.Disk((X0, 0.0), 0.01, velocity=(V0, 0.0)),
        "polygon": upm.Polygon(
            [(-0.01, -0.01), (0.01, -0.01), (0.01, 0.01), (-0.01, 0.01)], (X0, 0.0), velocity=(V0, 0.0)
        ),
    }[kind]
    for grid in (lambda x, y: 1.0 + 4.0 * x, [[0.2, 1.8], [0.2, 1.8]]):  # the same map twice
        r = upm.simulate(REST, [part], duration=1.0, dt=1e-5, mu=MU, plate_size=0.4, friction_map=grid,
                         record_every=10**6)  # fmt: skip
        assert r.positions[-1, 0, 0] == pytest.approx(stop(1.0, 4.0), abs=2e-6)  # 60 mm of sliding
        assert r.stuck[-1, 0]
    plain = upm.simulate(REST, [part], duration=1.0, dt=1e-5, mu=MU, plate_size=0.4, record_every=10**6)
    assert plain.positions[-1, 0, 0] - X0 == pytest.approx(V0**2 / (2 * MU * G), abs=2e-6)


def test_a_uniform_map_is_the_same_as_scaled_friction():
    rng = np.random.default_rng(3)
    parts = rng.uniform(-0.1, 0.1, (40, 2))
    turn = spin((0.02, -0.01), 0.3)
    mu = rng.uniform(0.2, 0.4, 40)
    a = upm.simulate(turn, parts, duration=0.3, dt=2e-5, mu=mu, mu_s=mu * 1.2, plate_size=0.4,
                     friction_map=np.full((3, 3), 1.25), record_every=500)  # fmt: skip
    b = upm.simulate(turn, parts, duration=0.3, dt=2e-5, mu=mu * 1.25, mu_s=mu * 1.2 * 1.25, plate_size=0.4,
                     record_every=500)  # fmt: skip
    assert np.abs(a.positions - b.positions).max() < 1e-9
    assert np.abs(a.positions[-1] - a.positions[0]).max() > 1e-4  # and they moved


def test_a_batch_on_a_map_matches_its_worlds_alone():
    parts = np.array([[0.05, 0.0], [-0.08, 0.06]])
    motions = [spin(c, 0.2) for c in [(0.0, 0.0), (0.1, 0.05), (-0.05, 0.1)]]
    surface = smooth_map(0.6, 1.5, seed=2)
    both = upm.simulate_batch(motions, parts, duration=0.2, dt=2e-5, mu=0.3, plate_size=0.4,
                              friction_map=surface, record_every=1000)  # fmt: skip
    for b, m in enumerate(motions):
        one = upm.simulate(m, parts, duration=0.2, dt=2e-5, mu=0.3, plate_size=0.4, friction_map=surface,
                           record_every=1000)  # fmt: skip
        assert np.array_equal(both.positions[b], one.positions)


def test_bad_maps_are_refused_naming_the_parameter():
    ok = dict(duration=0.01, dt=1e-4, mu=0.3)
    with pytest.raises(upm.ParameterError, match="plate_size"):
        upm.simulate(REST, [[0.0, 0.0]], friction_map=np.ones((2, 2)), **ok)
    for bad in (np.ones(3), np.ones((1, 4)), np.ones((2, 2, 2))):
        with pytest.raises(upm.ShapeError, match="friction_map"):
            upm.simulate(REST, [[0.0, 0.0]], friction_map=bad, plate_size=0.4, **ok)
    for bad in ([[1.0, 0.0], [1.0, 1.0]], [[1.0, np.nan], [1.0, 1.0]], [[1.0, -2.0], [1.0, 1.0]], "rough"):
        with pytest.raises(upm.ParameterError, match="friction_map"):
            upm.simulate(REST, [[0.0, 0.0]], friction_map=bad, plate_size=0.4, **ok)
    with pytest.raises(upm.ParameterError, match="friction_map"):
        friction_grid(lambda x, y: np.ones(7), 0.4)
    with pytest.raises(ZeroDivisionError):  # the user's own error, as it is
        friction_grid(lambda x, y: 1 / 0, 0.4)


def test_a_map_changes_a_sort_on_the_simulated_plate():
    # the plant passes its map to the integrator: parts on the slippery half travel farther
    parts = np.array([[-0.1, 0.0], [0.1, 0.0]])
    slippery_left = [[0.5, 1.5], [0.5, 1.5]]  # x = -0.2 .. 0.2: factor 0.5 .. 1.5
    shove = drive(20.0)
    moved = {}
    for name, m in (("flat", None), ("map", slippery_left)):
        plant = SimulatedUPM(parts=parts.copy(), friction_map=m, snr_db=None)
        plant.play(shove)
        moved[name] = np.abs(plant.parts[:, 0] - parts[:, 0])
    assert moved["flat"][0] == pytest.approx(moved["flat"][1], rel=0.05)
    assert moved["map"][0] > 1.3 * moved["map"][1]


def test_a_stuck_part_holds_until_the_plate_outpulls_its_grip():
    parts = np.array([[-0.05, 0.0], [0.05, 0.0]])
    plant = SimulatedUPM(parts=parts.copy(), stuck={1: 12.0}, snr_db=None)
    assert plant.mu_s[1] == pytest.approx(12.0 / G) and plant.mu_s[0] == pytest.approx(MU)
    plant.play(drive(6.0))  # beyond a free part's grip (mu_s g = 2.9 m/s^2), within the stuck one's
    assert abs(plant.parts[0, 0] - parts[0, 0]) > 1e-4
    assert np.abs(plant.parts[1] - parts[1]).max() < 1e-7  # it rode with the plate and is home
    plant.play(drive(30.0))
    assert abs(plant.parts[1, 0] - parts[1, 0]) > 1e-4
    for bad in ({5: 10.0}, {0: -1.0}, {0: np.nan}, [0]):
        with pytest.raises(upm.ParameterError, match="stuck"):
            SimulatedUPM(parts=parts.copy(), stuck=bad)
