"""The closed loop and its tasks (thesis 4.3, 5.2.5, 6.3): camera → vision → task → planner → device.

The planners live in :mod:`upm.plan` and are re-exported here.

>>> from upm import control  # doctest: +SKIP
>>> loop = control.Loop(plant, plant.camera("penny"), control.JetPlanner(mu=0.3),
...                     control.GotoTask([(0.05, 0.0)]), part_radius=0.0095)  # doctest: +SKIP
>>> log = loop.run(50, log="out/run.npz")  # doctest: +SKIP

Needs OpenCV and SciPy (``pip install 'upm[control]'``).
"""

from __future__ import annotations

from ..plan import (
    DisplacementPlanner,
    FieldPlanner,
    FixedPlanner,
    GreedyLibraryPlanner,
    JetPlanner,
    Planner,
    PosePlanner,
    PredictivePlanner,
    RotationsPlanner,
)
from .devices import BoardDevice, Device, SimulatedDevice, SimulatedDevice6, as_device
from .loop import LoadedLog, Log, Loop, load_log
from .orient import PoseLog, PoseLoop, PoseTask
from .parts import PartsTask
from .shape import ShapeTask
from .tasks import GatherTask, GotoTask, SortTask, State, Task, TrajectoryTask, WatchTask

__all__ = [
    "BoardDevice",
    "Device",
    "DisplacementPlanner",
    "FieldPlanner",
    "FixedPlanner",
    "GatherTask",
    "GotoTask",
    "GreedyLibraryPlanner",
    "JetPlanner",
    "LoadedLog",
    "Log",
    "Loop",
    "PartsTask",
    "Planner",
    "PoseLog",
    "PoseLoop",
    "PosePlanner",
    "PoseTask",
    "PredictivePlanner",
    "RotationsPlanner",
    "ShapeTask",
    "SimulatedDevice",
    "SimulatedDevice6",
    "SortTask",
    "State",
    "Task",
    "TrajectoryTask",
    "WatchTask",
    "as_device",
    "load_log",
]
