"""The predictive planner's look-ahead: a candidate scored as the first of two pulses.

* :func:`two_step`: followed by the best long pulse of the planner's displacement tables
  (:class:`~upm.plan.macros.MacroTable`);
* :func:`pair_rates`: followed by the best of the one-step favourites, predicted from where the
  first pulse leaves the parts.

A first pulse that leaves a part in the edge band scores ``-inf`` in both: a prediction error
there, over the pulse that follows, loses a part.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._errors import ParameterError
from ..plate.pulses import Pulse
from .penalties import in_band

FloatArray = NDArray[np.float64]


def pair_sizes(pairs: Any) -> tuple[int, int]:
    """``PredictivePlanner(pairs=)`` checked: first pulses, second pulses."""
    ok = isinstance(pairs, (tuple, list)) and len(pairs) == 2
    ok = ok and all(isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n >= 1 for n in pairs)
    if not ok:
        raise ParameterError(
            f"pairs must be None or two integers >= 1 (first pulses, second pulses); got {pairs!r}"
        )
    return int(pairs[0]), int(pairs[1])


def _in_band(planner: Any, q: FloatArray) -> NDArray[np.bool_]:
    return in_band(q, planner.limits.size / 2, planner.edge)


def two_step(
    planner: Any,
    task: Any,
    state: Any,
    pos: FloatArray,
    final: FloatArray,
    durations: FloatArray,
    among: NDArray[np.int64] | None = None,
) -> FloatArray:
    """Gain per second of each candidate of ``planner`` (leaving the parts at ``final (K, M, 2)``
    after ``durations (K,)``; ``among`` them only: the others ``-inf``) followed by the best long
    pulse (its table)."""
    macros = planner.macros
    if macros is None:
        return np.full(len(final), -np.inf)
    if among is not None:
        out_all = np.full(len(final), -np.inf)
        out_all[among] = two_step(planner, task, state, pos, final[among], durations[among])
        return out_all
    safe = np.where(np.isfinite(final), final, pos)
    after = macros.apply(safe)  # (K, R, M, 2)
    total = durations[:, None] + macros.durations[None, :]
    still = np.broadcast_to(pos, after.shape)
    flat = (-1, *pos.shape)
    # resting: the same layout throughout (its penalty once), only the time differs
    rest = np.asarray(task.cost(state, still, total), dtype=float)
    rest = rest + planner._penalty(pos[None], overlaps=False)[0]
    cost = np.asarray(task.cost(state, after, total), dtype=float)
    # each first pulse's layout is where its R long pulses start
    cost = cost + planner._penalty(after.reshape(flat), overlaps=False, start=safe).reshape(total.shape)
    lost = ~np.all(np.isfinite(final), axis=(1, 2)) | _in_band(planner, final)
    out: FloatArray = np.max((rest - cost) / total, axis=1)
    out[lost] = -np.inf
    return out


def pair_rates(
    planner: Any,
    task: Any,
    state: Any,
    pos: FloatArray,
    second: Sequence[Pulse],
    second_time: FloatArray,
    final: FloatArray,
    durations: FloatArray,
    gain_of: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Gain per second (and gain [m]) of each of ``F`` first pulses (leaving the parts at
    ``final (F, M, 2)`` after ``durations (F,)``) followed by the best of the ``second``
    pulses (plate times ``second_time`` as from the present layout), predicted by ``planner`` from
    there (point parts do not interact, so all the first pulses' layouts ride in one world; each
    part's step scaled by its learnt gain ``gain_of``)."""
    f, m = final.shape[:2]
    after, _ = planner.predict(second, final.reshape(-1, 2))
    after = after.reshape(len(second), f, m, 2).transpose(1, 0, 2, 3)  # (F, S, M, 2)
    base = final[:, None]
    after = base + gain_of[None, None, :, None] * (after - base)
    total = durations[:, None] + second_time[None, :]
    still = np.broadcast_to(pos, after.shape)
    rest = np.asarray(task.cost(state, still, total), dtype=float) + planner._penalty(pos[None])[0]
    safe = np.where(np.isfinite(after), after, still)
    cost = np.asarray(task.cost(state, safe, total), dtype=float)
    cost = cost + planner._penalty(after.reshape(-1, m, 2), start=final).reshape(total.shape)
    per_second = (rest - cost) / total
    pick = np.argmax(per_second, axis=1)
    rows = np.arange(f)
    out: FloatArray = per_second[rows, pick]
    won: FloatArray = (rest - cost)[rows, pick]
    out[_in_band(planner, final)] = -np.inf
    return out, won
