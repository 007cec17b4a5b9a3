"""Planning: from what the parts should do to the pulses that do it, one module per method.

* :mod:`~upm.plan.rotations` (chapter 4): :func:`rotation_pulses`, :class:`RotationsPlanner`;
* :mod:`~upm.plan.displacements` (chapter 5): :func:`plan_pulses`, :func:`plan_to_motion`,
  :func:`sustain_for_displacement`, :class:`DisplacementPlanner`;
* :mod:`~upm.plan.jets` (chapter 6): :func:`jet_pulses`, :func:`jet_plan`, :class:`JetPlanner`;
* :mod:`~upm.plan.predictive`: :class:`PredictivePlanner`, receding-horizon sampling on the
  batched simulator within the drive's force and stroke; its candidate families
  (:mod:`~upm.plan.candidates`), its look-ahead (:mod:`~upm.plan.lookahead`: two-pulse scores;
  :mod:`~upm.plan.macros`: the long pulses' tables);
* :mod:`~upm.plan.greedy`: :class:`GreedyLibraryPlanner`, the published Chladni-plate
  controller (greedy, one step, a fixed library with displacement maps) as the peer;
* :mod:`~upm.plan.fields`: :class:`FieldPlanner`, velocity fields of a plate that moves out of
  its plane (docs/ppod.md);
* :mod:`~upm.plan.orient`: :class:`PosePlanner`, pulses that turn and place polygon parts,
  chosen by simulating every candidate (docs/polygons.md);
* :mod:`~upm.plan.sizing`: sizing one pulse against the integrator, shared by all;
* :mod:`~upm.plan.fixed`: the :class:`Planner` protocol and :class:`FixedPlanner`;
* :mod:`~upm.plan.solvers` (chapters 4 and 5): the rotation and displacement programs' linear
  solves (:func:`upm.solve_rotations`, ...); :mod:`~upm.plan.field_design`: a 6-DOF plate
  motion for a wanted field (:func:`upm.design_field`).

Every planner sizes its pulses within :class:`upm.DriveLimits` (``limits=device.limits``). This
package never imports the loop, the board, vision or the plant.
"""

from __future__ import annotations

from .candidates import Candidates, aligned_centers, generate
from .candidates import aligned_centres as aligned_centres  # earlier spelling
from .displacements import DisplacementPlanner, plan_pulses, plan_to_motion, sustain_for_displacement
from .fields import FieldPlanner
from .fixed import FixedPlanner, Planner
from .greedy import GreedyLibraryPlanner, default_library
from .jets import JetPlanner, jet_plan, jet_pulses
from .macros import MacroTable
from .orient import PosePlanner
from .predictive import PredictivePlanner
from .rotations import RotationsPlanner, rotation_pulses
from .sizing import trim_rests

__all__ = [
    "Candidates",
    "DisplacementPlanner",
    "FieldPlanner",
    "FixedPlanner",
    "GreedyLibraryPlanner",
    "JetPlanner",
    "MacroTable",
    "Planner",
    "PosePlanner",
    "PredictivePlanner",
    "RotationsPlanner",
    "aligned_centers",
    "default_library",
    "generate",
    "jet_plan",
    "jet_pulses",
    "plan_pulses",
    "plan_to_motion",
    "rotation_pulses",
    "sustain_for_displacement",
    "trim_rests",
]
