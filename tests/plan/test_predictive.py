"""Drive limits, the stroke, task costs and the predictive planner (issue: predictive planning)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import upm
from upm import control
from upm.board import protocol
from upm.board.emulator import BoardEmulator
from upm.control.tasks import State
from upm.physics.waveforms import Harmonics
from upm.plan import PredictivePlanner, aligned_centres, generate, goals
from upm.plate.drive import DriveLimits, StrokeError, flexures
from upm.plate.plant import Channel, Envelope, SimulatedUPM
from upm.plate.pulses import Pulse

CHIP = 0.0195


def _slow_plate(plant: SimulatedUPM, forces: np.ndarray, state: np.ndarray) -> np.ndarray:
    """The plate's pose, one sample at a time: (5.8), then ``f = m q'' + b q' + k q`` by
    semi-implicit Euler (written out here, independent of the filter the plant runs)."""
    r = plant.plate.lever
    m = forces
    wrench = np.stack(
        [m[:, 0] - m[:, 1], m[:, 2] - m[:, 3], r * ((m[:, 2] + m[:, 3]) - (m[:, 0] + m[:, 1]))], 1
    )
    inertia = [plant.plate.mass, plant.plate.mass, plant.plate.inertia]
    dt = 1.0 / plant.sample_rate
    pose = np.empty_like(wrench)
    for k in range(3):
        q, v = state[k]
        b = 0.0 if plant.axes is None else plant.axes[k].damping
        s = 0.0 if plant.axes is None else plant.axes[k].stiffness
        for n in range(len(wrench)):
            v += dt * (wrench[n, k] - b * v - s * q) / inertia[k]
            q += dt * v
            pose[n, k] = q
    return pose


@pytest.mark.parametrize("free", [False, True])
def test_the_plate_model_is_the_per_sample_recurrence(free: bool) -> None:
    plant = SimulatedUPM(axes=None) if free else SimulatedUPM()
    start = np.array([[0.002, 0.01], [-0.001, 0.02], [0.01, 0.3]])  # per axis (position, velocity)
    plant._state = start.copy()
    forces = np.random.default_rng(1).normal(0.0, 50.0, (2000, 4))
    plant.plate_state(forces)
    expected = _slow_plate(plant, forces, start)
    assert np.allclose(plant._state[:, 0], expected[-1], rtol=1e-9, atol=1e-12)
    # the recorded pose keeps every 10th sample and the last
    assert np.allclose(plant.pose[:-1], expected[::10], rtol=1e-9, atol=1e-12)
    assert plant.max_excursion == pytest.approx(plant.limits.excursion(expected), rel=1e-9)


def test_the_planner_knows_where_the_plate_is_after_a_pulse() -> None:
    # DriveLimits.play (phasors, precompensated per harmonic) against the plant playing the same
    # pulse through its four motor channels (the board's fields) and the rest after it
    plant = SimulatedUPM()
    pulse = Pulse.rotation(
        (0.05, 0.0), Harmonics([5.0, -2.5], [0.0, 0.0], 35.0), 3 / 35, 0.23, 3 / 35, rest=0.05
    )
    pose, after = plant.limits.play(pulse)
    channels = [Channel(**c) for c in pulse.channels(plant.plate, plant.axes)]
    plant.run(channels, Envelope(pulse.attack, pulse.sustain, pulse.decay), rest=pulse.rest)
    assert np.allclose(after, plant._state, rtol=1e-6, atol=1e-12)
    assert plant.limits.excursion(pose) == pytest.approx(plant.max_excursion, rel=1e-3)


def test_excursion_of_known_poses() -> None:
    limits = DriveLimits()
    h = limits.size / 2
    assert limits.excursion([[0.003, -0.004, 0.0]]) == pytest.approx(0.005)
    # a small turn about the centre moves every corner by h sqrt(2) theta
    assert limits.excursion([[0.0, 0.0, 0.01]]) == pytest.approx(
        2 * h * math.sqrt(2) * math.sin(0.005), rel=1e-12
    )


def test_candidates_stay_within_force_and_stroke_on_the_plant() -> None:
    plant = SimulatedUPM()
    limits = plant.limits
    parts = np.array([[0.05, 0.05], [-0.08, 0.02], [0.1, -0.1]])
    aligned = (np.array([[0.02, 0.3], [-0.1, -0.04]]), np.array([1.0, -1.0]))
    cands = generate(limits, parts, use=0.9, aligned=aligned)
    families = set(cands.family)
    assert {"translation", "rotation", "part-rotation", "aligned-rotation", "jet", "fine-jet"} <= families
    kinds = {p.kind for p in cands.pulses}
    assert kinds == {"translation", "rotation", "jet"}
    assert len(cands) >= 250
    for k in sorted(set(range(0, len(cands), 5)) | set(np.nonzero(cands.family == "aligned-rotation")[0])):
        p = cands.pulses[k]
        force = p.peak_force(limits.plate, limits.axes)  # the channels' own arithmetic
        channels = [Channel(**c) for c in p.channels(limits.plate, limits.axes)]
        reach = plant.excursion(channels, Envelope(p.attack, p.sustain, p.decay))  # at 5 kHz
        assert force <= limits.force * 0.9 * 1.001
        assert reach <= limits.stroke * 0.93, (cands.family[k], p.frequency, reach)
        # and at least one of the two limits is nearly used: the candidate is as strong as allowed
        # (but for the gentle jets, at a set fraction of that)
        if cands.family[k] != "fine-jet":
            assert max(force / limits.force, reach / limits.stroke) > 0.85


def test_a_pulse_beyond_the_stroke_is_refused_by_plant_host_and_emulator() -> None:
    plant = SimulatedUPM(parts=[[0.05, 0.0]])
    big = Pulse.rotation((0.0, 0.0), Harmonics([8.0, -4.0], [0.0, 0.0], 25.0), 0.12, 0.3, 0.12)  # 85 N, 17 mm
    assert plant.limits.pulse_excursion(big) > plant.stroke
    channels = [Channel(**c) for c in big.channels(plant.plate, plant.axes)]
    with pytest.raises(StrokeError, match="stroke"):
        plant.run(channels, Envelope(big.attack, big.sustain, big.decay))
    assert np.all(plant._state == 0) and np.allclose(plant.parts, [[0.05, 0.0]])  # nothing moved
    with pytest.raises(StrokeError):
        control.SimulatedDevice(plant).execute([big])
    with pytest.raises(StrokeError):
        plant.limits.check(big)  # the host's check before it sends anything
    with pytest.raises(upm.UpmError):  # and the same from the top-level name
        DriveLimits(stroke=0.01).check(big)
    # the board: SET_CHANNEL x 4, SET_ENVELOPE, PULSE -> NACK STROKE
    board = BoardEmulator(SimulatedUPM(snr_db=None))
    decoder = protocol.Decoder()
    frames: list[protocol.Message] = [protocol.Hello(1)]
    for k, c in enumerate(channels):
        frames.append(protocol.SetChannel(k, 1.0, c.frequency, c.h1_amplitude, c.h1_phase, c.h2_amplitude,
                                          c.h2_phase, c.h23_amplitude, c.h23_phase))  # fmt: skip
    frames += [protocol.SetEnvelope(big.attack, big.sustain, big.decay), protocol.Pulse(9)]
    replies = []
    for seq, message in enumerate(frames, 1):
        replies += [m for _, m in decoder.feed(board.receive(protocol.encode(message, seq), 0.0))]
    nacks = [m for m in replies if isinstance(m, protocol.Nack)]
    assert [n.code for n in nacks] == [protocol.NackCode.STROKE]
    # a gentle pulse is played
    small = Pulse.rotation((0.0, 0.0), Harmonics([2.0, -1.0], [0.0, 0.0], 35.0), 0.1, 0.3, 0.1)
    plant.limits.check(small)
    control.SimulatedDevice(plant).execute([small])
    assert 0 < plant.max_excursion <= plant.stroke


def test_the_loop_refuses_a_planner_whose_limits_differ_from_the_device() -> None:
    plant = SimulatedUPM(parts=[[0.0, 0.0]])
    other = DriveLimits(plant.plate, flexures(plant.plate.mass, plant.plate.inertia), stroke=0.02)
    with pytest.raises(upm.ParameterError, match="limits differ"):
        control.Loop(plant, plant.camera(), PredictivePlanner(other), control.WatchTask(1), part_radius=CHIP)
    control.Loop(
        plant, plant.camera(), PredictivePlanner(plant.limits), control.WatchTask(1), part_radius=CHIP
    )
    with pytest.raises(upm.ParameterError, match="limits must be"):
        PredictivePlanner(plant.plate)


def _state(positions: list[list[float]], labels: tuple[str, ...]) -> State:
    p = np.array(positions, dtype=float)
    return State(0, 0.0, np.arange(len(p)), p, labels, 0.0)


def test_task_costs_vanish_at_the_goal_and_grow_with_distance() -> None:
    goals = np.array([[0.05, 0.0], [-0.05, 0.02]])
    task = control.GotoTask(goals, starts=goals, tolerance=0.002)
    state = _state(goals.tolist(), ("a", "b"))
    assert task.cost(state) == 0.0
    offsets = np.array([0.0, 0.001, 0.005, 0.02, 0.05])
    batch = goals[None] + offsets[:, None, None] * np.array([1.0, 0.0])
    cost = task.cost(state, batch)
    assert cost[0] == 0.0 and np.all(np.diff(cost[1:]) > 0)
    # each part's distance less half the tolerance, squared over the first tolerance beyond it
    assert cost[-1] == pytest.approx(2 * (0.05 - 0.001 - 0.001))
    assert cost[2] == pytest.approx(2 * (0.005 - 0.001 - 0.001))
    assert cost[1] == pytest.approx(0.0, abs=1e-15)  # at the slack
    assert task.cost(state, goals[None] + [0.002, 0.0])[0] == pytest.approx(2 * 0.001**2 / (2 * 0.002))

    sort = control.SortTask({"red": -1, "blue": 1}, line=0.1, past=0.01, clear=0.003)
    s = _state([[-0.2, 0.0], [0.15, 0.0]], ("red", "blue"))
    assert sort.cost(s) == 0.0 and sort.done(s)
    # the blue's way d to 3 mm past its line weighs 2, bent over 0.6 of the 16" plate's side
    # (2 d (1 + d / 0.24384)); its way to half of past beyond it 0.3
    moved = np.array([[[-0.2, 0.0], [0.05, 0.0]], [[-0.2, 0.0], [0.0, 0.0]], [[-0.2, 0.0], [0.104, 0.0]]])
    reach = 0.6 * 0.4064
    assert sort.cost(s, moved) == pytest.approx(
        [
            2 * 0.053 * (1 + 0.053 / reach) + 0.3 * 0.055,
            2 * 0.103 * (1 + 0.103 / reach) + 0.3 * 0.105,
            0.3 * 0.001,
        ]
    )
    # the bend: a metre of the farther part's way weighs more (a part left for last costs most)
    step = np.array([[[-0.2, 0.0], [x, 0.0]] for x in (0.0, 0.01, 0.08, 0.09)])
    c = sort.cost(s, step)
    assert c[0] - c[1] > c[2] - c[3] > 0
    # a lost part costs more than one anywhere on the plate
    lost = np.array([[[-0.2, 0.0], [np.nan, np.nan]], [[-0.2, 0.0], [-0.2, 0.0]]])
    far, gone = sort.cost(s, lost[1:]), sort.cost(s, lost[:1])
    assert gone[0] > far[0] > 0
    with pytest.raises(upm.ParameterError, match="clear"):
        control.SortTask({"red": -1}, clear=-0.001)

    path = [[0.0, 0.0], [0.1, 0.0]]
    traj = control.TrajectoryTask([path], speed=0.01)
    t0 = _state([[0.0, 0.0]], ("p",))
    assert traj.cost(t0) == 0.0
    # after 2 s the reference is 2 cm along: a part left behind costs 2 cm, one there nothing
    assert traj.cost(t0, np.array([[[0.0, 0.0]], [[0.02, 0.0]]]), elapsed=2.0) == pytest.approx([0.02, 0.0])


@pytest.mark.parametrize("sense", [1.0, -1.0])
def test_aligned_centres_find_the_rotation_that_serves_every_part(sense: float) -> None:
    # four parts whose goals lie 15 mm along their tangents about (0.05, -0.02), one way round:
    # the quick model's best rotation is about that centre (a lattice point), in that sense
    size = 0.4
    lattice = np.linspace(-0.9 * size, 0.9 * size, 37)
    centre = np.array([lattice[20], lattice[17]])
    parts = centre + np.array([[0.06, 0.0], [0.0, 0.08], [-0.05, 0.0], [0.0, -0.07]])
    rel = parts - centre
    tangent = sense * np.stack([-rel[:, 1], rel[:, 0]], 1) / np.hypot(*rel.T)[:, None]
    goals = parts + 0.015 * tangent
    task = control.GotoTask(goals, starts=parts, tolerance=1e-9)
    state = _state(parts.tolist(), ("a", "b", "c", "d"))
    centres, senses = aligned_centres(lambda q: task.cost(state, q), parts, size, count=5)
    assert np.allclose(centres[0], centre) and senses[0] == sense
    assert len(centres) == 5 and np.all(np.hypot(*(centres[1:] - centres[0]).T) >= 0.03)
    # the rotations built about them turn every part that way round the centre, and the shorter
    # one brings them nearer their goals (the exact integrator, not the quick model)
    limits = SimulatedUPM().limits
    cands = generate(limits, parts, grid=0, jet_radii=(), fine=(), aligned=(centres[:1], senses[:1]))
    mine = [p for p, f in zip(cands.pulses, cands.family, strict=True) if f == "aligned-rotation"]
    assert len(mine) == 2  # on-times 0.2 and 0.4 s
    final, _ = PredictivePlanner(limits, mu=0.3).predict(mine, parts)
    assert np.all(np.einsum("kmi,mi->km", final - parts, tangent) > 0.005)
    assert task.cost(state, final)[0] < task.cost(state) - 0.02
    # nothing lowers the cost of parts at their goals
    done = control.GotoTask(parts, starts=parts, tolerance=1e-9)
    none, _ = aligned_centres(lambda q: done.cost(state, q), parts, size)
    assert none.shape == (0, 2)


def test_a_sort_with_a_lost_part_is_not_done() -> None:
    sort = control.SortTask({"red": -1, "blue": 1})
    first = State(0, 0.0, np.arange(3), np.array([[-0.15, 0.0], [0.15, 0.0], [0.15, 0.05]]),
                  ("red", "blue", "blue"), 0.0)  # fmt: skip
    assert sort.done(first)
    lost = State(1, 1.0, np.arange(2), first.positions[:2], ("red", "blue"), 1.0)  # one fell off
    assert not sort.done(lost)
    unseen = State(1, 1.0, np.arange(3), np.vstack([first.positions[:2], [[np.nan, np.nan]]]),
                   ("red", "blue", "blue"), 1.0)  # fmt: skip
    assert not sort.done(unseen)


def test_a_sorted_part_is_not_pushed_past_its_line() -> None:
    sort = control.SortTask({"red": -1, "blue": 1}, line=0.1, past=0.01, margin=0.04)
    s = _state([[-0.105, 0.0], [0.12, 0.0], [0.05, 0.0]], ("red", "blue", "blue"))
    steps = sort.steps(s)
    assert steps[0, 0] == pytest.approx(-0.005)  # to the line plus past, no further
    assert steps[1, 0] == 0.0  # beyond it already
    assert steps[2, 0] > 0


def test_the_planner_picks_the_obviously_best_pulse() -> None:
    limits = SimulatedUPM().limits
    planner = PredictivePlanner(limits, mu=0.3, lookahead=None)
    goal = np.array([[0.03, 0.0]])
    task = control.GotoTask(goal, starts=goal)
    state = _state([[0.0, 0.0]], ("p",))
    h = Harmonics([0.6, -0.3], [0.0, 0.0], 25.0)
    pulses = [
        Pulse.translation((-1.0, 0.0), h, 0.12, 0.2, 0.12),
        Pulse.translation((0.0, 1.0), h, 0.12, 0.2, 0.12),
        Pulse.translation((1.0, 0.0), h, 0.12, 0.2, 0.12),  # towards the goal
        Pulse.rotation((0.0, 0.0), Harmonics([2.0, -1.0], [0.0, 0.0], 35.0), 0.1, 0.2, 0.1),  # on the part
    ]
    best, gain, _ = planner.choose(task, state, pulses)
    assert best == 2 and gain[2] > 0 and gain[0] < 0
    # nothing to gain at the goal: no pulse
    assert planner.choose(task, _state([[0.03, 0.0]], ("p",)), pulses)[0] is None


def test_a_pulse_that_leaves_a_part_at_the_edge_is_not_played() -> None:
    # six parts to move 10 cm along x, a free one 30 mm from the right edge: a translation
    # along x gains most but leaves the free part under a millimetre from the edge, where a
    # prediction's error drops it; a rotation about the free part gains less and keeps it
    limits = SimulatedUPM().limits
    half = limits.size / 2
    pos = np.array([[-0.05, y] for y in (-0.1, -0.06, -0.02, 0.02, 0.06, 0.1)] + [[half - 0.03, 0.1]])
    steps = np.array([[0.1, 0.0]] * 6 + [[np.nan, np.nan]])
    pulses = [
        Pulse.translation((1.0, 0.0), Harmonics([0.3, -0.15], [0.0, 0.0], 25.0), 0.12, 0.2, 0.12),
        Pulse.rotation((half - 0.03, 0.1), Harmonics([3.0, -1.5], [0.0, 0.0], 35.0), 0.1, 0.2, 0.1),
    ]
    kw = {"mu": 0.3, "lookahead": None, "pairs": None, "aligned": 0}
    guarded = PredictivePlanner(limits, **kw)
    final, _ = guarded.predict(pulses, pos)
    assert 0 < half - final[0, -1, 0] < guarded.guard  # on the plate, within the guard
    assert half - final[1, -1, 0] > 0.02
    view, goal = goals.PositionsView(pos), goals.StepsGoal(pos + steps)
    # without the guard (nor the worst case of the part's way, `spread`) the translation wins
    best, gain, _ = PredictivePlanner(limits, guard=0.0, spread=0.0, **kw).choose(goal, view, pulses)
    assert best == 0 and gain[0] > gain[1] > 0
    for alone in ({"spread": 0.0}, {"guard": 0.0}, {}):  # either one, or both, count the part lost
        best, gain, _ = PredictivePlanner(limits, **alone, **kw).choose(goal, view, pulses)
        assert best == 1 and gain[0] < -1.0, alone


def test_a_pulse_is_scored_with_the_best_second_pulse_after_it() -> None:
    # every (first, second) pair predicted one layout at a time and scored by hand: the planner's
    # rate for each first pulse is the better of its own gain per second and the best pair's
    limits = SimulatedUPM().limits
    planner = PredictivePlanner(limits, mu=0.3, lookahead=None, pairs=(4, 4))
    start = np.array([[0.0, 0.0], [-0.04, 0.03]])
    goals = np.array([[0.05, 0.02], [0.0, 0.05]])
    task = control.GotoTask(goals, starts=start, tolerance=0.002)
    state = _state(start.tolist(), ("a", "b"))
    h = Harmonics([0.6, -0.3], [0.0, 0.0], 25.0)
    pulses = [
        Pulse.translation((1.0, 0.0), h, 0.12, 0.2, 0.12),
        Pulse.translation((0.0, 1.0), h, 0.12, 0.1, 0.12),
        Pulse.translation((1.0, 1.0), h, 0.12, 0.3, 0.12),
        Pulse.rotation((0.1, 0.0), Harmonics([2.0, -1.0], [0.0, 0.0], 35.0), 0.1, 0.2, 0.1),
    ]

    def cost(q: np.ndarray) -> float:
        return float(np.sum(np.maximum(np.hypot(*(q - goals).T) - 0.001, 0.0)))

    firsts = [planner.predict([p], start) for p in pulses]
    c0 = cost(start)
    want = []
    for final, time in firsts:
        rates = [(c0 - cost(final[0])) / time[0]]
        for s, (_, time_s) in enumerate(firsts):
            after, _ = planner.predict([pulses[s]], final[0])
            rates.append((c0 - cost(after[0])) / (time[0] + time_s[0]))
        want.append(max(rates))
    best, _, rate = planner.choose(task, state, pulses)
    assert np.allclose(rate, want, rtol=1e-9, atol=1e-12)
    assert best == int(np.argmax(want))
    # without pairs: each pulse's own gain per second
    alone = PredictivePlanner(limits, mu=0.3, lookahead=None, pairs=None).choose(task, state, pulses)[2]
    assert np.allclose(alone, [(c0 - cost(f[0])) / t[0] for f, t in firsts], rtol=1e-9)
    assert np.all(rate >= alone) and np.any(rate > alone + 1e-6)
    for bad in ((0, 5), (3,), "16,100", (2.5, 4), (True, 4)):
        with pytest.raises(upm.ParameterError, match="pairs must be None or two integers"):
            PredictivePlanner(limits, pairs=bad)


def test_a_short_predictive_sort_sorts_without_loss_within_the_stroke() -> None:
    parts = np.array([[-0.07, 0.06], [0.06, 0.05], [-0.05, -0.06], [0.07, -0.05]])
    labels = ["red", "blue", "red", "blue"]
    plant = SimulatedUPM(parts=parts, part_radius=CHIP, seed=3)
    planner = PredictivePlanner(plant.limits, mu=0.3, part_radius=CHIP)
    task = control.SortTask({"red": -1, "blue": 1}, line=0.09, margin=0.08)
    log = control.Loop(plant, plant.camera(labels, seed=3), planner, task, part_radius=CHIP).run(40)
    assert log.done and plant.fallen == 0
    assert np.all(plant.parts[[0, 2], 0] < -0.09) and np.all(plant.parts[[1, 3], 0] > 0.09)
    assert 0 < plant.max_excursion <= plant.stroke  # the plate's recorded pose
    assert planner.step_errors and np.median(planner.step_errors) < 0.006


def test_the_planner_learns_a_lower_friction() -> None:
    # the plate's friction is 0.21, the planner is told 0.3: its estimate moves towards 0.21
    parts = np.array([[-0.03, 0.05], [0.04, -0.05]])
    plant = SimulatedUPM(parts=parts.copy(), mu=0.21)
    planner = PredictivePlanner(plant.limits, mu=0.3, lookahead=None)
    device = control.SimulatedDevice(plant)
    task = control.GotoTask(np.array([[-0.12, 0.05], [0.12, -0.05]]), starts=parts)
    for cycle in range(4):
        state = State(cycle, 0.0, np.arange(2), plant.parts.copy(), ("a", "b"), 0.0)
        device.execute(planner.plan_task(state, task))
    planner.plan_task(State(4, 0.0, np.arange(2), plant.parts.copy(), ("a", "b"), 0.0), task)
    assert planner.mu_estimate < 0.26


def test_the_end_of_a_sort_does_not_stall_against_the_edge() -> None:
    # a layout where a sort stalled (seed 1 of bench/control.py sort8): two reds still to go left,
    # two sorted reds on the edge band's border and the blues just past their target, so every
    # pulse that moves a red nudges the others; a steep edge penalty then refused every pulse
    # (with the cost that weighed every millimetre to past / 2 alike)
    at = np.array([[114.7, -133.6], [148.9, -39.2], [111.8, 79.9], [111.3, -50.4],
                   [-81.9, 61.8], [-43.2, -74.7], [-168.1, 21.6], [-168.0, -53.7]]) / 1000  # fmt: skip
    labels = ("blue",) * 4 + ("red",) * 4
    task = control.SortTask({"red": -1, "blue": 1}, margin=0.08, spacing=0.046, max_step=0.025)
    limits = SimulatedUPM().limits
    state = _state(at.tolist(), labels)
    chosen = PredictivePlanner(limits, mu=0.3, part_radius=CHIP).plan_task(state, task)
    assert len(chosen) == 1

    class Even(control.SortTask):  # every millimetre to half of past beyond the line alike
        NEAR, FAR = 0.0, 1.0

    even = Even({"red": -1, "blue": 1}, margin=0.08, spacing=0.046, max_step=0.025)
    kw = {"mu": 0.3, "part_radius": CHIP, "edge_weight": 3.0, "lookahead": None, "aligned": 0}
    # (one pulse with that cost and a steep edge penalty refused every candidate while jets
    # ramped over 6 periods; with 4 one jet gains even so, so that contrast is gone)
    # two pulses see past it even then: the second puts back what the first nudges
    assert len(PredictivePlanner(limits, **kw).plan_task(state, even)) == 1
    # and so does the sort's own cost, whose pull on a part not yet over its line outweighs the
    # nudges to those past it
    assert len(PredictivePlanner(limits, pairs=None, **kw).plan_task(state, task)) == 1
    # what the chosen pulse does: the cost falls, and no part is predicted off the plate
    planner = PredictivePlanner(limits, mu=0.3, part_radius=CHIP)
    final, _ = planner.predict(chosen, at, disks=True, fine=True)
    assert np.all(np.isfinite(final)) and np.all(np.abs(final) < limits.size / 2)
    assert task.cost(state, final[0]) < task.cost(state) - 1e-3


def test_parts_slide_to_rest_as_the_integrator_has_them() -> None:
    # the closed form against the integrator itself: point parts thrown across a plate at rest
    from upm.plan.sizing import slide_to_rest

    rng = np.random.default_rng(4)
    start = rng.uniform(-0.1, 0.1, (12, 2))
    velocity = rng.normal(0.0, 0.3, (12, 2))
    velocity[0] = 0.0  # one part already at rest
    mu = rng.uniform(0.15, 0.6, 12)
    parts = [upm.Point(tuple(p), tuple(v)) for p, v in zip(start, velocity, strict=True)]
    dt = 1e-4
    run = upm.simulate(upm.PlateMotion.rest(1.0), parts, duration=0.5, dt=dt, mu=mu, record_every=1)
    final, stop = slide_to_rest(start, velocity, mu)
    assert np.allclose(run.positions[-1], final, atol=0.5 * 9.81 * 0.6 * dt * dt + 1e-12, rtol=0)
    moving = ~run.stuck
    last = np.array(
        [run.t[np.nonzero(moving[:, j])[0][-1]] if moving[:, j].any() else 0.0 for j in range(12)]
    )
    assert np.all(np.abs(last + dt - stop) <= dt + 1e-12) and stop[0] == 0.0


def test_the_macro_tables_apply_as_a_plain_interpolation_does() -> None:
    # every macro of the look-ahead applied to random layouts, against a slow evaluation written
    # here: each part's distance from the rotation's centre, np.interp in the table, the
    # displacement turned with the part about the centre; translations shift every part
    limits = SimulatedUPM().limits
    table = PredictivePlanner(limits, mu=0.3).macros
    assert table is not None
    rng = np.random.default_rng(7)
    layouts = rng.uniform(-0.25, 0.25, (6, 5, 2))
    layouts[2, 3] = np.nan
    layouts[4, 1] = table.centres[3]  # a part at a centre: r = 0
    got = table.apply(layouts)
    n_rot = len(table.centres)
    assert got.shape == (6, n_rot + len(table.shift), 5, 2)
    for k, layout in enumerate(layouts):
        for c, centre in enumerate(table.centres):
            for i, p in enumerate(layout):
                rel = p - centre
                r = math.hypot(*rel)
                if not math.isfinite(r):
                    assert np.all(np.isnan(got[k, c, i]))
                    continue
                d = [np.interp(r, table.radii, table.turn[c, :, a]) for a in (0, 1)]
                cos, sin = (rel / r) if r > 0 else (1.0, 0.0)
                want = p + np.array([cos * d[0] - sin * d[1], sin * d[0] + cos * d[1]])
                assert np.allclose(got[k, c, i], want, rtol=0, atol=1e-15)
        assert np.allclose(
            got[k, n_rot:], layout[None] + table.shift[:, None], rtol=0, atol=1e-15, equal_nan=True
        )
    assert table.apply(layouts[0]).shape == (n_rot + len(table.shift), 5, 2)  # one layout, no batch axis


def test_the_edge_penalty_counts_band_depth_and_lost_parts() -> None:
    planner = PredictivePlanner(SimulatedUPM().limits, mu=0.3, edge=0.04, edge_weight=2.0, lost_cost=1.5)
    half = planner.limits.size / 2
    q = np.array(
        [
            [[0.0, 0.0], [half - 0.03, 0.0]],
            [[0.0, -(half - 0.014)], [np.nan, 0.0]],
            [[half + 1e-3, 0.0], [0.0, 0.0]],
        ]
    )
    # per coordinate: its depth in the 40 mm band, plus five times its depth in the band's outer half
    want = [2.0 * 0.01, 2.0 * (0.026 + 5 * 0.006) + 1.5, 1.5]
    assert planner._penalty(q, overlaps=False) == pytest.approx(want, abs=1e-12)
    # within the guard (12 mm by default) of an edge a part counts half lost, besides its depth: a
    # prediction is off by a millimetre or two, and a part left riding at the edge is dropped
    # sooner or later; but off the plate it counts whole, or a pulse that pushes a part already in
    # the guard over the edge would cost no more than resting (sort32 seed 5 lost a chip so)
    near = np.array([[[0.0, half - 0.01]], [[0.0, half - 0.014]], [[0.0, half + 0.001]]])
    want = [0.75 + 2.0 * (0.03 + 5 * 0.01), 2.0 * (0.026 + 5 * 0.006), 1.5]
    assert planner._penalty(near, overlaps=False) == pytest.approx(want, abs=1e-12)
    for bad in (-1e-3, 0.04, math.nan, "1"):
        with pytest.raises(upm.ParameterError, match="guard must be >= 0 and below edge"):
            PredictivePlanner(SimulatedUPM().limits, edge=0.04, guard=bad)


def test_a_long_way_to_just_inside_the_edge_band_counts_a_part_lost_a_short_one_does_not() -> None:
    # the edge penalty scores a part where a prediction error proportional to its way could put it
    planner = PredictivePlanner(DriveLimits(), spread=0.15)
    half = planner.limits.size / 2
    end = np.array([[[half - 0.02, 0.0]]])  # 20 mm from the edge: in the band, outside the guard
    far = np.array([[half - 0.22, 0.0]])  # 200 mm away: worst case 30 mm further, off the plate
    near = np.array([[half - 0.03, 0.0]])  # 10 mm away: worst case 1.5 mm further
    lost = planner._penalty(end, start=far)[0]
    kept = planner._penalty(end, start=near)[0]
    assert lost >= planner.lost_cost
    assert 0 < kept < 0.1 * planner.lost_cost
    assert planner._penalty(end)[0] == pytest.approx(
        PredictivePlanner(DriveLimits(), spread=0.0)._penalty(end, start=far)[0]
    )
    with pytest.raises(upm.ParameterError, match="spread"):
        PredictivePlanner(DriveLimits(), spread=2.0)


def test_the_focus_breaks_ties_of_slope_by_distance_and_falls_back_to_every_part() -> None:
    # a distance cost's far parts all have slope 1: the parts aimed at first are the farthest, not
    # the first by index (a stalled 32-part shape aimed every pulse at the same 16 jammed parts)
    from upm.plan.aim import aimed as _focus

    goals = np.zeros((5, 2))
    pos = np.array([[0.01, 0.0], [0.05, 0.0], [0.02, 0.0], [0.09, 0.0], [0.0, 0.001]])
    task = control.GotoTask(goals, starts=pos, tolerance=0.004)
    state = _state(pos.tolist(), tuple("abcde"))
    toward = np.array([[-1.0, 0.0]] * 4 + [[0.0, 0.0]])  # the last part is home
    first, every = _focus(task, state, pos, toward, 2)
    np.testing.assert_array_equal(first[0], pos[[1, 3]])  # the two farthest, in part order
    np.testing.assert_array_equal(every[0], pos)
    assert len(_focus(task, state, pos, toward, None)) == 1


def test_a_stalled_search_is_made_again_with_the_edge_band_relaxed(monkeypatch: pytest.MonkeyPatch) -> None:
    """sort32 seed 3's end, built by hand: sorted chips along both edges (in the band, 17 mm
    from it), one blue chip 0.7 mm short of its line. Every pulse that nudges it also nudges a
    chip in the band outward at five times the task's price per metre, so the full search finds
    nothing and the loop would idle for good; the search made again at a relaxed band weight
    carries it over while no chip comes within the guard."""
    from upm.experiments.demos import LIMITS
    from upm.plan import predictive

    line = 0.0366
    task = control.SortTask({"red": -1, "blue": 1}, line=line, margin=0.08, part_radius=CHIP)
    ys = [-0.15, -0.1, -0.05, 0.0, 0.05, 0.1, 0.15]
    s = _state([[-0.186, y] for y in ys] + [[0.186, y] for y in ys] + [[line - 0.0007, -0.052]],
               ("red",) * 7 + ("blue",) * 8)  # fmt: skip
    assert not task.done(s)
    monkeypatch.setattr(predictive, "RELAXED", 1.0)  # no relief: the search as it was
    assert PredictivePlanner(LIMITS, mu=0.3, part_radius=CHIP).plan_task(s, task) == []
    monkeypatch.undo()
    planner = PredictivePlanner(LIMITS, mu=0.3, part_radius=CHIP)
    pulses = planner.plan_task(s, task)
    assert len(pulses) == 1 and planner.expected is not None
    after = planner.expected[1]
    assert after[-1, 0] > line  # over its line
    assert np.all(np.abs(after) < LIMITS.size / 2 - planner.guard)  # nothing pushed to the edge
    assert planner.edge_weight == 1.0  # the relief lasts one search
