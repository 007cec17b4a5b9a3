"""Benchmark: batched rotation solves, upm versus numpy.linalg over the stack.

Run with ``make bench`` (or ``python bench/solvers.py [--quick]``). Both sides solve the same
``B`` systems (4.10) of ``M = 10`` parts and ``N = 24`` centres (20 x 24, minimum-norm):

* ours: ``upm.solve_rotations_batch`` (assembly, SVD, rank and condition number in Rust, rayon);
* NumPy, vectorised: assemble every matrix with broadcasting, then ``numpy.linalg.pinv`` over the
  stack (batched LAPACK SVD) and a batched product;
* NumPy, per system: ``numpy.linalg.lstsq`` in a Python loop (timed on a subset).

The script checks that all three agree before printing ratios, then times one call of
``upm.solve_rotations`` for 2 parts and 9 centres from Python (target: under 20 microseconds).
"""

from __future__ import annotations

import argparse
import os
import timeit

import numpy as np

import upm


def assemble(parts: np.ndarray, centers: np.ndarray) -> np.ndarray:
    """(B, 2M, N) matrices of (4.10), vectorised."""
    d = parts[:, :, None, :] - centers[None, None, :, :]
    r = np.hypot(d[..., 0], d[..., 1])
    return np.concatenate([-d[..., 1] / r, d[..., 0] / r], axis=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="a smaller batch (for smoke tests)")
    args = parser.parse_args()
    b = 1_000 if args.quick else 10_000
    m, n = 10, 24
    rng = np.random.default_rng(0)
    parts = rng.uniform(-0.1, 0.1, (b, m, 2))
    forces = rng.normal(0.0, 0.01, (b, m, 2))
    centers = upm.ring_centers(n, 0.25)
    mu_m_g = 0.1

    def ours() -> np.ndarray:
        return upm.solve_rotations_batch(parts, forces, centers, mu_m_g=mu_m_g).strengths

    def numpy_pinv() -> np.ndarray:
        a = assemble(parts, centers)
        rhs = (n / mu_m_g) * np.concatenate([forces[..., 0], forces[..., 1]], axis=1)
        return np.einsum("bij,bj->bi", np.linalg.pinv(a, rcond=np.finfo(float).eps * n), rhs)

    subset = max(b // 10, 100)

    def numpy_lstsq() -> np.ndarray:
        a = assemble(parts[:subset], centers)
        rhs = (n / mu_m_g) * np.concatenate([forces[:subset, :, 0], forces[:subset, :, 1]], axis=1)
        return np.stack([np.linalg.lstsq(a[i], rhs[i], rcond=None)[0] for i in range(subset)])

    k_ours, k_pinv, k_lstsq = ours(), numpy_pinv(), numpy_lstsq()
    # Random layouts are often ill-conditioned (parts near a centre or each other): both sides are
    # backward stable, so they agree to about condition number x eps.
    cond = upm.solve_rotations_batch(parts, forces, centers, mu_m_g=mu_m_g).condition_number
    bound = 1e-14 * cond + 1e-12
    scale = np.abs(k_pinv).max(axis=1)
    assert np.all(np.abs(k_ours - k_pinv).max(axis=1) <= bound * scale)
    assert np.all(np.abs(k_ours[:subset] - k_lstsq).max(axis=1) <= bound[:subset] * scale[:subset])

    def best(fn, repeat: int = 3) -> float:
        return min(timeit.repeat(fn, number=1, repeat=repeat))

    t_ours, t_pinv, t_lstsq = best(ours), best(numpy_pinv), best(numpy_lstsq) * b / subset
    threads = os.environ.get("RAYON_NUM_THREADS", str(os.cpu_count()))
    print(f"{b} systems of {2 * m} x {n} (M = {m} parts, N = {n} centres), {threads} threads; "
          f"median condition number {np.median(cond):.2g}; all agree to cond x 1e-14")  # fmt: skip
    print(f"  upm.solve_rotations_batch   {t_ours * 1e6 / b:8.2f} us/system")
    print(f"  numpy.linalg.pinv (stack)   {t_pinv * 1e6 / b:8.2f} us/system   ratio {t_pinv / t_ours:6.1f}x")
    print(
        f"  numpy.linalg.lstsq (loop)   {t_lstsq * 1e6 / b:8.2f} us/system   ratio {t_lstsq / t_ours:6.1f}x"
    )

    p2 = rng.uniform(-0.05, 0.05, (2, 2))
    f2 = rng.normal(0.0, 0.01, (2, 2))
    c9 = upm.ring_centers(9, 0.2)
    calls = 2_000 if args.quick else 20_000
    upm.solve_rotations(p2, f2, c9)
    single = min(timeit.repeat(lambda: upm.solve_rotations(p2, f2, c9), number=calls, repeat=3)) / calls

    def numpy_single() -> np.ndarray:
        a = assemble(p2[None], c9)[0]
        return np.linalg.lstsq(a, 9 * np.concatenate([f2[:, 0], f2[:, 1]]), rcond=None)[0]

    single_np = min(timeit.repeat(numpy_single, number=calls, repeat=3)) / calls
    print(f"one solve, 2 parts x 9 centres, from Python: {single * 1e6:.1f} us (target < 20 us); "
          f"numpy assemble + lstsq {single_np * 1e6:.1f} us, ratio {single_np / single:.1f}x")  # fmt: skip


if __name__ == "__main__":
    main()
