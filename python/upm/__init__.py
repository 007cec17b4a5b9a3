"""upm: vibratory planar manipulation (D. Reznik, *The Universal Planar Manipulator*, 2000).

A plate vibrating in its own plane moves the parts lying on it through Coulomb sliding friction.
upm computes the plate motions that produce the part motions you want, exactly and fast.

SI units throughout; forces are averages over one period divided by ``mu m g``. The maths, with
equation numbers pointing into the thesis, is in ``docs/theory.md``.
"""

from __future__ import annotations

from . import theory
from ._core import __version__
from ._errors import ConvergenceError, InternalError, ParameterError, ShapeError, UpmError
from .feeding import feed_rate, force_table, mean_force, theorem1_force
from .motion import PlateMotion
from .sim import Disk, Point, SimResult, simulate, simulate_batch
from .waveforms import BangBang, Harmonics, TwoHarmonic, Waveform

__all__ = [
    "BangBang",
    "ConvergenceError",
    "Disk",
    "Harmonics",
    "InternalError",
    "ParameterError",
    "PlateMotion",
    "Point",
    "ShapeError",
    "SimResult",
    "TwoHarmonic",
    "UpmError",
    "Waveform",
    "__version__",
    "feed_rate",
    "force_table",
    "mean_force",
    "simulate",
    "simulate_batch",
    "theorem1_force",
    "theory",
]
