"""Benchmark: the point-part integrator, upm versus hand-written Numba loops, a vectorised NumPy
reference (and MuJoCo).

Run with ``make bench`` or ``python bench/integrator.py [--quick] [--mujoco]``. All sides run in
this one process on the same data. The peers implement the same exact implicit Coulomb step
(docs/spec.md §1) with the same stick rule: NumPy vectorised over parts, and Numba
(``bench/numba_peer.py``, ``pip install 'upm[bench]'``) as a serial loop on one thread and as
blocks of parts in ``prange`` on every core. The script checks that each reproduces upm's final
state before it prints ns per part-step and the ratios, with the CPU model and the build of upm's
step chosen on it. Plate: translating (two-harmonic) and rotating (about a centre off the origin)
at 35 Hz.
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Any

import numpy as np

import upm

try:
    import numba

    import numba_peer
except ImportError:  # the Numba peer is optional: pip install 'upm[bench]'
    numba = numba_peer = None

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
    from mujoco_plate import drive, plate_world

    model, data = plate_world(spheres, half=0.3, dt=dt, mu=MU, g=G, settle=200)
    elapsed = drive(model, data, motion.velocity(np.arange(1, steps + 1) * dt))
    xy = data.qpos[3:].reshape(-1, 7)[:, :2].copy()
    return elapsed, xy


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


def best_of(f, runs: int = 3) -> float:
    """Best of ``runs`` wall-clock seconds of ``f()`` (this machine is shared)."""
    best = np.inf
    for _ in range(runs):
        start = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - start)
    return best


def numba_times(
    motion: upm.PlateMotion, pos: np.ndarray, steps: int, dt: float, cores: int, ours: np.ndarray
) -> tuple[float, float]:
    """ns per part-step of the Numba peer: serial on one thread and blocked on ``cores``, on the
    plate velocity table upm uses; each checked against upm's final positions ``ours``."""
    u = motion.velocity((np.arange(1, steps + 1) - 1e-6) * dt)
    slide, hold = MU * G * dt, MU_S * G * dt
    out = []
    for loop in (numba_peer.serial, numba_peer.blocked):
        numba_peer.run(loop, u[:2], pos[:64], slide, hold, dt)  # compile outside the timing
        numba.set_num_threads(1 if loop is numba_peer.serial else cores)
        out.append(
            best_of(lambda loop=loop: numba_peer.run(loop, u, pos, slide, hold, dt))
            * 1e9
            / (len(pos) * steps)
        )
        diff = np.abs(numba_peer.run(loop, u, pos, slide, hold, dt) - ours).max()
        assert diff < 1e-12, f"the Numba peer must reproduce upm's trajectory; differs by {diff:.1e}"
    return out[0], out[1]


def per_call(motion: upm.PlateMotion, dt: float) -> None:
    """The fixed cost of a call: 2-step calls on 1e6 parts at rest, per part, on one thread and on
    every core, beside NumPy allocating and writing the same result arrays (the floor of any
    call that returns them in fresh memory)."""
    n = 1_000_000
    pos = np.random.default_rng(4).uniform(-0.1, 0.1, (n, 2))
    kw = dict(duration=2 * dt, dt=dt, mu=MU, mu_s=MU_S, record_every=2)
    ours = {
        th: best_of(lambda th=th: upm.simulate(motion, pos, threads=th, **kw), 5) * 1e9 / n for th in (1, 2)
    }

    def write() -> None:
        for a in (np.empty((2, n, 2)), np.empty((2, n, 2)), np.empty((2, n), bool)):
            a.fill(1)

    floor = best_of(write, 5) * 1e9 / n
    print(f"\na 2-step call on {n:,} parts: {ours[1]:.1f} ns per part on 1 thread, {ours[2]:.1f} on 2")
    print(f"  numpy writing the same positions, velocities and stuck flags: {floor:.1f} ns per part")


def small_calls(motion: upm.PlateMotion, dt: float) -> None:
    """The whole cost of a small call, as a control loop or a planner makes many: 8 parts, 100
    steps, from Python (arguments checked, result built), on every core and on one thread."""
    pos = np.random.default_rng(5).uniform(-0.1, 0.1, (8, 2))
    out, calls = [], 500
    for th in (None, 1):
        kw = dict(duration=100 * dt, dt=dt, mu=MU, mu_s=MU_S, record_every=100, threads=th)

        def many(kw=kw) -> None:
            for _ in range(calls):
                upm.simulate(motion, pos, **kw)

        many()
        out.append(best_of(many, 5) * 1e6 / calls)
    print(f"\na call of 8 parts x 100 steps: {out[0]:.0f} us on every core, {out[1]:.0f} us on one thread")


def batch_times(quick: bool) -> None:
    """Batches of small worlds (the predictive planner's rollouts: enveloped jets, 8 parts each)
    against one world of as many parts on the first of those motions, per part-step on every
    core; then worlds of 1 to 256 parts on one thread (up to 32 points a world run side by side,
    eight worlds to a vector, larger worlds one by one)."""
    rng = np.random.default_rng(6)
    dt, duration = 1 / (24 * 100), 0.35
    steps = round(duration / dt)
    kw = dict(duration=duration, dt=dt, mu=MU, record_every=2**40)

    def ratio(b: int, m: int, **more: Any) -> tuple[float, float]:
        pulses = [
            upm.Pulse.jet(tuple(rng.uniform(-0.1, 0.1, 2)), (0.6, 0.8), 0.06, 0.3, 50.0, 0.12, 0.11, 0.12)
            for _ in range(b)
        ]
        motions = [p.motion(rest=False) for p in pulses]
        pos, one = rng.uniform(-0.1, 0.1, (m, 2)), rng.uniform(-0.1, 0.1, (b * m, 2))
        # (best of 15: a few ms each, and a shared machine's other work comes and goes)
        per = 1e9 / (b * m * steps)
        batch = best_of(lambda: upm.simulate_batch(motions, pos, **kw, **more), 15) * per
        world = best_of(lambda: upm.simulate(motions[0], one, **kw, **more), 15) * per
        return batch, world

    b, m = (100, 8) if quick else (500, 8)
    batch, world = ratio(b, m)
    print(f"\n{b} worlds x {m} parts (enveloped jets), every core: {batch:.2f} ns per part-step; one world of"
          f" {b * m} parts: {world:.2f}; the batch costs {batch / world:.2f}x")  # fmt: skip
    parts = 800 if quick else 4000
    cells = []
    for m in (1, 3, 8, 32, 64, 256):
        batch, world = ratio(parts // m, m, threads=1)
        cells.append(f"{parts // m} x {m}: {batch / world:.2f}x")
    print(f"  one thread, worlds x parts, against one world of as many: {'; '.join(cells)}")


def disk_times(dt: float, quick: bool) -> None:
    """Disks on a rotating plate, one thread: upm against the Numba port of the disk step as it
    stood when the speed issue was filed (``numba_peer.disks_serial``), both from rest on the
    same positions, the final positions checked against each other."""
    rot = upm.PlateMotion.rotation((0.03, -0.02), upm.Harmonics([0.5, -0.25], frequency=F))
    n, steps = (500, 500) if quick else (2000, 2000)
    radius = 0.005
    pos = np.random.default_rng(5).uniform(-0.1, 0.1, (n, 2))
    disks = [upm.Disk((x, y), radius=radius) for x, y in pos]
    kw = dict(duration=steps * dt, dt=dt, mu=MU, mu_s=MU_S, record_every=steps, threads=1)
    ns = 1e9 / (n * steps)
    ours = best_of(lambda: upm.simulate(rot, disks, **kw)) * ns
    print(
        f"\ndisks on a rotating plate, {n:,} disks x {steps} steps, 1 thread: upm {ours:.1f} ns per disk-step"
    )
    if not numba:
        print("  (no Numba peer: pip install 'upm[bench]')")
        return
    final = upm.simulate(rot, disks, **kw).positions[-1]
    u = rot.velocity((np.arange(1, steps + 1) - 1e-6) * dt)
    slide, hold = MU * G * dt, MU_S * G * dt
    numba.set_num_threads(1)
    numba_peer.run_disks(u[:2], pos[:8], radius, slide, hold, dt)  # compile outside the timing
    peer = best_of(lambda: numba_peer.run_disks(u, pos, radius, slide, hold, dt)) * ns
    diff = np.abs(numba_peer.run_disks(u, pos, radius, slide, hold, dt) - final).max()
    assert diff < 1e-9, f"the Numba disk peer must reproduce upm's trajectory; differs by {diff:.1e}"
    print(f"  Numba port of the step as the speed issue found it: {peer:.1f} ns, ratio {peer / ours:.1f}x"
          f" (final positions agree to {diff:.1e} m)")  # fmt: skip


def polygon_times(dt: float, quick: bool) -> None:
    """Hexagons (issue 27's shape for its cost target, 150 ns) on a rotating and a translating
    plate, one thread, spinning at the start, beside disks of the same size on the same motion;
    then on two of the PPOD's fields, whose rocking loads each part unevenly."""
    rot = upm.PlateMotion.rotation((0.03, -0.02), upm.Harmonics([0.5, -0.25], frequency=F))
    tra = upm.PlateMotion.translation(
        (0.6, 0.8), upm.TwoHarmonic(0.5, np.pi / 2, amplitude=0.03, frequency=F)
    )
    n, steps = (50, 200) if quick else (200, 1000)
    rng = np.random.default_rng(8)
    pos, angle, spin = rng.uniform(-0.1, 0.1, (n, 2)), rng.uniform(0, 1, n), rng.uniform(-5, 5, n)
    hexagons = [
        upm.Polygon.regular(6, 0.008, position=tuple(p), angle=a, spin=w)
        for p, a, w in zip(pos, angle, spin, strict=True)
    ]
    disks = [
        upm.Disk(tuple(p), radius=0.008, angle=a, spin=w) for p, a, w in zip(pos, angle, spin, strict=True)
    ]
    kw = dict(duration=steps * dt, dt=dt, mu=MU, mu_s=MU_S, record_every=1, threads=1)
    ns = 1e9 / (n * steps)
    print(f"\nhexagons, {n} parts x {steps} steps, 1 thread, ns per part-step:")
    for name, motion in (("rotating", rot), ("translating", tra)):
        run = upm.simulate(motion, hexagons, **kw)
        gon = best_of(lambda m=motion: upm.simulate(m, hexagons, **kw)) * ns
        disk = best_of(lambda m=motion: upm.simulate(m, disks, **kw)) * ns
        print(f"  {name} plate: hexagons {gon:.0f} (stuck {run.stuck.mean():.0%} of steps), disks {disk:.0f}")
    # the PPOD's fields rock the plate: the pressure varies across each part (docs/ppod.md)
    kw = dict(kw, duration=steps * 0.05 / 400, dt=0.05 / 400)
    for name in ("Sink", "Source"):
        field = upm.PlateMotion.ppod(name)
        gon = best_of(lambda m=field: upm.simulate(m, hexagons, **kw)) * ns
        print(f"  PPOD {name} (the pressure varies across each part): hexagons {gon:.0f}")


def spatial_times(quick: bool) -> None:
    """The lift-off step (a plate that moves out of its plane, docs/ppod.md) against the planar
    step on the same in-plane motion: a circular translation at 20 Hz alone, and with the PPOD
    Sink's rocking (the normal force varies over the plate, parts lift off at its corners)."""
    n, steps = (2_000, 2000) if quick else (20_000, 4000)
    pos = np.random.default_rng(7).uniform(-0.1, 0.1, (n, 2))
    planar = upm.PlateMotion.harmonic(20.0, x=[(1, 10.0, 0.0)], y=[(1, 10.0, np.pi / 2)])
    spatial = upm.PlateMotion.ppod("Sink")
    dt = 0.05 / 400
    kw = dict(duration=steps * dt, dt=dt, mu=MU, mu_s=MU_S, record_every=steps)
    ns = 1e9 / (n * steps)
    print(f"\nout-of-plane plate (the PPOD Sink), {n:,} parts x {steps} steps, ns per part-step:")
    for th in sorted({1, os.cpu_count() or 1}):
        flat = best_of(lambda th=th: upm.simulate(planar, pos, threads=th, **kw)) * ns
        lift = best_of(lambda th=th: upm.simulate(spatial, pos, threads=th, **kw)) * ns
        print(f"  {th} thread(s): planar {flat:.2f}, out of plane {lift:.2f}: {lift / flat:.2f}x planar")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="smaller problems")
    parser.add_argument("--mujoco", action="store_true", help="also run the MuJoCo peer (pip install mujoco)")
    args = parser.parse_args()
    motion = program()
    dt = 1 / F / 400
    rng = np.random.default_rng(3)
    info = upm.build_info()
    cores = os.cpu_count() or 1
    builds = ", ".join(info["available"])
    print(f"machine: {info['cpu']}, {cores} cores; upm's step: {info['simd']} (of {builds})")
    sizes = [(1_000, 20_000), (10_000, 2_000), (100_000, 1000), (1_000_000, 200)]
    if args.quick:
        sizes = [(1_000, 2000), (100_000, 100)]
    numpy_ns: dict[int, float] = {}
    rows = []
    for n, steps in sizes:
        pos = rng.uniform(-0.1, 0.1, (n, 2))
        kw = dict(duration=steps * dt, dt=dt, mu=MU, mu_s=MU_S, record_every=steps)
        ns = 1e9 / (n * steps)
        ours = {}
        for th in (1, cores):
            # (once before timing: a pool's fresh threads take a few calls to come up to speed)
            upm.simulate(motion, pos, threads=th, **kw)
            ours[th] = best_of(lambda th=th, pos=pos, kw=kw: upm.simulate(motion, pos, threads=th, **kw)) * ns
        run = upm.simulate(motion, pos, **kw)
        start = time.perf_counter()
        x, y, _, _ = numpy_reference(motion, pos, steps, dt)
        numpy_ns[n] = (time.perf_counter() - start) * ns
        diff = np.abs(run.positions[-1] - np.stack([x, y], 1)).max()
        assert diff < 1e-12, "the reference must reproduce upm's trajectory for the ratio to mean anything"
        peer = numba_times(motion, pos, steps, dt, cores, run.positions[-1]) if numba else None
        rows.append((n, steps, ours, peer, numpy_ns[n], diff))
    print("\nns per part-step (best of 3); ratio = peer / upm")
    many_t = f"{cores}t"
    head = f"{'parts':>9} {'steps':>6} | {'upm 1t':>7} {'numba':>7} {'ratio':>6} | {'upm ' + many_t:>7}"
    print(f"{head} {'numba ' + many_t:>9} {'ratio':>6} {'vs 1t':>6} | {'numpy':>7} {'ratio':>6}  max|diff|")
    for n, steps, ours, peer, t_np, diff in rows:
        one, many = ours[1], ours[cores]
        s1, sb = peer if peer else (np.nan, np.nan)
        serial = f"{one:>7.2f} {s1:>7.2f} {s1 / one:>5.2f}x"
        threaded = f"{many:>7.2f} {sb:>9.2f} {sb / many:>5.2f}x {one / many:>5.2f}x"
        print(f"{n:>9,} {steps:>6} | {serial} | {threaded} | {t_np:>7.2f} {t_np / one:>5.1f}x  {diff:.1e}")
    if not numba:
        print("(no Numba peer: pip install 'upm[bench]')")
    per_call(motion, dt)
    small_calls(motion, dt)
    batch_times(quick=args.quick)
    disk_times(dt, quick=args.quick)
    polygon_times(dt, quick=args.quick)
    spatial_times(quick=args.quick)

    recording(motion, dt, rng, quick=args.quick)

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
