"""Benchmark: a 10^4-point feed-rate sweep with the exact integrator.

Run with ``make bench`` (or ``python bench/sweeps.py [--quick]``). The grid is 25 values of ``b``
x 20 of ``phi`` x 20 of ``gamma`` (2..20); every point simulates a part on the two-harmonic plate
until it settles (20 + 1.5 gamma periods at 400 steps per period) and measures its feed rate.
Printed:

* points per second with ``n_jobs=1`` and ``n_jobs=2`` and the scaling (target: at least 1.8x);
* the overhead per chunk: the sweep's wall time on one thread minus the same chunks computed
  back to back without it, per chunk, beside the work per chunk; and with a Zarr store;
* the peer: the loop a user would write, one ``upm.simulate`` call per point (on a subset),
  points per second and the ratio.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

import upm
from upm.experiments.sweeps import SCENARIOS, _plan, run_chunk


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="10^3 points (for smoke tests)")
    args = parser.parse_args()
    nb = 10 if args.quick else 25
    grid = {"b": np.linspace(0.1, 1.5, nb), "phi": np.linspace(0.2, 3.0, 10 if args.quick else 20),
            "gamma": np.linspace(2.0, 20.0, 10 if args.quick else 20)}  # fmt: skip
    n = int(np.prod([len(v) for v in grid.values()]))
    print(f"feed-rate sweep, exact integrator: {n} points, chunks of {SCENARIOS['feed_rate'].chunk}")

    upm.sweep("feed_rate", {"b": [0.5], "phi": [1.0], "gamma": [2.0]}, progress=False)  # imports, warm-up
    times = {}
    results = {}
    for jobs in (1, 2):
        start = time.perf_counter()
        results[jobs] = upm.sweep("feed_rate", grid, n_jobs=jobs, progress=False)
        times[jobs] = time.perf_counter() - start
        print(f"  n_jobs={jobs}: {times[jobs]:6.2f} s, {n / times[jobs]:8.0f} points/s")
    assert results[1].identical(results[2]), "1 and 2 threads must give identical results"
    print(f"  scaling 1 -> 2 threads: {times[1] / times[2]:.2f}x (target >= 1.8x)")

    plan, _ = _plan("feed_rate", grid, {}, None)
    chunks = list(plan.chunks())
    start = time.perf_counter()
    for _, region in chunks:
        run_chunk("feed_rate", plan.points(region), {})
    work = time.perf_counter() - start
    store = Path(tempfile.mkdtemp()) / "bench.zarr"
    start = time.perf_counter()
    upm.sweep("feed_rate", grid, n_jobs=1, progress=False, store=store)
    stored = time.perf_counter() - start
    shutil.rmtree(store.parent)
    k = len(chunks)
    print(
        f"  {k} chunks: work {work / k * 1e3:.1f} ms per chunk; overhead per chunk "
        f"{(times[1] - work) / k * 1e3:+.2f} ms in memory, "
        f"{(stored - work) / k * 1e3:+.2f} ms with a Zarr store"
    )

    subset = 100 if args.quick else 400
    rng = np.random.default_rng(0)
    pick = rng.choice(n, subset, replace=False)
    mesh = np.meshgrid(*grid.values(), indexing="ij")
    b, phi, gamma = (m.ravel()[pick] for m in mesh)
    start = time.perf_counter()
    for bi, pi, gi in zip(b, phi, gamma, strict=True):
        t = np.linspace(0, 2 * np.pi, 4096, endpoint=False)
        peak = np.abs(np.cos(t) + 2 * bi * np.cos(2 * t + pi)).max()
        a = gi * 0.3 * 9.81 / (2 * np.pi * 35.0 * peak)
        periods = 20 + int(np.ceil(1.5 * gi))
        motion = upm.PlateMotion.translation((1.0, 0.0), upm.TwoHarmonic(bi, pi, amplitude=a, frequency=35.0))
        upm.simulate(
            motion, [[0.0, 0.0]], duration=periods / 35.0, dt=1 / 35.0 / 400, mu=0.3, record_every=400
        )
    loop = (time.perf_counter() - start) / subset
    print(
        f"  peer, one upm.simulate per point (Python loop, {subset} points): {1 / loop:8.0f} points/s; "
        f"the sweep on 2 threads is {loop * n / times[2]:.1f}x faster"
    )


if __name__ == "__main__":
    main()
