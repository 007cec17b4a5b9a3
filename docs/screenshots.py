"""Regenerate docs/viz.md's pictures: rerun's web viewer replaying a recorded sort8, and the desk
in the middle of moving two parts (one to a goal, one along a drawn path).

Run: ``python docs/screenshots.py`` (needs ``upm[viz,desk]`` and Debian's chromium; about a minute).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from upm.experiments.demos import run_demo
from upm.desk import DeskServer, simulated
from upm.viz import chromium, free_port, screenshot

HERE = Path(__file__).parent / "img"


def viewer() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        run_demo("sort8", tmp, planner="predictive", rrd=True, verbose=False)
        print(f"wrote {screenshot(Path(tmp) / 'sort8' / 'run.rrd', HERE / 'replay_sort8.png', wait=60)}")


def desk() -> None:
    from playwright.sync_api import sync_playwright

    d = simulated(watchdog=5.0).start()
    with DeskServer(d, port=free_port()) as server, sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=chromium())
        page = browser.new_page(viewport={"width": 900, "height": 680})
        page.goto(server.url)
        page.wait_for_selector("#plate")
        time.sleep(1.0)
        t = d.tracks
        a, b = int(t.ids[0]), int(t.ids[2])
        pa, pb = t.positions[0], t.positions[2]
        d.command({"type": "goto", "id": a, "to": [float(pa[0]) + 0.06, float(pa[1])]})
        path = np.array([pb + [0.0, -0.01 * k] for k in range(8)])
        d.command({"type": "path", "id": b, "path": path.tolist()})
        while d.pulses_played < 1:
            time.sleep(0.1)
        page.screenshot(path=str(HERE / "desk.png"))
        print(f"wrote {HERE / 'desk.png'}")
        browser.close()


if __name__ == "__main__":
    HERE.mkdir(parents=True, exist_ok=True)
    viewer()
    desk()
