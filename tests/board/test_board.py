"""The host driver and the board emulator, end to end over a real pseudo-terminal and TCP."""

import math
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import upm
from upm import actuation as act
from upm.board import Board, CommandRefused, protocol
from upm.board.emulator import BoardEmulator
from upm.plate.plant import SimulatedUPM

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals")

PLATE = SimulatedUPM().plate  # the plant's own plate, so motors sized for it move it as asked
SENSOR = (-0.18, -0.18)
F = 35.0


def start_emulator(*args):
    proc = subprocess.Popen(
        [sys.executable, "-m", "upm.board.emulator", *args], stdout=subprocess.PIPE, text=True
    )
    where = proc.stdout.readline().strip()
    assert where, "the emulator printed no address"
    return proc, where


# These tests exercise the protocol with abrupt 20 ms envelopes, whose velocity drift swings the
# plate's corners up to about 15 mm on its flexures: they run on a long-stroke plate (200 mm). The
# 10 mm default and its refusals are tested in tests/plan/test_predictive.py.
LONG = 0.2


@pytest.fixture
def emulator():
    proc, path = start_emulator("--stroke", str(LONG))
    yield path
    proc.kill()
    proc.wait()


def command_rotation(board, center, sustain=0.3):
    # Angular-velocity amplitude 2 rad/s: velocity_amplitudes are per (1/w) of the waveform.
    motors = PLATE.motors_for_rotation(center, omega=2.0 * 2 * np.pi * F)
    board.set_motors(motors, F)
    board.set_envelope(0.02, sustain, 0.02)


def test_end_to_end_rotation_pulse_recovers_the_centre(emulator):
    center = (0.05, -0.03)
    with Board(emulator) as board:
        assert board.info.version == protocol.VERSION and board.info.sample_rate == 5000
        command_rotation(board, center)
        board.samples()
        end = board.pulse(1)
        time.sleep(0.05)
        first, counts = board.samples()
        assert board.gaps == 0
        # The sustain: from 30 ms after the pulse's start to 30 ms before its end.
        start = end - round(0.34 * 5000)
        sustain = counts[start - first + 150 : end - first - 150].astype(float)
        rot = act.cor_from_accelerometers(sustain[:, :2], sustain[:, 2:], SENSOR, 5000.0, F)
        assert np.hypot(*(rot.center - center)) < 1e-3  # metres: within 1 mm
        status = board.status()
        assert status.state == protocol.State.IDLE and status.pulses == 1 and status.rejected == 0


def test_limits_are_checked_by_host_and_board(emulator):
    with Board(emulator) as board:
        with pytest.raises(upm.BoardError, match="exceeds the board's limit"):
            board.set_channel(0, 1e6, F)
        with pytest.raises(upm.BoardError, match="frequency must be in"):
            board.set_channel(0, 1.0, 1e5)
        # Bypass the host's check: the board itself refuses.
        with pytest.raises(CommandRefused) as refused:
            board._command(protocol.SetChannel(0, 1e6, F))
        assert refused.value.code == protocol.NackCode.OUT_OF_LIMITS
        assert board.status().faults & protocol.Status.LIMIT_REFUSED
        # NaN passed the host's comparisons before; now the host refuses it, and a bad envelope
        # or watchdog, before anything is sent (the board's counters do not move).
        before = board.status()
        for call in (
            lambda: board.set_channel(0, math.nan, F),
            lambda: board.set_channel(7, 1.0, F),
            lambda: board.set_envelope(0.02, math.inf, 0.02),
            lambda: board.set_envelope(-0.01, 0.2, 0.02),
            lambda: board.set_watchdog(70000),
        ):
            with pytest.raises(protocol.ProtocolError):
                call()
        assert board.status().rejected == before.rejected


def test_context_manager_stops_the_motors_on_exceptions(emulator):
    with pytest.raises(RuntimeError, match="boom"), Board(emulator) as board:
        command_rotation(board, (0.0, 0.0), sustain=5.0)
        board.pulse(2, wait=False)
        raise RuntimeError("boom")
    with Board(emulator) as board:
        status = board.status()
        assert status.state == protocol.State.STOPPED and status.pulses == 0


def test_stop_from_another_thread_ends_a_waiting_pulse_and_holds_until_cleared(emulator):
    import threading

    with Board(emulator) as board:
        command_rotation(board, (0.0, 0.0), sustain=5.0)
        timer = threading.Timer(0.3, board.stop)
        timer.start()
        t0 = time.monotonic()
        with pytest.raises(upm.BoardError, match="cut short"):
            board.pulse(5, wait=True, timeout=10.0)
        assert time.monotonic() - t0 < 3.0  # not the 5 s pulse
        assert board.status().state == protocol.State.STOPPED
        with pytest.raises(upm.BoardError, match="clear_stop"):  # nothing slips in after a STOP
            board.pulse(6, wait=True)
        assert board.status().pulses == 0  # the pulse cut short did not complete, none other ran
        board.clear_stop()
        board.set_envelope(0.01, 0.05, 0.01)
        board.pulse(7, wait=True)
        assert board.status().pulses == 1


HOST = textwrap.dedent(
    """
    import sys, time, numpy as np
    from upm.board import Board
    from upm import actuation as act
    board = Board(sys.argv[1])
    motors = act.Plate(1.0, 0.0275, 0.2).motors_for_rotation((0.0, 0.0), omega=2.0 * 2 * np.pi * 35)
    board.set_motors(motors, 35.0)
    board.set_envelope(0.02, 10.0, 0.02)
    board.pulse(3, wait=False)
    print("pulsing", flush=True)
    time.sleep(30)
    """
)


def test_watchdog_stops_the_motors_when_the_host_dies(emulator):
    host = subprocess.Popen([sys.executable, "-c", HOST, emulator], stdout=subprocess.PIPE, text=True)
    assert host.stdout.readline().strip() == "pulsing"
    os.kill(host.pid, signal.SIGKILL)  # no STOP, no more heartbeats
    host.wait()
    time.sleep(2.0)  # nobody reads the terminal meanwhile: what the board sends is lost
    with Board(emulator) as board:
        status = board.status()
        assert status.faults & protocol.Status.WATCHDOG_TRIPPED
        assert status.pulses == 0  # the 10 s pulse was cut short
        # the board kept its clock (it did not stall on a full terminal until a host came back)
        assert not status.faults & protocol.Status.SAMPLES_DROPPED


def test_watchdog_timing_in_the_board_logic():
    # The board's logic without I/O: a pulse starts at t = 0 and the host falls silent.
    board = BoardEmulator(SimulatedUPM(snr_db=None, stroke=LONG), watchdog_ms=250)
    decoder = protocol.Decoder()
    motors = PLATE.motors_for_rotation((0.0, 0.0), omega=2.0 * 2 * np.pi * F)
    frames = [protocol.Hello(1), protocol.SetEnvelope(0.0, 10.0, 0.0), protocol.Pulse(7)]
    frames += [protocol.SetChannel(k, float(m), F, 1.0, 0.0, 1.0, np.pi / 2) for k, m in enumerate(motors)]
    for seq, message in enumerate(frames[:2] + frames[3:] + frames[2:3]):
        decoder.feed(board.receive(protocol.encode(message, seq + 1), 0.0))
    received = []
    for k in range(1, 101):  # 0.5 s in 5 ms ticks
        received += decoder.feed(board.tick(k * 0.005))
    samples = [m for _, m in received if isinstance(m, protocol.Samples)]
    counts = np.concatenate([np.array(m.values) for m in samples])
    # Blocks of 10 ms: motors on until the watchdog (250 ms = sample 1250), off right after it.
    blocks = np.abs(counts[: len(counts) // 50 * 50]).reshape(-1, 50, 4).max(axis=(1, 2))
    assert (blocks[:24] > 0).all() and not (blocks[26:] > 0).any()
    statuses = [m for _, m in received if isinstance(m, protocol.Status)]
    assert statuses and statuses[0].state == protocol.State.WATCHDOG


def test_the_link_survives_injected_faults():
    proc, path = start_emulator(
        "--drop", "0.1", "--corrupt", "0.05", "--duplicate", "0.05", "--seed", "3", "--stroke", str(LONG)
    )
    try:
        with Board(path, timeout=0.1, retries=8) as board:
            for k in range(4):
                board.set_channel(k, 1.0, F)  # every command gets through by resending
            board.set_envelope(0.01, 0.05, 0.01)
            assert board.pulse(5, timeout=5.0) is not None
            time.sleep(0.2)
            _, counts = board.samples()
            assert board._decoder.rejected > 0  # corrupted frames were seen and dropped
            assert board.gaps > 0  # dropped sample frames are detected by their counters
            assert np.all(np.abs(counts) <= 1024)
            status = board.status()
            assert status.pulses == 1  # the resent PULSE was played once
    finally:
        proc.kill()
        proc.wait()


def test_tcp_and_sustained_throughput():
    proc, url = start_emulator("--tcp", "0", "--stroke", str(LONG))
    try:
        assert url.startswith("socket://")
        with Board(url) as board:
            board.samples()
            time.sleep(1.0)
            _, counts = board.samples()
            # 5 kHz for a second, none lost (generous bounds: a shared machine).
            assert 4000 <= len(counts) <= 6000 and board.gaps == 0
    finally:
        proc.kill()
        proc.wait()


def test_no_board_is_a_clear_timeout(tmp_path):
    with pytest.raises(upm.BoardError, match="echo"):
        Board("loop://", timeout=0.05, retries=1)
    with pytest.raises(upm.BoardError, match="cannot open"):
        Board(str(tmp_path / "no-such-tty"))


def test_parts_on_the_emulated_plate_follow_the_pulse():
    # Parts on the plant move when a pulse ends: tangentially about the commanded centre, in the
    # direction of the time-asymmetric drive's force, as upm.simulate has them.
    parts = np.array([[0.1, 0.0], [0.0, 0.12]])
    plant = SimulatedUPM(snr_db=None, parts=parts.copy(), mu=0.3, stroke=LONG)
    board = BoardEmulator(plant)
    motors = PLATE.motors_for_rotation((0.0, 0.0), omega=2.0 * 2 * np.pi * F)
    frames = [protocol.Hello(1), protocol.SetEnvelope(0.02, 0.2, 0.02)]
    frames += [protocol.SetChannel(k, float(m), F, 1.0, 0.0, 1.0, np.pi / 2) for k, m in enumerate(motors)]
    frames += [protocol.Pulse(1)]
    for seq, message in enumerate(frames):
        board.receive(protocol.encode(message, seq + 1), 0.0)
    decoder = protocol.Decoder()
    done = []
    for k in range(1, 60):
        done += [m for _, m in decoder.feed(board.tick(k * 0.005)) if isinstance(m, protocol.PulseDone)]
        board.receive(protocol.encode(protocol.Heartbeat(), 100 + k), k * 0.005)
    assert done and done[0].id == 1
    moved = plant.parts - parts
    tangent = np.stack([-parts[:, 1], parts[:, 0]], axis=1) / np.hypot(*parts.T)[:, None]
    along = np.einsum("ij,ij->i", moved, tangent)
    assert np.all(np.abs(along) > 1e-4)  # they moved (0.1 mm or more) ...
    assert np.all(
        np.abs(along) > 5 * np.abs(np.einsum("ij,ij->i", moved, parts / np.hypot(*parts.T)[:, None]))
    )
    assert np.sign(along[0]) == np.sign(along[1])  # ... both the same way round the centre


def test_upm_emulate_command():
    exe = os.path.join(os.path.dirname(sys.executable), "upm")
    proc = subprocess.Popen([exe, "emulate", "--tcp", "0"], stdout=subprocess.PIPE, text=True)
    try:
        url = proc.stdout.readline().strip()
        with Board(url) as board:
            assert board.info.watchdog_ms == 250
    finally:
        proc.kill()
        proc.wait()


def test_plant_run_records_the_pulse_and_moves_the_parts():
    from upm.plate.plant import Channel, Envelope

    plant = SimulatedUPM(snr_db=None, parts=[[0.1, 0.0]], stroke=LONG)
    motors = PLATE.motors_for_rotation((0.0, 0.0), omega=2.0 * 2 * np.pi * F)
    counts = plant.run([Channel(float(m), F) for m in motors], Envelope(0.02, 0.1, 0.02), rest=0.3)
    assert counts.shape == (round(0.44 * 5000), 4) and counts.dtype == np.int16
    # Strong during the pulse; after it the flexures (3 Hz) bring the plate home.
    peak = np.abs(counts[:700]).max()
    assert peak > 50 and np.abs(counts[-200:]).max() <= 0.01 * peak
    assert abs(plant.parts[0, 1]) > 1e-4  # moved tangentially
    rot = act.cor_from_accelerometers(counts[150:550, :2], counts[150:550, 2:], SENSOR, 5000.0, F)
    assert np.hypot(*rot.center) < 1e-3


def test_a_stalled_board_shows_as_a_gap_and_the_link_recovers():
    proc, path = start_emulator("--stall-after", "0.3", "--stall-for", "0.3", "--stroke", str(LONG))
    try:
        with Board(path, timeout=0.1, retries=8) as board:
            time.sleep(0.9)
            _, counts = board.samples()
            assert board.gaps >= 1  # the samples' counters jump over the silence
            assert len(counts) < 0.8 * 5000 * 0.9
            assert board.status().state == protocol.State.IDLE  # talking again
    finally:
        proc.kill()
        proc.wait()
