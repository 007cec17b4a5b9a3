"""The closed loop (thesis 5.2.5, Fig. 4.5): camera → vision → task → planner → device → camera.

Each cycle reads a frame, tracks the parts (:class:`upm.vision.Tracker`), asks the task for the
steps it wants, asks the planner for pulses, plays them on the device, and on the next frame
measures the steps achieved; the error (achieved - desired) is logged with the positions, the
commands and the timings. :meth:`Log.save` writes one ``.npz`` file; :func:`load_log` reads it.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from .._arrays import integer, real
from .._errors import ParameterError, PlanWarning, PulseCut, VisionError
from ..plan import Planner
from ..plate.drive import PLATE_SIZE, StrokeError
from ..plate.pulses import Pulse
from ._steps import PointTargets
from .devices import Device, as_device, pulse_time
from .log import LoadedLog, Log, load_log, writable
from .state import State, Task

__all__ = ["LoadedLog", "Log", "Loop", "load_log", "loop_tracker", "plan_cycle"]

FloatArray = NDArray[np.float64]

#: Pulses refused in a row as beyond the stroke before the loop gives up (the planner's
#: ``refused()`` lowers its pulses 15 % each time).
MAX_REFUSALS = 4


class _Camera(Protocol):
    def read(self) -> tuple[bool, Any]: ...


class Loop:
    """The closed loop.

    Parameters
    ----------
    device : SimulatedUPM, Board, or a Device
        What plays the pulses.
    camera : object with ``read() -> (ok, frame)``
        An OpenCV ``VideoCapture``, a :class:`~upm.vision.synthetic.VirtualCamera`, a
        :class:`~upm.vision.RemoteCamera`.
    planner : Planner
        Its ``plan(positions, steps)``; or, when it has ``plan_task(state, task)`` (a
        :class:`~upm.plan.PredictivePlanner`) and the task a ``cost``, that. A planner with
        ``limits`` must have the device's (``ParameterError`` otherwise). When the device refuses a
        pulse as beyond its stroke (:class:`upm.drive.StrokeError`: nothing played) and the
        planner has ``refused()``, that is called (it sizes later pulses lower) and the cycle is
        planned again, up to :data:`MAX_REFUSALS` times in a row; otherwise the error is raised.
        A pulse the board cut short (:class:`upm.PulseCut`: its watchdog, a STOP) is counted in
        ``log.meta["cut"]`` and the next cycle plans from where it left the parts (up to
        :data:`MAX_REFUSALS` in a row).
    task : Task
    part_radius : float
        Part radius [m] (for vision).
    table : upm.vision.Table, upm.vision.Calibration or path, optional
        The plate in the image: a calibration (or the file ``upm calibrate`` wrote) maps pixels
        to the plate through the lens; default: found from its outline in the first frame.
    plate_size : float
        Side of the plate [m] (for finding the table).
    palette : upm.vision.Palette, optional
        Colour references for labels.
    search : float, optional
        How far [top-view px] a part may move between frames (default: the task's longest step
        plus two radii, in pixels).
    keep_frames : int
        Keep every this-many-th frame in the log (0: none) for animations.
    min_cycle : float
        Shortest cycle [s of plate time]: a cycle whose pulses are shorter rests for the remainder
        (time passes while the loop sees and thinks, so trajectories keep moving when the parts
        are on their references).
    pipeline : float or None
        Plan while the plate plays: as each pulse plays, the planner (one with ``speculate`` and
        ``adopt``: :class:`~upm.plan.PredictivePlanner`) plans the next from where the pulse is
        predicted to leave the parts; when the frame arrives, that plan is played if every part
        is within ``pipeline`` [m, at most 0.1] of its prediction (for a task of points with a
        ``tolerance``, within a quarter of its way still to go, at least half the tolerance; and
        the same parts are seen);
        else the planner's ``revise`` plans again from where the parts are (the predictive
        planner chooses among that plan's best candidates for up to ``focus`` parts:
        ``log.meta["revised"]`` counts those cycles; it searches afresh beyond), or a planner
        without one plans afresh. ``None``: see, plan, play in turn.
    """

    def __init__(
        self,
        device: Any,
        camera: _Camera,
        planner: Planner,
        task: Task,
        *,
        part_radius: float,
        table: Any = None,
        plate_size: float = PLATE_SIZE,
        palette: Any = None,
        search: float | None = None,
        keep_frames: int = 1,
        min_cycle: float = 0.25,
        pipeline: float | None = None,
    ) -> None:
        from ..vision import THESIS_PALETTE, find_table
        from ..vision.calibration import table_of

        self.device: Device = as_device(device)
        if not hasattr(camera, "read"):
            raise ParameterError(f"camera must have read() -> (ok, frame); got {type(camera).__name__}")
        if not hasattr(planner, "plan"):
            raise ParameterError(f"planner must have plan(positions, steps); got {type(planner).__name__}")
        if not all(hasattr(task, n) for n in ("steps", "done", "errors")):
            raise ParameterError(f"task must have steps, done and errors; got {type(task).__name__}")
        if not (math.isfinite(part_radius) and part_radius > 0):
            raise ParameterError(f"part_radius must be finite and > 0 [m]; got {part_radius!r}")
        mine, theirs = getattr(planner, "limits", None), getattr(self.device, "limits", None)
        if mine is not None and theirs is not None and mine != theirs:
            raise ParameterError(
                f"the planner's drive limits differ from the device's: planner {mine!r}, device {theirs!r}; "
                "build the planner with limits=device.limits"
            )
        self.camera, self.planner, self.task = camera, planner, task
        self.part_radius, self.plate_size = float(part_radius), float(plate_size)
        self.keep_frames = int(keep_frames)
        if not (math.isfinite(min_cycle) and min_cycle >= 0):
            raise ParameterError(f"min_cycle must be finite and >= 0 [s]; got {min_cycle!r}")
        self.min_cycle = float(min_cycle)
        if pipeline is not None:
            # a distance on the plate: millimetres given as metres would keep every plan
            real("pipeline", pipeline, low=0.0, low_open=True, high=0.1)
            if not (hasattr(planner, "speculate") and hasattr(planner, "adopt")):
                raise ParameterError(
                    f"pipeline needs a planner that plans ahead (speculate, adopt: PredictivePlanner); "
                    f"got {type(planner).__name__}"
                )
        self.pipeline = None if pipeline is None else float(pipeline)
        self._find_table = find_table
        self.palette = THESIS_PALETTE if palette is None else palette
        self.table: Any = table_of(table, self.plate_size)
        self.search = search
        self.tracker: Any = None
        self.plate_time = 0.0
        self._pool: Any = None

    def _player(self) -> Any:
        """The one worker thread that plays pulses while the loop plans ahead (``pipeline``)."""
        if self._pool is None:
            from concurrent.futures import ThreadPoolExecutor

            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="upm-plate")
        return self._pool

    def _read(self) -> NDArray[np.uint8]:
        ok, frame = self.camera.read()
        if not ok or frame is None:
            raise VisionError("the camera returned no frame")
        return np.asarray(frame)

    def _start(self, frame: NDArray[np.uint8]) -> None:
        if self.table is None:
            self.table = self._find_table(frame, self.plate_size)
        longest = float(getattr(self.task, "max_step", 0.02))
        self.tracker = loop_tracker(self.table, self.part_radius, self.palette, longest, self.search)

    def run(
        self,
        cycles: int = 100,
        *,
        timeout: float | None = None,
        log: str | Path | None = None,
        callback: Callable[[State, list[Pulse]], None] | None = None,
        flush_every: float = 30.0,
        recording: str | Path | Any = None,
    ) -> Log:
        """Run until the task is done, ``cycles`` cycles have passed, or ``timeout`` seconds of
        plate time; returns the :class:`Log`.

        With ``log``, the log is written on the way out whatever ends the run (Ctrl-C or an
        exception included: ``meta["stopped"]`` says what), and every ``flush_every`` seconds of
        wall time on the way, so a long experiment is never lost. The path is checked before the
        first cycle.

        With ``recording`` (an ``.rrd`` path, ``"spawn"`` for a live viewer, or a
        :class:`upm.viz.Recorder`; extra ``viz``), the run is recorded for rerun as it goes (docs/viz.md):
        frames, tracked parts, goals, steps, the planned field, the plate's series, timings and
        events, by a background thread that never holds the loop up. A recorder given here is
        left open; one made here is closed (the file complete) when the run ends."""
        cycles = integer("cycles", cycles, low=1)
        if timeout is not None:
            real("timeout", timeout, low=0.0, low_open=True)
        flush = real("flush_every", flush_every, low=0.0, low_open=True)
        out = Log(meta={"planner": type(self.planner).__name__, "task": type(self.task).__name__})
        start = time.perf_counter()
        target = None if log is None else writable(log)
        out.meta["stopped"] = "running"
        recorder, owned = _recorder(recording)
        try:
            self._cycles(out, cycles, timeout, callback, start, target, flush, recorder)
        except BaseException as error:
            out.meta["stopped"] = f"{type(error).__name__}: {error}"[:500]
            raise
        finally:
            out.meta.update(
                cycles=len(out.rows), plate_time=self.plate_time, wall=time.perf_counter() - start
            )
            if target is not None:
                out.save(target)
            if owned:
                recorder.close()
            if self._pool is not None:
                self._pool.shutdown(wait=True)
                self._pool = None
        return out

    def _cycles(
        self,
        out: Log,
        cycles: int,
        timeout: float | None,
        callback: Callable[[State, list[Pulse]], None] | None,
        start: float,
        target: Path | None,
        flush: float,
        recorder: Any = None,
    ) -> None:
        flushed = start
        last_cycle = 0.0
        refusals = 0  # pulses refused in a row as beyond the stroke
        cuts = 0  # pulses cut short in a row (PulseCut)
        pending: tuple[list[Pulse], object, NDArray[np.int64], FloatArray] | None = None
        ahead_planner: Any = self.planner  # with speculate and adopt when pipelined (checked)
        prev: dict[int, FloatArray] = {}  # positions at the start of the last cycle
        known: set[int] = set()
        for cycle in range(cycles + 1):
            t0 = time.perf_counter()
            frame = self._read()
            if self.tracker is None:
                self._start(frame)
                if recorder is not None:
                    recorder.begin(
                        part_radius=self.part_radius,
                        pixels_per_metre=self.table.pixels_per_metre,
                        palette=self.palette,
                        plate_size=self.plate_size,
                        limits=getattr(self.device, "limits", None),
                    )
            tracks = self.tracker.update(frame)
            t1 = time.perf_counter()
            pos = tracks.positions
            for k, i in enumerate(tracks.ids):  # ids new to the log get a column
                if int(i) not in known:
                    known.add(int(i))
                    out.ids = np.append(out.ids, int(i))
                    out.labels.append(tracks.labels[k])
            achieved: dict[int, FloatArray] = {}
            before = prev
            for k, i in enumerate(tracks.ids):
                if int(i) in prev and np.all(np.isfinite(pos[k])):
                    achieved[int(i)] = pos[k] - prev[int(i)]
            if cycle > 0:
                out.achieved_rows.append(achieved)
            state = State(cycle, self.plate_time, tracks.ids, pos, tracks.labels, last_cycle)
            errors = np.asarray(self.task.errors(state), dtype=np.float64)
            finished = bool(self.task.done(state))
            if self.keep_frames and (cycle % self.keep_frames == 0 or finished or cycle == cycles):
                out.frames.append(frame.copy() if frame.ndim == 3 else np.repeat(frame[..., None], 3, axis=2))
                out.frame_cycles.append(cycle)
            if finished or cycle == cycles or (timeout is not None and self.plate_time >= timeout):
                nothing = np.full_like(pos, np.nan)
                out.record(tracks.ids, pos, nothing, errors, self.plate_time, time.perf_counter() - start, [],
                           (t1 - t0, 0.0, 0.0))  # fmt: skip
                out.done = finished
                out.kept.append(False)
                out.ahead.append(0.0)
                out.meta["stopped"] = "done" if finished else ("cycles" if cycle == cycles else "timeout")
                if recorder is not None:
                    seen_now = (state, tracks, frame, achieved, before, errors)
                    self._record(recorder, seen_now, nothing, [], (t1 - t0, 0.0, 0.0), out.meta["stopped"])
                break
            steps = np.asarray(self.task.steps(state), dtype=np.float64)
            seen = np.all(np.isfinite(pos), axis=1)
            steps[~seen] = 0.0
            pulses = None
            token = None
            if pending is not None:  # planned while the last pulse played: kept if it still holds
                ahead_pulses, token, p_ids, p_pos = pending
                pending = None
                if _holds(tracks.ids[seen], pos[seen], p_ids, p_pos, self._within(errors[seen])):
                    ahead_planner.adopt(token, tracks.ids[seen], pos[seen])
                    pulses = _padded(list(ahead_pulses), self.min_cycle)
            out.kept.append(pulses is not None)
            if pulses is None:
                revised = getattr(self.planner, "revisions", 0)
                pulses = plan_cycle(self.planner, self.task, state, steps, self.min_cycle, token)
                if getattr(self.planner, "revisions", 0) > revised:
                    out.meta["revised"] = int(out.meta.get("revised", 0)) + 1
            t2 = time.perf_counter()
            if callback is not None:
                callback(state, pulses)
            expected = getattr(self.planner, "expected", None)
            if expected is not None and pulses:  # the planner's prediction guides the next search
                self.tracker.expect(*expected)
            waited = float(getattr(self.device, "waited", 0.0))
            ahead = 0.0
            try:
                pending, ahead = self._play(pulses, expected, cycle, tracks, ahead_planner)
                refusals = cuts = 0
            except StrokeError as error:
                # nothing of the refused pulse played: the planner sizes its pulses lower and the
                # cycle is planned again from the next frame
                refusals += 1
                pending = None
                out.meta["refused"] = int(out.meta.get("refused", 0)) + 1
                shrink = getattr(self.planner, "refused", None)
                if shrink is None or refusals > MAX_REFUSALS:
                    raise
                shrink()
                warnings.warn(f"cycle {cycle}: {error}; the planner sizes its pulses lower", PlanWarning,
                              stacklevel=2)  # fmt: skip
                pulses = []
            except PulseCut as error:
                # part of it played (its time is counted in full: the most it can have been);
                # the next frame shows where it left the parts, and the plan made ahead from
                # where the whole pulse would have is dropped
                pending = None
                dropped = getattr(self.planner, "cut", None)
                if dropped is not None:  # a pulse that did not play out teaches nothing
                    dropped()
                out.meta["cut"] = int(out.meta.get("cut", 0)) + 1
                cuts += 1
                if cuts > MAX_REFUSALS:  # cut again and again: the link is not holding
                    raise
                warnings.warn(f"cycle {cycle}: {error}; planned again from the next frame", PlanWarning,
                              stacklevel=2)  # fmt: skip
            out.ahead.append(ahead)
            t3 = time.perf_counter()
            last_cycle = pulse_time(pulses) + float(getattr(self.device, "waited", 0.0)) - waited
            self.plate_time += last_cycle
            prev = {int(i): pos[k] for k, i in enumerate(tracks.ids) if seen[k]}
            desired = np.where(seen[:, None], steps, np.nan)
            out.record(tracks.ids, pos, desired, errors, state.time, time.perf_counter() - start, pulses,
                       (t1 - t0, t2 - t1, t3 - t2))  # fmt: skip
            if recorder is not None:
                seen_now = (state, tracks, frame, achieved, before, errors)
                self._record(recorder, seen_now, desired, pulses, (t1 - t0, t2 - t1, t3 - t2))
            if target is not None and time.perf_counter() - flushed >= flush:
                out.meta.update(cycles=len(out.rows), plate_time=self.plate_time)
                out.save(target)
                flushed = time.perf_counter()

    def _within(self, errors: FloatArray) -> FloatArray:
        """How far each part (its task error ``errors``) may end from its prediction for the plan
        made ahead to hold: ``pipeline``; for a task of points with a ``tolerance`` no more than a
        quarter of the part's way still to go, nor less than half the tolerance. A plan made for
        parts 6 mm from where they are places none of them to 3.7 mm: shape8 ended each cycle
        2-6 mm off its kept plan's start, and its total error swung 25-60 mm for 100 s."""
        base = np.full(len(errors), self.pipeline or 0.0)
        if not isinstance(self.task, PointTargets):
            return base
        way = np.where(np.isfinite(errors), errors, base * 4) / 4
        out: FloatArray = np.minimum(base, np.maximum(0.5 * self.task.tolerance, way))
        return out

    def _play(
        self, pulses: list[Pulse], expected: Any, cycle: int, tracks: Any, ahead_planner: Any
    ) -> tuple[tuple[list[Pulse], object, NDArray[np.int64], FloatArray] | None, float]:
        """Play ``pulses``; when pipelined, plan the next cycle from the prediction ``expected``
        while they play (in a worker thread): that plan (or ``None``) and the time it took."""
        if self.pipeline is None or expected is None or not any(p.kind != "rest" for p in pulses):
            self.device.execute(pulses)
            return None, 0.0
        # the cycle ends when both the plate and the plan have
        labels = dict(zip((int(i) for i in tracks.ids), tracks.labels, strict=True))
        e_ids, e_pos = expected
        alive = np.all(np.isfinite(e_pos), axis=1)  # a part predicted off the plate is not planned for
        e_ids, e_pos = np.asarray(e_ids)[alive], np.asarray(e_pos)[alive]
        guess = State(cycle + 1, self.plate_time + pulse_time(pulses), e_ids, e_pos,
                      tuple(labels.get(int(i), "") for i in e_ids), pulse_time(pulses))  # fmt: skip
        playing = self._player().submit(self.device.execute, pulses)
        try:
            a0 = time.perf_counter()
            ahead_pulses, token = ahead_planner.speculate(guess, self.task)
            return (ahead_pulses, token, e_ids.copy(), e_pos.copy()), time.perf_counter() - a0
        finally:
            playing.result()

    def _record(
        self,
        recorder: Any,
        seen: tuple[State, Any, NDArray[np.uint8], dict[int, FloatArray], dict[int, FloatArray], FloatArray],
        desired: FloatArray,
        pulses: list[Pulse],
        timings: tuple[float, float, float],
        end: str | None = None,
    ) -> None:
        """Hand the cycle to the recorder: what was seen (``(state, tracks, frame, achieved steps,
        where they started, errors)``), asked for and played, with the task's goals and lines
        when it has them."""
        state, tracks, frame, achieved, origins, errors = seen
        targets, lines = getattr(self.task, "targets", None), getattr(self.task, "lines", None)
        recorder.cycle(
            cycle=state.cycle,
            plate_time=state.time,
            tracks=tracks,
            frame=frame,
            desired=desired,
            achieved=achieved,
            origins=origins,
            errors=errors,
            targets=None if targets is None else targets(state),
            lines=[] if lines is None else lines(),
            pulses=pulses,
            timings=timings,
            end=end,
        )


def loop_tracker(
    table: Any, part_radius: float, palette: Any, longest: float, search: float | None = None
) -> Any:
    """The loop's :class:`upm.vision.Tracker` on ``table``: parts may move ``longest`` [m] a cycle
    (``search`` [top-view px], default: that plus two radii), are searched for on the whole plate
    every fifth frame and reacquired within three steps."""
    from ..vision import Tracker

    reach = search if search is not None else (longest + 2 * part_radius) * float(table.pixels_per_metre)
    return Tracker(table, part_radius, palette=palette, search=reach, detect_every=5, max_missed=3,
                   reacquire=3 * longest + 10 * part_radius)  # fmt: skip


def plan_cycle(
    planner: Any, task: Any, state: State, steps: FloatArray, min_cycle: float, token: object = None
) -> list[Pulse]:
    """One cycle's pulses: the planner's ``plan_task(state, task)`` when it has one and the task a
    ``cost`` (on the parts seen; ``revise(token, state, task)`` instead when a plan made ahead,
    ``token``, did not hold), else its ``plan(positions, steps)``; padded with a rest to
    ``min_cycle`` [s] of plate time."""
    seen = np.all(np.isfinite(state.positions), axis=1)
    if hasattr(planner, "plan_task") and hasattr(task, "cost"):
        labels = tuple(lab for lab, s in zip(state.labels, seen, strict=True) if s)
        view = State(
            state.cycle, state.time, state.ids[seen], state.positions[seen], labels, state.last_cycle
        )
        if token is not None and hasattr(planner, "revise"):
            pulses = list(planner.revise(token, view, task))
        else:
            pulses = list(planner.plan_task(view, task))
    else:
        pulses = list(planner.plan(state.positions[seen], steps[seen]))
    return _padded(pulses, min_cycle)


def _padded(pulses: list[Pulse], min_cycle: float) -> list[Pulse]:
    """``pulses`` with a rest to ``min_cycle`` [s] of plate time when shorter."""
    short = min_cycle - pulse_time(pulses)
    return [*pulses, Pulse.pause(short)] if short > 1e-9 else pulses


def _holds(
    ids: NDArray[np.int64], pos: FloatArray, p_ids: NDArray[np.int64], p_pos: FloatArray, within: Any
) -> bool:
    """Whether the parts seen (``ids`` at ``pos``) are the ones predicted (``p_ids`` at
    ``p_pos``), each within ``within`` [m] of its prediction (one value or one per part)."""
    if len(ids) != len(p_ids) or set(map(int, ids)) != set(map(int, p_ids)):
        return False
    at = {int(i): k for k, i in enumerate(p_ids)}
    d = pos - p_pos[[at[int(i)] for i in ids]]
    return bool(np.all(np.isfinite(d)) and np.all(np.hypot(d[:, 0], d[:, 1]) <= within))


def _recorder(recording: Any) -> tuple[Any, bool]:
    """The recorder for ``Loop.run``'s ``recording``, and whether the loop made it (and closes it)."""
    if recording is None:
        return None, False
    if hasattr(recording, "cycle") and hasattr(recording, "begin"):
        return recording, False
    if not isinstance(recording, (str, Path)):
        raise ParameterError(
            f"recording must be a .rrd path, 'spawn' or a upm.viz.Recorder; got {type(recording).__name__}"
        )
    from ..viz import Recorder

    return Recorder(recording), True
