"""The 6-DOF plate: out-of-plane motions, lift-off, and the drift and asymptotic velocity fields
(docs/spec.md §10), against closed forms and an independent slow reference written here."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

import upm

W = 2 * math.pi * 20.0  # the library's base angular frequency (T = 0.05 s)
G = 9.81


def one_dim(v_amp: float, a: float) -> float:
    """The 1-D closed form: v_h = -V cos wt, g + a_z = g - a cos wt gives v* = V sin(delta),
    delta = (a / g) cos(delta)."""
    delta = brentq(lambda d: d - (a / G) * math.cos(d), -math.pi / 2, math.pi / 2)
    return v_amp * math.sin(delta)


# ---------------------------------------------------------------- motions


def test_harmonic_motion_velocities_are_the_zero_mean_integrals() -> None:
    m = upm.PlateMotion.harmonic(20.0, x=[(1, 15.0, 0.3)], y=[(2, 4.0, 1.0)], z=[(1, 5.0, 2.0)],
                                 rx=[(1, 70.0, 0.5)], ry=[(3, 40.0, -1.0)], rz=[(1, 100.0, 0.0)])  # fmt: skip
    t = np.linspace(0.0, 0.1, 37)
    u = m.velocity(t)
    assert np.allclose(u[:, 0], -15.0 / W * np.cos(W * t + 0.3), atol=1e-15)
    assert np.allclose(u[:, 1], -4.0 / (2 * W) * np.cos(2 * W * t + 1.0), atol=1e-15)
    assert np.allclose(u[:, 2], -100.0 / W * np.cos(W * t), atol=1e-13)
    assert np.allclose(m.acceleration(t)[:, 0], 15.0 * np.sin(W * t + 0.3), atol=1e-12)
    n = m.normal_acceleration(t)
    assert np.allclose(n[:, 0], 5.0 * np.sin(W * t + 2.0), atol=1e-12)
    assert np.allclose(n[:, 1], 70.0 * np.sin(W * t + 0.5), atol=1e-12)
    assert np.allclose(n[:, 2], 40.0 * np.sin(3 * W * t - 1.0), atol=1e-12)
    assert m.is_spatial and m.duration is None and m.max_frequency == pytest.approx(60.0)
    flat = upm.PlateMotion.harmonic(20.0, x=[(1, 15.0, 0.0)])
    assert not flat.is_spatial and np.all(flat.normal_acceleration(t) == 0)
    assert (
        upm.PlateMotion.translation(
            (1, 0), upm.TwoHarmonic(0.5, 1.0, amplitude=0.02, frequency=35.0)
        ).is_spatial
        is False
    )


def test_an_envelope_scales_the_out_of_plane_velocity() -> None:
    base = upm.PlateMotion.harmonic(20.0, z=[(1, 5.0, 0.0)])
    pulse = base.with_envelope(0.05, 0.1, 0.05)
    t = np.linspace(0.001, 0.199, 301)
    # a_z = d/dt (e v_z): compare with a finite difference of e v_z
    e = np.where(
        t < 0.05,
        0.5 - 0.5 * np.cos(np.pi * t / 0.05),
        np.where(t <= 0.15, 1.0, 0.5 - 0.5 * np.cos(np.pi * (0.2 - t) / 0.05)),
    )
    vz = -5.0 / W * np.cos(W * t)
    h = 1e-6

    def ev(s: np.ndarray) -> np.ndarray:
        es = np.where(
            s < 0.05,
            0.5 - 0.5 * np.cos(np.pi * s / 0.05),
            np.where(s <= 0.15, 1.0, 0.5 - 0.5 * np.cos(np.pi * (0.2 - s) / 0.05)),
        )
        return es * (-5.0 / W * np.cos(W * s))

    want = (ev(t + h) - ev(t - h)) / (2 * h)
    assert np.allclose(pulse.normal_acceleration(t)[:, 0], want, atol=1e-5)
    assert np.allclose(e * vz, ev(t))
    assert np.all(pulse.normal_acceleration([0.25])[0] == 0)


def test_the_library_has_every_field_and_its_turned_variants() -> None:
    names = """Sink Source Whirlpool Centrifuge Saddle Circle TransX TransNegX LineSinkX LineSourceX ShearX
               ShearY SqueezeTransY TransY TransNegY LineSinkY LineSourceY SqueezeTransX VerticalBouncing"""
    assert set(names.split()) <= set(upm.PPOD_FIELDS)
    for name in upm.PPOD_FIELDS:
        assert upm.PlateMotion.ppod(name).duration is None
    with pytest.raises(upm.ParameterError, match=r"unknown PPOD field 'Sinc'.*Sink, Source"):
        upm.PlateMotion.ppod("Sinc")
    # TransY is TransX turned by 90 degrees: its field at the turned point, turned
    p = np.array([[0.03, -0.02], [0.07, 0.01]])
    turn = np.array([[0.0, -1.0], [1.0, 0.0]])
    for x, y in (("TransX", "TransY"), ("LineSinkX", "LineSinkY"), ("TransNegX", "TransNegY")):
        fx = upm.asymptotic_field(upm.PlateMotion.ppod(x), p).velocity
        fy = upm.asymptotic_field(upm.PlateMotion.ppod(y), p @ turn.T).velocity
        assert np.allclose(fy, fx @ turn.T, atol=1e-9), (x, y)


def test_bad_motions_are_parameter_errors() -> None:
    H = upm.PlateMotion.harmonic
    with pytest.raises(upm.ParameterError, match="harmonic must be an integer"):
        H(20.0, x=[(0, 1.0, 0.0)])
    with pytest.raises(upm.ParameterError, match=r"z\[0\] must be \(harmonic, amplitude, phase\)"):
        H(20.0, z=[(1, 1.0)])
    with pytest.raises(upm.ParameterError, match="x must be a list"):
        H(20.0, x=5.0)
    with pytest.raises(upm.ParameterError, match="amplitude must be finite"):
        H(20.0, y=[(1, math.nan, 0.0)])
    with pytest.raises(upm.ParameterError, match=r"rx.*small angles"):
        H(1.0, rx=[(1, 100.0, 0.0)])
    with pytest.raises(upm.ParameterError, match=r"z.*out of range"):
        H(20.0, z=[(1, 5000.0, 0.0)])
    with pytest.raises(upm.ParameterError, match="frequency"):
        H(0.0, x=[(1, 1.0, 0.0)])


# ---------------------------------------------------------------- the asymptotic field


def test_asymptotic_field_meets_the_closed_forms() -> None:
    # TransX: v_h = -(15/w) cos wt, g + a_z = g - 5 cos wt, anywhere on the plate
    want = one_dim(15.0 / W, 5.0)
    got = upm.asymptotic_field(upm.PlateMotion.ppod("TransX"), [(0.05, 0.0), (-0.08, 0.03)])
    assert np.allclose(got.velocity[:, 0], want, rtol=1e-6) and np.all(got.velocity[:, 1] == 0)
    assert want * 1e3 == pytest.approx(52.70, abs=0.01)
    # Circle at (x, 0): v_h = (0, -(100 x / w) cos wt), g + a_z = g + 7 cos wt
    circle = upm.asymptotic_field(upm.PlateMotion.ppod("Circle"), [(0.05, 0.0), (0.1, 0.0)])
    for x, v in zip((0.05, 0.1), circle.velocity, strict=True):
        assert v[1] == pytest.approx(one_dim(100 * x / W, -7.0), rel=1e-6) and abs(v[0]) < 1e-12
    assert circle.velocity[:, 1] * 1e3 == pytest.approx([-22.21, -44.41], abs=0.01)
    # SPEC §10's known answers for the Centrifuge
    cf = upm.asymptotic_field(upm.PlateMotion.ppod("Centrifuge"), [(0.05, 0.0), (0.1, 0.0)])
    assert cf.velocity * 1e3 == pytest.approx(np.array([[0.0, 18.7], [0.0, 32.6]]), abs=0.06)
    assert np.all(cf.converged) and np.all(cf.lift_off == 0)


def test_the_small_modulation_limit_of_a_circular_hodograph() -> None:
    # circular hodograph of speed V, g + a_z = g (1 + eps cos(wt - phi)): v* ~ eps V along the
    # plate velocity at the instant of largest normal force
    eps, phi = 0.02, 0.7
    a = 12.0  # m/s^2: V = a / w
    m = upm.PlateMotion.harmonic(20.0, x=[(1, a, 0.0)], y=[(1, a, -math.pi / 2)],
                                 z=[(1, eps * G, math.pi / 2 - phi)])  # fmt: skip
    v = upm.asymptotic_field(m, [(0.0, 0.0)]).velocity[0]
    t = phi / W
    along = m.velocity([t])[0, :2]
    V = a / W
    assert np.linalg.norm(along) == pytest.approx(V, rel=1e-9)
    assert np.linalg.norm(v) == pytest.approx(eps * V, rel=0.05)
    assert upm.field_angle(v, along) == pytest.approx(0.0, abs=3.0)


# ---------------------------------------------------------------- the drift field


def slow_drift(field: str, p: tuple[float, float], mu: float, steps: int) -> np.ndarray:
    """An independent plain-loop drift: SPEC §10's table and formulas written out here, the exact
    implicit Coulomb step with mu (g + a_z) dt, the part held at p, whole periods until the mean
    velocity settles."""
    table = {
        "Sink": {
            "x": (10, 0),
            "y": (10, math.pi / 2),
            "rx": (70, 75 * math.pi / 64),
            "ry": (70, 107 * math.pi / 64),
        },
        "Whirlpool": {"x": (8, 0), "y": (8, math.pi / 2), "rx": (56, 3 * math.pi / 2), "ry": (50, 0)},
    }[field]
    amp = {k: table.get(k, (0.0, 0.0)) for k in ("x", "y", "z", "rx", "ry", "rz")}
    x, y = p
    T = 0.05
    dt = T / steps
    vel = np.zeros(2)
    stuck = False
    last = None
    for _ in range(400):
        moved = np.zeros(2)
        for k in range(steps):
            t = (k + 1) * dt
            acc = {a: A * math.sin(W * t + ph) for a, (A, ph) in amp.items()}
            v = {a: -A / W * math.cos(W * t + ph) for a, (A, ph) in amp.items()}
            s = np.array([v["x"] - v["rz"] * y, v["y"] + v["rz"] * x])
            n = G + acc["z"] + y * acc["rx"] - x * acc["ry"]
            assert n > 0
            w = vel - s
            wn = math.hypot(*w)
            slide = mu * n * dt
            if wn <= slide or (stuck and wn <= slide):
                new, stuck = s, True
            else:
                new, stuck = s + w * (1 - slide / wn), False
            moved += 0.5 * (vel + new) * dt
            vel = new
        mean = moved / T
        if last is not None and np.linalg.norm(mean - last) < 1e-7:
            return mean
        last = mean
    raise AssertionError("the slow reference did not settle")


@pytest.mark.parametrize("field", ["Sink", "Whirlpool"])
def test_drift_field_against_an_independent_slow_reference(field: str) -> None:
    pts = [(0.06, 0.0), (-0.03, 0.05)]
    got = upm.drift_field(upm.PlateMotion.ppod(field), pts, mu=0.3, steps=400, tol=1e-8)
    assert np.all(got.converged)
    for p, v in zip(pts, got.velocity, strict=True):
        ref = slow_drift(field, p, 0.3, 400)
        assert np.linalg.norm(v - ref) < 2e-5, (p, v, ref)  # 0.02 mm/s (sample times differ by 1e-6 dt)
        assert np.linalg.norm(ref) > 5e-3


def test_drift_tends_to_the_asymptotic_field_as_mu_falls_and_converges_in_the_step() -> None:
    m = upm.PlateMotion.ppod("Sink")
    pts = [(0.08, 0.0), (0.0, -0.05)]
    star = upm.asymptotic_field(m, pts).velocity
    gaps = []
    for mu in (0.3, 0.1, 0.03):
        d = upm.drift_field(m, pts, mu=mu)
        assert np.all(d.converged)
        gaps.append(np.linalg.norm(d.velocity - star, axis=1))
    gaps = np.array(gaps)
    assert np.all(np.diff(gaps, axis=0) < 0), gaps  # monotone approach at every point
    assert np.all(gaps[-1] < 0.25 * gaps[0])
    fine = upm.drift_field(m, pts, mu=0.3, steps=4000).velocity
    coarse = upm.drift_field(m, pts, mu=0.3, steps=2000).velocity
    assert np.max(np.abs(fine - coarse)) < 1e-4  # halving the step: < 0.1 mm/s
    # the angle between them is reported, tens of degrees at the PPOD's operating point
    d = upm.drift_field(m, pts, mu=0.3)
    angle = np.abs(upm.field_angle(d, upm.asymptotic_field(m, pts)))
    assert np.all((angle > 5) & (angle < 60)), angle
    assert np.allclose(d.validity, 0.3 * G / d.max_acceleration)


def test_a_sink_gathers_and_a_source_spreads() -> None:
    xs = np.linspace(-0.1, 0.1, 7)
    grid = np.stack(np.meshgrid(xs, xs), axis=-1)
    for name, sign in (("Sink", -1), ("Source", 1)):
        d = upm.drift_field(upm.PlateMotion.ppod(name), grid, mu=0.3)
        div, _ = upm.divergence_curl(d.velocity, xs, xs)
        assert sign * div[3, 3] > 0.5, (name, div[3, 3])
        # radial: away from the centre the drift points inwards (sink) or outwards (source)
        r = grid.reshape(-1, 2)
        radial = np.sum(d.velocity.reshape(-1, 2) * r, axis=1) / np.maximum(np.linalg.norm(r, axis=1), 1e-12)
        far = np.linalg.norm(r, axis=1) > 0.05
        assert np.all(sign * radial[far] > 0), name
    with pytest.raises(upm.ShapeError):
        upm.divergence_curl(np.zeros((3, 4, 2)), xs, xs)


# ---------------------------------------------------------------- the integrator


def test_lift_off_flight_times_against_the_ballistic_closed_form() -> None:
    A, f = 13.0, 20.0
    w = 2 * math.pi * f
    m = upm.PlateMotion.harmonic(f, z=[(1, A, 0.0)])
    cycles = 10
    dt = 1 / (f * 4000)
    r = upm.simulate(m, [(0.0, 0.0), (0.05, -0.02)], duration=cycles / f, dt=dt, mu=0.3, record_every=1000)
    # leaves when g + A sin(wt) first falls below 0, lands when h(tau) = 0
    phi0 = math.pi + math.asin(G / A)

    def h(tau: float) -> float:
        return (
            -G * tau**2 / 2
            + A / w**2 * (math.sin(phi0 + w * tau) - math.sin(phi0))
            - A / w * tau * math.cos(phi0)
        )

    flight = brentq(h, 1e-6, 1 / f)
    assert flight < 1 / f - (2 * math.pi - phi0) / w  # it lands before the next lift-off phase
    # each cycle's flight starts at phi0 / w; the last one is still in the air at the end
    t0 = phi0 / w
    assert t0 + flight > 1 / f
    want = (cycles - 1) * flight + (1 / f - t0)
    assert np.allclose(r.flight_time, want, atol=cycles * 2 * dt)
    # vertical vibration alone moves nothing sideways
    assert np.array_equal(r.positions[-1], r.positions[0]) and np.all(r.velocities == 0)


def test_no_creep_on_a_still_plate_after_out_of_plane_motion() -> None:
    m = upm.PlateMotion.sequence(
        [upm.PlateMotion.ppod("Whirlpool").for_duration(0.5), upm.PlateMotion.rest(0.3)]
    )
    p = np.array([[0.05, 0.02], [-0.03, -0.07]])
    r = upm.simulate(m, p, duration=0.8, dt=1e-4, mu=0.3, record_every=100)
    still = r.t >= 0.6
    assert np.all(r.velocities[still] == 0)
    assert np.all(r.positions[still] == r.positions[still][0])
    assert np.linalg.norm(r.positions[-1] - p) > 1e-3  # it moved while the plate did


def test_simulated_parts_follow_the_drift_field() -> None:
    m = upm.PlateMotion.ppod("Whirlpool")
    p = np.array([[0.06, 0.0], [0.0, 0.06], [-0.05, -0.03]])
    dur = 0.5
    r = upm.simulate(m, p, duration=dur, dt=0.05 / 2000, mu=0.3, record_every=200)
    moved = (r.positions[-1] - r.positions[r.t.searchsorted(0.2)]) / (dur - 0.2)
    mid = 0.5 * (r.positions[-1] + r.positions[r.t.searchsorted(0.2)])
    d = upm.drift_field(m, mid, mu=0.3).velocity
    assert np.all(np.linalg.norm(moved - d, axis=1) < 0.15 * np.linalg.norm(d, axis=1)), (moved, d)


def test_disks_scale_friction_with_the_normal_force_and_fly() -> None:
    # a disk with no spin on a translating plate moves as a point: the same field
    m = upm.PlateMotion.ppod("TransX")
    dt = 0.05 / 2000
    pts = upm.simulate(m, [(0.0, 0.0)], duration=0.5, dt=dt, mu=0.3, record_every=1000)
    disk = upm.simulate(m, [upm.Disk((0.0, 0.0), 0.01)], duration=0.5, dt=dt, mu=0.3, record_every=1000)
    assert np.allclose(disk.positions, pts.positions, atol=1e-9)
    hop = upm.PlateMotion.harmonic(20.0, z=[(1, 13.0, 0.0)])
    r = upm.simulate(hop, [upm.Disk((0.0, 0.0), 0.01), upm.Point((0.0, 0.0))], duration=0.2, dt=dt, mu=0.3)
    assert r.flight_time[0] == pytest.approx(r.flight_time[1]) and r.flight_time[0] > 0
    with pytest.raises(
        upm.ParameterError, match="contacts are not supported on a plate that moves out of its plane"
    ):
        upm.simulate(hop, [upm.Disk((0.0, 0.0), 0.01)], duration=0.01, dt=dt, mu=0.3, contacts=True)


def test_fields_need_a_periodic_motion_and_valid_settings() -> None:
    m = upm.PlateMotion.ppod("Sink")
    with pytest.raises(upm.ParameterError, match="periodic motion"):
        upm.drift_field(m.for_duration(1.0), [(0, 0)], mu=0.3)
    with pytest.raises(upm.ParameterError, match="mu_s"):
        upm.drift_field(m, [(0, 0)], mu=0.3, mu_s=0.2)
    with pytest.raises(upm.ShapeError):
        upm.asymptotic_field(m, [(0, 0, 0)])
    with pytest.raises(upm.ParameterError, match="points"):
        upm.asymptotic_field(m, [(math.nan, 0)])
    g = upm.drift_field(m, np.zeros((2, 3, 2)), mu=0.3)
    assert g.velocity.shape == (2, 3, 2) and g.validity.shape == (2, 3)


# ---------------------------------------------------------------- designing a field


def test_a_designed_sink_points_at_its_centre_and_gathers_parts() -> None:
    c = np.array([0.03, -0.02])
    d = upm.design_field("sink", c, 0.5, mu=0.3)
    assert d.motion.is_spatial and d.error < 0.05 and not d.limited
    # checked away from the design points: 16 directions at 5 cm, on the exact drift
    ang = np.linspace(0, 2 * np.pi, 16, endpoint=False) + 0.1
    pts = c + 0.05 * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    v = upm.drift_field(d.motion, pts, mu=0.3).velocity
    assert np.all(np.abs(upm.field_angle(v, c - pts)) < 5.0)
    # simulated parts, no sensing: all end within 1 cm of the centre
    start = c + np.random.default_rng(3).uniform(-0.06, 0.06, (12, 2))
    r = upm.simulate(d.motion, start, duration=15.0, dt=0.05 / 200, mu=0.3, record_every=100_000)
    assert np.all(np.linalg.norm(r.positions[-1] - c, axis=1) < 0.01)


@pytest.mark.parametrize(
    ("kind", "strength", "grad"),
    [
        ("source", 0.4, [[0.4, 0], [0, 0.4]]),
        ("rotation", 0.4, [[0, -0.4], [0.4, 0]]),
        ("shear", 0.3, [[0, 0.3], [0, 0]]),
    ],
)
def test_designed_fields_have_the_wanted_gradient(kind: str, strength: float, grad: list) -> None:
    d = upm.design_field(kind, (0.0, 0.01), strength, mu=0.25)
    assert d.error < 0.05, d.error
    xs = np.linspace(-0.03, 0.03, 5)
    ys = xs + 0.01
    v = upm.drift_field(d.motion, np.stack(np.meshgrid(xs, ys), -1), mu=0.25).velocity
    dvx_dy, dvx_dx = np.gradient(v[..., 0], ys, xs)
    dvy_dy, dvy_dx = np.gradient(v[..., 1], ys, xs)
    got = np.array([[dvx_dx[2, 2], dvx_dy[2, 2]], [dvy_dx[2, 2], dvy_dy[2, 2]]])
    assert np.allclose(got, grad, atol=0.06), got


def test_design_limits_and_bad_input() -> None:
    d = upm.design_field("sink", (0, 0), 5.0, limits={"rx": 30.0, "ry": 30.0})
    assert d.limited and d.error > 0.2  # too strong for the limits: reported, not hidden
    terms = d.motion._recipe
    assert all(t[1] <= 30.0 + 1e-9 for axis in terms[5:7] for t in axis)
    with pytest.raises(upm.ParameterError, match="kind must be one of"):
        upm.design_field("vortex", (0, 0), 1.0)
    with pytest.raises(upm.ParameterError, match="needs matrix"):
        upm.design_field("affine", (0, 0), 1.0)
    with pytest.raises(upm.ParameterError, match="unknown axis 'q'"):
        upm.design_field("sink", (0, 0), 1.0, limits={"q": 1.0})
    t = upm.design_field("affine", (0.0, 0.0), 0.0, matrix=[[-0.3, 0.0], [0.0, -0.3]], offset=(0.01, 0.0))
    assert t.error < 0.05


# ---------------------------------------------------------------- demos and figures


def test_the_sensorless_gathering_demo_gathers_every_part(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from upm.experiments.ppod_demos import run_ppod_demo

    m = run_ppod_demo("ppod", tmp_path, quick=True, verbose=False)
    for label in ("library Sink at (0, 0)", "designed sink at (0.03, -0.02)"):
        assert m[label]["seeds"] == 3 and m[label]["fraction_within_1cm"] == 1.0
        assert m[label]["max_distance_mm"]["max"] < 10.0
    assert (tmp_path / "ppod" / "gather.png").stat().st_size > 10_000
    seq = run_ppod_demo("ppod-sequences", tmp_path, quick=True, verbose=False)["square"]
    corners = np.array(seq["centroid_after_each_mm"])
    assert seq["lost"] == 0 and corners[1, 0] > 80 and corners[2, 1] < -80  # the cluster goes round
    assert np.linalg.norm(corners[4]) < 10  # and comes back


def test_the_field_figure_draws_drift_asymptotic_and_parts() -> None:
    pytest.importorskip("matplotlib")
    import upm.viz.plot

    fig = upm.plot.field(
        "both", (-0.1, -0.1, 0.1, 0.1), motion=upm.PlateMotion.ppod("Whirlpool"), resolution=7
    )
    assert len(fig.axes) >= 2 and "angle" in fig._suptitle.get_text()
    with pytest.raises(upm.ParameterError, match="needs motion"):
        upm.plot.field("drift", (-0.1, -0.1, 0.1, 0.1))
