"""The board path in real time: the emulator works a pulse out as it starts (its parts take no
host-visible time to settle), a pulse's channels go out in one round trip, and the emulator's
camera has the frame after a pulse ready before it is asked for."""

import queue
import threading
import time

import numpy as np
import pytest
import serial

import upm
from upm import BoardError, PulseCut
from upm.board import Board, protocol
from upm.board.emulator import BoardEmulator
from upm.board.process import CameraServer
from upm.plate.plant import Channel, Envelope, SimulatedUPM

F = 35.0
PARTS = np.array([[0.1, 0.0], [0.0, 0.12], [-0.08, -0.05]])


def plant():
    return SimulatedUPM(snr_db=None, parts=PARTS.copy(), mu=0.3, part_radius=0.012, stroke=0.2)


def rotation(p):
    return [Channel(float(m), F) for m in p.plate.motors_for_rotation((0.0, 0.0), omega=2.0 * 2 * np.pi * F)]


def start(board, channels, envelope):
    frames = [protocol.Hello(1), protocol.SetEnvelope(*envelope)]
    frames += [
        protocol.SetChannel(k, c.amplitude, F, 1.0, 0.0, 1.0, np.pi / 2) for k, c in enumerate(channels)
    ]
    frames += [protocol.Pulse(7)]
    for seq, message in enumerate(frames):
        board.receive(protocol.encode(message, seq + 1), 0.0)


def run_until(board, until, done, decoder, step=0.005):
    k = 0
    while k * step < until:
        k += 1
        out = board.tick(k * step)
        done += [m for _, m in decoder.feed(out) if isinstance(m, protocol.PulseDone)]
        board.receive(protocol.encode(protocol.Heartbeat(), 1000 + k), k * step)
    return k * step


def reference(board, samples=None):
    """The board's pulse (its channels and envelope as the wire gave them: float32) on a plant of
    its own, played and settled after it ends (no emulator)."""
    p = plant()
    channels, env = board.channels[:4], board.envelope
    n = round(env.duration * p.sample_rate)
    t = np.arange(n) / p.sample_rate
    forces = p.forces(channels, t, env(t))[: samples if samples is not None else n]
    _, vel = p.plate_state(forces)
    p.settle_parts(vel)
    return p


def test_a_pulse_worked_out_at_its_start_moves_the_parts_as_played_after_it():
    p = plant()
    channels, envelope = rotation(p), (0.02, 0.2, 0.02)
    board, decoder, done = BoardEmulator(p), protocol.Decoder(), []
    start(board, channels, envelope)
    run_until(board, 0.1, done, decoder)
    assert not done and np.array_equal(p.parts, PARTS)  # mid-pulse: the parts are where they were
    run_until(board, 0.3, done, decoder)  # the pulse is over: its parts may still be settling
    if board.settling is not None:
        board.settling.thread.join()
    run_until(board, 0.01, done, decoder)
    assert [d.id for d in done] == [7]
    ref = reference(board)
    assert np.array_equal(p.parts, ref.parts)  # to the bit
    assert np.array_equal(p._state, ref._state) and p.max_excursion == ref.max_excursion
    assert np.min(np.hypot(*(p.parts - PARTS).T)) > 1e-4  # and they did move


def test_a_pulse_cut_short_moves_the_parts_only_as_far_as_it_played():
    p = plant()
    channels, envelope = rotation(p), (0.02, 0.3, 0.02)
    board, decoder, done = BoardEmulator(p), protocol.Decoder(), []
    start(board, channels, envelope)
    now = run_until(board, 0.1, done, decoder)
    played = board.produced - board.pulse[1]
    assert 0 < played < round(0.34 * p.sample_rate)
    board.receive(protocol.encode(protocol.Stop(), 999), now)
    assert board.state == protocol.State.STOPPED and board.pulse is None and board.settling is None
    ref = reference(board, samples=played)
    assert np.array_equal(p.parts, ref.parts) and np.array_equal(p._state, ref._state)
    whole = reference(board)
    assert np.max(np.hypot(*(whole.parts - p.parts).T)) > 1e-4  # the rest of the pulse did not play


def test_settled_leaves_the_plant_alone_until_applied():
    p = plant()
    channels = rotation(p)
    env = Envelope(0.02, 0.2, 0.02)
    t = np.arange(round(env.duration * p.sample_rate)) / p.sample_rate
    played = p.ahead(p.forces(channels, t, env(t)))
    state = p._state.copy()
    moved = p.settled(played.vel)
    assert np.array_equal(p.parts, PARTS) and np.array_equal(p._state, state) and p.max_excursion == 0.0
    p.commit(played)
    p.apply(moved)
    q = plant()
    q.settle_parts(q.plate_state(q.forces(channels, t, env(t)))[1])
    assert np.array_equal(p.parts, q.parts) and np.array_equal(p._state, q._state)


@pytest.fixture
def link():
    p = plant()
    board = BoardEmulator(p)
    sent = []

    class Wire:  # the host's port wired straight to the emulator's logic, on a clock of our own
        in_waiting = 0
        replies: queue.Queue = queue.Queue()
        lock = threading.Lock()

        def write(self, data):
            sent.append(bytes(data))
            with self.lock:
                self.replies.put(board.receive(bytes(data), 0.0))

        def tick(self, now):
            with self.lock:
                self.replies.put(board.tick(now))

        def read(self, n):
            try:
                return self.replies.get(timeout=0.005)
            except queue.Empty:
                return b""

        def close(self):
            pass

    real = serial.serial_for_url
    wire = Wire()
    serial.serial_for_url = lambda *a, **k: wire
    try:
        host = Board("wire://", timeout=0.5)
    finally:
        serial.serial_for_url = real
    host.wire = wire
    yield host, board, sent
    host.close(stop=False)


def test_a_pulses_channels_and_envelope_go_out_together(link):
    host, board, sent = link
    channels = [Channel(10.0 + k, F, 1.0, 0.1 * k, 0.5, 0.2) for k in range(4)]
    before = len(sent)
    host.set_channels(channels, (0.02, 0.3, 0.04))
    assert len(sent) - before == 5
    for k, c in enumerate(channels):
        got = board.channels[k]
        assert (got.amplitude, got.frequency, got.h1_phase, got.h2_amplitude) == pytest.approx(
            (c.amplitude, c.frequency, c.h1_phase, c.h2_amplitude), rel=1e-6
        )
    assert (board.envelope.attack, board.envelope.sustain, board.envelope.decay) == pytest.approx(
        (0.02, 0.3, 0.04)
    )


def test_a_bad_channel_or_envelope_sends_none_of_them(link):
    host, _, sent = link
    before = len(sent)
    ok = Channel(10.0, F)
    with pytest.raises(BoardError, match="amplitude"):
        host.set_channels([ok, ok, Channel(1e4, F), ok])
    with pytest.raises(protocol.ProtocolError, match="attack"):
        host.set_channels([ok] * 4, (-0.1, 0.3, 0.02))
    assert len(sent) == before


def test_the_emulators_camera_has_the_frame_after_a_pulse_ready():
    p = plant()
    camera = CameraServer(p.camera(["red", "blue", "penny"]))
    try:
        camera.prepare()
        ready = camera.shot[1]
        assert camera.frame() is ready  # taken ahead and served once
        assert camera.frame() is not ready  # the next request takes a new one
        camera.prepare()
        ahead = camera.shot[1]
        p.parts[0] += 0.01  # something moved the parts since: a new frame shows them
        frame = camera.frame()
        assert frame is not ahead and not np.array_equal(frame, ahead)
    finally:
        camera.server.close()


def test_a_pulse_the_watchdog_cut_short_is_reported_as_such(link, capfd):
    host, board, _ = link
    host.set_channels([Channel(10.0, F)] * 4, (0.02, 0.3, 0.02))
    failed = []

    def play():
        try:
            host.pulse(5, wait=True, timeout=5.0)
        except Exception as error:  # what it raised is the test
            failed.append(error)

    player = threading.Thread(target=play)
    player.start()
    for _ in range(500):
        if board.state == protocol.State.PULSING:
            break
        time.sleep(0.002)
    host.wire.tick(0.01)  # a little of the pulse plays
    host.wire.tick(1.0)  # then the board hears nothing for a second: its watchdog (250 ms) trips
    player.join(10.0)
    assert len(failed) == 1 and isinstance(failed[0], PulseCut), failed
    assert "watchdog" in str(failed[0])
    assert "watchdog tripped" in capfd.readouterr().err  # the board says so too


def test_the_board_device_gives_a_busy_host_a_second_of_watchdog(link):
    from upm.control import BoardDevice

    host, board, _ = link
    assert board.watchdog == 0.25
    device = BoardDevice(host)
    assert board.watchdog == 1.0 and host.info.watchdog_ms == 1000 and device.info.watchdog_ms == 1000
    BoardDevice(host, watchdog=None)
    assert board.watchdog == 1.0  # left as it was
    with pytest.raises(upm.ParameterError, match="heartbeat"):
        host.set_watchdog(60)  # the host beats every 50 ms
