"""Gymnasium environments over the batched simulator (``pip install 'upm[gym]'``; docs/envs.md).

``import upm.envs`` registers ``upm/Goto-v0``, ``upm/Sort-v0``, ``upm/Shape-v0`` and
``upm/Orient-v0`` (one polygon to a pose; ``n_parts`` for more): each a
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
    "DEFAULTS",
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
IDS = {"upm/Goto-v0": "goto", "upm/Sort-v0": "sort", "upm/Shape-v0": "shape", "upm/Orient-v0": "orient"}
#: Keywords an id sets beyond its task (a user's own keywords override them).
DEFAULTS: dict[str, dict[str, object]] = {"upm/Orient-v0": {"n_parts": 1}}

for _id, _task in IDS.items():
    if _id not in gym.registry:
        gym.register(
            _id,
            entry_point="upm.envs.env:PlateEnv",
            vector_entry_point="upm.envs.env:PlateVectorEnv",
            kwargs={"task": _task, **DEFAULTS.get(_id, {})},
        )
