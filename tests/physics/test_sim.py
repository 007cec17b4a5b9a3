"""upm.simulate and upm.PlateMotion against references independent of the integrator."""

import math

import numpy as np
import pytest

import upm

G = 9.81


def reference_1d(a, f, mu, periods, steps_per_period):
    """Independent 1-D stick-slip reference: explicit Coulomb sliding at +-mu g, exact stick when
    the relative velocity changes sign within a step, release when the plate's acceleration
    exceeds mu g. Plate velocity a (sin wt + cos(2wt)/2) (the optimal two-harmonic drive)."""
    w = 2 * math.pi * f
    dt = 1.0 / f / steps_per_period
    x = v = 0.0
    stuck = True
    xs = []
    for n in range(int(periods * steps_per_period)):
        t1 = (n + 1) * dt
        vs1 = a * (math.sin(w * t1) + 0.5 * math.cos(2 * w * t1))
        as1 = a * w * (math.cos(w * t1) - math.sin(2 * w * t1))
        if stuck and abs(as1) <= mu * G:
            v_new = vs1
        else:
            rel = v - vs1
            v_new = v - math.copysign(mu * G * dt, rel)
            stuck = (v_new - vs1) * rel <= 0  # the relative velocity changed sign: caught
            if stuck:
                v_new = vs1
        x += 0.5 * (v + v_new) * dt
        v = v_new
        if (n + 1) % steps_per_period == 0:
            xs.append(x)
    return np.array(xs)


@pytest.mark.parametrize("mu", [0.1, 0.03])
def test_finite_gamma_feeding_matches_an_independent_reference(mu):
    # Gamma = A w / (mu g) = 4.5 and 15: the median rule (0.5 A) does not hold exactly here.
    a, f, periods = 0.02, 35.0, 40
    ref = reference_1d(a, f, mu, periods, 8000)
    v_ref = (ref[-1] - ref[-11]) * f / 10
    drive = upm.TwoHarmonic(0.5, np.pi / 2, amplitude=a, frequency=f)
    motion = upm.PlateMotion.translation((1, 0), drive)
    run = upm.simulate(motion, [[0.0, 0.0]], duration=periods / f, dt=1 / f / 4000, mu=mu, record_every=4000)
    x = run.positions[:, 0, 0]
    v_ours = (x[-1] - x[-11]) * f / 10
    assert v_ours == pytest.approx(v_ref, rel=3e-3)
    if mu == 0.03:  # large Gamma: near the quasi-static feed rate
        assert v_ours / a == pytest.approx(0.5, abs=0.03)


def test_pulse_displacement_grows_as_sustain_squared_and_the_coast_is_v2_over_2_mu_g():
    # SPEC §5: displacement ~ S^2 while v_p << v_max; afterwards the part slides v^2/(2 mu g).
    f, mu, amp = 35.0, 0.002, 0.05
    drive = upm.TwoHarmonic(0.5, np.pi / 2, amplitude=amp, frequency=f)
    period = 1 / f
    moved, coasts = [], []
    for sustain in (2 * period, 4 * period, 8 * period):
        pulse = upm.PlateMotion.translation((0, 1), drive).with_envelope(period / 2, sustain, period / 2)
        end = pulse.duration
        program = upm.PlateMotion.sequence([pulse, upm.PlateMotion.rest(1.0)])
        run = upm.simulate(program, [[0.0, 0.0]], duration=end + 0.5, dt=period / 2000, mu=mu)
        y, vy = run.positions[:, 0, 1], run.velocities[:, 0, 1]
        k = int(np.searchsorted(run.t, end - 1e-12))
        assert vy[k] < 0.05 * 0.5 * amp  # v_p << v_eq: the viscous regime has not set in
        coasts.append((y[-1] - y[k], vy[k] ** 2 / (2 * mu * G)))
        moved.append(y[-1])
        assert run.stuck[-1, 0]
    # d = k (S + c)^2, c from the ramps: sqrt(d) is linear in S (the thesis's S ~ sqrt(d)).
    s = np.array([2.0, 4.0, 8.0])
    root = np.sqrt(moved)
    slope, intercept = np.polyfit(s, root, 1)
    assert np.max(np.abs(slope * s + intercept - root)) < 5e-3 * root.max()
    assert 0 < intercept / slope < 2  # the ramps add less than two periods of sustain
    for got, want in coasts:
        assert got == pytest.approx(want, rel=1e-2)


def test_batch_equals_separate_runs_and_records_what_it_promises():
    drives = [upm.TwoHarmonic(b, np.pi / 2, amplitude=0.02, frequency=35.0) for b in (0.25, 0.5, 1.0)]
    motions = [upm.PlateMotion.translation((1, 0), d) for d in drives]
    parts = [upm.Point((0.0, 0.0)), upm.Point((0.01, 0.02), velocity=(0.01, 0.0))]
    kw = dict(duration=0.2, dt=1e-4, mu=[0.2, 0.3], mu_s=0.35, record_every=50)
    batch = upm.simulate_batch(motions, parts, **kw)
    assert batch.positions.shape == (3, 41, 2, 2)
    assert batch.stuck.shape == (3, 41, 2)
    np.testing.assert_allclose(batch.t, np.arange(41) * 50 * 1e-4, atol=1e-15)
    for b, motion in enumerate(motions):
        single = upm.simulate(motion, parts, **kw)
        assert np.array_equal(single.positions, batch.positions[b])
        assert np.array_equal(single.velocities, batch.velocities[b])
    np.testing.assert_array_equal(batch.positions[:, 0, 1], [[0.01, 0.02]] * 3)
    np.testing.assert_array_equal(batch.velocities[:, 0, 1], [[0.01, 0.0]] * 3)


def address(a: np.ndarray) -> int:
    return a.__array_interface__["data"][0]


def _recycling_run():
    """The body of the test below, run in a process of its own."""
    motion = upm.PlateMotion.translation(
        (1, 0), upm.TwoHarmonic(0.5, np.pi / 2, amplitude=0.02, frequency=35.0)
    )
    rng = np.random.default_rng(3)
    a, b = rng.uniform(-0.1, 0.1, (2, 5000, 2))
    kw = dict(duration=0.01, dt=1e-4, mu=0.3, mu_s=0.35, record_every=10)
    first = upm.simulate(motion, a, **kw)
    kept = first.positions.copy(), first.velocities.copy()
    other = upm.simulate(motion, b, **kw)
    view = other.velocities[4]
    view_kept = view.copy()
    assert not np.array_equal(other.positions, kept[0])
    seen = {address(other.positions), address(other.velocities)}
    del other
    for _ in range(3):
        again = upm.simulate(motion, a, **kw)
        assert address(again.positions) in seen, "the result memory given back was not reused"
        seen |= {address(again.positions), address(again.velocities)}
        assert np.array_equal(again.positions, kept[0]) and np.array_equal(again.velocities, kept[1])
        assert np.array_equal(first.positions, kept[0]) and np.array_equal(first.velocities, kept[1])
        assert np.array_equal(view, view_kept)
        again.positions[:] = np.nan  # the caller may write into a result; the next run is whole
        del again
    del first
    assert np.array_equal(upm.simulate(motion, a, **kw).positions, kept[0])


def test_results_kept_are_never_overwritten_and_recycled_memory_gives_the_same_results():
    """Result buffers go back to a pool when their arrays go, and later calls write into them: a
    result (or a view of it) still held must never change, and a run into recycled memory must
    equal the first run bit for bit. In a fresh process, so that the pool holds only what this
    test gives back (after other tests, as pytest-xdist orders them, a spare of a closer size may
    rightly be handed out instead)."""
    import inspect
    import subprocess
    import sys

    script = "\n".join(
        ["import numpy as np", "import upm", inspect.getsource(address), inspect.getsource(_recycling_run),
         "_recycling_run()"]
    )  # fmt: skip
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr


def test_turning_parts_write_every_angle_and_spin_into_recycled_memory():
    """Where every part is a disk or a polygon the run fills its angles and spins into memory
    handed back by earlier results (not zeroed): whatever that memory held (NaN here), each run
    equals the one before it bit for bit, on every path that records them: disks and polygons
    stepped on their own, leaving the plate, in contact, and on a plate that leaves its plane;
    and where some parts are points their angle and spin stay zero."""
    rot = upm.PlateMotion.rotation((0.01, 0.0), upm.Harmonics([0.6, -0.2], frequency=35.0))
    rng = np.random.default_rng(5)
    n = 60
    xy = rng.uniform(-0.08, 0.08, (n, 2))
    spin = rng.uniform(-3, 3, n)
    disks = [upm.Disk(tuple(p), radius=0.004, spin=float(w)) for p, w in zip(xy, spin, strict=True)]
    hexagons = [
        upm.Polygon.regular(6, 0.004, position=tuple(p), spin=float(w)) for p, w in zip(xy, spin, strict=True)
    ]
    grid = np.stack(np.meshgrid(np.linspace(-0.07, 0.07, 10), np.linspace(-0.04, 0.04, 6)), -1).reshape(-1, 2)
    apart = [upm.Disk(tuple(p), radius=0.004, spin=float(w)) for p, w in zip(grid, spin, strict=True)]
    # (1200 rows of 60 parts: results large enough for the pool of buffers to keep)
    dt = 1 / 35 / 400
    kw = dict(duration=1200 * dt, dt=dt, mu=0.3, mu_s=0.35, record_every=1)
    cases = [
        (rot, disks, kw),
        (rot, hexagons, kw),
        (rot, disks, dict(kw, plate_size=0.1)),  # some leave the plate
        (rot, apart, dict(kw, contacts=True)),
        (upm.PlateMotion.ppod("Sink"), disks, dict(kw, duration=1200 * 0.05 / 400, dt=0.05 / 400)),
    ]
    reused = 0
    for motion, parts, k in cases:
        first = upm.simulate(motion, parts, **k)
        kept = first.angles.copy(), first.spins.copy()
        assert np.isfinite(kept[0]).all() and np.isfinite(kept[1]).all()
        assert np.any(kept[1] != kept[1][0])
        for _ in range(2):
            given = {address(first.angles), address(first.spins)}
            first.angles[:] = np.nan  # given back holding NaN
            first.spins[:] = np.nan
            del first
            first = upm.simulate(motion, parts, **k)
            reused += bool(given & {address(first.angles), address(first.spins)})
            assert np.array_equal(first.angles, kept[0]) and np.array_equal(first.spins, kept[1])
        del first
    assert reused >= len(cases), "the angles and spins given back were not reused"
    mixed = upm.simulate(rot, [*disks[:5], upm.Point((0.01, 0.02))], **kw)
    assert np.all(mixed.angles[:, 5] == 0.0) and np.all(mixed.spins[:, 5] == 0.0)
    assert np.any(mixed.spins[:, :5] != 0.0)


def test_what_points_lack_is_a_read_only_zero_that_takes_no_memory():
    """Point parts have no angle, spin or flight: those results are one zero seen at every index
    (no memory cleared or mapped), which no one can write through, in one world and in a batch."""
    motion = upm.PlateMotion.translation((1, 0), upm.TwoHarmonic(0.5, 0.0, amplitude=0.02, frequency=35.0))
    kw = dict(duration=0.01, dt=1e-4, mu=0.3, record_every=10)
    one = upm.simulate(motion, np.zeros((4, 2)), **kw)
    many = upm.simulate_batch([motion] * 3, np.zeros((4, 2)), **kw)
    for r, lead in ((one, ()), (many, (3,))):
        rows = len(r.t)
        for a, shape in (
            (r.angles, (*lead, rows, 4)),
            (r.spins, (*lead, rows, 4)),
            (r.flight_time, (*lead, 4)),
        ):
            assert a.shape == shape and a.dtype == np.float64
            assert not np.any(a) and all(s == 0 for s in a.strides)
            assert not a.flags.writeable
            with pytest.raises(ValueError, match="read-only"):
                a[(0,) * a.ndim] = 1.0
            with pytest.raises(ValueError):
                a.setflags(write=True)
            c = a.copy()
            c[(0,) * c.ndim] = 2.0  # a copy is the caller's own
            assert a[(0,) * a.ndim] == 0.0
    assert np.array_equal(upm.simulate(motion, np.zeros((4, 2)), **kw).angles, np.zeros((len(one.t), 4)))


def test_parts_that_leave_the_plate_are_flagged():
    run = upm.simulate(
        upm.PlateMotion.rest(1.0),
        [upm.Point((0.09, 0.0), (1.0, 0.0))],
        duration=0.1,
        dt=1e-4,
        mu=0.3,
        plate_size=0.2,
    )
    assert run.left_plate.tolist() == [True]
    assert run.left_time[0] == pytest.approx(0.01015, abs=2e-4)


def test_plate_motion_programs():
    drive = upm.TwoHarmonic(0.5, np.pi / 2, amplitude=0.02, frequency=35.0)
    rot = upm.PlateMotion.rotation((0.1, -0.2), drive)
    assert rot.duration is None
    t = np.linspace(0, 0.05, 7)
    u = rot.velocity(t)
    w = drive(t)
    np.testing.assert_allclose(u, np.stack([w * -0.2, -w * 0.1, w], -1), atol=1e-15)
    np.testing.assert_allclose(rot.acceleration(t)[:, 2], drive.acceleration(t), atol=1e-12)
    assert rot.is_closed(1e-12)
    pulse = upm.PlateMotion.translation((3, 4), drive).with_envelope(0.01, 0.05, 0.01)
    program = upm.PlateMotion.sequence([pulse, upm.PlateMotion.rest(0.1), rot.for_duration(0.2)])
    assert program.duration == pytest.approx(0.37)
    assert np.all(program.velocity([0.0, 0.08, 0.5]) == 0)  # envelope starts at 0, rest, after the end
    np.testing.assert_allclose(program.velocity(0.03)[:2], 0.02 * drive(0.03) / 0.02 * np.array([0.6, 0.8]))
    # A pulse under an envelope displaces the plate unless its integral vanishes.
    disp = pulse.displacement()
    t_fine = np.linspace(0, 0.07, 700_001)
    want = np.trapezoid(pulse.velocity(t_fine)[:, 0], t_fine)
    assert disp[0] == pytest.approx(want, rel=1e-6)
    jet = upm.PlateMotion.jet((0, 0), (0, 1), rho=0.05, amplitude=0.02, frequency=35.0)
    # Translation and rotation do not commute, so closure is not exact in general; the jet's angle
    # returns exactly and its position to far below any physical tolerance.
    d = jet.displacement()
    assert abs(d[2]) < 1e-15
    assert jet.is_closed(1e-9)
    samples = upm.PlateMotion.from_samples([0, 1, 2], [0, 1, 0], [0, 0, 0], [0, 0, 0])
    np.testing.assert_allclose(samples.velocity([0.5, 1.5]), [[0.5, 0, 0], [0.5, 0, 0]])
    assert samples.displacement()[0] == pytest.approx(1.0, rel=1e-9)


@pytest.mark.parametrize(
    ("call", "error", "match"),
    [
        (
            lambda m: upm.simulate(m, [[0, 0]], duration=1, dt=1e-3, mu=0.3),
            upm.ParameterError,
            r"dt <= 7\.142857e-4",
        ),
        (
            lambda m: upm.simulate(m, [[0, 0]], duration=1, dt=1e-4, mu=0.3, mu_s=0.2),
            upm.ParameterError,
            "mu_s must",
        ),
        (
            lambda m: upm.simulate(m, [[0, 0]], duration=-1, dt=1e-4, mu=0.3),
            upm.ParameterError,
            "duration must",
        ),
        (
            lambda m: upm.simulate(m, [[0, 0]], duration=1, dt=1e-4, mu=np.nan),
            upm.ParameterError,
            "mu must be finite",
        ),
        (lambda m: upm.simulate(m, [0, 0], duration=1, dt=1e-4, mu=0.3), upm.ShapeError, r"\(M, 2\)"),
        (
            lambda m: upm.simulate(m, [[0, 0]], duration=1, dt=1e-4, mu=[0.3, 0.2]),
            upm.ShapeError,
            "mu must be",
        ),
        (
            lambda m: upm.simulate(m, [[0, 0]], duration=1, dt=1e-4, mu=0.3, record_every=0),
            upm.ParameterError,
            "record_every",
        ),
        (
            lambda m: upm.simulate(m, [[0, 0]], duration=1e3, dt=1e-7, mu=0.3),
            upm.ParameterError,
            "record_every is too small",
        ),
        (lambda m: upm.PlateMotion.sequence([m, m]), upm.ParameterError, "repeats forever"),
        (
            lambda m: upm.PlateMotion.translation((0, 0), upm.TwoHarmonic(0.5, 1)),
            upm.ParameterError,
            "non-zero vector",
        ),
        (
            lambda m: upm.PlateMotion.rotation((0, 0), upm.TwoHarmonic([0.5, 1], 1)),
            upm.ShapeError,
            "single waveform",
        ),
        (
            lambda m: upm.PlateMotion.from_samples([0, 0], [0, 1], [0, 0], [0, 0]),
            upm.ParameterError,
            "strictly increasing",
        ),
        (
            lambda m: upm.PlateMotion.jet((0, 0), (0, 1), rho=0, amplitude=1, frequency=1),
            upm.ParameterError,
            "rho must",
        ),
        # a batch's motions: each checked, the first that is not one named
        (
            lambda m: upm.simulate_batch([m, m, 3], [[0, 0]], duration=0.01, dt=1e-4, mu=0.3),
            upm.ParameterError,
            r"motions\[2\] must be a upm.PlateMotion; got int",
        ),
        (
            lambda m: upm.simulate_batch((m, m._inner), [[0, 0]], duration=0.01, dt=1e-4, mu=0.3),
            upm.ParameterError,
            r"motions\[1\] must be a upm.PlateMotion",
        ),
        (
            lambda m: upm.simulate_batch([], [[0, 0]], duration=0.01, dt=1e-4, mu=0.3),
            upm.ParameterError,
            "at least one",
        ),
        (
            lambda m: upm.simulate_batch(m, [[0, 0]], duration=0.01, dt=1e-4, mu=0.3),
            upm.ParameterError,
            "motions must be a sequence",
        ),
    ],
)
def test_bad_input(call, error, match):
    motion = upm.PlateMotion.translation((1, 0), upm.TwoHarmonic(0.5, 1.0, amplitude=0.02, frequency=35.0))
    with pytest.raises(error, match=match):
        call(motion)


def test_points_and_disks_together_keep_their_order():
    # On a still plate: point and disk slide v^2/(2 mu g) (the disk without spin like a point);
    # the spinning disk turns and stops turning when it stops sliding.
    mu = 0.3
    parts = [
        upm.Point((0.0, 0.0), (0.2, 0.0)),
        upm.Disk((0.0, 0.05), radius=0.01, velocity=(0.2, 0.0)),
        upm.Disk((0.0, -0.05), radius=0.01, velocity=(0.1, 0.0), spin=30.0),
    ]
    run = upm.simulate(upm.PlateMotion.rest(1.0), parts, duration=0.2, dt=1e-5, mu=mu, record_every=100)
    assert run.positions.shape == (201, 3, 2)
    assert run.spins.shape == run.angles.shape == (201, 3)
    want = 0.2**2 / (2 * mu * G)
    assert run.positions[-1, 0, 0] == pytest.approx(want, abs=3e-6)
    assert run.positions[-1, 1, 0] == pytest.approx(want, abs=3e-6)
    assert run.positions[-1, 1, 1] == 0.05
    # Spin turns part of the friction sideways to the slide, so a spinning disk slides farther.
    assert run.positions[-1, 2, 0] > 0.1**2 / (2 * mu * G)
    assert run.angles[-1, 2] > 0
    assert run.stuck[-1].all()
    np.testing.assert_array_equal(run.spins[:, :2], 0.0)
    assert run.spins[-1, 2] == 0.0


def test_a_disk_needs_a_positive_radius():
    with pytest.raises(upm.ParameterError, match="radius must be > 0 for a Disk"):
        upm.simulate(upm.PlateMotion.rest(1.0), [upm.Disk((0, 0), 0.0)], duration=0.1, dt=1e-4, mu=0.3)


def test_friction_per_world_equals_separate_runs():
    # Before: simulate_batch took one friction for every world, so a friction sweep could not batch.
    spin = upm.PlateMotion.rotation((0.0, 0.0), upm.Harmonics([2.0, -1.0], frequency=35.0))
    parts = np.array([[0.05, 0.0], [0.0, 0.08]])
    mus = np.array([[0.2], [0.4], [0.2]])
    opts = {"duration": 0.1, "dt": 1e-4, "record_every": 50}
    batch = upm.simulate_batch([spin, spin, spin], parts, mu=mus, mu_s=mus + 0.1, **opts)
    for w, mu in enumerate(mus[:, 0]):
        alone = upm.simulate(spin, parts, mu=mu, mu_s=mu + 0.1, threads=1, **opts)
        np.testing.assert_array_equal(batch.positions[w], alone.positions)
        np.testing.assert_array_equal(batch.stuck[w], alone.stuck)
    assert not np.array_equal(batch.positions[0], batch.positions[1])
    with pytest.raises(upm.ShapeError, match=r"mu per world must have shape \(3, 2\) or \(3, 1\)"):
        upm.simulate_batch([spin, spin, spin], parts, mu=np.full((2, 2), 0.3), **opts)


def _wave() -> upm.PlateMotion:
    return upm.PlateMotion.translation((1.0, 0.0), upm.Harmonics([0.3, -0.15], [0.0, 0.0], 30.0))


def test_progress_reports_the_fraction_done_and_can_stop_a_run():
    seen: list[float] = []
    parts = np.zeros((10, 2))
    # 20,000 steps: several blocks of at most 4096
    run = upm.simulate(_wave(), parts, duration=1.0, dt=5e-5, mu=0.3, record_every=1000, progress=seen.append)
    assert len(seen) >= 5 and seen[-1] == 1.0 and np.all(np.diff(seen) > 0) and 0 < seen[0] < 0.5
    quiet = upm.simulate(_wave(), parts, duration=1.0, dt=5e-5, mu=0.3, record_every=1000)
    assert np.array_equal(run.positions, quiet.positions)  # reporting changes nothing

    class Stop(Exception):
        pass

    def stop(fraction: float) -> None:
        if fraction > 0.3:
            raise Stop

    with pytest.raises(Stop):
        upm.simulate(_wave(), parts, duration=1.0, dt=5e-5, mu=0.3, record_every=1000, progress=stop)
    with pytest.raises(Stop):  # on a pool of its own too
        upm.simulate(_wave(), parts, duration=1.0, dt=5e-5, mu=0.3, threads=2, progress=stop)
    with pytest.raises(upm.ParameterError, match="progress"):
        upm.simulate(_wave(), parts, duration=0.01, dt=5e-5, mu=0.3, progress=1)  # type: ignore[arg-type]


def test_progress_of_a_batch_with_friction_per_world_runs_once_to_the_end():
    seen: list[float] = []
    mu = np.array([[0.2], [0.3], [0.2], [0.4]])
    upm.simulate_batch([_wave()] * 4, np.zeros((3, 2)), duration=0.5, dt=5e-5, mu=mu, record_every=500,
                       progress=seen.append)  # fmt: skip
    assert seen[-1] == 1.0 and np.all(np.diff(seen) > 0)
    # one run for every world (it was one per distinct friction): the fractions of a batch whose
    # worlds share one friction
    shared: list[float] = []
    upm.simulate_batch([_wave()] * 4, np.zeros((3, 2)), duration=0.5, dt=5e-5, mu=0.3, record_every=500,
                       progress=shared.append)  # fmt: skip
    assert seen == shared


def test_friction_per_world_and_part_with_disks_equals_separate_runs():
    spin = upm.PlateMotion.rotation((0.0, 0.0), upm.Harmonics([2.0, -1.0], frequency=35.0))
    parts = [upm.Point((0.05, 0.0)), upm.Disk((0.0, 0.08), 0.01), upm.Disk((-0.06, 0.0), 0.015)]
    rng = np.random.default_rng(3)
    mus = rng.uniform(0.15, 0.5, (5, 3))
    opts = {"duration": 0.08, "dt": 1e-4, "record_every": 40}
    batch = upm.simulate_batch([spin] * 5, parts, mu=mus, mu_s=1.2 * mus, threads=2, **opts)
    for w in range(5):
        alone = upm.simulate(spin, parts, mu=mus[w], mu_s=1.2 * mus[w], threads=1, **opts)
        np.testing.assert_array_equal(batch.positions[w], alone.positions)
        np.testing.assert_array_equal(batch.angles[w], alone.angles)
    with pytest.raises(upm.ParameterError, match="mu_s"):  # a world whose mu_s < mu
        bad = 1.2 * mus
        bad[3, 1] = 0.5 * mus[3, 1]
        upm.simulate_batch([spin] * 5, parts, mu=mus, mu_s=bad, **opts)


def test_the_disk_friction_curve_matches_a_brute_force_average_over_the_footprint():
    # _core.disk_friction (the bench's Numba peer builds its table from it) against the friction
    # averaged here over a polar grid of the unit disk: the relative velocity at a point is the
    # centre's velocity (1, 0) plus the spin W = tan(phi) turning about the centre
    from upm import _core

    phi = np.array([0.0, 0.3, 0.7851, 1.2, np.pi / 2])
    f, t = _core.disk_friction(phi)
    r = (np.arange(400) + 0.5) / 400
    th = (np.arange(800) + 0.5) / 800 * 2 * np.pi
    rr, tt = np.meshgrid(r, th, indexing="ij")
    x, y = rr * np.cos(tt), rr * np.sin(tt)
    weight = rr / (math.pi * 400 * 800 / (2 * math.pi))  # dA / area, summing to 1
    for k, p in enumerate(phi[1:-1], start=1):
        spin = math.tan(p)
        vx, vy = 1.0 - spin * y, spin * x
        n = np.hypot(vx, vy)
        force = np.sum(weight * vx / n)
        torque = np.sum(weight * (x * vy - y * vx) / n)
        assert f[k] == pytest.approx(force, abs=2e-4) and t[k] == pytest.approx(torque, abs=2e-4)
    assert (f[0], t[0]) == (1.0, 0.0) and f[-1] == pytest.approx(0.0, abs=1e-12)
    assert t[-1] == pytest.approx(2 / 3, rel=1e-12)
    with pytest.raises(upm.ParameterError, match="phi"):
        _core.disk_friction(np.array([np.nan]))


@pytest.mark.parametrize("kind", ["one world", "batch", "out of plane", "per-world friction"])
def test_a_point_whose_position_is_not_finite_is_named(kind: str) -> None:
    # Point parts' positions are checked as the simulator reads them, chunk by chunk (one pass
    # over the caller's array); the error must still name the part, whatever path the run takes.
    n = 1000
    pos = np.random.default_rng(3).uniform(-0.05, 0.05, (n, 2))
    pos[700] = (0.01, np.nan)
    motion = upm.PlateMotion.translation((1.0, 0.0), upm.Harmonics([0.3], frequency=35.0))
    if kind == "out of plane":
        motion = upm.PlateMotion.harmonic(35.0, x=[(1, 5.0, 0.0)], z=[(1, 3.0, 0.0)])
    kw = dict(duration=0.01, dt=1e-4, mu=0.3)
    part = 20 if kind == "batch" else 700
    with pytest.raises(
        upm.ParameterError, match=rf"position must be finite; got \(0.01, NaN\) \(part {part}\)"
    ) as info:
        if kind == "one world" or kind == "out of plane":
            upm.simulate(motion, pos, **kw)
        elif kind == "batch":  # worlds of 30 points, run side by side
            upm.simulate_batch([motion] * 5, pos[680:710], **kw)
        else:
            upm.simulate_batch([motion] * 3, pos, **{**kw, "mu": np.full((3, n), 0.3)})
    assert isinstance(info.value, upm.UpmError)


def test_leaving_recorded_alike_in_a_result_streamed_to_memory():
    # 300 000 points: a result of more than 16 MB, written with non-temporal stores (times and
    # flags of leaving in whole vectors), against the same parts run in small calls
    rng = np.random.default_rng(11)
    n = 300_001
    pos = rng.uniform(-0.09, 0.09, (n, 2))
    vel = rng.uniform(-12.0, 12.0, (n, 2))
    kw = dict(duration=0.02, dt=1e-4, mu=0.3, plate_size=0.2, record_every=50)
    motion = upm.PlateMotion.rest(1.0)
    parts = [upm.Point(tuple(p), tuple(v)) for p, v in zip(pos.tolist(), vel.tolist(), strict=True)]
    big = upm.simulate(motion, parts, **kw)
    assert big.left_plate.dtype == np.bool_ and big.left_plate.shape == (n,)
    assert np.array_equal(big.left_plate, ~np.isnan(big.left_time))
    assert 0.2 * n < big.left_plate.sum() < 0.9 * n
    for part in (slice(0, 37), slice(150_000, 150_013), slice(n - 29, n)):
        small = upm.simulate(motion, parts[part], **kw)
        assert np.array_equal(small.left_plate, big.left_plate[part])
        assert np.array_equal(small.left_time, big.left_time[part], equal_nan=True)
        assert np.array_equal(small.positions, big.positions[:, part])
