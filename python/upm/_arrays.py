"""Conversion and validation of array-like inputs, shared by every public function."""

from __future__ import annotations

import math
import operator
from collections.abc import Sequence
from itertools import repeat
from typing import Any, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._errors import ParameterError, ShapeError

FloatArray = NDArray[np.float64]
T = TypeVar("T")

_REALS = (int, float, np.integer, np.floating)


def show(value: Any) -> str:
    """A short description of ``value`` for an error message."""
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape}" if value.ndim else repr(value[()])
    text = repr(value)
    return text if len(text) <= 60 else f"{text[:57]}..."


def real(
    name: str,
    value: Any,
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
    finite: bool = True,
) -> float:
    """``value`` as a Python float: a real scalar (Python or NumPy, or a 0-d array), finite unless
    ``finite=False``, within the stated interval; `ParameterError` naming ``name`` otherwise."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, _REALS):
        raise ParameterError(f"{name} must be a real number; got {show(value)}")
    x = _float(name, value, finite)
    ok = (low is None or (x > low if low_open else x >= low)) and (
        high is None or (x < high if high_open else x <= high)
    )
    if not ok:
        raise ParameterError(f"{name} must lie in {_interval(low, high, low_open, high_open)}; got {x:g}")
    return x


def _float(name: str, value: Any, finite: bool) -> float:
    """A real scalar ``value`` as a Python float, finite if ``finite``; `ParameterError` naming
    ``name`` otherwise."""
    try:
        x = float(value)
    except OverflowError:
        raise ParameterError(f"{name} is too large for a float; got {show(value)}") from None
    if finite and not math.isfinite(x):
        raise ParameterError(f"{name} must be finite; got {x}")
    return x


def integer(name: str, value: Any, *, low: int | None = None, high: int | None = None) -> int:
    """``value`` as a Python int (not a bool) within ``[low, high]``; `ParameterError` otherwise."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, (bool, np.bool_)):
        raise ParameterError(f"{name} must be an integer; got {value!r}")
    n = as_int(name, value)
    if (low is not None and n < low) or (high is not None and n > high):
        if low is None:
            allowed = f"<= {high}"
        elif high is None:
            allowed = f">= {low}"
        else:
            allowed = f"in [{low}, {high}]"
        raise ParameterError(f"{name} must be an integer {allowed}; got {show(n)}")
    return n


def threads(value: Any) -> int | None:
    """A ``threads=`` option: None (rayon's global pool, one thread per core) or 1..4096."""
    return None if value is None else integer("threads", value, low=1, high=4096)


def instance(name: str, value: Any, kind: type[T], what: str) -> T:
    """``value`` itself if it is a ``kind``; `ParameterError` naming ``name`` and ``what`` otherwise."""
    if not isinstance(value, kind):
        raise ParameterError(f"{name} must be {what}; got {type(value).__name__}")
    return value


def items(name: str, value: Any, kind: type[T], what: str, *, min_len: int = 0) -> list[T]:
    """``value`` as a list of ``kind`` with at least ``min_len`` items; `ParameterError` otherwise."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray, tuple)):
        raise ParameterError(f"{name} must be a sequence of {what}; got {show(value)}")
    out = list(value)
    if not all(map(isinstance, out, repeat(kind))):  # (no Python loop when all are right)
        for k, item in enumerate(out):
            if not isinstance(item, kind):
                raise ParameterError(f"{name}[{k}] must be {what}; got {type(item).__name__}")
    if len(out) < min_len:
        raise ParameterError(f"{name} must hold at least {min_len} item(s) ({what}); got {len(out)}")
    return out


def as_float(name: str, value: ArrayLike, *, finite: bool = True) -> FloatArray:
    """``value`` as a float64 array; `ParameterError` naming ``name`` if it is not real or finite."""
    if value is None:
        raise ParameterError(f"{name} must be a real number or an array of them; got None")
    if type(value) is float or type(value) is int:
        # the common scalar without NumPy's per-call cost (a control loop's many small calls)
        return np.array(_float(name, value, finite))
    try:
        array = np.asarray(value, dtype=np.float64)
    except OverflowError:
        raise ParameterError(f"{name} is too large for a float; got {show(value)}") from None
    except (TypeError, ValueError) as error:
        raise ParameterError(f"{name} must be a real number or an array of them; got {value!r}") from error
    if finite and not np.all(np.isfinite(array)):
        bad = np.argwhere(~np.isfinite(array))[0]
        where = f" at index {tuple(int(i) for i in bad)}" if array.ndim else ""
        raise ParameterError(f"{name} must be finite; got {array[tuple(bad)]}{where}")
    return array


def _pair_or_none(value: object) -> tuple[float, float] | None:
    """``value`` as two finite floats when it plainly is a pair of them (a tuple or list of two
    reals, or a float64 array of shape (2,)), else ``None`` (left to the general checks): the
    planners build hundreds of pulses a cycle, each through several such checks."""
    if type(value) is np.ndarray:
        if value.shape != (2,) or value.dtype != np.float64:
            return None
        x, y = float(value[0]), float(value[1])
    elif type(value) is tuple or type(value) is list:
        if len(value) != 2:
            return None
        x, y = value
        if (
            not (isinstance(x, (float, int)) and isinstance(y, (float, int)))
            or isinstance(x, bool)
            or isinstance(y, bool)
        ):
            return None
        x, y = float(x), float(y)
    else:
        return None
    return (x, y) if math.isfinite(x) and math.isfinite(y) else None


def vector(name: str, value: ArrayLike, n: int) -> FloatArray:
    """``value`` as a finite float64 vector of shape ``(n,)``; `ShapeError` naming ``name`` otherwise."""
    if n == 2:
        pair = _pair_or_none(value)
        if pair is not None:
            return np.array(pair)
    v = as_float(name, value)
    if v.shape != (n,):
        raise ShapeError(f"{name} must have shape ({n},); got {v.shape}")
    return v


def point(name: str, value: ArrayLike) -> tuple[float, float]:
    """``value`` as a finite 2-vector, as the binding takes it."""
    pair = _pair_or_none(value)
    if pair is not None:
        return pair
    x, y = vector(name, value, 2)
    return float(x), float(y)


def as_int(name: str, value: Any) -> int:
    """``value`` as a Python int; `ParameterError` if it is not an integer."""
    try:
        return operator.index(value)
    except TypeError as error:
        raise ParameterError(f"{name} must be an integer; got {show(value)}") from error


#: The most elements a broadcast of inputs may have (one float64 result of 8 GB), refused before
#: NumPy tries to allocate it.
MAX_ELEMENTS = 2**30


def broadcast_shape(**arrays: FloatArray) -> tuple[int, ...]:
    """The common shape of ``arrays``; `ShapeError` listing every shape if there is none."""
    listed = ", ".join(f"{name} {a.shape}" for name, a in arrays.items())
    try:
        shape = tuple(np.broadcast_shapes(*(a.shape for a in arrays.values())))
    except ValueError as error:
        raise ShapeError(f"shapes do not broadcast together: {listed}") from error
    if math.prod(shape) > MAX_ELEMENTS:
        raise ShapeError(
            f"the inputs broadcast to {math.prod(shape):.3g} elements ({listed}), more than the "
            f"{MAX_ELEMENTS:.3g} (8 GB of float64) one call evaluates: split the inputs"
        )
    return shape


def flat(array: FloatArray, shape: tuple[int, ...]) -> FloatArray:
    """``array`` broadcast to ``shape`` and flattened (C order, contiguous float64)."""
    return np.ascontiguousarray(np.broadcast_to(array, shape), dtype=np.float64).reshape(-1)


def shaped(result: FloatArray, shape: tuple[int, ...]) -> Any:
    """``result`` reshaped to ``shape``; a Python float when ``shape`` is ``()``."""
    out = np.asarray(result).reshape(shape)
    return float(out) if out.ndim == 0 else out


def check_range(
    name: str,
    array: FloatArray,
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
) -> None:
    """`ParameterError` unless every entry of ``array`` lies in the stated interval."""
    ok = np.ones(array.shape, dtype=bool)
    if low is not None:
        ok &= (array > low) if low_open else (array >= low)
    if high is not None:
        ok &= (array < high) if high_open else (array <= high)
    if not np.all(ok):
        bad = tuple(int(i) for i in np.argwhere(~ok)[0])
        where = f" at index {bad}" if array.ndim else ""
        interval = _interval(low, high, low_open, high_open)
        raise ParameterError(f"{name} must lie in {interval}; got {array[bad]}{where}")


def _interval(low: float | None, high: float | None, low_open: bool, high_open: bool) -> str:
    """``[low, high)`` and the like, ``-inf``/``inf`` for a missing bound."""
    left, right = "(" if low_open else "[", ")" if high_open else "]"
    lo = "-inf" if low is None else f"{low:g}"
    hi = "inf" if high is None else f"{high:g}"
    return f"{left}{lo}, {hi}{right}"
