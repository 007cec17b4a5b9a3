"""Seeing the loop: rerun recordings of loops and simulations, read back or replayed (extra
``viz``: ``pip install 'upm[viz]'``). docs/viz.md has the entity paths and the layout.

- ``Loop.run(..., recording="run.rrd")`` records a closed loop through a :class:`Recorder`
  (a background thread behind a bounded queue: the loop never waits for it);
- ``SimResult.to_rerun(path)``, ``MChipResult.to_rerun(path)`` record simulations;
- :func:`read_recording` reads an ``.rrd`` back through rerun's own reader;
- ``upm replay FILE.rrd [--web | --screenshot PNG]`` (:func:`replay`).
"""

from __future__ import annotations

from .layout import ENTITIES, TIMELINES, blueprint, colors_of
from .recorder import Recorder, field_on_grid, pulse_series
from .replay import chromium, free_port, replay, screenshot, serve_web
from .results import Recording, mchip_to_rerun, read_recording, sim_to_rerun

__all__ = [
    "ENTITIES",
    "TIMELINES",
    "Recorder",
    "Recording",
    "blueprint",
    "chromium",
    "colors_of",
    "field_on_grid",
    "free_port",
    "mchip_to_rerun",
    "pulse_series",
    "read_recording",
    "replay",
    "screenshot",
    "serve_web",
    "sim_to_rerun",
]
