"""Benchmark: the point-part integrator, upm versus a vectorised NumPy reference (and MuJoCo).

Run with ``make bench`` or ``python bench/integrator.py [--quick] [--mujoco]``. All sides run in
this one process. The NumPy reference implements the same exact implicit Coulomb step (SPEC §1)
with the same stick rule, vectorised over parts; the script checks it reproduces upm's final state
before it prints ns per part-step and the ratio. Plate: translating (two-harmonic) and rotating
(about a centre off the origin) at 35 Hz.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

import numpy as np

import upm
from mujoco_plate import drive, plate_world

F, G, MU, MU_S = 35.0, 9.81, 0.3, 0.4
HALF = 0.0005  # half-size of MuJoCo's point-like box parts [m]


def program() -> upm.PlateMotion:
    """A translating + rotating plate: translation then rotation, repeated as one timed program."""
    trans = upm.PlateMotion.translation(
        (0.6, 0.8), upm.TwoHarmonic(0.5, np.pi / 2, amplitude=0.05, frequency=F)
    )
    rot = upm.PlateMotion.rotation((0.03, -0.02), upm.Harmonics([0.5, -0.25], frequency=F))
    return upm.PlateMotion.sequence([trans.for_duration(2 / F), rot.for_duration(2 / F)])


def numpy_reference(
    motion: upm.PlateMotion, pos: np.ndarray, steps: int, dt: float
) -> tuple[np.ndarray, ...]:
    """The implicit Coulomb step of SPEC §1, vectorised over parts, plate velocity tabulated once."""
    u = motion.velocity((np.arange(1, steps + 1) - 1e-6) * dt)
    x, y = pos[:, 0].copy(), pos[:, 1].copy()
    vx, vy = np.zeros_like(x), np.zeros_like(x)
    stuck = np.ones(x.shape, dtype=bool)
    slide, hold = MU * G * dt, MU_S * G * dt
    for u1, u2, u3 in u:
        sx, sy = u1 - u3 * y, u2 + u3 * x
        wx, wy = vx - sx, vy - sy
        wn = np.sqrt(wx * wx + wy * wy)
        stuck = (wn <= slide) | (stuck & (wn <= hold))
        keep = np.where(stuck, 0.0, 1.0 - slide / np.where(wn > 0, wn, 1.0))
        nvx, nvy = sx + wx * keep, sy + wy * keep
        x += 0.5 * (vx + nvx) * dt
        y += 0.5 * (vy + nvy) * dt
        vx, vy = nvx, nvy
    return x, y, vx, vy


def mujoco_peer(motion: upm.PlateMotion, pos: np.ndarray, steps: int, dt: float) -> tuple[float, np.ndarray]:
    """MuJoCo: a massive plate on slide/slide/hinge joints whose joint velocities are prescribed
    open-loop from ``motion`` each step, and small boxes lying on it as point-like parts (spheres
    would roll instead of sliding).
    Elliptic friction cones, impratio 100, solref 0.001, timestep ``dt``. Returns the seconds the
    steps took and the parts' final (x, y)."""
    spheres = "\n".join(
        f'<body pos="{x:.6f} {y:.6f} 0.0105"><freejoint/>'
        f'<geom type="box" size="{HALF} {HALF} {HALF}" mass="0.001"/></body>'
        for x, y in pos
    )
    # Let the parts settle onto the still plate first.
    model, data = plate_world(spheres, half=0.3, dt=dt, mu=MU, g=G, settle=200)
    elapsed = drive(model, data, motion.velocity(np.arange(1, steps + 1) * dt))
    xy = data.qpos[3:].reshape(-1, 7)[:, :2].copy()
    return elapsed, xy


def ours_only(n: int, steps: int) -> float:
    """Best-of-three ns per part-step of upm alone (used to measure thread scaling)."""
    motion, dt = program(), 1 / F / 400
    pos = np.random.default_rng(3).uniform(-0.1, 0.1, (n, 2))
    best = np.inf
    for _ in range(3):
        start = time.perf_counter()
        upm.simulate(motion, pos, duration=steps * dt, dt=dt, mu=MU, mu_s=MU_S, record_every=steps)
        best = min(best, time.perf_counter() - start)
    return best * 1e9 / (n * steps)


def recording(motion: upm.PlateMotion, dt: float, rng: np.random.Generator, quick: bool) -> None:
    """Every step recorded (``record_every=1``) beside sparse recording, and beside the peer
    "writing the numbers": NumPy allocating the same result arrays and filling them once."""
    n, steps = (20_000, 1000) if not quick else (5_000, 200)
    pos = rng.uniform(-0.1, 0.1, (n, 2))
    ns = 1e9 / (n * steps)
    best = {}
    for every in (steps, 1):
        best[every] = np.inf
        for _ in range(3):
            start = time.perf_counter()
            run = upm.simulate(motion, pos, duration=steps * dt, dt=dt, mu=MU, mu_s=MU_S, record_every=every)
            best[every] = min(best[every], time.perf_counter() - start)
            del run
    write = np.inf
    for _ in range(3):
        start = time.perf_counter()
        shape = (steps + 1, n)
        arrays = [
            np.empty((*shape, 2)),
            np.empty((*shape, 2)),
            np.empty(shape, bool),
            np.empty(shape),
            np.empty(shape),
        ]
        for a in arrays:
            a.fill(1)
        write = min(write, time.perf_counter() - start)
        del arrays
    full, sparse, peer = best[1] * ns, best[steps] * ns, write * ns
    size = (steps + 1) * n * 49 / 1e9
    print(f"\nrecording every step, {n:,} parts x {steps} steps ({size:.2f} GB of results), ns/part-step:")
    print(f"  upm record_every=1 {full:.1f}; sparse {sparse:.2f}; numpy writing the same arrays {peer:.1f}")
    overhead = full - sparse
    print(f"  recording costs {overhead:.1f} = {overhead / peer:.2f}x writing the numbers")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="smaller problems")
    parser.add_argument("--mujoco", action="store_true", help="also run the MuJoCo peer (pip install mujoco)")
    parser.add_argument("--ours-only", nargs=2, type=int, metavar=("PARTS", "STEPS"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.ours_only:
        print(ours_only(*args.ours_only))
        return
    motion = program()
    dt = 1 / F / 400
    rng = np.random.default_rng(3)
    print(f"machine: {os.cpu_count()} cores; RAYON_NUM_THREADS={os.environ.get('RAYON_NUM_THREADS', 'all')}")
    head = f"{'parts':>9} {'steps':>7} {'upm ns/part-step':>17} {'numpy ns/part-step':>19} {'ratio':>7}"
    print(head + "  max |diff|")
    sizes = [(1_000, 20_000), (100_000, 1000), (1_000_000, 200)]
    if args.quick:
        sizes = [(1_000, 2000), (100_000, 100)]
    numpy_ns: dict[int, float] = {}
    for n, steps in sizes:
        pos = rng.uniform(-0.1, 0.1, (n, 2))
        kw = dict(duration=steps * dt, dt=dt, mu=MU, mu_s=MU_S, record_every=steps)
        t_ours = np.inf
        for _ in range(3):  # best of three: this machine is shared
            start = time.perf_counter()
            run = upm.simulate(motion, pos, **kw)
            t_ours = min(t_ours, time.perf_counter() - start)
        start = time.perf_counter()
        x, y, _, _ = numpy_reference(motion, pos, steps, dt)
        t_np = time.perf_counter() - start
        diff = np.abs(run.positions[-1] - np.stack([x, y], 1)).max()
        ns = 1e9 / (n * steps)
        numpy_ns[n] = t_np * ns
        print(
            f"{n:>9,} {steps:>7} {t_ours * ns:>17.2f} {t_np * ns:>19.2f} {t_np / t_ours:>6.1f}x  {diff:.1e}"
        )
        assert diff < 1e-12, "the reference must reproduce upm's trajectory for the ratio to mean anything"

    recording(motion, dt, rng, quick=args.quick)

    n, steps = (100_000, 1000) if not args.quick else (100_000, 100)
    per_thread = {}
    for threads in ("1", str(os.cpu_count())):
        env = dict(os.environ, RAYON_NUM_THREADS=threads)
        out = subprocess.run(
            [sys.executable, __file__, "--ours-only", str(n), str(steps)],
            env=env,
            capture_output=True,
            text=True,
        )
        per_thread[threads] = float(out.stdout.strip())
    one, many = per_thread["1"], per_thread[str(os.cpu_count())]
    cores = os.cpu_count()
    print(f"\nthread scaling at {n:,} parts: 1 thread {one:.2f} ns/part-step, {cores} threads {many:.2f}")
    print(f"  speed-up {one / many:.2f}x")
    if n in numpy_ns:
        print(f"  per core (1 thread) against numpy at {n:,} parts: {numpy_ns[n] / one:.1f}x")

    if args.mujoco:
        print("\nMuJoCo peer (same plate motion, 1 mm boxes as point-like parts), ns per part-step:")
        for n, steps in [(100, 2000), (1_000, 500)]:
            pos = rng.uniform(-0.1, 0.1, (n, 2))
            t_mj, xy = mujoco_peer(motion, pos, steps, dt)
            run = upm.simulate(motion, pos, duration=steps * dt, dt=dt, mu=MU, mu_s=MU_S, record_every=steps)
            start = time.perf_counter()
            run = upm.simulate(motion, pos, duration=steps * dt, dt=dt, mu=MU, mu_s=MU_S, record_every=steps)
            t_ours = time.perf_counter() - start
            moved_mj = 1e3 * np.mean(xy - pos, axis=0)
            moved_ours = 1e3 * np.mean(run.positions[-1] - pos, axis=0)
            ns = 1e9 / (n * steps)
            times = f"upm {t_ours * ns:8.2f}  mujoco {t_mj * ns:10.1f}  ratio {t_mj / t_ours:8.0f}x"
            disks = [upm.Disk((x, y), radius=HALF) for x, y in pos]
            start = time.perf_counter()
            upm.simulate(motion, disks, duration=steps * dt, dt=dt, mu=MU, mu_s=MU_S, record_every=steps)
            t_disk = time.perf_counter() - start
            print(f"  {n:>6,} parts: {times}")
            disk_ns = t_disk * ns
            print(
                f"          upm disks {disk_ns:8.2f} ns/part-step, ratio to mujoco boxes {t_mj / t_disk:.0f}x"
            )
            print(
                f"          mean displacement [mm]: upm {np.round(moved_ours, 4)}, "
                f"mujoco {np.round(moved_mj, 4)}"
            )


if __name__ == "__main__":
    main()
