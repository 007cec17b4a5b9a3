"""The desk: a plate steered by hand from a browser page (extra ``desk``:
``pip install 'upm[desk]'``; docs/viz.md).

``upm desk`` serves the simulated plate (or ``--board URL --camera N``) on 127.0.0.1: the live
camera with the tracked parts and the planned field; click a part and a point to send it there,
drag to draw its path, or press Sort, Gather (out-of-plane plates), Pause and STOP.

>>> from upm.desk import DeskServer, simulated  # doctest: +SKIP
>>> with DeskServer(simulated().start()) as server:  # doctest: +SKIP
...     print(server.url)
"""

from __future__ import annotations

from .cli import hardware, simulated
from .server import DeskServer, app
from .session import COMMANDS, Desk

__all__ = ["COMMANDS", "Desk", "DeskServer", "app", "hardware", "simulated"]
