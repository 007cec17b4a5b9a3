"""The predictive planner's online friction fit: the factor on its friction estimate that best
explains the last pulse, from a handful of predictions (:class:`~upm.plan.PredictivePlanner`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["FACTORS", "best_factor", "learn", "restarted"]

FACTORS = np.array([0.7, 0.8, 0.9, 1.0, 1.1, 1.25, 1.4])
"""Factors on the friction estimate the last pulse is predicted again with."""


def best_factor(factors: NDArray[np.float64], err: NDArray[np.float64]) -> float:
    """The factor of least ``err`` (one value per factor), refined between its neighbours by the
    vertex of the parabola through the three in log factor (kept within them)."""
    best = int(np.argmin(err))
    f = float(factors[best])
    if 0 < best < len(factors) - 1:
        y0, y1, y2 = err[best - 1], err[best], err[best + 1]
        x0, x1, x2 = np.log(factors[best - 1 : best + 2])
        den = (x0 - x1) * (x0 - x2) * (x1 - x2)
        if den != 0:
            aa = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / den
            bb = (x2**2 * (y0 - y1) + x1**2 * (y2 - y0) + x0**2 * (y1 - y2)) / den
            if aa > 0:
                f = float(np.exp(np.clip(-bb / (2 * aa), x0, x2)))
    return f


def restarted(last: tuple[Any, ...], ids: NDArray[np.int64], pos: NDArray[np.float64]) -> tuple[Any, ...]:
    """A pulse's record (the pulse, its parts' ids, where they started, where they were predicted
    to end) with each part's predicted step restarted where it is seen now (parts ``ids`` at
    ``pos``; parts not seen keep theirs). A plan made ahead starts from where the parts were
    predicted to be: kept, :func:`learn` then sees the pulse's own error, not the last
    prediction's as well."""
    pulse, last_ids, start, final = last
    index = {int(i): k for k, i in enumerate(ids)}
    now = np.array(start, dtype=np.float64, copy=True)
    for k, i in enumerate(last_ids):
        if int(i) in index:
            now[k] = pos[index[int(i)]]
    return pulse, last_ids, now, now + (final - start)


def learn(planner: Any, last: tuple[Any, ...], ids: NDArray[np.int64], pos: NDArray[np.float64]) -> None:
    """What the predictive ``planner`` learns from its ``last`` pulse (the pulse, its parts' ids,
    where they started and where they were predicted to end), its parts ``ids`` seen now at
    ``pos``: every step's prediction error (``planner.step_errors``); the friction factor that best
    explains the pulse (:data:`FACTORS`, :func:`best_factor`), moved part way
    (``planner.mu_estimate``, the look-ahead's tables refreshed); and a per-part gain on the
    predicted step (``planner.gains``)."""
    pulse, last_ids, start, predicted = last
    index = {int(i): k for k, i in enumerate(ids)}
    rows = [(k, index[int(i)]) for k, i in enumerate(last_ids) if int(i) in index]
    if not rows:
        return
    a, b = np.array(rows).T
    achieved = pos[b] - start[a]
    guessed = predicted[a] - start[a]
    ok = np.all(np.isfinite(achieved), axis=1) & np.all(np.isfinite(guessed), axis=1)
    if not ok.any():
        return
    planner.step_errors += [float(e) for e in np.hypot(*(achieved[ok] - guessed[ok]).T)]
    if not planner.adapt:
        return
    # only steps well clear of vision noise and of a neighbour's nudge inform the friction:
    # parts predicted to move more than 1 cm that also did
    big = (np.hypot(*guessed.T) > 0.01) & (np.hypot(*achieved.T) > 0.005)
    moved = ok & big
    if moved.sum() >= 2:
        # friction: the value among a few that best explains this pulse (parts replicated, one
        # friction each: point parts do not interact), moved half way in log
        factors = FACTORS
        m = int(moved.sum())
        starts = np.tile(start[a][moved], (len(factors), 1))
        mus = np.repeat(planner.mu_estimate * factors, m)
        final, _ = planner.predict([pulse], starts, mu=mus)
        miss = np.hypot(
            *(final[0].reshape(len(factors), m, 2) - (start[a][moved] + achieved[moved])[None]).transpose(
                2, 0, 1
            )
        )
        # a parabola through the best and its neighbours for a value between the factors
        f = best_factor(factors, np.nansum(miss**2, axis=1))
        # damped, and trusted only where the pulse moved the parts well clear of noise
        weight = 0.5 if float(np.median(np.hypot(*achieved[moved].T))) > 0.02 else 0.25
        planner.mu_estimate = float(np.clip(planner.mu_estimate * f**weight, 0.05, 1.5))
        if planner.macros is not None:
            planner.macros.refresh(planner.mu_estimate)
        if planner.learn_tilt:
            fit_tilt(planner, pulse, start[a][moved], (start[a] + achieved)[moved])
    for k, r in zip(np.nonzero(ok)[0], a[ok], strict=True):
        g2 = float(guessed[k] @ guessed[k])
        if g2 < (8e-3) ** 2:
            continue
        ratio = float(np.clip(achieved[k] @ guessed[k] / g2, 0.5, 1.5))
        pid = int(last_ids[r])
        old = planner.gains.get(pid, 1.0)
        planner.gains[pid] = float(np.clip(0.7 * old + 0.3 * ratio * old, 0.6, 1.6))


#: The slope step [rad] of :func:`fit_tilt`'s finite differences, the most it moves the estimate
#: in one pulse, and the steepest slope it believes.
TILT_STEP, TILT_MOVE, TILT_MAX = math.radians(0.1), math.radians(0.25), math.radians(3.0)


def fit_tilt(planner: Any, pulse: Any, start: NDArray[np.float64], seen: NDArray[np.float64]) -> None:
    """Move ``planner.tilt_estimate`` toward the slope that best explains where the pulse left the
    parts (``start`` and ``seen`` (m, 2), parts that moved well clear of noise): the drift common
    to them that the friction does not explain. The prediction's change with each slope component
    (finite differences of :data:`TILT_STEP`) gives a linear least-squares step, taken a quarter
    of the way and at most :data:`TILT_MOVE`, the estimate kept within :data:`TILT_MAX`."""
    base = planner.tilt_estimate
    trials = (base, (base[0] + TILT_STEP, base[1]), (base[0], base[1] + TILT_STEP))
    finals = np.stack([planner.predict([pulse], start, tilt=t)[0][0] for t in trials])  # (3, m, 2)
    if not np.all(np.isfinite(finals)):
        return
    jac = np.stack([finals[1] - finals[0], finals[2] - finals[0]], axis=-1) / TILT_STEP  # (m, 2, 2)
    if not np.any(jac):
        return
    step = np.linalg.lstsq(jac.reshape(-1, 2), (seen - finals[0]).reshape(-1), rcond=None)[0]
    step = 0.25 * step
    size = float(np.hypot(*step))
    if size > TILT_MOVE:
        step *= TILT_MOVE / size
    new = np.clip(np.asarray(base) + step, -TILT_MAX, TILT_MAX)
    planner.tilt_estimate = (float(new[0]), float(new[1]))
