"""How well the predictive planner's model foresees its own candidates on the plate of record.

The planner predicts a pulse by simulating the parts under the pulse's ideal plate motion
(``Pulse.motion()``: every harmonic at full amplitude under the raised-cosine envelope). The plant
(``SimulatedUPM``, as ``make demo`` and the scale demos run it) is driven like real hardware: the
board multiplies each motor's *force* by the envelope and the plate answers through its flexures.
This plays each candidate family from a scatter of parts on both the plant and an ideal plate that
follows ``Pulse.motion()`` exactly, and prints the parts' final-position error of the prediction
against each (median and max over parts and pulses) beside the median move; and the error on the
plant of the prediction corrected for how the drive plays the pulse (:mod:`upm.plan.played`, what
the planner's re-ranked candidates carry).

    python bench/prediction.py [--parts 8] [--layouts 3] [--per-family 6]

Each pulse plays from rest on a fresh plant, so the plate's leftover motion from a pulse before
plays no part here.
"""

from __future__ import annotations

import argparse
from collections import defaultdict
from dataclasses import replace
from typing import Any

import numpy as np

from upm._build import cpu_model
from upm.control.devices import SimulatedDevice
from upm.control.shapes import scatter
from upm.experiments.demos import LIMITS
from upm.plan import PredictivePlanner
from upm.plan.played import drive_shift
from upm.plate.plant import SimulatedUPM

RADIUS = 0.005  # 10 mm washers: the shapes' parts


def played(pulse: Any, parts: np.ndarray, ideal: bool, rest: float) -> np.ndarray:
    plant = SimulatedUPM(
        plate=LIMITS.plate, axes=LIMITS.axes, stroke=LIMITS.stroke, parts=parts.copy(), seed=1
    )
    SimulatedDevice(plant, ideal=ideal).execute([replace(pulse, rest=rest)])
    return np.asarray(plant.parts)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", type=int, default=8)
    parser.add_argument("--layouts", type=int, default=3)
    parser.add_argument("--per-family", type=int, default=6)
    args = parser.parse_args()
    rows: dict[str, list[tuple[float, float]]] = defaultdict(list)
    for seed in range(1, args.layouts + 1):
        rng = np.random.default_rng(seed)
        parts = scatter(rng, args.parts, 0.12, 4 * RADIUS)
        planner = PredictivePlanner(LIMITS, mu=0.3, part_radius=RADIUS, adapt=False)
        toward = -parts / np.maximum(np.hypot(*parts.T), 1e-9)[:, None]  # toward the centre
        cands = planner.candidates(parts, toward)
        for family in sorted(set(cands.family)):
            members = np.flatnonzero(cands.family == family)
            for k in rng.choice(members, min(args.per_family, len(members)), replace=False):
                pulse = cands.pulses[int(k)]
                final, durations = planner.predict([pulse], parts)
                driven = final + drive_shift(LIMITS, [pulse], parts, mu=0.3)
                rest = float(durations[0] - pulse.on_time + 0.05)
                plant = played(pulse, parts, False, rest)
                for name, truth, guess in (
                    ("plant", plant, final[0]),
                    ("ideal plate", played(pulse, parts, True, rest), final[0]),
                    ("plant, predicted as the drive plays it", plant, driven[0]),
                ):
                    on = np.all(np.isfinite(truth), axis=1) & np.all(np.isfinite(guess), axis=1)
                    err = np.hypot(*(guess[on] - truth[on]).T)
                    move = np.hypot(*(truth[on] - parts[on]).T)
                    rows[f"{family} | {name}"] += list(zip(err, move, strict=True))
    print(f"{cpu_model()}: {args.parts} parts of {2000 * RADIUS:.0f} mm, {args.layouts} layouts, up to "
          f"{args.per_family} pulses a family; error of the planner's prediction [mm]\n")  # fmt: skip
    print("| family | played on | median move | median error | 90th pct error | max error |")
    print("|---|---|---|---|---|---|")
    for key in sorted(rows):
        a = 1000 * np.array(rows[key])
        family, name = key.split(" | ")
        print(f"| {family} | {name} | {np.median(a[:, 1]):.2f} | {np.median(a[:, 0]):.2f} | "
              f"{np.percentile(a[:, 0], 90):.2f} | {a[:, 0].max():.2f} |")  # fmt: skip


if __name__ == "__main__":
    main()
