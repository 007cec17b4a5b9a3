"""upm: vibratory planar manipulation (D. Reznik, *The Universal Planar Manipulator*, 2000).

A plate vibrating in its own plane moves the parts lying on it through Coulomb sliding friction.
upm computes the plate motions that produce the part motions you want, exactly and fast.

SI units throughout; forces are averages over one period divided by ``mu m g``. The maths, with
equation numbers pointing into the thesis, is in ``docs/theory.md``.

The package is layered (docs/architecture.md; ``pyproject.toml``'s import-linter contract checks
it): :mod:`upm.physics` (the forward model) < :mod:`upm.plate` (motors, limits, pulses, the
simulated plate) < :mod:`upm.plan` | :mod:`upm.vision` | :mod:`upm.viz` < :mod:`upm.board` <
:mod:`upm.control` < :mod:`upm.experiments` | :mod:`upm.envs` < :mod:`upm.desk` < ``upm.cli``.
The names below are the face: the ones most programs need, grouped by layer.
"""

from __future__ import annotations

from . import _moved  # first: the paths of before the layer packages (upm.sim, ...) still import
from ._build import build_info
from ._core import __version__
from ._errors import (
    BoardError,
    BoardTimeout,
    CommandRefused,
    ConvergenceError,
    InternalError,
    MissingExtraError,
    ParameterError,
    PlanWarning,
    ProtocolError,
    PulseCut,
    RankWarning,
    ResonanceWarning,
    ShapeError,
    StrokeError,
    UpmError,
    UpmWarning,
    VersionMismatch,
    VisionError,
)
from .control import shapes
from .experiments.sweeps import sweep
from .physics import mchip, theory
from .physics.feeding import feed_rate, force_table, mean_force, theorem1_force
from .physics.fields import average_field, jet_field, rotation_curl, rotation_field
from .physics.motion import PlateMotion
from .physics.orienting import Equilibria, RadialField, SqueezeField, orientation_equilibria
from .physics.polygon import Polygon
from .physics.ppod import (
    PPOD_FIELDS,
    PPOD_SEQUENCES,
    FieldResult,
    asymptotic_field,
    divergence_curl,
    drift_field,
    field_angle,
)
from .physics.sim import Disk, Point, SimResult, simulate, simulate_batch
from .physics.waveforms import BangBang, Harmonics, TwoHarmonic, Waveform
from .plan import (
    DisplacementPlanner,
    FieldPlanner,
    FixedPlanner,
    GreedyLibraryPlanner,
    JetPlanner,
    Planner,
    PosePlanner,
    PredictivePlanner,
    RotationsPlanner,
    jet_plan,
    jet_pulses,
    plan_pulses,
    plan_to_motion,
    sustain_for_displacement,
    trim_rests,
)
from .plan.field_design import FieldDesign, design_field
from .plan.solvers import (
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
from .plate import actuation
from .plate.drive import DriveLimits
from .plate.pulses import Pulse

# fmt: off
__all__ = [  # noqa: RUF022 - grouped by layer, not sorted
    # the package
    "__version__", "build_info",
    # errors and warnings (upm._errors): UpmError and UpmWarning are the roots
    "UpmError", "ParameterError", "ShapeError", "StrokeError", "ConvergenceError", "InternalError",
    "MissingExtraError", "VisionError", "BoardError", "BoardTimeout", "CommandRefused",
    "ProtocolError", "PulseCut", "VersionMismatch",
    "UpmWarning", "PlanWarning", "RankWarning", "ResonanceWarning",
    # physics: the forward model
    "Waveform", "BangBang", "Harmonics", "TwoHarmonic",
    "feed_rate", "force_table", "mean_force", "theorem1_force", "theory",
    "PlateMotion", "average_field", "jet_field", "rotation_curl", "rotation_field",
    "PPOD_FIELDS", "PPOD_SEQUENCES", "FieldResult", "asymptotic_field", "divergence_curl",
    "drift_field", "field_angle",
    "Disk", "Point", "SimResult", "simulate", "simulate_batch",
    "Polygon", "Equilibria", "RadialField", "SqueezeField", "orientation_equilibria",
    "mchip",
    # plate: the machine
    "actuation", "DriveLimits", "Pulse",
    # plan: the inverse solvers and every planner
    "RotationPlan", "DisplacementPlan", "solve_rotations", "solve_rotations_batch",
    "solve_displacements", "corner_centers", "grid_centers", "ring_centers", "rotation_order",
    "flow_error", "FieldDesign", "design_field",
    "Planner", "PredictivePlanner", "RotationsPlanner", "DisplacementPlanner", "JetPlanner",
    "GreedyLibraryPlanner", "FieldPlanner", "PosePlanner", "FixedPlanner",
    "jet_plan", "jet_pulses", "plan_pulses", "plan_to_motion", "sustain_for_displacement",
    "trim_rests",
    # control: target shapes for the tasks
    "shapes",
    # experiments
    "sweep",
]
# fmt: on

#: Packages that load on first use (``upm.control.Loop`` after ``import upm``): each pulls in its
#: extra (matplotlib, OpenCV, pyserial, ...) only when it is used.
_ON_USE = ("board", "control", "desk", "envs", "experiments", "physics", "plan", "plate", "vision", "viz")


def __getattr__(name: str) -> object:
    if name in _ON_USE:
        import importlib

        return importlib.import_module(f".{name}", __name__)
    if name in _moved.MOVED:  # upm.sim, upm.plot, ...: the module at its new path
        return _moved.module(name)
    raise AttributeError(f"module 'upm' has no attribute {name!r}")
