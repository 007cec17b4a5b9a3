"""Benchmark: exact feed rates and force tables, upm versus a vectorised NumPy reference.

Run with ``make bench`` (or ``python bench/theory.py [--quick]``). Both sides run in this one
process on the same inputs; the NumPy side is a straightforward vectorised implementation of the
same rigorous root-based method (bound-guarded subdivision of a grid to isolate every sign change,
vectorised Newton-bisection to refine them, bisection on the level for the median). A plain fixed
grid cannot reach 1e-9: near the force peaks of Theorem 1 the roots come in pairs closer than any
affordable grid spacing. The script checks that
both agree to 1e-9 before it prints the ratio.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable

import numpy as np

import upm

TAU = 2.0 * np.pi


def _timed(fn: Callable[[], np.ndarray], repeat: int = 3) -> tuple[float, np.ndarray]:
    best, out = np.inf, None
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
    assert out is not None
    return best, out


def _eval(c: np.ndarray, d: np.ndarray, x: np.ndarray, level: np.ndarray) -> tuple[np.ndarray, ...]:
    """v - level, v', v'' of harmonic rows ``c, d`` (n, K) at points ``x`` (n,)."""
    k = np.arange(1, c.shape[1] + 1)
    kx = k * x[:, None]
    cos, sin = np.cos(kx), np.sin(kx)
    even, odd = c * cos + d * sin, d * cos - c * sin
    return even.sum(1) - level, (k * odd).sum(1), -(k * k * even).sum(1)


def _mean_sign_numpy(c: np.ndarray, d: np.ndarray, level: np.ndarray, grid: int) -> np.ndarray:
    """Mean of sgn(v(t) - level) over [0, 2 pi) for rows of harmonic coefficients (B, K).

    The same rigorous method as upm, vectorised over every cell of every row: a cell is settled
    when a Lipschitz bound proves it has no root, or a bound on v'' proves v monotone; other cells
    are halved. Settled one-root cells are refined together by Newton-bisection.
    """
    n, kmax = c.shape
    k = np.arange(1, kmax + 1)
    amp = np.hypot(c, d)
    lip1, lip2 = (amp * k).sum(1), (amp * k * k).sum(1)
    total = np.zeros(n)
    rows = np.repeat(np.arange(n), grid)
    t0 = np.tile(TAU * np.arange(grid) / grid, n)
    t1 = np.tile(TAU * np.arange(1, grid + 1) / grid, n)
    f0, d0, _ = _eval(c[rows], d[rows], t0, level[rows])
    f1, d1, _ = _eval(c[rows], d[rows], t1, level[rows])
    roots = []
    while rows.size:
        h = t1 - t0
        change = (f0 >= 0) != (f1 >= 0)
        monotone = (d0 * d1 > 0) & (np.abs(d0) + np.abs(d1) > lip2[rows] * h)
        no_root = ~change & (monotone | (np.abs(f0) + np.abs(f1) > lip1[rows] * h))
        tiny = h < 1e-11
        np.add.at(
            total, rows[no_root | (tiny & ~change)], np.where(f0 >= 0, h, -h)[no_root | (tiny & ~change)]
        )
        one = change & (monotone | tiny)
        roots.append((rows[one], t0[one], t1[one], f0[one]))
        split = ~(no_root | one | tiny)
        r, a, b, fa, da, fb, db = (x[split] for x in (rows, t0, t1, f0, d0, f1, d1))
        m = 0.5 * (a + b)
        fm, dm, _ = _eval(c[r], d[r], m, level[r])
        rows = np.concatenate([r, r])
        t0, t1 = np.concatenate([a, m]), np.concatenate([m, b])
        f0, f1 = np.concatenate([fa, fm]), np.concatenate([fm, fb])
        d0, d1 = np.concatenate([da, dm]), np.concatenate([dm, db])
    r = np.concatenate([x[0] for x in roots])
    lo, hi = np.concatenate([x[1] for x in roots]), np.concatenate([x[2] for x in roots])
    flo = np.concatenate([x[3] for x in roots])
    left, right = lo.copy(), hi.copy()
    x = 0.5 * (lo + hi)
    for _ in range(100):
        f, df, _ = _eval(c[r], d[r], x, level[r])
        same = (f >= 0) == (flo >= 0)
        lo, hi = np.where(same, x, lo), np.where(same, hi, x)
        newton = x - f / np.where(df == 0, 1.0, df)
        x_new = np.where((newton > lo) & (newton < hi), newton, 0.5 * (lo + hi))
        done = np.all(np.abs(x_new - x) <= 4e-16 * np.maximum(1.0, np.abs(x)))
        x = x_new
        if done:
            break
    sign = np.where(flo >= 0, 1.0, -1.0)
    np.add.at(total, r, sign * (x - left) - sign * (right - x))
    return total / TAU


def force_table_numpy(n1: int, n2: int, psi: np.ndarray, grid: int, chunk: int = 20_000) -> np.ndarray:
    out = np.empty_like(psi)
    for i in range(0, psi.size, chunk):
        p = psi[i : i + chunk]
        c = np.zeros((p.size, n2))
        s = np.zeros((p.size, n2))
        c[:, n1 - 1] = 1.0
        c[:, n2 - 1] = -np.cos(n2 * p)
        s[:, n2 - 1] = -np.sin(n2 * p)
        out[i : i + chunk] = _mean_sign_numpy(c, s, np.zeros(p.size), grid)
    return out


def feed_rate_numpy(b: np.ndarray, phi: np.ndarray, grid: int, chunk: int = 5_000) -> np.ndarray:
    out = np.empty_like(b)
    for i in range(0, b.size, chunk):
        bb, pp = b[i : i + chunk], phi[i : i + chunk]
        c = np.stack([np.zeros_like(bb), bb * np.sin(pp)], 1)
        s = np.stack([np.ones_like(bb), bb * np.cos(pp)], 1)
        lo, hi = -(1 + np.abs(bb)), 1 + np.abs(bb)
        for _ in range(45):  # bisection on the level: the median halves the period
            mid = 0.5 * (lo + hi)
            above = _mean_sign_numpy(c, s, mid, grid) > 0
            lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
        out[i : i + chunk] = 0.5 * (lo + hi)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="10x smaller problems")
    args = parser.parse_args()
    scale = 10 if args.quick else 1
    rng = np.random.default_rng(1)
    print(f"machine: {os.cpu_count()} cores; RAYON_NUM_THREADS={os.environ.get('RAYON_NUM_THREADS', 'all')}")

    n_psi = 1_000_000 // scale
    psi = rng.uniform(0, TAU, n_psi)
    sub = n_psi // 10  # the peer runs on the first tenth: its time would dominate the run
    t_ours, ours = _timed(lambda: upm.force_table(2, 5, psi))
    t_np, ref = _timed(lambda: force_table_numpy(2, 5, psi[:sub], grid=40), repeat=1)
    err = np.abs(ours[:sub] - ref).max()
    exact = np.abs(ours - upm.theorem1_force(2, 5, psi)).max()
    r_ours, r_np = n_psi / t_ours, sub / t_np
    print(f"\nforce_table(2, 5, psi): upm over {n_psi:,} phases, numpy over the first {sub:,}")
    print(f"  upm   {t_ours:8.3f} s  {r_ours / 1e6:8.3f} M/s   max |upm - Theorem 1| = {exact:.1e}")
    print(f"  numpy {t_np:8.3f} s  {r_np / 1e6:8.3f} M/s   max |numpy - upm|      = {err:.1e}")
    print(f"  throughput ratio upm/numpy: {r_ours / r_np:.1f}x")
    assert err < 1e-9 and exact < 1e-9, "the two sides must agree to 1e-9 for the ratio to mean anything"

    n_pairs = 100_000 // scale
    b = rng.uniform(0, 2, n_pairs)
    phi = rng.uniform(-np.pi, np.pi, n_pairs)
    sub = n_pairs // 10
    t_ours, ours = _timed(lambda: upm.feed_rate(upm.TwoHarmonic(b, phi)))
    t_np, ref = _timed(lambda: feed_rate_numpy(b[:sub], phi[:sub], grid=16), repeat=1)
    err = np.abs(ours[:sub] - ref).max()
    r_ours, r_np = n_pairs / t_ours, sub / t_np
    small = np.abs(b) <= 0.5
    closed = np.abs(ours[small] - b[small] * np.sin(phi[small])).max()
    print(f"\nfeed_rate(TwoHarmonic(b, phi)): upm over {n_pairs:,} pairs, numpy over the first {sub:,}")
    print(f"  upm   {t_ours:8.3f} s  {r_ours / 1e3:8.1f} k/s   max |upm - (3.16)|, |b| <= 1/2 = {closed:.1e}")
    print(f"  numpy {t_np:8.3f} s  {r_np / 1e3:8.1f} k/s   max |numpy - upm|            = {err:.1e}")
    print(f"  throughput ratio upm/numpy: {r_ours / r_np:.1f}x")
    assert err < 1e-9 and closed < 1e-11, "the two sides must agree to 1e-9 for the ratio to mean anything"


if __name__ == "__main__":
    main()
