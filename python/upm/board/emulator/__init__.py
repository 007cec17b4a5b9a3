"""A board that speaks protocol v1 and v2 (``docs/protocol.md``) and drives ``upm.plant.SimulatedUPM``.

With ``plate6=`` (``upm emulate --axes 6``) it is a six-axis board (version 2): six actuator
channels drive a :class:`upm.plate6.Plate6`, its three 3-axis accelerometers stream in SAMPLES6,
and the parts (points) follow the plate's motion out of its plane. A host that says version 1
gets a four-channel board of version 1.

``BoardEmulator`` is the board's logic, free of I/O: feed it received bytes and the time, and it
returns the bytes to send (replies, 5 kHz accelerometer samples, PULSE_DONE, watchdog STATUS).
:mod:`upm.board.process` serves it on a pseudo-terminal (printing the path to open) or a TCP
port; ``python -m upm.board.emulator`` and ``upm emulate`` start it in its own process. Faults can be
injected on the outgoing bytes (drop, duplicate, corrupt, delay, stall) for tests.

With ``camera=`` (``--camera-port``) the same process also serves the simulated plate's overhead
camera on a TCP port (read it with :class:`upm.vision.RemoteCamera`): the frames show the parts
where the emulated plate has moved them. Each request is one byte: ``F`` answers ``b"UPMF"``,
height, width, channels (little-endian u32) and the frame's bytes (uint8, row-major); ``P``
answers ``b"UPMP"``, the part count (u32) and their true positions (float64 x, y [m], NaN for a
part that fell off) — the simulation's ground truth, for reports and tests; ``S`` answers
``b"UPMS"`` and the largest plate-corner excursion the emulated plate has made (float64 [m]).
"""

from __future__ import annotations

import math
import random
import sys
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..._errors import ParameterError
from ...plate.plant import Channel, Envelope, Moved, Played, SimulatedUPM
from ...plate.plate6 import Plate6
from .. import protocol as p

__all__ = ["BoardEmulator", "Faults", "Limits"]

SAMPLES_PER_FRAME = 127
SAMPLES6_PER_FRAME = 56  # nine int16 a sample within the 1024-byte payload


@dataclass(frozen=True)
class Limits:
    """What the board accepts (advertised in HELLO)."""

    max_amplitude: float = 200.0
    min_frequency: float = 5.0
    max_frequency: float = 400.0


@dataclass(frozen=True)
class Faults:
    """Faults injected on outgoing frames, each with the given probability (seeded)."""

    drop: float = 0.0
    duplicate: float = 0.0
    corrupt: float = 0.0
    delay: float = 0.0
    seed: int = 0
    stall_after: float | None = None
    """Seconds after the first frame when the board stops talking for ``stall_for`` seconds."""
    stall_for: float = 0.0


class BoardEmulator:
    """The board's state machine (no I/O). Times are seconds on any monotonic clock."""

    def __init__(
        self,
        plant: SimulatedUPM | None = None,
        limits: Limits = Limits(),
        watchdog_ms: int = 250,
        faults: Faults = Faults(),
        plate6: Plate6 | None = None,
        max_version: int = p.VERSION,
    ) -> None:
        self.plant = plant if plant is not None else SimulatedUPM()
        if plate6 is not None and (self.plant.part_radius is not None or self.plant.part_shape is not None):
            raise ParameterError("a six-axis board moves point parts: give the plant part_radius=None")
        if max_version not in p.VERSIONS:
            raise ParameterError(f"max_version must be one of {p.VERSIONS}; got {max_version!r}")
        self.plate6, self.max_version = plate6, max_version
        self.link = 1  # the version agreed in HELLO
        self.motion6: Any = None  # a six-axis pulse's motion, alone and enveloped
        self.limits = limits
        self.watchdog = watchdog_ms / 1000.0
        self.faults = faults
        self._rng = random.Random(faults.seed)
        self.decoder = p.Decoder()
        self.channels = [Channel() for _ in range(6 if plate6 is not None else 4)]
        self.envelope = Envelope()
        self.state = p.State.IDLE
        self.flags = 0
        self.pulses = 0
        self.t0: float | None = None
        self.produced = 0
        self.last_rx: float | None = None
        self.pulse: tuple[int, int, int] | None = None  # (id, first sample, last sample)
        self.played: Played | None = None  # the pulse's plate motion, worked out when it starts
        self.forces: np.ndarray = np.zeros((0, 4))
        self.idle_from = 0  # sample at which the plate was last left to move freely
        self.plant.excursion(self.channels[:4], self.envelope)  # loads the plate model before any command
        # The parts' way under a pulse is worked out in a thread from the pulse's start (colliding
        # disks can take seconds to simulate) while the board keeps answering; PULSE_DONE goes
        # out when the pulse has ended and they have: a real plate's parts take no time to think.
        self.settling: _Settling | None = None
        self._seq = 0
        self._last: tuple[int, list[p.Message]] | None = None

    # -- replies ---------------------------------------------------------------------------
    def _send(self, message: p.Message) -> bytes:
        self._seq = (self._seq + 1) & 0xFFFF
        frame = p.encode(message, self._seq, version=self.link)
        f = self.faults
        if f.drop and self._rng.random() < f.drop:
            return b""
        if f.corrupt and self._rng.random() < f.corrupt:
            k = self._rng.randrange(len(frame) - 1)
            frame = frame[:k] + bytes([frame[k] ^ (1 << self._rng.randrange(8)) or 1]) + frame[k + 1 :]
        if f.duplicate and self._rng.random() < f.duplicate:
            frame = frame + frame
        return frame

    def _status(self) -> p.Status:
        return p.Status(int(self.state), self.flags, self.pulses, self.produced, self.decoder.rejected)

    def _hello(self) -> p.Hello:
        lim = self.limits
        caps = 0b1 | (p.CAP_SIX_AXIS if self.six else 0)
        return p.Hello(self.link, caps, lim.max_amplitude, lim.min_frequency, lim.max_frequency,
                       int(self.plant.sample_rate), round(self.watchdog * 1000))  # fmt: skip

    @property
    def six(self) -> bool:
        """Whether the link runs the six-axis board (a version-2 host on a board with ``plate6``)."""
        return self.plate6 is not None and self.link >= 2

    def _check(self, message: p.Message) -> p.NackCode | None:
        lim = self.limits
        if isinstance(message, p.Hello):
            ok = message.version in p.VERSIONS and message.version <= self.max_version
            return None if ok else p.NackCode.VERSION
        if isinstance(message, p.SetChannel):
            if not 0 <= message.channel <= (5 if self.six else 3):
                return p.NackCode.BAD_CHANNEL
            if self.six and message.h23_amplitude != 0:
                return p.NackCode.OUT_OF_LIMITS  # the six-axis plate plays harmonics 1 and 2
            harmonics = (message.h1_amplitude, message.h2_amplitude, message.h23_amplitude)
            peak = abs(message.amplitude) * sum(abs(h) for h in harmonics)
            values = (message.amplitude, message.frequency, *harmonics)
            if not all(math.isfinite(v) for v in values) or peak > lim.max_amplitude:
                return p.NackCode.OUT_OF_LIMITS
            if not lim.min_frequency <= message.frequency <= lim.max_frequency:
                return p.NackCode.OUT_OF_LIMITS
        if isinstance(message, p.SetEnvelope):
            times = (message.attack, message.sustain, message.decay)
            if not all(math.isfinite(v) and v >= 0 for v in times) or sum(times) <= 0 or sum(times) > 600:
                return p.NackCode.OUT_OF_LIMITS
        if isinstance(message, p.SetWatchdog) and not 1 <= message.milliseconds <= 60000:
            return p.NackCode.OUT_OF_LIMITS
        if isinstance(message, p.Pulse) and self.state == p.State.PULSING:
            return p.NackCode.BAD_STATE
        if isinstance(message, p.Pulse) and self.six:
            return self._check6()
        if isinstance(message, p.Pulse):
            self._ride_out()
            # the pulse worked out from the plate's present state: checked now, played if accepted
            self.forces, self.played = self.plant.pulse_ahead(self.channels[:4], self.envelope)
            if self.plant.reach(self.played) > self.plant.stroke:
                self.played = None
                return p.NackCode.STROKE
        if isinstance(message, (p.Ack, p.Nack, p.Samples, p.Status, p.PulseDone)):
            return p.NackCode.UNKNOWN_TYPE
        return None

    def _check6(self) -> p.NackCode | None:
        """A six-axis PULSE: the channels' motion within every actuator's force and stroke."""
        from ...plate.drive import StrokeError

        assert self.plate6 is not None
        try:
            motion = self.plate6.motion_of_channels(self.channels)
            self.plate6.check(motion)
        except StrokeError:
            return p.NackCode.STROKE
        except ParameterError:
            return p.NackCode.OUT_OF_LIMITS
        e = self.envelope
        self.motion6 = (motion, motion.with_envelope(e.attack, e.sustain, e.decay))
        return None

    def _samples6(self, idx: np.ndarray, env: np.ndarray | None) -> p.Samples6:
        """Three 3-axis accelerometers at samples ``idx`` (the pulse's motion under ``env``, or
        at rest), as the plant's sensors report them. During the ramps the envelope's rate is left
        out of the readings (it moves nothing but the sensors)."""
        assert self.plate6 is not None
        acc = np.zeros((len(idx), 9))
        if env is not None and self.motion6 is not None:
            since = (idx - self.pulse[1]) / self.plant.sample_rate if self.pulse is not None else idx * 0.0
            acc = self.plate6.readings(self.motion6[0], since) * env[:, None]
        counts = self.plant.counts(acc)
        return p.Samples6(int(idx[0]), tuple(tuple(int(v) for v in row) for row in counts))

    def _ride_out(self) -> None:
        """The plate's free motion on its flexures since the last pulse ended (at most 5 s of it):
        between pulses the plate keeps moving and comes home."""
        idle = min(self.produced - self.idle_from, int(5 * self.plant.sample_rate))
        if idle > 0:
            self.plant.plate_state(np.zeros((idle, 4)))
        self.idle_from = self.produced

    def _act(self, message: p.Message) -> list[p.Message]:
        if isinstance(message, p.Hello):
            self.link = message.version
            return [self._hello()]
        if isinstance(message, p.SetChannel):
            m = message
            harmonics = (m.h1_amplitude, m.h1_phase, m.h2_amplitude, m.h2_phase, m.h23_amplitude, m.h23_phase)
            self.channels[m.channel] = Channel(m.amplitude, m.frequency, *harmonics)
        elif isinstance(message, p.SetEnvelope):
            self.envelope = Envelope(message.attack, message.sustain, message.decay)
        elif isinstance(message, p.SetWatchdog):
            self.watchdog = message.milliseconds / 1000.0
        elif isinstance(message, p.Pulse):
            n = round(self.envelope.duration * self.plant.sample_rate)
            self.pulse = (message.id, self.produced, self.produced + n)
            self.state = p.State.PULSING
            if self.played is not None:  # worked out by _check; its time starts with the pulse
                self.settling = _Settling(self.plant, self.played.vel, message.id)
        elif isinstance(message, p.Stop):
            self._end_pulse()
            self.state = p.State.STOPPED
        elif isinstance(message, p.GetStatus):
            return [self._status()]
        return []

    def receive(self, data: bytes, now: float) -> bytes:
        """Handle received bytes; returns the replies' bytes."""
        out = bytearray()
        for seq, message in self.decoder.feed(data):
            self.last_rx = now
            if self.t0 is None:
                self.t0 = now
            if self.state == p.State.WATCHDOG and not isinstance(message, p.Heartbeat):
                self.state = p.State.IDLE
            if isinstance(message, p.Heartbeat):
                continue
            if self._last is not None and self._last[0] == seq:  # a resend: answer, do not act again
                for m in self._last[1]:
                    out += self._send(m)
                continue
            code = self._check(message)
            replies: list[p.Message] = []
            if code is not None:
                if code == p.NackCode.OUT_OF_LIMITS:
                    self.flags |= p.Status.LIMIT_REFUSED
                replies.append(p.Nack(seq, int(code)))
            else:
                extra = self._act(message)
                if not isinstance(message, p.Hello):
                    replies.append(p.Ack(seq))
                replies += extra
            self._last = (seq, replies)
            for m in replies:
                out += self._send(m)
        return bytes(out)

    def _end_pulse(self, background: bool = False) -> None:
        """The pulse is over (played out, or cut short by STOP or the watchdog); ``background``:
        its parts may finish settling after this returns (:meth:`tick` sends PULSE_DONE)."""
        if self.six and self.pulse is not None and self.motion6 is not None and len(self.plant.parts):
            # the parts follow the plate out of its plane, for as much of the pulse as played
            played = (self.produced - self.pulse[1]) / self.plant.sample_rate
            whole = self.motion6[1]
            if played > 0:
                self.plant.play(whole if played >= whole.duration else whole.for_duration(played))
            self.motion6 = None
        if self.pulse is not None and self.played is not None:
            k = self.produced - self.pulse[1]
            if k >= len(self.played.vel):  # played out: as worked out at its start
                self.plant.commit(self.played)
            else:  # cut short: the motors stopped after k samples (the whole pulse's way is dropped)
                if self.settling is not None:
                    self.settling.thread.join()
                    self.settling = None
                self.plant.settle_parts(self.plant.plate_state(self.forces[:k])[1])
        self.pulse = None
        self.played = None
        self.idle_from = self.produced
        if self.settling is not None and not background:
            self.settling.finish(self.plant)
            self.settling = None

    def tick(self, now: float) -> bytes:
        """Produce the samples due by ``now``, PULSE_DONE, and the watchdog."""
        out = bytearray()
        if self.t0 is None:
            return b""
        if (
            self.last_rx is not None
            and now - self.last_rx > self.watchdog
            and self.state != p.State.WATCHDOG
            and self.state != p.State.STOPPED
        ):
            quiet = 1000 * (now - self.last_rx)
            print(f"upm board: watchdog tripped after {quiet:.0f} ms without a word from the host (state "
                  f"{self.state.name})", file=sys.stderr)  # fmt: skip
            self._end_pulse()
            self.state = p.State.WATCHDOG
            self.flags |= p.Status.WATCHDOG_TRIPPED
            out += self._send(self._status())
        fs = self.plant.sample_rate
        due = int((now - self.t0) * fs) - self.produced
        if due > 10 * SAMPLES_PER_FRAME * 4:  # a stall: skip ahead and say so
            self.flags |= p.Status.SAMPLES_DROPPED
            self.produced += due - SAMPLES_PER_FRAME
            due = SAMPLES_PER_FRAME
        while due > 0:
            n = min(due, SAMPLES6_PER_FRAME if self.six else SAMPLES_PER_FRAME)
            idx = self.produced + np.arange(n)
            pulsing = self.state == p.State.PULSING and self.pulse is not None
            if pulsing and self.pulse is not None:
                end = self.pulse[2]
                n = min(n, end - self.produced) if end > self.produced else 0
                idx = idx[:n]
            if self.six and n > 0:
                env = self.envelope((idx - self.pulse[1]) / fs) if pulsing and self.pulse else None
                out += self._send(self._samples6(idx, env))
            elif n > 0:
                if pulsing and self.pulse is not None and self.played is not None:
                    # worked out at the pulse's start (its time starts with it, as the host planned
                    # it: timed from the board's clock, the carrier's phase at the start, and with
                    # it what the pulse does, would depend on when the PULSE command arrived)
                    k = self.produced - self.pulse[1]
                    counts = self.plant.sensor_counts(self.played.acc[k : k + n], self.played.vel[k : k + n])
                else:
                    counts = self.plant.idle(n)
                rows = tuple(tuple(int(v) for v in row) for row in counts)
                out += self._send(p.Samples(self.produced, rows))
            if n > 0:
                self.produced += n
                due -= n
            if self.state == p.State.PULSING and self.pulse is not None and self.produced >= self.pulse[2]:
                pid = self.pulse[0]
                self._end_pulse(background=self.plant.part_radius is not None)
                if self.settling is None:
                    out += self._pulse_done(pid)
        if self.settling is not None and self.pulse is None and not self.settling.thread.is_alive():
            pid = self.settling.pulse
            self.settling.finish(self.plant)
            self.settling = None
            out += self._pulse_done(pid)
        return bytes(out)

    def _pulse_done(self, pid: int) -> bytes:
        """Back to idle, the pulse counted, and its PULSE_DONE."""
        self.state = p.State.IDLE
        self.pulses += 1
        return self._send(p.PulseDone(pid, self.produced))


class _Settling:
    """A pulse's parts worked out in a thread (:meth:`SimulatedUPM.settled`), the plant untouched
    until :meth:`finish` applies them."""

    def __init__(self, plant: SimulatedUPM, velocity: np.ndarray, pulse: int) -> None:
        self.pulse = pulse
        self.moved: Moved | None = None
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, args=(plant, velocity), daemon=True)
        self.thread.start()

    def _run(self, plant: SimulatedUPM, velocity: np.ndarray) -> None:
        try:
            self.moved = plant.settled(velocity)
        except BaseException as error:  # raised again in the board's own thread by finish()
            self.error = error

    def finish(self, plant: SimulatedUPM) -> None:
        self.thread.join()
        if self.error is not None:
            raise self.error
        plant.apply(self.moved)
