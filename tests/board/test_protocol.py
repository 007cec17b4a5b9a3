"""Board protocol v1 (docs/protocol.md): golden frames from an independent reference encoder,
round trips, fault injection and a decoder fuzz."""

import math
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import upm
from upm.board import protocol as p


def crc16_ccitt_false(data: bytes) -> int:
    """Bitwise reference: poly 0x1021, init 0xFFFF, no reflection."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else crc << 1
            crc &= 0xFFFF
    return crc


def cobs_reference(data: bytes) -> bytes:
    """Textbook COBS encoder (no library)."""
    out, block = bytearray(), bytearray()
    for byte in data:
        if byte == 0:
            out += bytes([len(block) + 1]) + block
            block.clear()
        else:
            block.append(byte)
            if len(block) == 254:
                out += b"\xff" + block
                block.clear()
    out += bytes([len(block) + 1]) + block
    return bytes(out)


def reference_frame(kind: int, seq: int, payload: bytes) -> bytes:
    body = struct.pack("<BBHH", 1, kind, seq, len(payload)) + payload
    return cobs_reference(body + struct.pack("<H", crc16_ccitt_false(body))) + b"\x00"


def test_crc_check_value():
    assert crc16_ccitt_false(b"123456789") == 0x29B1


GOLDEN = [
    (p.Hello(1, 0x3, 100.0, 5.0, 400.0, 5000, 250), 0x01,
     struct.pack("<BIfffIH", 1, 3, 100.0, 5.0, 400.0, 5000, 250)),
    (p.SetChannel(2, 0.5, 35.0, 1.0, 0.0, 0.5, 1.5, 0.0, 0.0), 0x10,
     struct.pack("<Bff6f", 2, 0.5, 35.0, 1.0, 0.0, 0.5, 1.5, 0.0, 0.0)),
    (p.SetEnvelope(0.0625, 0.25, 0.0625), 0x11, struct.pack("<fff", 0.0625, 0.25, 0.0625)),
    (p.Pulse(42), 0x12, struct.pack("<I", 42)),
    (p.PulseDone(42, 123456), 0x13, struct.pack("<II", 42, 123456)),
    (p.Stop(), 0x14, b""),
    (p.Heartbeat(), 0x15, b""),
    (p.GetStatus(), 0x16, b""),
    (p.Status(1, 0x5, 3, 5000, 2), 0x17, struct.pack("<BHIII", 1, 5, 3, 5000, 2)),
    (p.SetWatchdog(250), 0x18, struct.pack("<H", 250)),
    (p.Samples(7, ((1, -2, 1023, -1024), (0, 0, 5, 6))), 0x20,
     struct.pack("<IH8h", 7, 2, 1, -2, 1023, -1024, 0, 0, 5, 6)),
    (p.Ack(9), 0x30, struct.pack("<H", 9)),
    (p.Nack(9, p.NackCode.OUT_OF_LIMITS), 0x31, struct.pack("<HB", 9, 3)),
]  # fmt: skip


@pytest.mark.parametrize(("message", "kind", "payload"), GOLDEN, ids=lambda v: type(v).__name__)
def test_golden_frames(message, kind, payload):
    wire = p.encode(message, seq=0x1234)
    assert wire == reference_frame(kind, 0x1234, payload)
    assert wire.count(0) == 1 and wire.endswith(b"\x00")
    assert p.decode_frame(wire[:-1]) == (0x1234, message)


def test_documented_example_frame():
    # docs/protocol.md, "Example": HELLO from the host, seq 7.
    assert p.encode(p.Hello(1), 7).hex(" ") == (
        "04 01 01 07 02 17 02 01 01 01 01 01 01 01 01 01 01 01 01 01 01 01 01 01 01 01 01 01 01 03 c4 e3 00"
    )


floats = st.floats(width=32, allow_nan=False, allow_infinity=False)
u32 = st.integers(0, 2**32 - 1)
positive = st.floats(min_value=2.0**-10, max_value=2.0**20, width=32)
durations = st.floats(min_value=0.0, max_value=2.0**20, width=32)
messages = st.one_of(
    st.builds(p.Hello, st.integers(0, 255), u32, floats, floats, floats, u32, st.integers(0, 65535)),
    st.builds(
        p.SetChannel, st.integers(0, 3), floats, positive, floats, floats, floats, floats, floats, floats
    ),
    st.builds(p.SetEnvelope, durations, durations, durations),
    st.builds(p.Pulse, u32),
    st.builds(p.PulseDone, u32, u32),
    st.builds(p.Status, st.integers(0, 255), st.integers(0, 65535), u32, u32, u32),
    st.builds(p.Samples, u32, st.lists(st.tuples(*[st.integers(-1024, 1023)] * 4), max_size=100).map(tuple)),
    st.builds(p.Ack, st.integers(0, 65535)),
    st.builds(p.Nack, st.integers(0, 65535), st.integers(0, 255)),
    st.sampled_from([p.Stop(), p.Heartbeat(), p.GetStatus()]),
)


@settings(max_examples=300, deadline=None)
@given(messages, st.integers(0, 65535))
def test_round_trip(message, seq):
    assert p.decode_frame(p.encode(message, seq)[:-1]) == (seq, message)


@settings(max_examples=200, deadline=None)
@given(st.lists(messages, min_size=1, max_size=8), st.randoms(use_true_random=False))
def test_faults_never_pass_a_corrupted_message_and_the_link_recovers(batch, rng):
    frames = [p.encode(m, i) for i, m in enumerate(batch)]
    stream = bytearray()
    damaged = set()
    for i, f in enumerate(frames):
        f = bytearray(f)
        fault = rng.random()
        if fault < 0.15:  # flip a bit (not the delimiter)
            k = rng.randrange(len(f) - 1)
            f[k] ^= 1 << rng.randrange(8)
            damaged.add(i)
        elif fault < 0.25:  # drop a byte
            del f[rng.randrange(len(f) - 1)]
            damaged.add(i)
        elif fault < 0.35:  # duplicate a byte
            k = rng.randrange(len(f) - 1)
            f.insert(k, f[k])
            damaged.add(i)
        stream += f
    decoder = p.Decoder()
    got = []
    while stream:  # random chunking
        n = rng.randrange(1, 40)
        got += decoder.feed(bytes(stream[:n]))
        del stream[:n]
    originals = {i: m for i, m in enumerate(batch)}
    for seq, message in got:
        assert originals[seq] == message  # nothing corrupted gets through
    intact = {i for i in range(len(batch)) if i not in damaged}
    assert intact <= {seq for seq, _ in got}  # every undamaged frame arrives
    # After any damage, a clean frame is decoded (the link recovers).
    assert decoder.feed(p.encode(p.Heartbeat(), 99)) == [(99, p.Heartbeat())]


@settings(max_examples=500, deadline=None)
@given(st.binary(max_size=300))
def test_decoder_fuzz(data):
    decoder = p.Decoder()
    decoder.feed(data)  # never raises
    decoder.feed(b"\x00")
    try:
        p.decode_frame(data.replace(b"\x00", b"\x01"))
    except p.ProtocolError:
        pass


def test_errors_are_board_errors():
    assert issubclass(p.ProtocolError, upm.BoardError) and issubclass(upm.BoardError, upm.UpmError)
    with pytest.raises(p.ProtocolError, match="CRC mismatch"):
        frame = bytearray(p.encode(p.Pulse(1), 1)[:-1])
        frame[3] ^= 0x10
        p.decode_frame(bytes(frame))
    body = struct.pack("<BBHH", 3, 0x14, 0, 0)
    with pytest.raises(p.ProtocolError, match="version 3"):
        p.decode_frame(cobs_reference(body + struct.pack("<H", crc16_ccitt_false(body))))
    with pytest.raises(p.ProtocolError, match="version must be one of"):
        p.encode(p.Stop(), 0, version=3)
    with pytest.raises(p.ProtocolError, match="payload"):
        p.encode(p.Samples(0, ((0, 0, 0, 0),) * 200), 0)
    decoder = p.Decoder()
    assert decoder.feed(b"\x01" * 5000) == [] and decoder.rejected == 1


@pytest.mark.parametrize(
    ("message", "seq", "match"),
    [
        (p.SetChannel(7, 1.0, 35.0), 1, r"channel must be 0..3 .* or 0..5 on a six-axis board"),
        (p.SetChannel(0, math.nan, 35.0), 1, r"SetChannel.amplitude must be a finite number"),
        (p.SetChannel(0, 1.0, -35.0), 1, r"SetChannel.frequency must be > 0"),
        (p.SetChannel(0, 1e39, 35.0), 1, r"within float32"),
        (p.SetEnvelope(0.02, -0.1, 0.02), 1, r"SetEnvelope.sustain must be >= 0"),
        (p.SetWatchdog(70000), 1, r"SetWatchdog.milliseconds must be an integer in \[0, 65535\]"),
        (p.SetWatchdog(0), 1, r"SetWatchdog.milliseconds must be 1..60000"),
        (
            p.Samples(0, ((40000, 0, 0, 0),)),
            1,
            r"Samples.values\[0\] must be an integer in \[-32768, 32767\]",
        ),
        (p.Samples(0, ((1, 2, 3),)), 1, r"must be 4 integers"),
        (p.Pulse(1.5), 1, r"Pulse.id must be an integer"),
        (p.Stop(), 1.5, r"seq must be an integer in \[0, 65535\]"),
        (p.Stop(), 70000, r"seq must be an integer"),
    ],
)
def test_encode_refuses_what_the_wire_cannot_carry(message, seq, match):
    # Before: struct.error, or a frame with channel 7, NaN or a negative frequency on the wire.
    with pytest.raises(p.ProtocolError, match=match):
        p.encode(message, seq)


def test_version_2_frames_and_samples6_against_the_independent_encoder():
    # SAMPLES6 (0x21): first u32, count u16, then 9 int16 per sample, in a version-2 frame
    rows = ((1, -2, 3, -4, 5, -6, 7, -8, 1023), (-1024, 0, 0, 0, 0, 0, 0, 0, 9))
    payload = struct.pack("<IH", 77, 2) + struct.pack("<18h", *[v for r in rows for v in r])
    body = struct.pack("<BBHH", 2, 0x21, 513, len(payload)) + payload
    want = cobs_reference(body + struct.pack("<H", crc16_ccitt_false(body))) + b"\x00"
    assert p.encode(p.Samples6(77, rows), 513, version=2) == want
    assert p.decode_frame(want[:-1]) == (513, p.Samples6(77, rows))
    # a version-2 SET_CHANNEL for actuator 5; version-1 frames still decode
    seq, m = p.decode_frame(p.encode(p.SetChannel(5, 1.0, 20.0), 9, version=2)[:-1])
    assert seq == 9 and m == p.SetChannel(5, 1.0, 20.0)
    # a host's first HELLO offers version 2 in a version-1 frame, which every board reads
    hello = struct.pack("<BIfffIH", 2, 0, 0, 0, 0, 0, 0)
    body = struct.pack("<BBHH", 1, 0x01, 7, len(hello)) + hello
    assert (
        p.encode(p.Hello(2), 7) == cobs_reference(body + struct.pack("<H", crc16_ccitt_false(body))) + b"\x00"
    )
    with pytest.raises(p.ProtocolError, match="must be 9 integers"):
        p.encode(p.Samples6(0, ((0, 0, 0, 0),)), 0)
