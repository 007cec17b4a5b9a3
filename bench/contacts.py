"""Benchmark: disk parts with and without part–part contacts (rapier2d), beside MuJoCo's colliding boxes.

Run with ``make bench`` or ``python bench/contacts.py [--quick] [--no-mujoco]``. All sides run in
this one process. Scene: disks of radius 5 mm on a square grid with 0.2 mm gaps, its front 0.2 mm
from the plate's edge, fed along +x by the time-asymmetric translation drive at 35 Hz into a fence
(the plate's edge as a wall), so that they pile up and press on each other: nearly every step has
contacts. Printed: microseconds per step and nanoseconds per disk-step for upm without contacts (the
disks pass through each other), upm with contacts, and MuJoCo (the same plate motion prescribed
open-loop on a massive plate's joints, 5 mm boxes resting on it, box–box and box–wall contacts,
elliptic cones, impratio 100, solref 0.001, the same time step), the ratio MuJoCo / upm with
contacts, and the worst overlap seen in upm's run.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import upm
from mujoco_plate import drive, plate_world

F, G, MU, R, DT = 35.0, 9.81, 0.3, 0.005, 1e-4


def feed() -> upm.PlateMotion:
    return upm.PlateMotion.translation((1.0, 0.0), upm.Harmonics([0.1, -0.05], frequency=F))


def grid(n: int) -> tuple[np.ndarray, float]:
    """``n`` disk centres on a square grid with 0.2 mm gaps, the front column 0.2 mm from the
    plate's +x edge, and the plate's side."""
    side = int(np.ceil(np.sqrt(n)))
    pitch = 2 * R + 0.0002
    ij = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)[:n]
    size = side * pitch + 0.04
    pos = (ij - (side - 1) / 2) * pitch
    pos[:, 0] += size / 2 - 0.0002 - R - pos[:, 0].max()
    return pos, size


def worst_overlap(positions: np.ndarray) -> float:
    """Largest overlap between two disks over the recorded rows, as a fraction of the radius."""
    worst = -np.inf
    for row in positions:
        d = np.linalg.norm(row[:, None] - row[None], axis=-1)
        np.fill_diagonal(d, np.inf)
        worst = max(worst, 2 * R - d.min())
    return worst / R


def ours(n: int, steps: int, contacts: bool) -> tuple[float, upm.SimResult]:
    pos, size = grid(n)
    disks = [upm.Disk((x, y), R) for x, y in pos]
    kw = {"duration": steps * DT, "dt": DT, "mu": MU, "record_every": max(1, steps // 20), "plate_size": size}
    if contacts:
        kw.update(contacts=True, walls="plate", restitution=0.3, part_friction=0.3)
    best, run = np.inf, None
    for _ in range(3):  # best of three: this machine is shared
        start = time.perf_counter()
        run = upm.simulate(feed(), disks, **kw)
        best = min(best, time.perf_counter() - start)
    assert run is not None
    return best, run


def mujoco_peer(n: int, steps: int) -> float:
    """Seconds MuJoCo takes for ``steps`` steps of the same scene with boxes for disks."""
    pos, size = grid(n)
    h = size / 2
    boxes = "\n".join(
        f'<body pos="{x:.6f} {y:.6f} {0.01 + R:.6f}"><freejoint/>'
        f'<geom type="box" size="{R} {R} {R}" mass="0.002"/></body>'
        for x, y in pos
    )
    walls = "\n".join(
        f'<geom type="box" pos="{x} {y} 0.02" size="{sx} {sy} 0.01"/>'
        for x, y, sx, sy in [
            (h + 0.005, 0, 0.005, h),
            (-h - 0.005, 0, 0.005, h),
            (0, h + 0.005, h, 0.005),
            (0, -h - 0.005, h, 0.005),
        ]
    )
    model, data = plate_world(
        boxes, half=h, dt=DT, mu=MU, g=G, settle=100, fixed=walls, plate='contype="1" conaffinity="1"'
    )
    return drive(model, data, feed().velocity(np.arange(1, steps + 1) * DT))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="fewer steps")
    parser.add_argument("--no-mujoco", action="store_true", help="leave out the MuJoCo peer")
    args = parser.parse_args()
    print(f"machine: {os.cpu_count()} cores; dt = {DT} s, disks of radius {R * 1e3:.0f} mm fed into a fence")
    print(
        f"{'disks':>6} {'steps':>6} | {'no contacts':>20} | {'contacts (rapier2d)':>20} | "
        f"{'mujoco boxes':>20} | {'mujoco/ours':>11} {'max overlap':>12}"
    )
    print(f"{'':>6} {'':>6} |" + f" {'us/step  ns/disk-step':>20} |" * 3)
    sizes = [(10, 4000), (100, 2000), (1000, 400)]
    if args.quick:
        sizes = [(10, 1000), (100, 400), (1000, 50)]
    mj = None
    if not args.no_mujoco:
        try:
            import mujoco  # noqa: F401

            mj = True
        except ImportError:
            print("(mujoco not installed: pip install 'upm[bench]'; its column is left out)")
    for n, steps in sizes:
        t_free, _ = ours(n, steps, False)
        t_hit, run = ours(n, steps, True)
        cells = [f"{t * 1e6 / steps:>8.2f} {t * 1e9 / (steps * n):>11.1f}" for t in (t_free, t_hit)]
        line = f"{n:>6} {steps:>6} | {cells[0]:>20} | {cells[1]:>20} | "
        if mj:
            t_mj = mujoco_peer(n, steps)
            line += f"{t_mj * 1e6 / steps:>8.2f} {t_mj * 1e9 / (steps * n):>11.1f} | {t_mj / t_hit:>10.1f}x"
        else:
            line += f"{'-':>20} | {'-':>11}"
        print(f"{line} {worst_overlap(run.positions):>11.2%}")


if __name__ == "__main__":
    main()
