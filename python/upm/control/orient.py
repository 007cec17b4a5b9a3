"""Orientation control in the closed loop: polygon parts brought to target poses ``(x, y,
theta)``, seen by the camera (:func:`upm.vision.find_poses`) and moved by pulses a
:class:`upm.plan.orient.PosePlanner` chooses by simulation (issue 27, docs/polygons.md)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._arrays import as_float, integer, real
from .._errors import ParameterError, ShapeError, VisionError
from ..plan.orient import PosePlanner, pose_errors
from ..plate.pulses import Pulse
from .devices import Device, as_device

__all__ = ["PoseLog", "PoseLoop", "PoseTask"]

FloatArray = NDArray[np.float64]


@dataclass
class PoseTask:
    """Bring parts to ``targets`` ``(N, 3)``: frame origin [m] and angle [rad] each (the angle
    modulo the outline's symmetry), within ``tolerance`` [m] and ``angle_tolerance`` [deg]. The
    parts seen first are given the targets that minimise the total distance.

    ``kinds`` ``(N,)``: for parts of mixed shapes, the shape (an index into the planner's
    ``part`` list) each target is for; a part goes only to a target of its own shape (sorting
    by shape). None: one shape."""

    targets: Any
    tolerance: float = 0.003
    angle_tolerance: float = 5.0
    kinds: Any = None

    def __post_init__(self) -> None:
        t = as_float("targets", self.targets)
        if t.ndim != 2 or t.shape[1] != 3 or not len(t):
            raise ShapeError(f"targets must have shape (N, 3) (x, y, angle); got {t.shape}")
        if not np.all(np.isfinite(t)):
            raise ParameterError("targets must be finite")
        self.targets = t
        if self.kinds is None:
            self.kinds = np.zeros(len(t), dtype=np.int64)
        else:
            k = np.asarray(self.kinds)
            if k.shape != (len(t),) or not np.issubdtype(k.dtype, np.integer) or k.min() < 0:
                raise ParameterError(
                    f"kinds must hold one shape index >= 0 per target ({len(t)}); got {self.kinds!r}"
                )
            self.kinds = k.astype(np.int64)
        real("tolerance", self.tolerance, low=0.0, low_open=True)
        real("angle_tolerance", self.angle_tolerance, low=0.0, low_open=True)

    def errors(self, poses: FloatArray, symmetry: int | NDArray[np.int64]) -> FloatArray:
        """``(N, 2)``: distance [m] and angle error [deg] of each part (of ``symmetry``, or each
        part's ``(N,)``)."""
        d, a = pose_errors(poses, self.targets, symmetry)
        return np.column_stack([d, np.degrees(a)])

    def done(self, poses: FloatArray, symmetry: int | NDArray[np.int64]) -> bool:
        """Whether every part is within both tolerances."""
        e = self.errors(poses, symmetry)
        return bool(np.all(e[:, 0] <= self.tolerance) and np.all(np.abs(e[:, 1]) <= self.angle_tolerance))


@dataclass
class PoseLog:
    """What a :class:`PoseLoop` saw and did, cycle by cycle: plate time [s], poses ``(N, 3)``,
    errors ``(N, 2)`` (m, deg) and the pulse played (None: none helped)."""

    times: list[float] = field(default_factory=list)
    poses: list[FloatArray] = field(default_factory=list)
    errors: list[FloatArray] = field(default_factory=list)
    pulses: list[Pulse | None] = field(default_factory=list)
    done: bool = False
    stopped: str = "running"

    @property
    def plate_time(self) -> float:
        """Plate time [s] at the last frame."""
        return self.times[-1] if self.times else 0.0


class PoseLoop:
    """See the poses, plan a pulse, play it; until the task is done.

    Parameters
    ----------
    device : SimulatedUPM, Board or a Device
        What plays the pulses (its ``limits`` must be the planner's).
    camera : object with ``read() -> (ok, frame)``
    planner : PosePlanner
    task : PoseTask
    table : upm.vision.Table, optional
        The plate in the image (default: found in the first frame).
    palette : upm.vision.Palette, optional
        Colour references (default: the thesis's).
    """

    def __init__(
        self,
        device: Any,
        camera: Any,
        planner: PosePlanner,
        task: PoseTask,
        *,
        table: Any = None,
        palette: Any = None,
    ) -> None:
        from ..vision import THESIS_PALETTE

        self.device: Device = as_device(device)
        if not hasattr(camera, "read"):
            raise ParameterError(f"camera must have read() -> (ok, frame); got {type(camera).__name__}")
        if not isinstance(planner, PosePlanner):
            raise ParameterError(
                f"planner must be a upm.plan.orient.PosePlanner; got {type(planner).__name__}"
            )
        if not isinstance(task, PoseTask):
            raise ParameterError(f"task must be a upm.control.PoseTask; got {type(task).__name__}")
        theirs = getattr(self.device, "limits", None)
        if theirs is not None and theirs != planner.limits:
            raise ParameterError(
                "the planner's drive limits differ from the device's: build it with device.limits"
            )
        if int(task.kinds.max()) >= len(planner.shapes):
            raise ParameterError(
                f"the task's kinds must index the planner's {len(planner.shapes)} shapes; "
                f"got {task.kinds.max()}"
            )
        self.camera, self.planner, self.task = camera, planner, task
        self.table = table
        self.palette = THESIS_PALETTE if palette is None else palette
        self._last: FloatArray | None = None
        self.plate_time = 0.0

    def see(self) -> FloatArray:
        """The parts' poses ``(N, 3)`` in the task's order, from one camera frame."""
        from ..vision import find_poses, find_table

        ok, frame = self.camera.read()
        if not ok or frame is None:
            raise VisionError("the camera returned no frame")
        if self.table is None:
            self.table = find_table(frame)
        found = find_poses(frame, self.table, self.planner.shapes, palette=self.palette)
        poses = np.column_stack([found.positions, found.angles])
        n = len(self.task.targets)
        if len(poses) != n:
            raise VisionError(f"the camera sees {len(poses)} parts; the task has {n}")
        from scipy.optimize import linear_sum_assignment

        if (found.kinds < 0).any():
            where = found.centroids[int(np.flatnonzero(found.kinds < 0)[0])]
            raise VisionError(
                f"a part at {where.round(4).tolist()} m is too near the view's edge to tell its shape"
            )
        seen = np.bincount(found.kinds, minlength=len(self.planner.shapes))
        want = np.bincount(self.task.kinds, minlength=len(self.planner.shapes))
        if not np.array_equal(seen, want):
            raise VisionError(
                f"the camera sees {seen.tolist()} parts of each shape; the task has {want.tolist()}"
            )
        # the first frame: targets by least total distance; later frames: each part the detection
        # that keeps the total distance moved least; either way only between parts of one shape
        ref = self.task.targets if self._last is None else self._last
        cost = np.hypot(*(poses[:, None, :2] - ref[None, :, :2]).transpose(2, 0, 1))
        cost = np.where(found.kinds[:, None] == self.task.kinds[None, :], cost, 1e9)
        rows, cols = linear_sum_assignment(cost)
        pick = rows[np.argsort(cols)]
        self._last = poses[pick]
        return self._last.copy()

    def run(self, cycles: int = 200, *, timeout: float | None = None) -> PoseLog:
        """Run until the task is done, ``cycles`` cycles, ``timeout`` [s of plate time], or no
        candidate helps; returns the :class:`PoseLog`."""
        cycles = integer("cycles", cycles, low=1)
        if timeout is not None:
            real("timeout", timeout, low=0.0, low_open=True)
        log = PoseLog()
        k = self.planner.symmetries[self.task.kinds]
        for cycle in range(cycles + 1):
            poses = self.see()
            log.times.append(self.plate_time)
            log.poses.append(poses)
            log.errors.append(self.task.errors(poses, k))
            if self.task.done(poses, k):
                log.done, log.stopped = True, "done"
                break
            if cycle == cycles or (timeout is not None and self.plate_time >= timeout):
                log.stopped = "cycles" if cycle == cycles else "timeout"
                break
            pulse = self.planner.plan(poses, self.task.targets, self.task.kinds)
            log.pulses.append(pulse)
            if pulse is None:
                log.stopped = "stuck: no candidate lowers the score"
                break
            waited = float(getattr(self.device, "waited", 0.0))
            self.device.execute([pulse])
            self.plate_time += pulse.duration + float(getattr(self.device, "waited", 0.0)) - waited
        return log
