"""Sort two red and two blue chips by colour, in a closed loop with jets.

Each cycle the simulated plate's overhead camera takes a frame, the tracker finds the chips, the
sort task asks each chip for a step towards its side, the jet planner turns the steps into jets
(sized against the exact integrator, motor forces within 200 N), and the simulated plate plays them
through its motors. The log records what was asked and what happened.
"""

import numpy as np

from upm import control
from upm.plate.plant import SimulatedUPM

# the default plate: 1 kg, 16 in, on flexures; four 200 N motors; 10 mm stroke (plant.limits)
plant = SimulatedUPM(parts=[[0.04, 0.05], [0.03, -0.06], [-0.03, 0.0], [-0.05, -0.08]])
loop = control.Loop(
    plant,
    plant.camera(["red", "red", "blue", "blue"]),
    control.JetPlanner(mu=0.3, amplitude=0.1, rho=0.03, limits=plant.limits),
    control.SortTask({"red": -1, "blue": 1}, line=0.08, margin=0.08, spacing=0.046),
    part_radius=0.0195,
)
log = loop.run(30, log="sort.npz")
for c in range(len(log.rows)):
    still = np.nan_to_num(log.errors[c], nan=0.0) * 1000
    print(
        f"cycle {c:2d}  t = {log.time[c]:5.1f} s  distance to go [mm]: {np.round(still).astype(int).tolist()}"
    )
print(f"sorted: {log.done} in {log.meta['plate_time']:.1f} s of plate time; chips fallen off: {plant.fallen}")
print(
    f"median |achieved - desired| step: {1000 * np.nanmedian(log.tracking_error()):.1f} mm; log in sort.npz"
)
