"""What the loop asks of a planner, and the simplest one: the same pulses every cycle."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from .._errors import ParameterError
from ..plate.pulses import Pulse

__all__ = ["FixedPlanner", "Planner"]

FloatArray = NDArray[np.float64]


@runtime_checkable
class Planner(Protocol):
    """``plan(positions (M, 2), steps (M, 2)) -> list[Pulse]`` [m]. A NaN component of a step is
    free: the task does not care where the part goes along it."""

    def plan(self, positions: FloatArray, steps: FloatArray) -> list[Pulse]: ...


class FixedPlanner:
    """The same pulses every cycle, whatever the steps (an open-loop flow)."""

    def __init__(self, pulses: Sequence[Pulse]) -> None:
        self.pulses = list(pulses)
        if not all(isinstance(p, Pulse) for p in self.pulses):
            raise ParameterError("pulses must be upm.pulses.Pulse objects")

    def plan(self, positions: FloatArray, steps: FloatArray) -> list[Pulse]:
        return list(self.pulses)
