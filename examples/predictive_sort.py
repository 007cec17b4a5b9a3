"""Sort four chips by colour with the predictive planner, within a 10 mm plate stroke.

Each cycle the planner predicts a few hundred candidate pulses (translations, rotations, jets, at
the force and stroke limits of the plant's drive) with the batched simulator from the tracked
positions, plays the one that lowers the task's cost fastest, and compares what happened with what
it predicted. The chips are disks that collide; the plate's pose is recorded.
"""

import numpy as np

import upm
from upm import control
from upm.plate.plant import SimulatedUPM

chip = 0.0195
plant = SimulatedUPM(parts=[[0.04, 0.05], [0.03, -0.06], [-0.03, 0.0], [-0.05, -0.08]], part_radius=chip)
planner = upm.PredictivePlanner(plant.limits, mu=0.3, part_radius=chip)
task = control.SortTask({"red": -1, "blue": 1}, line=0.08, margin=0.08)
loop = control.Loop(plant, plant.camera(["red", "red", "blue", "blue"]), planner, task, part_radius=chip)
log = loop.run(60)
print(f"sorted: {log.done} in {log.meta['plate_time']:.1f} s of plate time, {len(log.rows) - 1} pulses")
print(f"chips fallen off: {plant.fallen}; largest plate-corner excursion {1000 * plant.max_excursion:.1f} mm")
print(f"median predicted-vs-achieved step error: {1000 * np.median(planner.step_errors):.1f} mm")
print(f"friction estimate: {planner.mu_estimate:.3f} (true {plant.mu})")
