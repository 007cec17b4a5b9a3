"""The Numba peer of ``bench/integrator.py``: the exact implicit Coulomb step of docs/spec.md §1
as a user who knows Numba would write it by hand (``pip install 'upm[bench]'``).

Two loops over the same arrays and the same plate velocity table as upm:

* :func:`serial`: ``@njit(error_model="numpy")``, parts inside the time loop, one thread;
* :func:`blocked`: blocks of parts in ``prange`` (one thread each), the time loop inside each block
  so that a block's state stays in cache: Numba's best multi-threaded loop.

Both take the state arrays and advance them in place; the stick rule and the trapezoidal position
update are the integrator's, so the final states agree with upm's to rounding.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

BLOCK = 2048  # parts per prange block (best of 512, 2048 and 8192 on the Xeon)


@njit(error_model="numpy", fastmath=False, cache=True)
def serial(u, x, y, vx, vy, stuck, slide, hold, dt):  # pragma: no cover - compiled
    n = x.shape[0]
    for k in range(u.shape[0]):
        u1, u2, u3 = u[k, 0], u[k, 1], u[k, 2]
        for i in range(n):
            sx = u1 - u3 * y[i]
            sy = u2 + u3 * x[i]
            wx = vx[i] - sx
            wy = vy[i] - sy
            wn = np.sqrt(wx * wx + wy * wy)
            st = (wn <= slide) or (stuck[i] and wn <= hold)
            keep = 0.0 if st else 1.0 - slide / wn
            nvx = sx + wx * keep
            nvy = sy + wy * keep
            x[i] += 0.5 * (vx[i] + nvx) * dt
            y[i] += 0.5 * (vy[i] + nvy) * dt
            vx[i] = nvx
            vy[i] = nvy
            stuck[i] = st


@njit(error_model="numpy", fastmath=False, parallel=True, cache=True)
def blocked(u, x, y, vx, vy, stuck, slide, hold, dt):  # pragma: no cover - compiled
    n = x.shape[0]
    blocks = (n + BLOCK - 1) // BLOCK
    for b in prange(blocks):
        lo = b * BLOCK
        hi = min(n, lo + BLOCK)
        serial(u, x[lo:hi], y[lo:hi], vx[lo:hi], vy[lo:hi], stuck[lo:hi], slide, hold, dt)


def run(loop, u: np.ndarray, pos: np.ndarray, slide: float, hold: float, dt: float) -> np.ndarray:
    """Parts at rest at ``pos`` advanced through the plate velocities ``u`` (steps, 3) by ``loop``;
    returns their final positions (N, 2)."""
    x, y = pos[:, 0].copy(), pos[:, 1].copy()
    vx, vy = np.zeros_like(x), np.zeros_like(x)
    stuck = np.ones(x.shape, dtype=np.bool_)
    loop(u, x, y, vx, vy, stuck, slide, hold, dt)
    return np.stack([x, y], 1)
