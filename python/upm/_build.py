"""What this installation runs on: :func:`build_info`."""

from __future__ import annotations

import os
import platform
from typing import Any

from . import _core


def cpu_model() -> str:
    """The CPU's model name (from ``/proc/cpuinfo`` on Linux; else what :mod:`platform` says)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def build_info() -> dict[str, Any]:
    """How upm runs on this machine, for bug reports and benchmark figures.

    Returns a dict with ``version``; ``simd``, the build of the point-part step chosen at run time
    (``"avx512"``, ``"avx2"`` or ``"portable"``; the environment variable ``UPM_SIMD`` picks
    another the CPU has); ``available``, the builds this CPU can run; ``cpu``, its model name;
    ``cores``; and ``machine``, the architecture.
    """
    chosen, available = _core.simd_info()
    return {
        "version": _core.__version__,
        "simd": chosen,
        "available": available,
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
        "machine": platform.machine(),
    }
