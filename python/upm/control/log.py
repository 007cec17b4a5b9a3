"""The loop's record of a run: :class:`Log` (per cycle: what was seen, asked for, played, and the
time each part of the cycle took), written to one ``.npz`` file by :meth:`Log.save` and read back
by :func:`load_log`."""

from __future__ import annotations

import json
import math
import os
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._errors import ParameterError
from ..plate.pulses import Pulse

__all__ = ["LoadedLog", "Log", "load_log", "npz_path", "writable"]

FloatArray = NDArray[np.float64]


@dataclass
class Log:
    """Per-cycle record of a run. Arrays have one row per cycle and one column per part id seen
    (``ids``); NaN where a part was not seen or not asked to move.

    Attributes
    ----------
    time : (C,) plate time at the start of each cycle [s]
    wall : (C,) wall-clock time since the start [s]
    positions : (C, P, 2) tracked positions [m]
    desired : (C, P, 2) steps asked for [m]
    achieved : (C, P, 2) steps measured on the next frame [m]
    errors : (C, P) the task's error of each part [m]
    pulses : (C,) pulses played; plate_time (C,) their length [s]
    vision, planning, execution : (C,) seconds spent on each (planning: while the plate waited)
    ahead : (C,) seconds spent planning the next cycle while the plate played (``pipeline``)
    kept : (C,) whether the cycle played the plan made ahead (its prediction held)
    centers : list of (n, 2) the centres (rotations) or foci (jets) of each cycle's pulses
    frames : (F, H, W, 3) the camera frames kept for an animation (every ``keep_frames``-th)
    frame_cycles : (F,) the cycle of each kept frame
    """

    ids: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    labels: list[str] = field(default_factory=list)
    time: list[float] = field(default_factory=list)
    wall: list[float] = field(default_factory=list)
    rows: list[dict[int, tuple[FloatArray, FloatArray, float]]] = field(default_factory=list)
    achieved_rows: list[dict[int, FloatArray]] = field(default_factory=list)
    pulses: list[int] = field(default_factory=list)
    plate_time: list[float] = field(default_factory=list)
    vision: list[float] = field(default_factory=list)
    planning: list[float] = field(default_factory=list)
    execution: list[float] = field(default_factory=list)
    centers: list[FloatArray] = field(default_factory=list)
    ahead: list[float] = field(default_factory=list)
    kept: list[bool] = field(default_factory=list)
    frames: list[NDArray[np.uint8]] = field(default_factory=list)
    frame_cycles: list[int] = field(default_factory=list)
    done: bool = False
    meta: dict[str, Any] = field(default_factory=dict)

    def record(
        self,
        ids: NDArray[np.int64],
        positions: FloatArray,
        desired: FloatArray,
        errors: FloatArray,
        time: float,
        wall: float,
        pulses: list[Pulse],
        timings: tuple[float, float, float],
    ) -> None:
        """Append one cycle: what was seen, asked for and played (``timings``: vision, planning,
        execution [s])."""
        self.rows.append({int(i): (positions[k], desired[k], float(errors[k])) for k, i in enumerate(ids)})
        self.time.append(time)
        self.wall.append(wall)
        played = [p for p in pulses if p.kind != "rest"]
        self.pulses.append(len(played))
        self.plate_time.append(math.fsum(p.duration for p in pulses))
        self.vision.append(timings[0])
        self.planning.append(timings[1])
        self.execution.append(timings[2])
        self.centers.append(np.array([p.center for p in played]).reshape(-1, 2))

    # -- as arrays -------------------------------------------------------------------------------
    def _grid(self, pick: Callable[[int, int], Any], width: int) -> FloatArray:
        c, p = len(self.rows), len(self.ids)
        out = np.full((c, p, width) if width > 1 else (c, p), np.nan)
        index = {int(i): k for k, i in enumerate(self.ids)}
        for r in range(c):
            for i in self.rows[r]:
                value = pick(r, i)
                if value is not None:
                    out[r, index[i]] = value
        return out

    @property
    def positions(self) -> FloatArray:
        return self._grid(lambda r, i: self.rows[r][i][0], 2)

    @property
    def desired(self) -> FloatArray:
        return self._grid(lambda r, i: self.rows[r][i][1], 2)

    @property
    def errors(self) -> FloatArray:
        return self._grid(lambda r, i: self.rows[r][i][2], 1)

    @property
    def achieved(self) -> FloatArray:
        return self._grid(
            lambda r, i: self.achieved_rows[r].get(i) if r < len(self.achieved_rows) else None, 2
        )

    def arrays(self) -> dict[str, Any]:
        """Every field as NumPy arrays (what :meth:`save` writes)."""
        cents = np.full((len(self.centers), max((len(c) for c in self.centers), default=0), 2), np.nan)
        for k, c in enumerate(self.centers):
            cents[k, : len(c)] = c
        frames = np.stack(self.frames) if self.frames else np.zeros((0, 1, 1, 3), np.uint8)
        return {
            "ids": self.ids,
            "labels": np.array(self.labels, dtype=str),
            "time": np.array(self.time),
            "wall": np.array(self.wall),
            "positions": self.positions,
            "desired": self.desired,
            "achieved": self.achieved,
            "errors": self.errors,
            "pulses": np.array(self.pulses, dtype=np.int64),
            "plate_time": np.array(self.plate_time),
            "vision": np.array(self.vision),
            "planning": np.array(self.planning),
            "execution": np.array(self.execution),
            "ahead": np.array(self.ahead),
            "kept": np.array(self.kept, dtype=bool),
            "centers": cents,
            "frames": frames,
            "frame_cycles": np.array(self.frame_cycles, dtype=np.int64),
        }

    def save(self, path: str | Path) -> Path:
        """Write the log to ``path`` (``.npz``; metadata as JSON inside). The file is replaced
        atomically: a reader, or a crash mid-write, never sees half a log."""
        path = npz_path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        meta = json.dumps({**self.meta, "done": self.done})
        partial = path.with_name(f".{path.name}.{os.getpid()}.partial.npz")
        try:
            np.savez_compressed(partial, meta=np.array(meta), **self.arrays())
            os.replace(partial, path)
        finally:
            partial.unlink(missing_ok=True)
        return path

    def tracking_error(self) -> FloatArray:
        """``|achieved - desired|`` per cycle and part [m] (NaN where unknown; a free component,
        NaN in ``desired``, counts as met)."""
        return _tracking_error(self.achieved, self.desired)


def npz_path(path: str | Path) -> Path:
    path = Path(path)
    return path if path.suffix == ".npz" else path.with_name(path.name + ".npz")


def _tracking_error(achieved: FloatArray, desired: FloatArray) -> FloatArray:
    d = np.where(np.isnan(desired) & np.isfinite(achieved), 0.0, achieved - desired)
    out: FloatArray = np.hypot(d[..., 0], d[..., 1])
    return out


@dataclass(frozen=True)
class LoadedLog:
    """A log read back by :func:`load_log`: the arrays of :meth:`Log.arrays` as attributes, and
    ``meta`` (the run's settings and results)."""

    data: dict[str, Any]
    meta: dict[str, Any]

    def __getattr__(self, name: str) -> Any:
        try:
            return self.data[name]
        except KeyError:
            raise AttributeError(name) from None

    @property
    def done(self) -> bool:
        """Whether the task was done when the run ended."""
        return bool(self.meta.get("done", False))

    @property
    def stopped(self) -> str:
        """Why the run ended: ``"done"``, ``"cycles"``, ``"timeout"``, ``"running"`` (a periodic
        flush of a run still going, or one that was killed), or the exception that ended it."""
        return str(self.meta.get("stopped", "running"))

    def tracking_error(self) -> FloatArray:
        """As :meth:`Log.tracking_error`."""
        return _tracking_error(self.data["achieved"], self.data["desired"])


def load_log(path: str | Path) -> LoadedLog:
    """Read a log written by :meth:`Log.save` (or :meth:`Loop.run` with ``log=``);
    :class:`upm.ParameterError` naming the file when it is missing or not such a log."""
    file = Path(path)
    if not file.is_file():
        raise ParameterError(f"path: no log at {str(file)!r}")
    try:
        with np.load(file, allow_pickle=False) as z:
            if "meta" not in z.files:
                raise ValueError("it holds no run metadata")
            data = {k: z[k] for k in z.files if k != "meta"}
            meta = json.loads(str(z["meta"]))
    except (OSError, ValueError, TypeError, EOFError, zipfile.BadZipFile, KeyError) as error:
        raise ParameterError(
            f"path: {str(file)!r} is not a log written by Log.save (an .npz archive with its run's "
            f"metadata): {error}"
        ) from error
    return LoadedLog(data, meta)


def writable(log: str | Path) -> Path:
    """The log's path, its folder created and proven writable now rather than after the run."""
    path = npz_path(log)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        probe = path.with_name(f".{path.name}.{os.getpid()}.probe")
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as error:
        raise ParameterError(f"log: cannot write {str(path)!r}: {error.strerror or error}") from error
    return path
