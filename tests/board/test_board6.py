"""Protocol version 2 and the six-axis board: negotiation both ways, six actuator channels,
SAMPLES6, and field pulses played through the emulator (docs/protocol.md, docs/ppod.md)."""

import json
import subprocess
import sys

import numpy as np
import pytest
from cobs import cobs

import upm
from upm.board import Board, protocol
from upm.board.emulator import BoardEmulator
from upm.plate.plant import SimulatedUPM
from upm.plate.plate6 import Plate6

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals")


def exchange(board, messages, first=1):
    """Feed ``messages`` (seq ``first``, ...) to the board logic; its replies with their frame
    versions (a HELLO goes in a version-1 frame, the rest at the link's version)."""
    out = []
    for seq, m in enumerate(messages, start=first):
        version = 1 if isinstance(m, protocol.Hello) else board.link
        raw = board.receive(protocol.encode(m, seq, version=version), 0.0)
        for frame in raw.split(b"\x00")[:-1]:
            version = cobs.decode(frame)[0]
            out.append((version, protocol.decode_frame(frame)[1]))
    return out


def test_a_version_1_host_gets_a_four_channel_board_of_version_1():
    board = BoardEmulator(SimulatedUPM(snr_db=None), plate6=Plate6())
    replies = exchange(board, [protocol.Hello(1), protocol.SetChannel(4, 1.0, 20.0)])
    version, hello = replies[0]
    assert version == 1 and hello.version == 1 and not hello.capabilities & protocol.CAP_SIX_AXIS
    assert replies[1] == (1, protocol.Nack(2, protocol.NackCode.BAD_CHANNEL))


def test_a_version_2_host_on_a_version_1_board_falls_back():
    board = BoardEmulator(SimulatedUPM(snr_db=None), max_version=1)
    assert exchange(board, [protocol.Hello(2)])[0][1] == protocol.Nack(1, protocol.NackCode.VERSION)
    hello = exchange(board, [protocol.Hello(1)], first=2)[0][1]
    assert hello.version == 1 and board.link == 1


def test_a_six_axis_pulse_in_the_board_logic():
    parts = np.array([[0.08, 0.0], [0.0, -0.07], [-0.06, 0.05]])
    plant = SimulatedUPM(snr_db=None, parts=parts.copy(), mu=0.3)
    plate = Plate6()
    board = BoardEmulator(plant, plate6=plate)
    sink = upm.PlateMotion.ppod("Sink")
    channels = [protocol.SetChannel(k, **c) for k, c in enumerate(plate.channels(sink))]
    replies = exchange(
        board, [protocol.Hello(2), *channels, protocol.SetEnvelope(0.1, 1.0, 0.1), protocol.Pulse(3)]
    )
    assert replies[0][1].capabilities & protocol.CAP_SIX_AXIS and board.six
    assert all(isinstance(m, protocol.Ack) and v == 2 for v, m in replies[1:])
    decoder = protocol.Decoder()
    got = []
    for k in range(1, 300):  # 1.5 s in 5 ms ticks, the host's heartbeat keeping the watchdog fed
        got += [m for _, m in decoder.feed(board.tick(k * 0.005))]
        board.receive(protocol.encode(protocol.Heartbeat(), 100 + k, version=2), k * 0.005)
    assert any(isinstance(m, protocol.PulseDone) and m.id == 3 for m in got)
    samples = [m for m in got if isinstance(m, protocol.Samples6)]
    counts = np.concatenate([np.array(m.values) for m in samples]).astype(float)
    assert counts.shape[1] == 9 and not any(type(m) is protocol.Samples for m in got)
    # the sustain's readings give back the commanded accelerations (11-bit counts, 200 m/s^2)
    hold = counts[round(0.15 * 5000) : round(1.05 * 5000)] * plant.full_scale / 1024
    est = plate.estimate(hold, 5000.0, 20.0, (1,))[1]
    _, want = sink.harmonic_phasors()
    phase = np.exp(-1j * 2 * np.pi * 20.0 * round(0.15 * 5000) / 5000)  # the fit starts at 0.15 s
    assert np.linalg.norm(est * phase - want[1]) / np.linalg.norm(want[1]) < 0.03
    # the parts moved towards the sink's centre
    assert np.all(np.hypot(*plant.parts.T) < np.hypot(*parts.T) - 0.01)


def test_limits_on_the_six_axis_board():
    board = BoardEmulator(SimulatedUPM(snr_db=None), plate6=Plate6())
    far = upm.PlateMotion.harmonic(5.0, z=[(1, 6.0, 0.0)])  # 6 mm: beyond the actuators' 3 mm
    channels = [protocol.SetChannel(k, **c) for k, c in enumerate(Plate6().channels(far))]
    replies = exchange(
        board, [protocol.Hello(2), *channels, protocol.SetEnvelope(0.1, 0.5, 0.1), protocol.Pulse(1)]
    )
    assert replies[-1][1] == protocol.Nack(len(channels) + 3, protocol.NackCode.STROKE)
    h23 = protocol.SetChannel(0, 1.0, 20.0, 1.0, 0.0, 0.0, 0.0, 0.5, 0.0)
    assert exchange(board, [h23], first=50)[0][1].code == protocol.NackCode.OUT_OF_LIMITS


@pytest.mark.slow
def test_field_pulses_through_the_emulator_process(tmp_path):
    from upm.control import BoardDevice
    from upm.vision import RemoteCamera

    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps({"parts": [[0.08, 0.0], [0.0, -0.07]]}))

    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "upm.board.emulator",
            "--axes",
            "6",
            "--scene",
            str(scene),
            "--camera-port",
            "0",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        url = proc.stdout.readline().strip()
        camera_url = proc.stdout.readline().strip().split()[-1]
        with Board(url) as board, RemoteCamera(camera_url) as camera:
            assert board.version == 2 and board.six_axis
            before = camera.truth()
            device = BoardDevice(board, wait_rest=False)
            device.execute([upm.Pulse.field(upm.PlateMotion.ppod("Sink"), 0.1, 0.8, 0.1)])
            after = camera.truth()
            assert np.all(np.hypot(*after.T) < np.hypot(*before.T) - 0.01)  # gathered towards the centre
            with pytest.raises(upm.ParameterError, match="six-axis board plays field pulses"):
                device.execute([upm.Pulse.jet((0, 0), (1, 0), 0.03, 0.1, 35.0, 0.1, 0.1, 0.1)])
            with pytest.raises(upm.BoardError, match=r"or 0\.\.5 on a six-axis board"):
                board.set_channel(6, 1.0, 20.0)
        # a version-1-only board: the same host falls back and drives four channels
        proc.kill()
        proc.wait()
        proc = subprocess.Popen(
            [sys.executable, "-m", "upm.board.emulator", "--max-version", "1"],
            stdout=subprocess.PIPE,
            text=True,
        )
        with Board(proc.stdout.readline().strip()) as board:
            assert board.version == 1 and not board.six_axis and board.info.version == 1
            with pytest.raises(upm.BoardError, match="channel 4 does not exist"):
                board.set_channel(4, 1.0, 20.0)
            assert board.samples()[1].shape[1] == 4
    finally:
        proc.kill()
        proc.wait()
