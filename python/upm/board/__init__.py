"""The board link (docs/spec.md §6, thesis 5.2.2): ``protocol`` (bytes <-> messages, no I/O), the host
driver ``Board`` (pyserial) and the ``emulator`` that speaks the protocol over a pseudo-terminal
or TCP and drives the simulated plate. ``docs/protocol.md`` is the firmware author's reference.

Needs the ``board`` extra: ``pip install 'upm[board]'``.
"""

from __future__ import annotations

from . import protocol
from .client import Board, BoardTimeout, CommandRefused, PulseCut, VersionMismatch

__all__ = ["Board", "BoardTimeout", "CommandRefused", "PulseCut", "VersionMismatch", "protocol"]
