"""upm: vibratory planar manipulation (D. Reznik, *The Universal Planar Manipulator*, 2000).

A plate vibrating in its own plane moves the parts lying on it through Coulomb sliding friction.
upm computes the plate motions that produce the part motions you want, exactly and fast.

SI units throughout; forces are averages over one period divided by ``mu m g``. The maths, with
equation numbers pointing into the thesis, is in ``docs/theory.md``.
"""

from __future__ import annotations

from . import actuation, mchip, shapes, theory
from ._build import build_info
from ._core import __version__
from ._errors import (
    BoardError,
    ConvergenceError,
    InternalError,
    MissingExtraError,
    ParameterError,
    PlanWarning,
    RankWarning,
    ResonanceWarning,
    ShapeError,
    UpmError,
    VisionError,
)
from .drive import DriveLimits, StrokeError
from .feeding import feed_rate, force_table, mean_force, theorem1_force
from .field_design import FieldDesign, design_field
from .fields import average_field, jet_field, rotation_curl, rotation_field
from .motion import PlateMotion
from .orienting import Equilibria, RadialField, SqueezeField, orientation_equilibria
from .plan import (
    PredictivePlanner,
    jet_plan,
    jet_pulses,
    plan_pulses,
    plan_to_motion,
    sustain_for_displacement,
    trim_rests,
)
from .polygon import Polygon
from .ppod import (
    PPOD_FIELDS,
    PPOD_SEQUENCES,
    FieldResult,
    asymptotic_field,
    divergence_curl,
    drift_field,
    field_angle,
)
from .pulses import Pulse
from .sim import Disk, Point, SimResult, simulate, simulate_batch
from .solvers import (
    DisplacementPlan,
    RotationPlan,
    corner_centers,
    flow_error,
    grid_centers,
    ring_centers,
    rotation_order,
    solve_displacements,
    solve_rotations,
    solve_rotations_batch,
)
from .sweeps import sweep
from .waveforms import BangBang, Harmonics, TwoHarmonic, Waveform

__all__ = [
    "PPOD_FIELDS",
    "PPOD_SEQUENCES",
    "BangBang",
    "BoardError",
    "ConvergenceError",
    "Disk",
    "DisplacementPlan",
    "DriveLimits",
    "Equilibria",
    "FieldDesign",
    "FieldResult",
    "Harmonics",
    "InternalError",
    "MissingExtraError",
    "ParameterError",
    "PlanWarning",
    "PlateMotion",
    "Point",
    "Polygon",
    "PredictivePlanner",
    "Pulse",
    "RadialField",
    "RankWarning",
    "ResonanceWarning",
    "RotationPlan",
    "ShapeError",
    "SimResult",
    "SqueezeField",
    "StrokeError",
    "TwoHarmonic",
    "UpmError",
    "VisionError",
    "Waveform",
    "__version__",
    "actuation",
    "asymptotic_field",
    "average_field",
    "build_info",
    "corner_centers",
    "design_field",
    "divergence_curl",
    "drift_field",
    "feed_rate",
    "field_angle",
    "flow_error",
    "force_table",
    "grid_centers",
    "jet_field",
    "jet_plan",
    "jet_pulses",
    "mchip",
    "mean_force",
    "orientation_equilibria",
    "plan_pulses",
    "plan_to_motion",
    "ring_centers",
    "rotation_curl",
    "rotation_field",
    "rotation_order",
    "shapes",
    "simulate",
    "simulate_batch",
    "solve_displacements",
    "solve_rotations",
    "solve_rotations_batch",
    "sustain_for_displacement",
    "sweep",
    "theorem1_force",
    "theory",
    "trim_rests",
]

#: Subpackages that load on first use (``upm.plot.sweep(...)`` after ``import upm``): each pulls in
#: its extra (matplotlib, OpenCV, pyserial, ...) only when it is used.
_ON_USE = ("board", "control", "desk", "envs", "plant", "plate6", "plot", "vision", "viz")


def __getattr__(name: str) -> object:
    if name in _ON_USE:
        import importlib

        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'upm' has no attribute {name!r}")
