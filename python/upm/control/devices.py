"""Devices play pulses: a :class:`~upm.plant.SimulatedUPM` in this process, or a board (real, or
the emulator in another process) over protocol v1.

Both go through the motors: each pulse becomes four channel waveforms (:meth:`upm.pulses.Pulse.channels`)
and an envelope. ``SimulatedDevice(plant, ideal=True)`` instead makes the plate follow each pulse's
velocity exactly (the idealised plate of the thesis's simulations, chapter 4).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import replace
from typing import Protocol, runtime_checkable

import numpy as np

from .._arrays import real
from .._errors import ParameterError
from ..board.client import Board, CommandRefused
from ..board.protocol import NackCode
from ..plate.drive import DriveLimits, StrokeError
from ..plate.plant import Channel, Envelope, SimulatedUPM
from ..plate.plate6 import Plate6
from ..plate.pulses import Pulse, program

__all__ = ["BoardDevice", "Device", "SimulatedDevice", "SimulatedDevice6", "as_device"]


@runtime_checkable
class Device(Protocol):
    """What the loop needs of a plate: play pulses in order, then return."""

    def execute(self, pulses: Sequence[Pulse]) -> None: ...


class SimulatedDevice:
    """A :class:`~upm.plant.SimulatedUPM` played directly (no protocol, no real time).

    Parameters
    ----------
    plant : SimulatedUPM
    ideal : bool
        Make the plate follow the pulses' velocity exactly instead of driving the motors: the
        pulses play back to back as one motion (rests included), and the parts slide to rest at the
        end.
    precompensate : bool
        Divide each harmonic by the plant's suspension response (its ``axes``) rather than by the
        inertial response alone.
    limit : float or None
        Largest motor force [N]; ``ParameterError`` beyond it (default the plant's
        ``motor_force``).

    The device's :attr:`limits` are the plant's (:attr:`upm.plant.SimulatedUPM.limits`); the
    plant refuses a pulse beyond its stroke (:class:`upm.drive.StrokeError`). When the plate's
    leftover motion from earlier pulses is what takes a pulse beyond the stroke, the device waits
    for the plate to come home (0.25 s at a time, up to 2 s, counted in :attr:`waited`) as a
    board's controller would; a pulse beyond the stroke from home raises.
    """

    def __init__(
        self,
        plant: SimulatedUPM,
        *,
        ideal: bool = False,
        precompensate: bool = True,
        limit: float | None = None,
    ) -> None:
        if not isinstance(plant, SimulatedUPM):
            raise ParameterError(f"plant must be a upm.plant.SimulatedUPM; got {type(plant).__name__}")
        self.plant, self.ideal, self.precompensate = plant, ideal, precompensate
        self.limit = plant.motor_force if limit is None else limit
        self.settle, self.retries = 0.25, 8
        self.waited = 0.0
        """Plate time [s] spent waiting for the plate to come home before a pulse that would
        otherwise have exceeded the stroke (the plate's leftover motion from earlier pulses)."""

    @property
    def limits(self) -> DriveLimits:
        """The plant's drive limits."""
        return self.plant.limits

    def execute(self, pulses: Sequence[Pulse]) -> None:
        plant = self.plant
        if self.ideal:
            moving = [p for p in pulses if p.kind != "rest"]
            if moving:
                plant.play(program(moving))
            return
        for pulse in pulses:
            if pulse.kind == "rest":
                if plant.axes is not None:
                    plant.ride_out(pulse.rest)
                continue  # the parts have already slid to rest after the previous pulse
            axes = plant.axes if self.precompensate else None
            channels = pulse.channels(plant.plate, axes, self.limit)
            envelope = Envelope(pulse.attack, pulse.sustain, pulse.decay)
            for _ in range(self.retries):
                try:
                    plant.check_stroke(channels, envelope)
                    break
                except StrokeError:
                    if plant.axes is None:
                        raise  # a free plate never comes home by itself
                    plant.ride_out(self.settle)
                    self.waited += self.settle
            plant.run(channels, envelope, rest=pulse.rest)


class SimulatedDevice6:
    """A :class:`~upm.plant.SimulatedUPM`'s parts on a six-actuator plate (:class:`upm.plate6.Plate6`)
    playing field pulses (:meth:`upm.pulses.Pulse.field`).

    Each pulse's actuator forces are checked against every actuator's force and stroke (refused
    with ``ParameterError`` / :class:`upm.drive.StrokeError` before anything moves); the actuators
    deliver their forces with a fixed calibration error (each a gain drawn once within
    ``1 +- gain_error``), so the plate plays a slightly different motion, which the parts follow
    exactly; the accelerometers read it with Gaussian ``noise`` [m/s²] at ``sample_rate`` [Hz],
    and the estimator's relative error against the commanded accelerations is appended to
    :attr:`tracking` (the PPOD group measured 11–14 %).
    """

    def __init__(
        self,
        plant: SimulatedUPM,
        plate: Plate6 | None = None,
        *,
        gain_error: float = 0.05,
        noise: float = 0.2,
        sample_rate: float = 5000.0,
        seed: int = 0,
    ) -> None:
        if not isinstance(plant, SimulatedUPM):
            raise ParameterError(f"plant must be a upm.plant.SimulatedUPM; got {type(plant).__name__}")
        if not (0 <= gain_error < 1 and noise >= 0 and sample_rate > 0):
            raise ParameterError("gain_error must be in [0, 1), noise >= 0 and sample_rate > 0")
        self.plant, self.plate = plant, plate or Plate6()
        self.rng = np.random.default_rng(seed)
        self.gains = 1 + self.rng.uniform(-gain_error, gain_error, 6)
        self.noise, self.sample_rate = float(noise), float(sample_rate)
        self.tracking: list[float] = []
        """Relative L2 error of the estimated against the commanded accelerations, per pulse."""

    def execute(self, pulses: Sequence[Pulse]) -> None:
        for pulse in pulses:
            if pulse.kind == "rest":
                continue
            if pulse.kind != "field" or pulse.plate_motion is None:
                raise ParameterError(f"a six-actuator plate plays field pulses; got a {pulse.kind} pulse")
            wanted = pulse.plate_motion
            self.plate.check(wanted)
            real = self.plate.achieved(wanted, self.gains)
            t = np.arange(round(0.25 * self.sample_rate)) / self.sample_rate
            seen = self.plate.readings(real, t) + self.rng.normal(0.0, self.noise, (len(t), 9))
            f, want = wanted.harmonic_phasors()
            got = self.plate.estimate(seen, self.sample_rate, f, tuple(sorted(want)))
            num = sum(float(np.linalg.norm(got[k] - want[k]) ** 2) for k in want)
            den = sum(float(np.linalg.norm(want[k]) ** 2) for k in want)
            self.tracking.append(math.sqrt(num / den))
            played = replace(pulse, plate_motion=real)
            self.plant.play(played.motion())


class BoardDevice:
    """A board (or the emulator) over protocol v1: per pulse SET_CHANNEL x 4, SET_ENVELOPE, PULSE,
    wait for PULSE_DONE, then wait out the pulse's rest while the parts stop. A six-axis board
    (protocol v2) plays field pulses instead, SET_CHANNEL x 6 from ``plate6``'s actuator forces.

    Parameters
    ----------
    board : Board
        An open connection (handshake done).
    limits : DriveLimits, optional
        The plate (mass, inertia, lever arm; calibrated), its suspension for precompensation
        (``axes=None``: the inertial model, 5.10) and its stroke; the motor force is the board's
        advertised ``max_amplitude`` unless these say less. Default :class:`~upm.drive.DriveLimits`
        (the simulated plant's plate and flexures, 10 mm). Every pulse is checked against them
        before it is sent (:meth:`upm.drive.DriveLimits.check`).
    wait_rest : bool
        Wait out each pulse's rest (a real plate's parts need it; the emulator settles them at
        the end of the pulse): until ``on_time + rest`` after the PULSE command, so time the
        board took to report the pulse done counts towards the rest.
    watchdog : float or None
        The board's watchdog [s], set on connecting: it stops the motors when it hears nothing
        from this host for that long (default 1 s; ``None``: leave the board's, 250 ms on the
        emulator, which a host starved of its CPU by other work can miss on a loaded machine,
        cutting a pulse short: :class:`upm.PulseCut`).
    """

    def __init__(
        self,
        board: Board,
        limits: DriveLimits | None = None,
        *,
        wait_rest: bool = True,
        plate6: Plate6 | None = None,
        watchdog: float | None = 1.0,
    ) -> None:
        if not isinstance(board, Board):
            raise ParameterError(f"board must be a upm.board.Board; got {type(board).__name__}")
        if limits is not None and not isinstance(limits, DriveLimits):
            raise ParameterError(f"limits must be a upm.DriveLimits; got {type(limits).__name__}")
        self.board = board
        if board.info is None:
            board.info = board.hello()
        if watchdog is not None:
            board.set_watchdog(round(1000 * real("watchdog", watchdog, low=0.001, high=60.0)))
        self.info = board.info
        given = limits if limits is not None else DriveLimits()
        self.limits = replace(given, force=min(given.force, float(self.info.max_amplitude)))
        self.plate, self.axes = self.limits.plate, self.limits.axes
        self.wait_rest = wait_rest
        self.plate6 = plate6 or Plate6()
        """The six-actuator plate a six-axis board drives (the same model as the emulator's)."""
        self._id = 0
        self.waited = 0.0
        """Seconds spent waiting for the plate to come home after a STROKE refusal."""

    def _channels(self, pulse: Pulse) -> list[Channel]:
        """The SET_CHANNEL fields of ``pulse``: four motors, or a six-axis board's six actuators
        (field pulses only, checked against each actuator's force and stroke)."""
        if not self.board.six_axis:
            self.limits.check(pulse)
            return pulse.channels(self.plate, self.axes, self.limits.force)
        if pulse.kind != "field" or pulse.plate_motion is None:
            raise ParameterError(f"a six-axis board plays field pulses; got a {pulse.kind} pulse")
        self.plate6.check(pulse.plate_motion)
        return self.plate6.channels(pulse.plate_motion)

    def execute(self, pulses: Sequence[Pulse]) -> None:
        board = self.board
        for pulse in pulses:
            if pulse.kind != "rest":
                board.set_channels(self._channels(pulse), (pulse.attack, pulse.sustain, pulse.decay))
                self._id = (self._id + 1) & 0xFFFF
                for attempt in range(8):
                    started = time.monotonic()
                    try:
                        board.pulse(self._id, wait=True, timeout=pulse.on_time + 5.0)
                        break
                    except CommandRefused as refused:  # the plate still moving from the last pulse
                        if refused.code != NackCode.STROKE:
                            raise
                        if attempt == 7:  # beyond the stroke from home: as the simulated plant says it
                            message = f"the board refused pulse {self._id}: beyond its stroke"
                            raise StrokeError(message) from refused
                        time.sleep(0.25)
                        self.waited += 0.25
                board.samples()  # the accelerometer record is not needed here: drop it
                if self.wait_rest and pulse.rest > 0:
                    # the parts slide while the pulse's rest runs from its end on the plate's
                    # clock: whatever of it the wait for PULSE_DONE took is not waited again
                    time.sleep(max(0.0, started + pulse.duration - time.monotonic()))
            elif self.wait_rest and pulse.rest > 0:
                time.sleep(pulse.rest)


def as_device(device: object) -> Device:
    """A :class:`Device` from a SimulatedUPM, a Board, or anything with ``execute(pulses)``."""
    if isinstance(device, SimulatedUPM):
        return SimulatedDevice(device)
    if isinstance(device, Board):
        return BoardDevice(device)
    if isinstance(device, Device):
        return device
    raise ParameterError(
        f"device must be a upm.plant.SimulatedUPM, a upm.board.Board or have execute(pulses); got "
        f"{type(device).__name__}"
    )


def pulse_time(pulses: Sequence[Pulse]) -> float:
    """Plate time [s] the pulses take, rests included."""
    return math.fsum(p.duration for p in pulses)
