"""Whether a simulation's recorded result fits in memory, checked before anything runs (a failed
allocation in the extension would abort the process)."""

from __future__ import annotations

import math

from ._errors import ParameterError

__all__ = ["available_memory", "check_memory"]

#: Bytes a recorded part-state takes in the result: position and velocity (4 float64), stuck
#: (bool), angle and spin (2 float64).
RECORD_BYTES = 49
#: The run's peak memory over the result's size: the result is written once, in place, for a
#: single world and a batch alike (measured 0.68 for points, whose zero angles and spins are never
#: touched; about 1 plus the parts' state for disks).
PEAK_FACTOR = 1.25
#: Results whose peak stays below this many bytes are not checked against the available memory.
SMALL_RESULT = 16 << 20


def available_memory() -> int | None:
    """Bytes of memory this process can still use: the smaller of the machine's available memory
    (``MemAvailable``) and the address-space limit (``ulimit -v``); None if unknown."""
    limits = []
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    limits.append(int(line.split()[1]) * 1024)
    except (OSError, ValueError):
        pass
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft != resource.RLIM_INFINITY:
            limits.append(int(soft))
    except (ImportError, OSError, ValueError):
        pass
    return min(limits) if limits else None


def check_memory(worlds: int, parts: int, duration: float, dt: float, every: int) -> None:
    """`ParameterError` when the recorded result cannot fit in memory, before anything runs (a
    failed allocation in the extension would abort the process)."""
    steps = max(1, math.ceil(duration / dt - 1e-9))
    rows = steps // every + 1 + (steps % every != 0)
    need = float(worlds) * rows * max(parts, 1) * RECORD_BYTES
    if need * PEAK_FACTOR <= SMALL_RESULT:
        return  # no machine that runs Python misses this much (the planners make many such calls)
    have = available_memory()
    if have is not None and need * PEAK_FACTOR > 0.9 * have:
        raise ParameterError(
            f"record_every is too small for this machine's memory: the result would hold "
            f"{worlds} x {rows} x {parts} part-states ({need / 1e9:.3g} GB, about "
            f"{need * PEAK_FACTOR / 1e9:.3g} GB while it is assembled) but {have / 1e9:.3g} GB of memory is "
            f"available: raise record_every (now {every}), simulate fewer parts, or split the batch"
        )
