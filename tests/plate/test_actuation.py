"""Actuation, calibration and sensing (SPEC §6): round trips, Table 5.1, synthetic records."""

import warnings

import numpy as np
import pytest

import upm
from upm import actuation as act

PLATE = act.Plate(mass=3.0, inertia=0.04, lever=0.2)


def test_wrench_follows_5_8():
    np.testing.assert_array_equal(act.wrench([1, 2, 3, 5], 0.5), [-1, -2, 0.5 * (8 - 3)])


@pytest.mark.parametrize("center", [(0.0, 0.0), (0.05, -0.02), (-0.3, 0.4)])
def test_round_trip_motors_cor_motors(center):
    motors = PLATE.motors_for_rotation(center, omega=2.0)
    c, w = PLATE.center_of_rotation(motors)
    np.testing.assert_allclose(c, center, atol=1e-12)
    assert w == pytest.approx(2.0)
    # Minimum norm: orthogonal to (1, 1, 1, 1), the combination that moves nothing.
    assert abs(motors.sum()) < 1e-12
    np.testing.assert_allclose(PLATE.motors_for(PLATE.velocity_amplitudes(motors)), motors, atol=1e-12)


def test_limits_and_unreachable_centres():
    motors = PLATE.motors_for_rotation((0.5, 0.0), omega=2.0)
    peak = np.abs(motors).max()
    spread = motors.max() - motors.min()
    bounded = PLATE.motors_for_rotation((0.5, 0.0), omega=2.0, limit=0.55 * spread)
    assert np.abs(bounded).max() <= 0.55 * spread + 1e-12
    np.testing.assert_allclose(PLATE.velocity_amplitudes(bounded), PLATE.velocity_amplitudes(motors))
    with pytest.raises(upm.ParameterError, match="out of reach"):
        PLATE.motors_for_rotation((0.5, 0.0), omega=2.0, limit=0.45 * spread)
    assert peak > 0
    with pytest.raises(upm.ParameterError, match="translation"):
        act.center_of_rotation((1.0, 0.0, 0.0))


def test_table_5_1_rows_are_minimum_norm_and_the_fit_reports_its_residual():
    table = act.TABLE_5_1
    m = table["motors"]
    s = (m[:, 2] + m[:, 3]) - (m[:, 0] + m[:, 1])
    assert np.all(s == 512)
    # Each printed row is the minimum-norm choice for its differences (an independent check of
    # the inverse: the thesis chose them by hand).
    unit = act.Plate(1.0, 1.0, 1.0)
    for row in m:
        u = (row[0] - row[1], row[2] - row[3], 512.0)
        np.testing.assert_allclose(unit.motors_for(u), row, atol=1e-9)
    cmap = act.fit_cor_map(m, table["cor_inches"])
    assert 0 < cmap.residual < 0.3  # inches, over six measured centres
    np.testing.assert_allclose(cmap.predict(m), table["cor_inches"], atol=0.4)
    # Erratum E5: the data say cx falls as X1 - X2 rises and cy as Y1 - Y2 rises, whatever the
    # printed column labels.
    assert cmap.matrix[0, 0] < 0 and cmap.matrix[1, 1] < 0
    assert abs(cmap.matrix[0, 1]) < 0.2 * abs(cmap.matrix[0, 0])
    # Predictions against measurements: each row from the map fitted to the other five.
    loo = act.cross_validate_cor_map(m, table["cor_inches"])
    assert loo.shape == (6,) and np.all(loo < 0.6)
    # The library inverts the map.
    targets = np.array([[0.0, 0.0], [1.5, 1.5], [-2.0, 3.0]])
    library = act.cor_library(cmap, targets, strength=512)
    np.testing.assert_allclose(cmap.predict(library), targets, atol=1e-9)
    with pytest.raises(upm.ParameterError, match="out of reach"):
        act.cor_library(cmap, [[40.0, 0.0]], strength=512, limit=300)


def test_harmonic_fit_recovers_coefficients_and_rejects_bad_records():
    fs, f = 5000.0, 35.0
    t = np.arange(2000) / fs
    w = 2 * np.pi * f
    a = 0.3 + 1.0 * np.cos(w * t) - 2.0 * np.sin(w * t) + 0.5 * np.cos(2 * w * t) + 0.25 * np.sin(2 * w * t)
    fit = act.harmonic_fit(a, fs, f)
    np.testing.assert_allclose(fit.coefficients, [1.0, -2.0, 0.5, 0.25], atol=1e-12)
    assert fit.offset == pytest.approx(0.3) and fit.residual < 1e-12
    np.testing.assert_allclose(fit.velocity(), np.array([2.0, 1.0, -0.125, 0.25]) / w, atol=1e-14)
    with pytest.raises(upm.ParameterError, match="at least one period"):
        act.harmonic_fit(a[:100], fs, f)
    with pytest.raises(upm.ParameterError, match="all zero"):
        act.harmonic_fit(np.zeros(2000), fs, f)
    with pytest.raises(upm.ParameterError, match="sample_rate"):
        act.harmonic_fit(a, 100.0, f)


def test_positive_force_test_agrees_with_mean_force():
    rng = np.random.default_rng(11)
    coefficients = rng.normal(size=(300, 4))
    test = act.positive_force(coefficients)
    agree = 0
    for (c1, s1, c2, s2), positive in zip(coefficients, test, strict=True):
        v = act.velocity_from_fit([c1, s1, c2, s2], 1 / (2 * np.pi))  # the velocity waveform
        force = upm.mean_force(upm.Harmonics([v[0], v[2]], [v[1], v[3]]))
        agree += (force > 0) == positive
    assert agree == 300


@pytest.mark.parametrize("center", [(0.02, -0.03), (0.15, 0.1)])
def test_accelerometers_recover_the_commanded_centre(center):
    f, r1 = 35.0, np.array([-0.18, -0.18])  # sensors near opposite corners of a 16" plate
    motors = PLATE.motors_for_rotation(center, omega=2.0)
    first, second = act.synthetic_accelerometers(PLATE, motors, r1, f, duration=0.4, snr_db=30.0, seed=4)
    rot = act.cor_from_accelerometers(first, second, r1, 5000.0, f)
    assert np.hypot(*(rot.center - center)) < 1e-3  # within 1 mm at 30 dB SNR and 11 bits
    # The feeding force's sign along x at the first sensor, from its fitted acceleration,
    # matches the exact average force of the true plate velocity there.
    fit = act.harmonic_fit(first[:, 0], 5000.0, f)
    u = PLATE.velocity_amplitudes(motors)
    vx = (u[0] - u[2] * r1[1]) / (2 * np.pi * f)  # (1/w)(sin wt + cos(2wt)/2) scaled
    truth = upm.mean_force(upm.Harmonics([0.0, vx / 2], [vx, 0.0], f))
    assert act.positive_force(fit.coefficients) == (truth > 0)


def test_accelerometer_errors():
    f = 35.0
    still = np.zeros((2000, 2))
    moving = np.ones((2000, 2))
    with pytest.raises(upm.ParameterError, match="reads all zero"):
        act.cor_from_accelerometers(still, moving, (0.1, 0.1), 5000.0, f)
    t = np.arange(2000) / 5000.0
    same = np.stack([np.cos(2 * np.pi * f * t)] * 2, axis=1)
    with pytest.raises(upm.ParameterError, match="no rotation"):
        act.cor_from_accelerometers(same, same, (0.1, 0.1), 5000.0, f)
    with pytest.raises(upm.ShapeError):
        act.cor_from_accelerometers(same, same[:10], (0.1, 0.1), 5000.0, f)


def test_plate_dynamics_resonance_check_and_precompensation():
    axis = act.Axis(mass=3.0, damping=20.0, stiffness=3.0e3)  # resonance ~5 Hz
    w0 = np.sqrt(3.0e3 / 3.0 - (20.0 / 6.0) ** 2)
    assert axis.resonance == pytest.approx(w0)
    assert act.Axis(1.0, 10.0, 1.0).resonance is None  # over-damped
    # Far above resonance, velocity = force / (i m w): the inertial limit of (5.10).
    assert axis.velocity_response(1000.0) == pytest.approx(1 / (1j * 3.0 * 2 * np.pi * 1000.0), rel=3e-3)
    with pytest.warns(upm.ResonanceWarning):
        assert not act.check_drive(w0 / (2 * np.pi) * 1.5, [axis])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert act.check_drive(35.0, [axis])
    wanted = {1.0: 0.1 + 0.0j, 2.0: 0.05j}
    forces = act.precompensate(axis, 20.0, wanted)
    for h, v in wanted.items():
        assert forces[h] * axis.velocity_response(h * 20.0) == pytest.approx(v)


def test_sustain_for_displacement_is_exact_and_grows_as_sqrt_d():
    kwargs = {"radius": 0.1, "mu": 0.3, "amplitude": 5.0, "frequency": 100.0}
    sustains = [upm.sustain_for_displacement(d, **kwargs) for d in (1e-3, 4e-3)]
    # S ∝ sqrt(d) while the part is slow (5.2.3), counting each ramp as half its length (the
    # attack is one period, 0.01 s): four times the step, about twice the on-time.
    on = [s + 0.01 for s in sustains]
    assert 1.9 < on[1] / on[0] < 2.4
    # The step it gives, simulated independently: the pulse then the coast to rest.
    wave = upm.Harmonics([5.0, -2.5], [0, 0], 100.0)
    pulse = upm.PlateMotion.rotation((0, 0), wave).with_envelope(0.01, sustains[1], 0.01)
    program = upm.PlateMotion.sequence([pulse, upm.PlateMotion.rest(0.2)])
    run = upm.simulate(
        program, [(0.1, 0.0)], duration=program.duration, dt=2.5e-5, mu=0.3, record_every=10**9
    )
    assert run.positions[-1, 0, 1] == pytest.approx(4e-3, rel=2e-3)
    assert run.stuck[-1, 0]
    with pytest.raises(upm.ParameterError, match="below what the attack and decay alone give"):
        upm.sustain_for_displacement(1e-7, **kwargs)


def test_precompensated_force_gives_the_wanted_velocity_in_the_ode():
    # Independent check: integrate m q'' + b q' + k q = F(t) (RK4) near resonance and fit the
    # steady-state velocity's harmonics.
    axis = act.Axis(mass=2.0, damping=15.0, stiffness=2.0e4)  # resonance ~16 Hz
    f = 20.0
    wanted = {1.0: 0.1 + 0.0j, 2.0: 0.05j}
    forces = act.precompensate(axis, f, wanted)
    w = 2 * np.pi * f

    def force(t):
        return sum((p * np.exp(1j * h * w * t)).real for h, p in forces.items())

    def rhs(t, y):
        q, v = y
        return np.array([v, (force(t) - axis.damping * v - axis.stiffness * q) / axis.mass])

    dt, y, t, vs = 1 / (f * 2000), np.zeros(2), 0.0, []
    for _ in range(int(3.0 / dt)):
        k1 = rhs(t, y)
        k2 = rhs(t + dt / 2, y + dt / 2 * k1)
        k3 = rhs(t + dt / 2, y + dt / 2 * k2)
        k4 = rhs(t + dt, y + dt * k3)
        y, t = y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4), t + dt
        if t > 2.0:  # transients (time constant 2m/b = 0.27 s) have died out
            vs.append(y[1])
    t0 = 2.0 + dt
    fit = act.harmonic_fit(np.array(vs), 1 / dt, f)
    # Re(p e^{i h w (t0 + s)}) = c cos(h w s) + s sin(h w s) with p' = p e^{i h w t0}.
    for k, (h, p) in enumerate(wanted.items()):
        shifted = p * np.exp(1j * h * w * t0)
        assert fit.coefficients[2 * k] == pytest.approx(shifted.real, abs=2e-4)
        assert fit.coefficients[2 * k + 1] == pytest.approx(-shifted.imag, abs=2e-4)


def test_the_plate_on_its_flexures_steps_as_its_recurrence_says():
    # DriveLimits.respond (the core's recurrence, batched) against the recurrence of (5.26)
    # written out sample by sample here, from a state off home
    from upm.plate.drive import DriveLimits

    lim = DriveLimits()
    rng = np.random.default_rng(0)
    wrench, state, dt = rng.normal(0, 50, (2, 400, 3)), rng.normal(0, 1e-3, (2, 3, 2)), 2e-4
    acc, vel, pos, after = lim.respond(wrench, dt, state)
    inertia = (lim.plate.mass, lim.plate.mass, lim.plate.inertia)
    for i in range(2):
        for k in range(3):
            m, b, stiff = inertia[k], lim.axes[k].damping, lim.axes[k].stiffness
            q, v = state[i, k]
            for n in range(400):
                a = (wrench[i, n, k] - b * v - stiff * q) / m
                v += dt * a
                q += dt * v
                got = (acc[i, n, k], vel[i, n, k], pos[i, n, k])
                assert got == pytest.approx((a, v, q), rel=1e-12, abs=1e-15)
            assert tuple(after[i, k]) == pytest.approx((q, v), rel=1e-12, abs=1e-15)
    # a free plate (no flexures) keeps drifting
    free = DriveLimits(axes=None)
    _, v_free, _, _ = free.respond(np.concatenate([np.full((50, 3), 1.0), np.zeros((50, 3))]), dt)
    assert v_free[-1] == pytest.approx(v_free[49])
    assert v_free[-1][0] == pytest.approx(50 * dt / lim.plate.mass)
