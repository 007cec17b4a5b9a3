"""Move three parts at once by different small steps with rotations about fixed centres (ch. 5).

Solve the displacement field (5.3) for a grid of centres, turn the plan into pulses of
time-asymmetric rotation (each sized by simulating it), run the program in the exact integrator,
and compare where the parts went with where they were asked to go.
"""

import numpy as np

import upm

parts = np.array([(-0.1, -0.1), (0.1, 0.0), (0.0, 0.1)])  # between the centres
steps = np.array([(4e-4, 0.0), (0.0, -3e-4), (-2e-4, 2e-4)])
centers = upm.grid_centers((4, 4), (-0.15, -0.15, 0.15, 0.15))

plan = upm.solve_displacements(parts, steps, centers)
print(f"{len(centers)} centres, condition number {plan.condition_number:.1f}, order {plan.order[:4]} ...")
second_order = np.abs(upm.flow_error(plan)).max()
print(f"second-order sequencing error (5.4.4): at most {1e6 * second_order:.1f} um")

program = upm.plan_to_motion(plan, mu=0.3, amplitude=5.0, frequency=100.0)
run = upm.simulate(program, parts, duration=program.duration, dt=5e-5, mu=0.3, record_every=10**6)
moved = run.positions[-1] - parts
for i, (want, got) in enumerate(zip(steps, moved, strict=True)):
    print(f"part {i}: asked {1e3 * want} mm, moved {np.round(1e3 * got, 4)} mm")
error = np.linalg.norm(moved - steps) / np.linalg.norm(steps)
at_rest = bool(run.stuck[-1].all())
print(f"program {program.duration:.2f} s; all parts at rest: {at_rest}; error {100 * error:.1f}%")
