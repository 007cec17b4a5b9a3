"""The upm board protocol, versions 1 and 2: pure bytes <-> messages (``docs/protocol.md``).

Version 2 adds a six-actuator plate: SET_CHANNEL channels 4 and 5, and SAMPLES6 (three 3-axis
accelerometers) from a board whose HELLO sets :data:`CAP_SIX_AXIS`. Both sides speak both
versions; the link runs at the version the host's HELLO offers if the board knows it.

A frame is ``version u8 | type u8 | seq u16 | length u16 | payload | crc u16`` (little-endian),
the CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) of everything before it; on the wire each frame
is COBS-encoded and followed by one zero byte. Nothing here does I/O.
"""

from __future__ import annotations

import binascii
import math
import struct
from dataclasses import dataclass, fields
from enum import IntEnum
from typing import Any, ClassVar

import numpy as np

from .._errors import ProtocolError
from .._extras import need

cobs = need("cobs.cobs", "board", "the board protocol (upm.board, upm.control)", "cobs")

__all__ = [
    "CAP_SIX_AXIS",
    "MAX_PAYLOAD",
    "VERSION",
    "VERSIONS",
    "Ack",
    "Decoder",
    "GetStatus",
    "Heartbeat",
    "Hello",
    "Message",
    "Nack",
    "NackCode",
    "ProtocolError",
    "Pulse",
    "PulseDone",
    "Samples",
    "Samples6",
    "SetChannel",
    "SetEnvelope",
    "SetWatchdog",
    "State",
    "Status",
    "Stop",
    "decode_frame",
    "encode",
]

VERSION = 2
"""The highest version this side speaks."""
VERSIONS = (1, 2)
"""Every version this side speaks (a frame of another is dropped)."""
CAP_SIX_AXIS = 0b10
"""HELLO capability (version 2): six actuator channels and SAMPLES6."""
MAX_PAYLOAD = 1024
_HEADER = struct.Struct("<BBHH")


class NackCode(IntEnum):
    """Why the board refused a command."""

    UNKNOWN_TYPE = 1
    BAD_LENGTH = 2
    OUT_OF_LIMITS = 3
    BAD_STATE = 4
    VERSION = 5
    BAD_CHANNEL = 6
    STROKE = 7
    """The pulse would swing a plate corner beyond the board's stroke."""


class State(IntEnum):
    """The board's state in STATUS."""

    IDLE = 0
    PULSING = 1
    STOPPED = 2
    WATCHDOG = 3
    FAULT = 4


_INT_RANGES = {"B": (0, 0xFF), "H": (0, 0xFFFF), "I": (0, 0xFFFFFFFF), "h": (-0x8000, 0x7FFF)}
_FLOAT32_MAX = 3.4028234663852886e38


def _codes(layout: str) -> list[str]:
    """The field codes of a struct layout: ``"<Bff6f"`` -> ``B f f f f f f f f``."""
    out: list[str] = []
    count = ""
    for ch in layout.lstrip("<"):
        if ch.isdigit():
            count += ch
        else:
            out.extend(ch * int(count or 1))
            count = ""
    return out


def _check_field(name: str, value: Any, code: str) -> None:
    if code == "f":
        ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
        if not ok or not math.isfinite(value) or abs(value) > _FLOAT32_MAX:
            raise ProtocolError(f"{name} must be a finite number within float32; got {value!r}")
        return
    low, high = _INT_RANGES[code]
    ok = isinstance(value, (int, np.integer)) and not isinstance(value, bool)
    if not ok or not low <= value <= high:
        raise ProtocolError(f"{name} must be an integer in [{low}, {high}]; got {value!r}")


def _require(ok: bool, message: str) -> None:
    if not ok:
        raise ProtocolError(message)


@dataclass(frozen=True)
class Message:
    """Base of every message; ``TYPE`` is its type byte, ``FORMAT`` its fixed payload layout."""

    TYPE: ClassVar[int]
    FORMAT: ClassVar[str] = "<"

    def payload(self) -> bytes:
        self.check()
        return struct.pack(self.FORMAT, *(getattr(self, f.name) for f in fields(self)))

    def check(self) -> None:
        """`ProtocolError` naming the field unless every field fits its wire type (integers in
        range, floats finite and within float32) and the message's own rules (:meth:`rules`)."""
        for f, code in zip(fields(self), _codes(self.FORMAT), strict=True):
            _check_field(f"{type(self).__name__}.{f.name}", getattr(self, f.name), code)
        self.rules()

    def rules(self) -> None:
        """Checks beyond the wire types (none by default)."""

    @classmethod
    def parse(cls, payload: bytes) -> Message:
        size = struct.calcsize(cls.FORMAT)
        if len(payload) != size:
            raise ProtocolError(f"{cls.__name__} payload must be {size} bytes; got {len(payload)}")
        return cls(*struct.unpack(cls.FORMAT, payload))


@dataclass(frozen=True)
class Hello(Message):
    """Handshake, both ways: the host sends its version (limits zero); the board answers with its
    version, capability flags and limits."""

    TYPE = 0x01
    FORMAT = "<BIfffIH"
    version: int
    capabilities: int = 0
    max_amplitude: float = 0.0
    min_frequency: float = 0.0
    max_frequency: float = 0.0
    sample_rate: int = 0
    watchdog_ms: int = 0


@dataclass(frozen=True)
class SetChannel(Message):
    """One motor channel (0..3 = X1, X2, Y1, Y2; version 2 on a six-axis board: 0..5, the
    actuators of :data:`upm.plate6.PPOD_LIKE`): overall amplitude, base frequency [Hz] and the
    amplitude and phase [rad] of the 1st, 2nd and 2/3 harmonics of ``cos``."""

    TYPE = 0x10
    FORMAT = "<Bff6f"
    channel: int
    amplitude: float
    frequency: float
    h1_amplitude: float = 1.0
    h1_phase: float = 0.0
    h2_amplitude: float = 0.0
    h2_phase: float = 0.0
    h23_amplitude: float = 0.0
    h23_phase: float = 0.0

    def rules(self) -> None:
        _require(
            0 <= self.channel <= 5,
            "SetChannel.channel must be 0..3 (X1, X2, Y1, Y2), or 0..5 on a six-axis board; "
            f"got {self.channel}",
        )
        _require(self.frequency > 0, f"SetChannel.frequency must be > 0 Hz; got {self.frequency!r}")


@dataclass(frozen=True)
class SetEnvelope(Message):
    """Raised-cosine envelope of the next pulses: attack, sustain, decay [s]."""

    TYPE = 0x11
    FORMAT = "<fff"
    attack: float
    sustain: float
    decay: float

    def rules(self) -> None:
        for name in ("attack", "sustain", "decay"):
            value = getattr(self, name)
            _require(value >= 0, f"SetEnvelope.{name} must be >= 0 s; got {value!r}")


@dataclass(frozen=True)
class Pulse(Message):
    """Play one envelope with the current channels; the board answers PULSE_DONE(id) at its end."""

    TYPE = 0x12
    FORMAT = "<I"
    id: int


@dataclass(frozen=True)
class PulseDone(Message):
    """Board -> host: pulse ``id`` ended; ``sample`` is the sample counter at its end."""

    TYPE = 0x13
    FORMAT = "<II"
    id: int
    sample: int


@dataclass(frozen=True)
class Stop(Message):
    """Every motor off now."""

    TYPE = 0x14


@dataclass(frozen=True)
class Heartbeat(Message):
    """Host -> board, at least every watchdog period."""

    TYPE = 0x15


@dataclass(frozen=True)
class GetStatus(Message):
    """Host -> board: ask for STATUS."""

    TYPE = 0x16


@dataclass(frozen=True)
class Status(Message):
    """Board -> host: state, fault flags, and counters (pulses played, samples taken, frames
    rejected for a bad CRC or layout)."""

    TYPE = 0x17
    FORMAT = "<BHIII"
    state: int
    faults: int
    pulses: int
    samples: int
    rejected: int

    WATCHDOG_TRIPPED: ClassVar[int] = 1
    LIMIT_REFUSED: ClassVar[int] = 2
    SAMPLES_DROPPED: ClassVar[int] = 4


@dataclass(frozen=True)
class SetWatchdog(Message):
    """Host -> board: the watchdog period [ms] (1..60000)."""

    TYPE = 0x18
    FORMAT = "<H"
    milliseconds: int

    def rules(self) -> None:
        _require(
            self.milliseconds >= 1, f"SetWatchdog.milliseconds must be 1..60000; got {self.milliseconds}"
        )
        _require(
            self.milliseconds <= 60000, f"SetWatchdog.milliseconds must be 1..60000; got {self.milliseconds}"
        )


@dataclass(frozen=True)
class Samples(Message):
    """Board -> host: ``count`` samples of the four accelerometer channels (a1x, a1y, a2x, a2y),
    signed 11-bit values in int16, starting at sample ``first`` (so gaps are detectable)."""

    TYPE = 0x20
    WIDTH: ClassVar[int] = 4
    first: int
    values: tuple[tuple[int, ...], ...]

    def check(self) -> None:
        _check_field("Samples.first", self.first, "I")
        rows = self.values
        _require(
            isinstance(rows, (tuple, list)) and len(rows) <= 0xFFFF,
            f"Samples.values must be a sequence of at most 65535 rows; got {type(rows).__name__}",
        )
        for k, row in enumerate(rows):
            _require(
                isinstance(row, (tuple, list)) and len(row) == self.WIDTH,
                f"{type(self).__name__}.values[{k}] must be {self.WIDTH} integers; got {row!r}",
            )
            for v in row:
                _check_field(f"{type(self).__name__}.values[{k}]", v, "h")

    def payload(self) -> bytes:
        self.check()
        flat = [v for row in self.values for v in row]
        return struct.pack(f"<IH{len(flat)}h", self.first, len(self.values), *flat)

    @classmethod
    def parse(cls, payload: bytes) -> Message:
        if len(payload) < 6:
            raise ProtocolError(f"Samples payload must be at least 6 bytes; got {len(payload)}")
        first, count = struct.unpack_from("<IH", payload)
        w = cls.WIDTH
        if len(payload) != 6 + 2 * w * count:
            raise ProtocolError(
                f"{cls.__name__} payload for {count} samples must be {6 + 2 * w * count} bytes; "
                f"got {len(payload)}"
            )
        flat = struct.unpack_from(f"<{w * count}h", payload, 6)
        return cls(first, tuple(tuple(flat[w * i : w * i + w]) for i in range(count)))


@dataclass(frozen=True)
class Samples6(Samples):
    """Board -> host (version 2, six-axis board): ``count`` samples of three 3-axis accelerometers
    (a1x, a1y, a1z, a2x, ..., a3z), as :class:`Samples` otherwise."""

    TYPE = 0x21
    WIDTH: ClassVar[int] = 9


@dataclass(frozen=True)
class Ack(Message):
    """Board -> host: command ``seq`` accepted."""

    TYPE = 0x30
    FORMAT = "<H"
    seq: int


@dataclass(frozen=True)
class Nack(Message):
    """Board -> host: command ``seq`` refused, with a :class:`NackCode`."""

    TYPE = 0x31
    FORMAT = "<HB"
    seq: int
    code: int


_TYPES: dict[int, type[Message]] = {
    cls.TYPE: cls
    for cls in (
        Hello, SetChannel, SetEnvelope, Pulse, PulseDone, Stop, Heartbeat, GetStatus, Status,
        SetWatchdog, Samples, Samples6, Ack, Nack,
    )
}  # fmt: skip


def encode(message: Message, seq: int, version: int = 1) -> bytes:
    """The wire bytes of ``message`` with sequence number ``seq`` in a frame of protocol
    ``version`` (1 by default: every board reads it; a link that agreed on 2 frames in 2):
    COBS(frame) + b"\\x00"."""
    if version not in VERSIONS:
        raise ProtocolError(f"version must be one of {VERSIONS}; got {version!r}")
    if not isinstance(message, Message):
        raise ProtocolError(f"message must be a protocol Message; got {type(message).__name__}")
    _check_field("seq", seq, "H")
    payload = message.payload()
    if len(payload) > MAX_PAYLOAD:
        raise ProtocolError(f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD}")
    body = _HEADER.pack(version, message.TYPE, seq, len(payload)) + payload
    crc = binascii.crc_hqx(body, 0xFFFF)
    return bytes(cobs.encode(body + struct.pack("<H", crc))) + b"\x00"


def decode_frame(frame: bytes) -> tuple[int, Message]:
    """``(seq, message)`` of one COBS-encoded frame without its zero delimiter."""
    if not isinstance(frame, (bytes, bytearray, memoryview)):
        raise ProtocolError(f"frame must be bytes; got {type(frame).__name__}")
    try:
        body = cobs.decode(frame)
    except cobs.DecodeError as error:
        raise ProtocolError(f"bad COBS encoding: {error}") from error
    if len(body) < _HEADER.size + 2:
        raise ProtocolError(f"frame of {len(body)} bytes is shorter than header and CRC (8)")
    (crc,) = struct.unpack_from("<H", body, len(body) - 2)
    if binascii.crc_hqx(body[:-2], 0xFFFF) != crc:
        raise ProtocolError("CRC mismatch")
    version, kind, seq, length = _HEADER.unpack_from(body)
    if version not in VERSIONS:
        raise ProtocolError(f"protocol version {version}; this side speaks {VERSIONS}")
    if length != len(body) - _HEADER.size - 2:
        raise ProtocolError(f"length field {length} disagrees with the frame ({len(body) - 8} payload bytes)")
    cls = _TYPES.get(kind)
    if cls is None:
        raise ProtocolError(f"unknown message type 0x{kind:02x}")
    return seq, cls.parse(body[_HEADER.size : -2])


class Decoder:
    """Streaming decoder: feed it bytes as they arrive; it returns the complete valid messages and
    counts the frames it had to drop (``rejected``) with the last reason (``last_error``). Garbage
    never raises: the next zero byte resynchronises the stream."""

    def __init__(self, max_frame: int = 2 * MAX_PAYLOAD) -> None:
        self._buffer = bytearray()
        self._max = max_frame
        self.rejected = 0
        self.last_error: str | None = None

    def feed(self, data: bytes) -> list[tuple[int, Message]]:
        out: list[tuple[int, Message]] = []
        self._buffer.extend(data)
        while True:
            end = self._buffer.find(0)
            if end < 0:
                if len(self._buffer) > self._max:  # a lost delimiter: drop and wait for the next
                    self._buffer.clear()
                    self._reject("frame longer than the maximum without a delimiter")
                return out
            frame = bytes(self._buffer[:end])
            del self._buffer[: end + 1]
            if not frame:
                continue
            try:
                out.append(decode_frame(frame))
            except ProtocolError as error:
                self._reject(str(error))

    def _reject(self, reason: str) -> None:
        self.rejected += 1
        self.last_error = reason
