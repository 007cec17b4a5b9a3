"""Disk contacts through rapier2d (``upm.simulate(contacts=True)``) against laws independent of the
code: momentum and Newton's restitution law, non-penetration, walls, falling off the plate."""

from __future__ import annotations

import numpy as np
import pytest

import upm

STILL = upm.PlateMotion.rest(1.0)


def _gaps(positions: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Smallest gap between any two disks at every recorded time, ``(T,)`` [m] (< 0: overlap)."""
    d = np.linalg.norm(positions[:, :, None] - positions[:, None], axis=-1)
    d = d - (radius[:, None] + radius[None, :])
    d[:, np.arange(len(radius)), np.arange(len(radius))] = np.inf
    return d.min(axis=(1, 2))


@pytest.mark.parametrize("e", [0.0, 0.3, 1.0])
def test_head_on_collision_conserves_momentum_and_follows_restitution(e: float) -> None:
    # Frictionless plate (mu -> 0) and frictionless parts: the 1-D impact law of two masses.
    ma, mb, va, vb = 2.0, 0.5, 0.15, -0.05
    parts = [
        upm.Disk((-0.03, 0.0), 0.01, velocity=(va, 0.0), mass=ma),
        upm.Disk((0.03, 0.0), 0.008, velocity=(vb, 0.0), mass=mb),
    ]
    r = upm.simulate(STILL, parts, duration=0.5, dt=1e-4, mu=1e-12, contacts=True, restitution=e,
                     part_friction=0.0)  # fmt: skip
    ua, ub = r.velocities[-1, :, 0]
    want_a = (ma * va + mb * vb + mb * e * (vb - va)) / (ma + mb)
    want_b = (ma * va + mb * vb + ma * e * (va - vb)) / (ma + mb)
    assert ma * ua + mb * ub == pytest.approx(ma * va + mb * vb, abs=1e-9)
    assert ua == pytest.approx(want_a, abs=0.02 * (va - vb))
    assert ub == pytest.approx(want_b, abs=0.02 * (va - vb))
    assert _gaps(r.positions, np.array([0.01, 0.008])).min() > -0.01 * 0.008


def test_a_jet_drives_one_disk_into_another_without_overlap() -> None:
    # The jet at the first disk pushes it along +x into the second, which it then pushes along.
    rad = 0.008
    parts = [upm.Disk((0.0, 0.0), rad), upm.Disk((2.3 * rad, 0.0), rad)]
    jet = upm.PlateMotion.jet((0.0, 0.0), (1.0, 0.0), rho=0.05, amplitude=0.15, frequency=35.0)
    free = upm.simulate(jet, parts, duration=1.5, dt=1e-4, mu=0.3, record_every=10)
    hit = upm.simulate(jet, parts, duration=1.5, dt=1e-4, mu=0.3, record_every=10, contacts=True)
    assert _gaps(free.positions, np.full(2, rad)).min() < -0.5 * rad  # without contacts: into it
    assert _gaps(hit.positions, np.full(2, rad)).min() > -0.01 * rad
    # The first disk was held back and pushed the second further than the jet alone moves it
    # (equal masses: their mean displacement is nearly the contact-free one).
    (a_hit, b_hit), (a_free, b_free) = hit.positions[-1, :, 0], free.positions[-1, :, 0]
    assert a_hit < a_free - 0.25 * rad and b_hit > b_free + 0.25 * rad
    assert (a_hit + b_hit) == pytest.approx(a_free + b_free, abs=0.25 * rad)


def test_parts_fall_off_the_edge_unless_it_is_a_wall() -> None:
    feed = upm.PlateMotion.translation((1.0, 0.0), upm.Harmonics([0.1, -0.05], frequency=35.0))
    parts = [upm.Disk((0.1, 0.0), 0.01), upm.Disk((0.0, 0.05), 0.01)]
    opts = {"duration": 4.5, "dt": 1e-4, "mu": 0.3, "plate_size": 0.3, "contacts": True}
    off = upm.simulate(feed, parts, **opts)
    assert off.left_plate.all()
    # The first reaches the edge at x = 0.15 earlier than the second, 0.1 m further back.
    assert 0.0 < off.left_time[0] < off.left_time[1] < 4.5
    assert np.all(np.abs(off.positions[-1, :, 0]) > 0.15)  # frozen where it left
    fenced = upm.simulate(feed, parts, walls="plate", **opts)
    assert not fenced.left_plate.any()
    assert np.all(fenced.positions[:, :, 0] <= 0.15 - 0.01 + 1e-4)
    assert fenced.positions[-1, :, 0] == pytest.approx(0.14, abs=1e-3)


@pytest.mark.slow
def test_ten_chips_in_a_sorting_run_never_overlap_beyond_tolerance() -> None:
    # Ten 39 mm chips packed 41 mm apart, sorted red left, blue right by jets through the closed
    # loop (virtual camera, tracker, JetPlanner, the motor-driven plate): chips bump on the way.
    from upm import control
    from upm.plate.actuation import Plate
    from upm.plate.drive import flexures
    from upm.plate.plant import SimulatedUPM

    chip = 0.0195
    rng = np.random.default_rng(5)
    pts: list[np.ndarray] = []
    while len(pts) < 10:
        p = rng.uniform(-0.1, 0.1, 2)
        if all(np.linalg.norm(p - q) > 2 * chip + 0.002 for q in pts):
            pts.append(p)
    start = np.array(pts)
    plate = Plate(1.0, 0.0275, 0.2)
    axes = flexures(plate.mass, plate.inertia)
    plant = SimulatedUPM(plate=plate, axes=axes, parts=start, snr_db=None, part_radius=chip)
    labels = ["red", "blue"] * 5
    task = control.SortTask({"red": -1, "blue": 1}, margin=0.08, spacing=0.046, max_step=0.025)
    planner = control.JetPlanner(mu=0.3, amplitude=0.1, rho=0.03, plate=plate, axes=axes)
    device = control.SimulatedDevice(plant, ideal=True)  # the plate follows the pulses exactly
    control.Loop(device, plant.camera(labels), planner, task, part_radius=chip).run(4)
    assert plant.fallen == 0
    assert plant.min_gap > -0.01 * chip, f"largest overlap {-plant.min_gap / chip:.2%} of a radius"
    side = np.array([-1.0, 1.0] * 5)
    assert np.mean(side * plant.parts[:, 0]) > np.mean(side * start[:, 0]) + 0.01  # towards the sides


def test_contacts_identical_run_to_run_and_for_one_and_two_threads() -> None:
    spin = upm.PlateMotion.rotation((0.01, 0.0), upm.Harmonics([2.0, -1.0], frequency=35.0))
    grid = np.stack(np.meshgrid(np.arange(4), np.arange(3)), -1).reshape(-1, 2) * 0.0205 - 0.03
    parts = [upm.Disk(tuple(p), 0.01) for p in grid]
    motions = [spin, upm.PlateMotion.rotation((-0.01, 0.0), upm.Harmonics([2.0, -1.0], frequency=35.0))]
    runs = [
        upm.simulate_batch(motions, parts, duration=0.1, dt=1e-4, mu=0.3, contacts=True, threads=t)
        for t in (1, 2, 1)
    ]
    for r in runs[1:]:
        np.testing.assert_array_equal(r.positions, runs[0].positions)
        np.testing.assert_array_equal(r.spins, runs[0].spins)
    one = upm.simulate(motions[1], parts, duration=0.1, dt=1e-4, mu=0.3, contacts=True)
    np.testing.assert_array_equal(one.positions, runs[0].positions[1])


def test_contacts_off_is_the_plain_integrator() -> None:
    spin = upm.PlateMotion.rotation((0.0, 0.0), upm.Harmonics([2.0, -1.0], frequency=35.0))
    parts = [upm.Disk((0.05, 0.0), 0.01), upm.Disk((0.0, 0.05), 0.005), upm.Disk((-0.05, 0.0), 0.01)]
    a = upm.simulate(spin, parts, duration=0.2, dt=1e-4, mu=0.3)
    b = upm.simulate(spin, parts, duration=0.2, dt=1e-4, mu=0.3, contacts=True)
    # Far apart: contacts change nothing, to rounding.
    np.testing.assert_allclose(b.positions, a.positions, rtol=0, atol=1e-12)
    # A point has no size to collide with: contacts refuse it rather than let it pass walls.
    with pytest.raises(upm.ParameterError, match=r"parts\[1\] is a point"):
        upm.simulate(spin, [parts[0], upm.Point((0.0, 0.05))], duration=0.01, dt=1e-4, mu=0.3, contacts=True)


def test_bad_contact_input_is_refused_with_the_reason() -> None:
    two = [upm.Disk((0.0, 0.0), 0.01), upm.Disk((0.015, 0.0), 0.01)]
    opts = {"duration": 0.01, "dt": 1e-4, "mu": 0.3}
    with pytest.raises(upm.ParameterError, match="disks 0 and 1 overlap"):
        upm.simulate(STILL, two, contacts=True, **opts)
    upm.simulate(STILL, two, **opts)  # without contacts overlap is allowed
    apart = [upm.Disk((0.0, 0.0), 0.01), upm.Disk((0.05, 0.0), 0.01)]
    with pytest.raises(upm.ParameterError, match="restitution"):
        upm.simulate(STILL, apart, contacts=True, restitution=2.0, **opts)
    with pytest.raises(upm.ParameterError, match="part_friction"):
        upm.simulate(STILL, apart, contacts=True, part_friction=-1, **opts)
    with pytest.raises(upm.ParameterError, match="walls need contacts=True"):
        upm.simulate(STILL, apart, walls="plate", plate_size=0.3, **opts)
    with pytest.raises(upm.ParameterError, match="plate_size"):
        upm.simulate(STILL, apart, contacts=True, walls="plate", **opts)
    with pytest.raises(upm.ShapeError, match=r"\(K, 2, 2\)"):
        upm.simulate(STILL, apart, contacts=True, walls=[[0, 0, 1, 1]], **opts)
    with pytest.raises(upm.ParameterError, match="wall 0 cuts disk 1"):
        upm.simulate(STILL, apart, contacts=True, walls=[[[0.05, -1], [0.05, 1]]], **opts)
    with pytest.raises(upm.ParameterError, match="every Disk or for none"):
        upm.simulate(STILL, [upm.Disk((0, 0), 0.01, mass=1.0), apart[1]], contacts=True, **opts)
    with pytest.raises(upm.ParameterError, match="mass"):
        upm.simulate(STILL, [upm.Disk((0, 0), 0.01, mass=-1.0), upm.Disk((0.05, 0), 0.01, mass=1.0)],
                     contacts=True, **opts)  # fmt: skip
    with pytest.raises(upm.ParameterError, match="contact_iterations"):
        upm.simulate(STILL, apart, contacts=True, contact_iterations=0, **opts)
