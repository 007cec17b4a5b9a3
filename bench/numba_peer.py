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
            # without branches (`|`, `&` and a select over a guarded division), so that LLVM
            # vectorises the loop over parts: `or`/`and` made it branchy and scalar (2.6x slower)
            st = (wn <= slide) | (stuck[i] & (wn <= hold))
            q = 1.0 - slide / max(wn, 1e-300)
            keep = 0.0 if st else q
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


# -- disks -------------------------------------------------------------------------------------
# The disk step as it stood when the speed issue was filed (`git show 2ea4fb0:crates/upm-core/src/
# disk.rs`), written out in Numba: the limit curve (force, torque) tabulated over the angle
# phi = atan2(R |W|, |w|) and interpolated by Catmull-Rom; the stick test between the chord and
# the curve by Brent's method on the curve's polar angle; sliding by the fixed point
# phi <- atan2(b(phi), a(phi)), with Brent's method where it does not converge. The table's
# values come from upm's quadrature (`_core.disk_friction`), so both sides use the same curve.

DISK_TABLE = 8193


def disk_table() -> np.ndarray:
    """``(f, t)`` at ``DISK_TABLE`` evenly spread ``phi`` in ``[0, pi/2]``, ``(DISK_TABLE, 2)``."""
    from upm import _core

    f, t = _core.disk_friction(np.linspace(0.0, np.pi / 2, DISK_TABLE))
    return np.ascontiguousarray(np.stack([f, t], 1))


@njit(cache=True)
def _curve(tab, phi):  # pragma: no cover - compiled
    n = tab.shape[0]
    u = min(max(phi, 0.0), np.pi / 2) / (np.pi / 2) * (n - 1)
    i = min(int(np.floor(u)), n - 2)
    s = u - i
    out = np.empty(2)
    for c in range(2):
        a = tab[max(i - 1, 0), c]
        b = tab[i, c]
        cc = tab[i + 1, c]
        d = tab[min(i + 2, n - 1), c]
        out[c] = b + 0.5 * s * (
            cc - a + s * (2.0 * a - 5.0 * b + 4.0 * cc - d + s * (3.0 * (b - cc) + d - a))
        )
    return out[0], out[1]


@njit(cache=True)
def _residual(kind, p, tab, x0, x1, x2):  # pragma: no cover - compiled
    f, t = _curve(tab, p)
    if kind == 0:  # the curve's polar angle against psi = x0
        return np.arctan2(t, f) - x0
    a = x0 - x2 * f  # sliding: phi against the angle of (a(phi), b(phi)); x0 = a0, x1 = b0, x2 = c
    b = x1 - 2.0 * x2 * t
    return p - np.arctan2(b, a)


@njit(cache=True)
def _brent(kind, tab, x0, x1, x2, a, b, tol):  # pragma: no cover - compiled
    fa = _residual(kind, a, tab, x0, x1, x2)
    fb = _residual(kind, b, tab, x0, x1, x2)
    if fa == 0.0:
        return a
    if fb == 0.0:
        return b
    c, fc = a, fa
    d = b - a
    e = d
    for _ in range(400):
        if (fb > 0.0) == (fc > 0.0):
            c, fc = a, fa
            d = b - a
            e = d
        if abs(fc) < abs(fb):
            a, b, c = b, c, b
            fa, fb, fc = fb, fc, fb
        tol1 = 2.0 * 2.220446049250313e-16 * abs(b) + 0.5 * tol
        xm = 0.5 * (c - b)
        if abs(xm) <= tol1 or fb == 0.0:
            return b
        if abs(e) >= tol1 and abs(fa) > abs(fb):
            s = fb / fa
            if a == c:
                p = 2.0 * xm * s
                q = 1.0 - s
            else:
                qa = fa / fc
                r = fb / fc
                p = s * (2.0 * xm * qa * (qa - r) - (b - a) * (r - 1.0))
                q = (qa - 1.0) * (r - 1.0) * (s - 1.0)
            if p > 0.0:
                q = -q
            p = abs(p)
            if 2.0 * p < min(3.0 * xm * q - abs(tol1 * q), abs(e * q)):
                e = d
                d = p / q
            else:
                d = xm
                e = d
        else:
            d = xm
            e = d
        a, fa = b, fb
        b += d if abs(d) > tol1 else (tol1 if xm > 0 else -tol1)
        fb = _residual(kind, b, tab, x0, x1, x2)
    return b


@njit(cache=True)
def _disk_step(tab, wx, wy, s_free, slide, hold, was_stuck):  # pragma: no cover - compiled
    """(w'x, w'y, R W', stuck) of one implicit step (see the block comment above)."""
    a0 = np.hypot(wx, wy)
    b0 = abs(s_free)
    if a0 == 0.0 and b0 == 0.0:
        return 0.0, 0.0, 0.0, True
    c = hold if was_stuck else slide
    na = a0 / c
    nb = 0.5 * b0 / c
    if na <= 1.0 and nb <= 2.0 / 3.0:
        if na + 1.5 * nb <= 1.0:
            return 0.0, 0.0, 0.0, True
        phi = _brent(0, tab, np.arctan2(nb, na), 0.0, 0.0, 0.0, np.pi / 2, 1e-15)
        f, t = _curve(tab, phi)
        if na * na + nb * nb <= f * f + t * t:
            return 0.0, 0.0, 0.0, True
    if b0 == 0.0:
        a, b = a0 - slide, 0.0
    elif a0 == 0.0:
        a, b = 0.0, b0 - 4.0 / 3.0 * slide
    else:
        phi = np.arctan2(b0, a0)
        converged = False
        for _ in range(30):
            f, t = _curve(tab, phi)
            nxt = np.arctan2(b0 - 2.0 * slide * t, a0 - slide * f)
            if not (0.0 <= nxt <= np.pi / 2):
                break
            if abs(nxt - phi) <= 1e-15:
                phi = nxt
                converged = True
                break
            phi = nxt
        if not converged:
            phi = _brent(1, tab, a0, b0, slide, 0.0, np.pi / 2, 1e-15)
        f, t = _curve(tab, phi)
        a, b = a0 - slide * f, b0 - 2.0 * slide * t
    a, b = max(a, 0.0), max(b, 0.0)
    scale = a / a0 if a0 > 0.0 else 0.0
    return wx * scale, wy * scale, np.copysign(b, s_free), False


@njit(error_model="numpy", cache=True)
def disks_serial(u, tab, x, y, vx, vy, spin, stuck, radius, slide, hold, dt):  # pragma: no cover - compiled
    """Disks (resting or moving) through the plate velocities ``u`` (steps, 3), one thread."""
    n = x.shape[0]
    for k in range(u.shape[0]):
        u1, u2, u3 = u[k, 0], u[k, 1], u[k, 2]
        for i in range(n):
            sx = u1 - u3 * y[i]
            sy = u2 + u3 * x[i]
            wx, wy, s, st = _disk_step(
                tab, vx[i] - sx, vy[i] - sy, radius * (spin[i] - u3), slide, hold, stuck[i]
            )
            nvx, nvy = sx + wx, sy + wy
            nspin = u3 + s / radius
            x[i] += 0.5 * (vx[i] + nvx) * dt
            y[i] += 0.5 * (vy[i] + nvy) * dt
            vx[i], vy[i], spin[i], stuck[i] = nvx, nvy, nspin, st


def run_disks(
    u: np.ndarray, pos: np.ndarray, radius: float, slide: float, hold: float, dt: float
) -> np.ndarray:
    """Disks at rest at ``pos`` advanced through ``u`` by :func:`disks_serial`; final positions."""
    x, y = pos[:, 0].copy(), pos[:, 1].copy()
    vx, vy, spin = np.zeros_like(x), np.zeros_like(x), np.zeros_like(x)
    stuck = np.zeros(x.shape, dtype=np.bool_)
    disks_serial(u, disk_table(), x, y, vx, vy, spin, stuck, radius, slide, hold, dt)
    return np.stack([x, y], 1)
