"""Planning: from what the parts should do to the pulses that do it.

* :class:`PredictivePlanner` (:mod:`upm.plan.predictive`): receding-horizon sampling on the
  batched simulator, one pulse a cycle, within the drive's force and stroke.
* :mod:`upm.plan.candidates`: the candidate pulse families, sized within :class:`upm.DriveLimits`.

The thesis's planners (rotations, ch. 4; displacements, ch. 5; jets, ch. 6) are in
:mod:`upm.control.planners` and take the same limits.
"""

from __future__ import annotations

from .candidates import Candidates, generate
from .predictive import PredictivePlanner

__all__ = ["Candidates", "PredictivePlanner", "generate"]
