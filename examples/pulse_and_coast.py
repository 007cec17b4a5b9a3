"""Three pulses of the optimal two-harmonic drive move a part; it coasts v^2/(2 mu g) and stops.

While the part is slow next to the plate, sqrt(displacement) grows linearly with the sustain
(thesis 5.2.3); the longest pulse here nears the feed rate, so its part coasts no faster.
"""

import numpy as np

import upm

F, MU, G = 35.0, 0.05, 9.81
drive = upm.TwoHarmonic(0.5, np.pi / 2, amplitude=0.05, frequency=F)
for periods in (5, 10, 20):
    pulse = upm.PlateMotion.translation((1, 0), drive).with_envelope(1 / F, periods / F, 1 / F)
    program = upm.PlateMotion.sequence([pulse, upm.PlateMotion.rest(0.5)])
    run = upm.simulate(program, [[0.0, 0.0]], duration=pulse.duration + 0.5, dt=1 / F / 1000, mu=MU)
    k = int(np.searchsorted(run.t, pulse.duration - 1e-12))
    x, v = run.positions[:, 0, 0], run.velocities[k, 0, 0]
    print(
        f"sustain {periods:>2} periods: moved {1000 * x[-1]:6.3f} mm, of which coasting "
        f"{1000 * (x[-1] - x[k]):.3f} mm (v^2/2 mu g = {1000 * v * v / (2 * MU * G):.3f} mm);",
        f"at rest: {run.stuck[-1, 0]}",
    )
