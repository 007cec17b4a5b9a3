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
from typing import Protocol, runtime_checkable

from .._errors import ParameterError
from ..actuation import Axis, Plate
from ..board.client import Board
from ..plant import Channel, Envelope, SimulatedUPM, _suspension
from ..pulses import Pulse, program

__all__ = ["BoardDevice", "Device", "SimulatedDevice", "as_device"]


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
        Largest motor force [N]; ``ParameterError`` beyond it.
    """

    def __init__(
        self,
        plant: SimulatedUPM,
        *,
        ideal: bool = False,
        precompensate: bool = True,
        limit: float | None = 200.0,
    ) -> None:
        if not isinstance(plant, SimulatedUPM):
            raise ParameterError(f"plant must be a upm.plant.SimulatedUPM; got {type(plant).__name__}")
        self.plant, self.ideal, self.precompensate, self.limit = plant, ideal, precompensate, limit

    def execute(self, pulses: Sequence[Pulse]) -> None:
        plant = self.plant
        if self.ideal:
            moving = [p for p in pulses if p.kind != "rest"]
            if moving:
                plant.play(program(moving))
            return
        for pulse in pulses:
            if pulse.kind == "rest":
                continue  # the parts have already slid to rest after the previous pulse
            axes = plant.axes if self.precompensate else None
            channels = [Channel(**c) for c in pulse.channels(plant.plate, axes, self.limit)]
            plant.run(channels, Envelope(pulse.attack, pulse.sustain, pulse.decay), rest=pulse.rest)


class BoardDevice:
    """A board (or the emulator) over protocol v1: per pulse SET_CHANNEL x 4, SET_ENVELOPE, PULSE,
    wait for PULSE_DONE, then wait out the pulse's rest while the parts stop.

    Parameters
    ----------
    board : Board
        An open connection (handshake done).
    plate : Plate
        The plate's mass, inertia and lever arm (calibrated; default the simulated plant's).
    axes : (Axis, Axis, Axis) or None
        Suspension model for precompensation (default the simulated plant's flexures); ``None``:
        the inertial model (5.10).
    wait_rest : bool
        Sleep for each pulse's rest (a real plate's parts need it; the emulator settles them at
        the end of the pulse).
    """

    def __init__(
        self,
        board: Board,
        plate: Plate | None = None,
        axes: tuple[Axis, Axis, Axis] | str | None = "default",
        *,
        wait_rest: bool = True,
    ) -> None:
        if not isinstance(board, Board):
            raise ParameterError(f"board must be a upm.board.Board; got {type(board).__name__}")
        self.board = board
        self.plate = plate if plate is not None else Plate(3.0, 0.04, 0.2)
        self.axes = _suspension(self.plate.mass, self.plate.inertia) if axes == "default" else axes
        self.wait_rest = wait_rest
        self.info = board.info if board.info is not None else board.hello()
        self._id = 0

    def execute(self, pulses: Sequence[Pulse]) -> None:
        board = self.board
        for pulse in pulses:
            if pulse.kind != "rest":
                channels = pulse.channels(self.plate, self.axes, self.info.max_amplitude)  # type: ignore[arg-type]
                for k, c in enumerate(channels):
                    board.set_channel(
                        k,
                        c["amplitude"],
                        c["frequency"],
                        h1=(c["h1_amplitude"], c["h1_phase"]),
                        h2=(c["h2_amplitude"], c["h2_phase"]),
                        h23=(c["h23_amplitude"], c["h23_phase"]),
                    )
                board.set_envelope(pulse.attack, pulse.sustain, pulse.decay)
                self._id = (self._id + 1) & 0xFFFF
                board.pulse(self._id, wait=True, timeout=pulse.on_time + 5.0)
                board.samples()  # the accelerometer record is not needed here: drop it
            if self.wait_rest and pulse.rest > 0:
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
