"""Gymnasium environments over the batched simulator (``pip install 'upm[gym]'``; docs/envs.md).

``import upm.envs`` registers ``upm/Goto-v0``, ``upm/Sort-v0`` and ``upm/Shape-v0``: each a
:class:`PlateEnv` for ``gymnasium.make`` and a :class:`PlateVectorEnv` for
``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")``.
"""

from __future__ import annotations

from .._extras import need

gym = need("gymnasium", "gym", "upm.envs")

from .actions import ACTION_SIZE, FREQUENCIES, ON_TIMES, PulseActions, library  # noqa: E402
from .env import PlateEnv, PlateVectorEnv  # noqa: E402
from .policies import PlannerPolicy, RandomPolicy  # noqa: E402

__all__ = [
    "ACTION_SIZE",
    "FREQUENCIES",
    "IDS",
    "ON_TIMES",
    "PlannerPolicy",
    "PlateEnv",
    "PlateVectorEnv",
    "PulseActions",
    "RandomPolicy",
    "library",
]

#: The registered ids and their task.
IDS = {"upm/Goto-v0": "goto", "upm/Sort-v0": "sort", "upm/Shape-v0": "shape"}

for _id, _task in IDS.items():
    if _id not in gym.registry:
        gym.register(
            _id,
            entry_point="upm.envs.env:PlateEnv",
            vector_entry_point="upm.envs.env:PlateVectorEnv",
            kwargs={"task": _task},
        )
