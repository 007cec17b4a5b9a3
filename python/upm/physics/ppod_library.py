"""The PPOD2 controller's library of plate motions (docs/spec.md §10): the data behind
``PlateMotion.ppod(name)`` and :data:`upm.PPOD_FIELDS`, in a module of its own so that
:mod:`~upm.physics.motion` builds them without importing the field computations of
:mod:`~upm.physics.ppod`."""

from __future__ import annotations

import math

__all__ = ["LIBRARY", "PPOD_FIELDS", "PPOD_SEQUENCES"]

_P = math.pi
_AXES = ("x", "y", "z", "rx", "ry", "rz")

# The PPOD2 controller's desired plate accelerations (SavedSignals_Pdd): per axis (amplitude,
# phase) of A sin(w t + p), period 0.05 s unless given (docs/spec.md §10).
_TABLE: dict[str, tuple[float, dict[str, tuple[float, float]]]] = {
    "Sink": (0.05, {"x": (10, 0), "y": (10, _P / 2), "rx": (70, 75 * _P / 64), "ry": (70, 107 * _P / 64)}),
    "Source": (0.05, {"x": (10, 0), "y": (10, _P / 2), "rx": (60, 11 * _P / 64), "ry": (60, 43 * _P / 64)}),
    "Whirlpool": (0.05, {"x": (8, 0), "y": (8, _P / 2), "rx": (56, 3 * _P / 2), "ry": (50, 0)}),
    "Centrifuge": (0.05, {"x": (7, 0), "y": (7, _P / 2), "rx": (70, _P / 2), "ry": (70, _P)}),
    "Saddle": (0.05, {"x": (10, 0), "y": (10, _P / 2), "rx": (70, 75 * _P / 64), "ry": (70, 43 * _P / 64)}),
    "Circle": (0.05, {"z": (7, _P / 2), "rz": (100, 0)}),
    "TransX": (0.05, {"x": (15, 0), "z": (5, 3 * _P / 2)}),
    "TransNegX": (0.05, {"x": (15, 0), "z": (5, _P / 2)}),
    "LineSinkX": (0.05, {"x": (15, 0), "ry": (100, 3 * _P / 2)}),
    "LineSourceX": (0.05, {"x": (15, 0), "ry": (100, _P / 2)}),
    "ShearX": (0.05, {"x": (10, 0), "rx": (70, 3 * _P / 2)}),
    "ShearY": (0.05, {"y": (10, 0), "ry": (90, _P / 2)}),
    "SqueezeTransY": (
        0.05,
        {"x": (10, 0), "y": (10, _P / 2), "z": (5, 3 * _P / 20), "ry": (100, 5 * _P / 3)},
    ),
    "VerticalBouncing": (1 / 38, {"z": (8, _P / 2)}),
}


def _turned(axes: dict[str, tuple[float, float]], quarter: int) -> dict[str, tuple[float, float]]:
    """The same motion turned by ``quarter * 90°`` about z: in-plane vectors and the rocking
    rates (about x, about y) turn alike; z and rz stay. Negative amplitudes become phases + pi."""
    out = dict(axes)
    for _ in range(quarter % 4):
        nxt = {k: v for k, v in out.items() if k in ("z", "rz")}
        for a, b in (("x", "y"), ("rx", "ry")):
            if b in out:  # new a = -old b
                amp, ph = out[b]
                nxt[a] = (amp, (ph + _P) % (2 * _P))
            if a in out:  # new b = old a
                nxt[b] = out[a]
        out = nxt
    return out


def _library() -> dict[str, tuple[float, dict[str, tuple[float, float]]]]:
    lib = dict(_TABLE)
    for name in ("TransX", "TransNegX", "LineSinkX", "LineSourceX"):
        period, axes = _TABLE[name]
        lib[name[:-1] + "Y"] = (period, _turned(axes, 1))  # x -> y
    lib["SqueezeTransX"] = (_TABLE["SqueezeTransY"][0], _turned(_TABLE["SqueezeTransY"][1], 3))
    return lib


LIBRARY = _library()
"""Every field: name -> (period [s], {axis: (amplitude, phase)})."""
PPOD_FIELDS: tuple[str, ...] = tuple(LIBRARY)
"""Names of the library's fields (SPEC §10's table, its Y variants turned by 90° about z, and
"SqueezeTransX", "SqueezeTransY" turned by -90°)."""

PPOD_SEQUENCES: dict[str, tuple[str, ...]] = {
    "square": ("Sink", "TransX", "TransNegY", "TransNegX", "TransY", "TransX", "TransNegY"),
    "sinkSource": ("Sink", "Source", "Whirlpool", "Centrifuge"),
}
"""The PPOD2 controller's sequences of library fields."""
