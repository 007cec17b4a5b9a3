"""The module paths of upm before its packages by layer (0.x): ``upm.sim``, ``upm.drive``,
``upm.demos``, ... each still imports, as the very module object of its new home
(``upm.physics.sim``, ``upm.plate.drive``, ``upm.experiments.demos``), so ``import upm.sim``,
``from upm.sim import simulate`` and ``upm.sim.simulate`` keep working and patching either name
patches both. Importing this module installs the finder; nothing else is imported until an old
path is asked for."""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
from collections.abc import Sequence
from types import ModuleType

#: Old path (without ``upm.``) -> new path.
MOVED = {
    **{
        n: f"physics.{n}"
        for n in "feeding fields mchip motion orienting polygon ppod sim theory waveforms".split()
    },
    **{n: f"plate.{n}" for n in ("actuation", "drive", "plant", "plate6", "pulses")},
    **{n: f"plan.{n}" for n in ("field_design", "solvers")},
    **{
        n: f"experiments.{n}"
        for n in "demo_outputs demos mchip_demos orient_demos ppod_demos scale_demos scenarios sweeps".split()
    },
    "plot": "viz.plot",
    "shapes": "control.shapes",
    "_experiments": "experiments.runner",
    "cli_calibrate": "vision.cli",
}


class _Alias(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds ``upm.<old>`` and loads it as the module at its new path."""

    def __init__(self) -> None:
        self.specs: dict[str, importlib.machinery.ModuleSpec | None] = {}

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        head, _, old = fullname.partition(".")
        if head != "upm" or old not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        real = importlib.import_module(f"upm.{MOVED[spec.name[4:]]}")
        self.specs[real.__name__] = real.__spec__
        return real

    def exec_module(self, module: ModuleType) -> None:
        # the import system has just set the alias's spec on the shared module: give its own back
        module.__spec__ = self.specs[module.__name__]


def install() -> None:
    """Put the finder on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, _Alias) for f in sys.meta_path):
        sys.meta_path.insert(0, _Alias())


def module(old: str) -> ModuleType:
    """``upm.<old>`` by its new path (for ``upm.__getattr__``)."""
    return importlib.import_module(f"upm.{MOVED[old]}")


install()
