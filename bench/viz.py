"""What seeing the loop costs the loop, and how fast the desk stops.

* Recording: the sort8 task (8 colliding chips, predictive planner, virtual camera and vision)
  for ``--cycles`` cycles with and without a rerun recording, alternated ``--repeats`` times;
  prints the median wall time per cycle of each and their ratio (the target: under 5 % more with
  recording on), and what the recorder dropped. The runs must also agree exactly: recording
  changes nothing the loop does.
* Desk: STOP pressed ``--stops`` times while the simulated plate works on a goal; prints the
  median and largest time from the request to the plate's last motion (the target: 250 ms).

Run: ``python bench/viz.py [--cycles 20] [--repeats 3] [--stops 10]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from upm import control
from upm.experiments.demos import DEMOS, LIMITS
from upm.plan import PredictivePlanner
from upm.plate.plant import SimulatedUPM
from upm.viz import Recorder

try:
    from control import cpu  # bench/control.py, when run from bench/
except ImportError:  # pragma: no cover
    import platform

    def cpu() -> str:
        return platform.processor() or "unknown CPU"


def sort8(cycles: int, recording: Recorder | None) -> control.Log:
    setup = DEMOS["sort8"].build(False, 1)
    plant = SimulatedUPM(
        plate=LIMITS.plate,
        axes=LIMITS.axes,
        stroke=LIMITS.stroke,
        parts=setup.parts,
        seed=1,
        part_radius=setup.radius,
    )
    planner = PredictivePlanner(LIMITS, mu=0.3, part_radius=setup.radius)
    camera = plant.camera(setup.labels, seed=1)
    loop = control.Loop(control.SimulatedDevice(plant), camera, planner, setup.task, part_radius=setup.radius)
    return loop.run(cycles, recording=recording)


def recording_cost(cycles: int, repeats: int) -> None:
    times: dict[str, list[float]] = {"off": [], "on": []}
    dropped = [0, 0]
    cpu, recorded = 0.0, 0
    first: dict[str, control.Log] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(repeats):
            for mode in ("off", "on") if r % 2 == 0 else ("on", "off"):
                rec = Recorder(Path(tmp) / f"run{r}.rrd") if mode == "on" else None
                log = sort8(cycles, rec)
                if rec is not None:
                    t0 = time.perf_counter()
                    rec.close()
                    tail = time.perf_counter() - t0
                    dropped[0] += rec.dropped_frames
                    dropped[1] += rec.dropped_cycles
                    cpu, recorded = cpu + rec.cpu_seconds, recorded + rec.cycles
                    print(f"  recording {r}: {rec.cycles} cycles, closed {1e3 * tail:.0f} ms after the run")
                times[mode].extend(np.diff(log.wall).tolist())
                first.setdefault(mode, log)
    same = np.array_equal(first["on"].positions, first["off"].positions, equal_nan=True)
    off, on = float(np.median(times["off"])), float(np.median(times["on"]))
    print(f"sort8, {cycles} cycles x {repeats}: median cycle {1e3 * off:.0f} ms without recording, "
          f"{1e3 * on:.0f} ms with: ratio {on / off:.3f} (target < 1.05)")  # fmt: skip
    print(f"  mean cycle {1e3 * np.mean(times['off']):.0f} / {1e3 * np.mean(times['on']):.0f} ms: ratio "
          f"{np.mean(times['on']) / np.mean(times['off']):.3f}; the recorder thread's CPU time "
          f"{1e3 * cpu / recorded:.1f} ms a cycle, {100 * cpu / recorded / off:.1f} % of a cycle "
          "(what it can take from the loop on a saturated machine)")  # fmt: skip
    print(f"  dropped: {dropped[0]} frames, {dropped[1]} cycles; identical runs: {same}")


def stop_latency(stops: int) -> None:
    from upm.desk import simulated

    desk = simulated(watchdog=60.0).start()
    lat = []
    try:
        for k in range(stops):
            t = desk.tracks
            i = int(t.ids[k % len(t.ids)])
            pos = t.positions[k % len(t.ids)]
            goal = [-0.1 if pos[0] > 0 else 0.1, float(np.clip(pos[1], -0.15, 0.15))]
            desk.command({"type": "goto", "id": i, "to": goal})
            before = desk.pulses_played
            deadline = time.monotonic() + 30
            while desk.pulses_played == before and time.monotonic() < deadline:
                time.sleep(0.01)
            time.sleep(0.05 * (k % 4))  # press at different points of a pulse
            desk.stop("bench")
            lat.append(float(desk.stops[-1]["latency"]))
    finally:
        desk.close()
    ms = 1e3 * np.array(lat)
    print(
        f"desk STOP: {stops} stops, time to the plate's last motion median {np.median(ms):.1f} ms, "
        f"largest {np.max(ms):.1f} ms (target 250 ms)"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cycles", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--stops", type=int, default=10)
    args = ap.parse_args()
    print(f"CPU: {cpu()}")
    recording_cost(args.cycles, args.repeats)
    stop_latency(args.stops)


if __name__ == "__main__":
    main()
