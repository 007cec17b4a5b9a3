"""``Board``: the host driver for protocol v1 and v2 over any pyserial URL (``docs/protocol.md``).

The handshake offers version 2 and falls back to 1 when the board refuses it (NACK VERSION);
on a six-axis board (version 2, :data:`~upm.board.protocol.CAP_SIX_AXIS`) channels 0..5 drive the
six actuators and :meth:`Board.samples` returns nine accelerometer channels.

A reader thread decodes everything the board sends (replies, samples, pulse completions, status)
and a heartbeat thread keeps the board's watchdog fed. Commands carry sequence numbers and are
resent on timeout; NACKs raise ``CommandRefused``. Used as a context manager the board always gets
STOP on the way out, whether the block ends normally, by an exception or by Ctrl-C.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from collections.abc import Sequence
from types import TracebackType
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .._arrays import integer, real
from .._errors import BoardError, BoardTimeout, CommandRefused, ParameterError, PulseCut, VersionMismatch
from .._extras import need
from . import protocol as p

if TYPE_CHECKING:
    from ..plate.pulses import Channel

__all__ = ["Board", "BoardTimeout", "CommandRefused", "PulseCut", "VersionMismatch"]


class Board:
    """A connection to a board (or the emulator).

    Parameters
    ----------
    url : str
        Any pyserial URL: ``/dev/ttyACM0``, ``/dev/pts/3``, ``socket://127.0.0.1:5555``, ``loop://``.
    timeout : float
        Seconds to wait for each answer before resending.
    retries : int
        Resends before `BoardTimeout`.
    heartbeat : float
        Seconds between heartbeats (keep it well under the board's watchdog).
    """

    def __init__(self, url: str, *, timeout: float = 0.25, retries: int = 3, heartbeat: float = 0.05) -> None:
        if not isinstance(url, str) or not url:
            raise ParameterError(f"url must be a pyserial URL or device path (str); got {url!r}")
        timeout = real("timeout", timeout, low=0.0, low_open=True, high=60.0)
        retries = integer("retries", retries, low=0, high=1000)
        heartbeat = real("heartbeat", heartbeat, low=1e-3, high=10.0)
        serial = need("serial", "board", "upm.board.Board", "pyserial")
        try:
            self._port = serial.serial_for_url(url, baudrate=921600, timeout=0.005)
        except (serial.SerialException, ValueError) as error:
            raise BoardError(f"cannot open {url!r}: {error}") from error
        self.url, self.timeout, self.retries, self.heartbeat = url, timeout, retries, heartbeat
        self._decoder = p.Decoder()
        self._lock = threading.Lock()
        self._changed = threading.Condition()
        self._replies: dict[int, p.Message] = {}
        self._done: dict[int, int] = {}
        self._status: p.Status | None = None
        self._hello: p.Hello | None = None
        self._chunks: list[NDArray[np.int16]] = []
        self._next_sample: int | None = None
        self._stopping = False  # stop() was called: no pulse() plays until clear_stop()
        self.first_sample: int | None = None
        self.gaps = 0
        self.info: p.Hello | None = None
        self.version = 1
        """The protocol version agreed with the board in HELLO."""
        self._seq = 0
        self._open = True
        self._error: BaseException | None = None
        self._reader = threading.Thread(target=self._read_loop, name="upm-board-reader", daemon=True)
        self._reader.start()
        self._beater = threading.Thread(target=self._beat_loop, name="upm-board-heartbeat", daemon=True)
        try:
            self.info = self.hello()
            dog = self.info.watchdog_ms / 1000.0
            if dog > 0 and heartbeat > dog / 2:
                raise ParameterError(
                    f"heartbeat must be at most half the board's watchdog ({1000 * dog:g} ms), or the board "
                    f"stops between beats; got {heartbeat:g} s"
                )
        except BaseException:
            self.close(stop=False)
            raise
        self._beater.start()

    # -- threads ---------------------------------------------------------------------------
    def _read_loop(self) -> None:
        while self._open:
            try:
                # what has arrived, or wait (up to the port's 5 ms timeout) for the first byte:
                # read(n) would wait the whole timeout for n bytes, and add it to every reply
                data = self._port.read(self._port.in_waiting or 1)
            except Exception as error:  # the port went away
                self._error = error
                with self._changed:
                    self._changed.notify_all()
                return
            if not data:
                continue
            for _, message in self._decoder.feed(data):
                self._dispatch(message)

    def _dispatch(self, message: p.Message) -> None:
        with self._changed:
            if isinstance(message, (p.Ack, p.Nack)):
                self._replies[message.seq] = message
            elif isinstance(message, p.Samples):
                if self._next_sample is not None and message.first != self._next_sample:
                    self.gaps += 1
                if self.first_sample is None:
                    self.first_sample = message.first
                self._next_sample = message.first + len(message.values)
                self._chunks.append(np.array(message.values, dtype=np.int16).reshape(-1, message.WIDTH))
            elif isinstance(message, p.PulseDone):
                self._done[message.id] = message.sample
            elif isinstance(message, p.Status):
                self._status = message
            elif isinstance(message, p.Hello):
                self._hello = message
            self._changed.notify_all()

    def _beat_loop(self) -> None:
        while self._open:
            time.sleep(self.heartbeat)
            if self._open:
                try:
                    self._write(p.Heartbeat())
                except BoardError:
                    return

    # -- sending ---------------------------------------------------------------------------
    def _write(self, message: p.Message, seq: int | None = None) -> int:
        with self._lock:
            if seq is None:
                self._seq = (self._seq + 1) & 0xFFFF
                seq = self._seq
            # a message the wire cannot carry: ProtocolError, unsent; HELLO always in version 1
            version = 1 if isinstance(message, p.Hello) else self.version
            frame = p.encode(message, seq, version=version)
            try:
                self._port.write(frame)
            except Exception as error:
                raise BoardError(f"writing to {self.url!r} failed: {error}") from error
        return seq

    def _wait(self, ready: Any, what: str) -> Any:
        deadline = time.monotonic() + self.timeout
        with self._changed:
            while True:
                value = ready()
                if value is not None:
                    return value
                if self._error is not None:
                    raise BoardError(f"the link to {self.url!r} failed: {self._error}")
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._changed.wait(left)

    def _command(self, message: p.Message) -> None:
        self._acknowledged(message, self._write(message))

    def _commands(self, messages: Sequence[p.Message]) -> None:
        """Send every message, then wait for each one's ACK (resending as :meth:`_command` does):
        one round trip for all. Only for commands the board may act on twice to the same effect
        (it recognises a resend of its last command only)."""
        for message, seq in [(m, self._write(m)) for m in messages]:
            self._acknowledged(message, seq)

    def _acknowledged(self, message: p.Message, seq: int) -> None:
        for attempt in range(self.retries + 1):
            reply = self._wait(lambda: self._replies.pop(seq, None), type(message).__name__)
            if isinstance(reply, p.Ack):
                return
            if isinstance(reply, p.Nack):
                known = reply.code in p.NackCode._value2member_map_
                name = p.NackCode(reply.code).name if known else f"code {reply.code}"
                raise CommandRefused(f"the board refused {message}: {name}", reply.code)
            if attempt < self.retries:
                self._write(message, seq)  # same seq: the board answers a resend without acting twice
        raise BoardTimeout(
            f"no answer to {type(message).__name__} from {self.url!r} after {self.retries} resends"
        )

    # -- commands --------------------------------------------------------------------------
    def hello(self) -> p.Hello:
        """Handshake; returns the board's version, capabilities and limits. Offers the highest
        version this host speaks, then the next lower one each time the board answers NACK VERSION."""
        offers = sorted(p.VERSIONS, reverse=True)
        while offers:
            offer = offers[0]
            self._hello = None
            for _ in range(self.retries + 1):
                seq = self._write(p.Hello(offer))
                reply = self._wait(lambda seq=seq: self._hello or self._replies.pop(seq, None), "HELLO")
                if isinstance(reply, p.Nack) and reply.code == p.NackCode.VERSION:
                    break
                if isinstance(reply, p.Hello):
                    if reply.sample_rate == 0:
                        raise BoardError(
                            f"{self.url!r} answered HELLO with a host's HELLO: "
                            "an echo (loopback), not a board"
                        )
                    if reply.version not in p.VERSIONS:
                        raise VersionMismatch(
                            f"the board speaks protocol {reply.version}; this host {p.VERSIONS}"
                        )
                    self.version = int(reply.version)
                    return reply
            else:
                raise BoardTimeout(f"no HELLO from {self.url!r}: is a board (or `upm emulate`) there?")
            offers.pop(0)
        raise VersionMismatch(f"the board refused every protocol version this host speaks {p.VERSIONS}")

    @property
    def six_axis(self) -> bool:
        """Whether the board drives a six-actuator plate (version 2, six channels, SAMPLES6)."""
        return self.info is not None and self.version >= 2 and bool(self.info.capabilities & p.CAP_SIX_AXIS)

    def set_channel(
        self,
        channel: int,
        amplitude: float,
        frequency: float,
        *,
        h1: tuple[float, float] = (1.0, 0.0),
        h2: tuple[float, float] = (1.0, math.pi / 2),
        h23: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        """Motor ``channel`` (0..3 = X1, X2, Y1, Y2; 0..5 the actuators of a six-axis board):
        force ``amplitude [h1 cos(wt + p1) + h2 cos(2wt + p2) + h23 cos(2wt/3 + p23)]``; default
        the thesis's ``cos wt - sin 2wt`` (5.9). Checked against the board's limits before sending."""
        self._command(self._channel(channel, amplitude, frequency, h1, h2, h23))

    def set_channels(
        self, channels: Sequence[Channel], envelope: tuple[float, float, float] | None = None
    ) -> None:
        """Channels ``0..len(channels)-1`` (:class:`upm.plate.pulses.Channel`, as a pulse's
        ``channels()`` gives them) and, if given, the envelope ``(attack, sustain, decay)`` [s]:
        each checked as :meth:`set_channel` and :meth:`set_envelope` check it, all checked before
        any is sent, then sent together and acknowledged in one round trip."""
        messages: list[p.Message] = [
            self._channel(
                k,
                c.amplitude,
                c.frequency,
                (c.h1_amplitude, c.h1_phase),
                (c.h2_amplitude, c.h2_phase),
                (c.h23_amplitude, c.h23_phase),
            )
            for k, c in enumerate(channels)
        ]
        if envelope is not None:
            attack, sustain, decay = envelope
            messages.append(p.SetEnvelope(attack, sustain, decay))
            messages[-1].check()  # ProtocolError before any is sent
        self._commands(messages)

    def _channel(
        self,
        channel: int,
        amplitude: float,
        frequency: float,
        h1: tuple[float, float],
        h2: tuple[float, float],
        h23: tuple[float, float],
    ) -> p.SetChannel:
        """The SET_CHANNEL message, checked against the protocol and the board's limits."""
        info = self.info
        message = p.SetChannel(channel, amplitude, frequency, *h1, *h2, *h23)
        message.check()  # types, finiteness, channel 0..5, frequency > 0 (ProtocolError)
        if channel > (5 if self.six_axis else 3):
            raise BoardError(
                f"channel {channel} does not exist on this board (0..{5 if self.six_axis else 3})"
            )
        peak = abs(amplitude) * (abs(h1[0]) + abs(h2[0]) + abs(h23[0]))
        if info is not None and not peak <= info.max_amplitude:
            raise BoardError(f"amplitude peak {peak:g} exceeds the board's limit {info.max_amplitude:g}")
        if info is not None and not info.min_frequency <= frequency <= info.max_frequency:
            raise BoardError(
                f"frequency must be in [{info.min_frequency:g}, {info.max_frequency:g}] Hz; got {frequency:g}"
            )
        return message

    def set_motors(self, amplitudes: Any, frequency: float) -> None:
        """All four channels at once with the default waveform (5.9)."""
        for k, a in enumerate(np.asarray(amplitudes, dtype=np.float64).reshape(4)):
            self.set_channel(k, float(a), frequency)

    def set_envelope(self, attack: float, sustain: float, decay: float) -> None:
        """Raised-cosine envelope of the next pulses [s]; each finite and >= 0, checked before sending."""
        self._command(p.SetEnvelope(attack, sustain, decay))  # encode checks it before sending

    def set_watchdog(self, milliseconds: int) -> None:
        """The board's watchdog period [ms], 1..60000 and at least twice the heartbeat, checked
        before sending: the motors stop when the board hears nothing from this host for that long."""
        message = p.SetWatchdog(milliseconds)
        message.check()  # ProtocolError: an integer 1..60000
        ms = int(milliseconds)
        if self.heartbeat > ms / 2000.0:
            raise ParameterError(
                f"milliseconds must be at least twice the heartbeat ({2000 * self.heartbeat:g} ms), or "
                f"the board stops between beats; got {ms}"
            )
        self._command(message)
        if self.info is not None:
            self.info = dataclasses.replace(self.info, watchdog_ms=ms)

    def pulse(self, pulse_id: int = 0, *, wait: bool = True, timeout: float | None = None) -> int | None:
        """Play one envelope; with ``wait``, block until it ends and return the sample counter at
        its end (from PULSE_DONE, or from STATUS if that frame was lost)."""
        self._done.pop(pulse_id, None)
        first = self.status() if wait else None
        before = first.pulses if first is not None else 0
        tripped = first is not None and bool(first.faults & p.Status.WATCHDOG_TRIPPED)
        if self._stopping:
            raise BoardError(
                f"pulse {pulse_id} not played: the board was stopped (Board.stop); clear_stop() first"
            )
        self._command(p.Pulse(pulse_id))
        if first is None:  # not waiting
            return None
        deadline = time.monotonic() + (timeout if timeout is not None else 600.0)
        last = first
        while time.monotonic() < deadline:
            with self._changed:
                self._changed.wait_for(
                    lambda: pulse_id in self._done or self._error is not None or self._stopping, timeout=0.5
                )
                if pulse_id in self._done:
                    return self._done.pop(pulse_id)
                if self._stopping:
                    raise BoardError(f"pulse {pulse_id} was cut short: STOP")
            status = self.status()  # PULSE_DONE may have been lost on the wire
            if status.state != p.State.PULSING and status.pulses > before:
                return int(status.samples)
            if status.state not in (p.State.PULSING, p.State.IDLE):
                raise BoardError(f"pulse {pulse_id} was cut short: board state {p.State(status.state).name}")
            if status.state == p.State.IDLE and status.pulses == before:
                # accepted, then stopped before its end: by the watchdog (which reads as IDLE once
                # the board hears from the host again) or a STOP from elsewhere
                why = (
                    f"the board's watchdog tripped (no word from this host for "
                    f"{self.info.watchdog_ms if self.info else '?'} ms)"
                    if status.faults & p.Status.WATCHDOG_TRIPPED and not tripped
                    else "the board stopped it (its watchdog, or a STOP)"
                )
                raise PulseCut(f"pulse {pulse_id} was cut short: {why}")
            last = status
        raise BoardTimeout(
            f"pulse {pulse_id} did not finish in time (the board's last status: state "
            f"{p.State(last.state).name}, {last.pulses} pulses done, {before} before this one, faults "
            f"{last.faults:#x})"
        )

    def stop(self) -> None:
        """Every motor off now. A :meth:`pulse` waiting in another thread ends at once, and none
        plays (``BoardError``) until :meth:`clear_stop`: a pulse another thread was about to
        start does not slip in after the STOP."""
        with self._changed:
            self._stopping = True
            self._changed.notify_all()
        self._command(p.Stop())

    def clear_stop(self) -> None:
        """Let :meth:`pulse` play again after :meth:`stop`."""
        self._stopping = False

    def status(self) -> p.Status:
        """The board's state, fault flags and counters."""
        for _ in range(self.retries + 1):
            self._status = None
            self._command(p.GetStatus())
            status = self._wait(lambda: self._status, "STATUS")
            if status is not None:
                return status  # type: ignore[no-any-return]
        raise BoardTimeout(f"no STATUS from {self.url!r} after {self.retries} requests")

    def samples(self) -> tuple[int | None, NDArray[np.int16]]:
        """Everything received since the last call: ``(index of the first sample, (T, 4) counts)``
        (``(T, 9)`` from a six-axis board: three 3-axis accelerometers)."""
        with self._changed:
            chunks, self._chunks = self._chunks, []
            first, self.first_sample = self.first_sample, None
        if not chunks:
            return first, np.zeros((0, 9 if self.six_axis else 4), dtype=np.int16)
        return first, np.concatenate(chunks)

    # -- lifetime --------------------------------------------------------------------------
    def close(self, stop: bool = True) -> None:
        """Send STOP (best effort), then close the link."""
        if stop and self._open:
            try:
                self._write(p.Stop())
            except BoardError:
                pass
        self._open = False
        try:
            self._port.close()
        except Exception:  # pragma: no cover - closing a dead port
            pass

    def __enter__(self) -> Board:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None, traceback: TracebackType | None
    ) -> None:
        self.close(stop=True)
