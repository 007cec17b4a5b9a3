"""The desk's plate: a closed loop that runs until told to stop, steered by commands from the page.

A :class:`Desk` owns a device, a camera and a planner. Its control thread reads a frame, tracks
the parts, and while there is something to do (part commands, Sort, Gather) plans and plays one
cycle of pulses; otherwise it only watches. Commands arrive from other threads (the web server)
through :meth:`Desk.command` and are checked there: a bad one raises :class:`upm.ParameterError`
with the reason, and changes nothing.

Safety: :meth:`Desk.stop` (STOP) clears every command and cuts the cycle short: no pulse starts
after it, a board is sent STOP at once, and the simulated plate (which plays a pulse at its start
and then waits out its duration in real time) waits no longer. A watchdog stops the plate when
the page's heartbeats stop for ``watchdog`` seconds, as the board's watchdog does for the host.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._arrays import real
from .._errors import ParameterError, UpmError
from ..control.loop import loop_tracker, plan_cycle
from ..control.parts import PartsTask
from ..control.tasks import GatherTask, SortTask, State
from ..plate.drive import PLATE_SIZE
from ..plate.pulses import Pulse

__all__ = ["Desk"]

FloatArray = NDArray[np.float64]
COMMANDS = ("heartbeat", "goto", "path", "clear", "sort", "gather", "pause", "resume", "stop")


class Desk:
    """A plate steered by hand (each cycle lasts at least ``MIN_CYCLE`` seconds of plate time, as
    in :class:`upm.control.Loop`).

    Parameters
    ----------
    device : a Device (``execute(pulses)``)
        What plays the pulses: ``SimulatedDevice``, ``SimulatedDevice6``, ``BoardDevice``.
    camera : object with ``read() -> (ok, frame)``
    planner : a Planner
        Its ``plan_task(state, task)`` when it has one, else ``plan(positions, steps)``.
    part_radius : float
        [m], for vision.
    sides : mapping of label to -1 / +1
        What Sort does (default: red left, blue right, as in the thesis).
    gather : bool
        Whether the plate moves out of its plane (Gather is offered).
    realtime : bool
        Wait out each pulse's duration after playing it (a simulated plate; a board plays in real
        time by itself).
    watchdog : float
        Seconds without a heartbeat from the page after which a moving plate is stopped.
    frame_rate : float
        Largest rate of JPEG frames made for the page [1/s].
    stop_device, resume_device : callable, optional
        What STOP calls besides ending the cycle (a board's ``Board.stop``), and what a new
        command calls before the plate moves again (``Board.clear_stop``).
    table : Table, Calibration or path, optional
        The plate in the camera: a calibration (``upm calibrate``'s file) maps pixels through the
        lens; default: found from the plate's outline in the first frame.
    """

    MIN_CYCLE = 0.25

    def __init__(
        self,
        device: Any,
        camera: Any,
        planner: Any,
        *,
        part_radius: float,
        plate_size: float = PLATE_SIZE,
        palette: Any = None,
        sides: dict[str, int] | None = None,
        gather: bool = False,
        realtime: bool = True,
        watchdog: float = 1.0,
        frame_rate: float = 10.0,
        stop_device: Any = None,
        resume_device: Any = None,
        table: Any = None,
    ) -> None:
        from ..vision import THESIS_PALETTE, find_table
        from ..vision.calibration import table_of

        if not hasattr(device, "execute"):
            raise ParameterError(f"device must have execute(pulses); got {type(device).__name__}")
        if not hasattr(camera, "read"):
            raise ParameterError(f"camera must have read() -> (ok, frame); got {type(camera).__name__}")
        for name, value in (("part_radius", part_radius), ("watchdog", watchdog), ("frame_rate", frame_rate)):
            real(name, value, low=0.0, low_open=True)
        self.device, self.camera, self.planner = device, camera, planner
        self.part_radius, self.plate_size = float(part_radius), float(plate_size)
        self.palette = palette or THESIS_PALETTE
        self.sides = dict(sides or {"red": -1, "blue": 1})
        self.can_gather, self.realtime = bool(gather), bool(realtime)
        self.watchdog, self.frame_rate = float(watchdog), float(frame_rate)
        self.stop_device, self.resume_device = stop_device, resume_device
        self.parts = PartsTask()
        self.task: Any = None  # what runs: self.parts, a SortTask, a GatherTask, or None
        self.mode = "idle"
        self.paused = False
        self.message = "click a part, then where it should go; drag to draw its path"
        self.plate_time = 0.0
        self.pulses_played = 0
        self.moving = False
        """Whether a pulse is being played now."""
        self.stops: list[dict[str, float | str]] = []
        """Every stop: ``reason``; ``motors`` [s] from the request to the motors off (a board's
        acknowledgement of STOP; on the simulated plate, the end of the pulse being played); and
        ``latency`` [s] to the control thread idle."""
        frame = self._read()
        self.table = table_of(table, plate_size) or find_table(frame, plate_size)
        self.tracker = loop_tracker(self.table, part_radius, self.palette, self.parts.max_step)
        self.tracks = self.tracker.update(frame)
        self.frame = frame
        self.jpeg: bytes = b""
        self.frame_seq = 0
        self._encode(frame)
        self._lock = threading.RLock()
        self._halt = threading.Event()  # STOP: cut the cycle short
        self._closed = threading.Event()
        self._beat = time.monotonic()
        self._thread = threading.Thread(target=self._run, name="upm-desk", daemon=True)
        self._dog = threading.Thread(target=self._watch, name="upm-desk-watchdog", daemon=True)

    # -- life --------------------------------------------------------------------------------------
    def start(self) -> Desk:
        """Start the control thread and the watchdog."""
        self._beat = time.monotonic()
        self._thread.start()
        self._dog.start()
        return self

    def close(self) -> None:
        """Stop the plate and the threads."""
        self.stop("the desk closed")
        self._closed.set()
        if self._thread.is_alive():
            self._thread.join(10)
        if self._dog.is_alive():
            self._dog.join(2)

    # -- commands (any thread) ---------------------------------------------------------------------
    def command(self, message: Any) -> str:
        """Act on one message from the page (a dict with ``type``); returns what was done.
        ``ParameterError`` for anything malformed, unknown or impossible (nothing changes)."""
        if not isinstance(message, dict) or not isinstance(message.get("type"), str):
            raise ParameterError("a message must be a JSON object with a string 'type'")
        kind = message["type"]
        if kind not in COMMANDS:
            raise ParameterError(f"unknown message type {kind!r}; known: {', '.join(COMMANDS)}")
        if kind == "heartbeat":
            self._beat = time.monotonic()
            return "ok"
        if kind == "stop":
            return self.stop("STOP pressed")
        if kind == "pause":
            self.paused = True
            self.message = "paused"
            return self.message
        if kind == "resume":
            self.paused = False
            self.message = "running" if self.task is not None else "idle"
            return self.message
        if kind == "clear":
            self.parts.clear(self._part(message) if "id" in message else None)
            return "cleared"
        if kind == "sort":
            self.parts.clear()  # one task at a time: the parts' goals give way to the sort
            return self._start(SortTask(self.sides, plate_size=self.plate_size), "sort")
        if kind == "gather":
            if not self.can_gather:
                raise ParameterError("Gather needs a plate that moves out of its plane (upm desk --six-axis)")
            self.parts.clear()
            return self._start(GatherTask((0.0, 0.0), radius=0.04), "gather")
        part = self._part(message)
        if kind == "goto":
            goal = self._point(message, "to")
            self._start(self.parts, "parts", lambda: self.parts.goto(part, goal))
            return f"part {part} to ({1e3 * goal[0]:.0f}, {1e3 * goal[1]:.0f}) mm"
        path = self._path(message)
        speed = message.get("speed", 0.03)
        if not isinstance(speed, (int, float)) or not (0 < speed <= 0.2):
            raise ParameterError(f"speed must be a number in (0, 0.2] [m/s]; got {speed!r}")
        self._start(self.parts, "parts", lambda: self.parts.follow(part, path, float(speed)))
        return f"part {part} along a path of {len(path)} points"

    def stop(self, reason: str = "STOP") -> str:
        """Stop the plate now: clear every command, cut the cycle short, STOP a board."""
        asked = time.monotonic()
        self._halt.set()
        with self._lock:
            self.parts.clear()
            self.task, self.mode = None, "stopped"
            self.message = f"stopped: {reason}"
        motors = None
        if self.stop_device is not None:
            try:
                self.stop_device()
                motors = time.monotonic() - asked  # the board acknowledged: its motors are off
            except UpmError as error:  # the link is gone: the board's own watchdog stops it
                self.message += f" (the board did not answer STOP: {error})"
        deadline = asked + 2.0
        while self.moving and time.monotonic() < deadline and threading.current_thread() is not self._thread:
            time.sleep(0.002)
        done = time.monotonic() - asked
        self.stops.append({"reason": reason, "latency": done, "motors": done if motors is None else motors})
        return self.message

    def _start(self, task: Any, mode: str, give: Any = None) -> str:
        """Run ``task`` (after ``give()``, which gives it its command: under the lock the control
        thread ends tasks under, so a command never lands in a task just found done)."""
        if self.resume_device is not None:  # a board refuses pulses after STOP until told
            self.resume_device()
        with self._lock:
            if give is not None:
                give()
            self._halt.clear()
            self.task, self.mode, self.paused = task, mode, False
            self.message = f"running: {mode}"
        return self.message

    def _part(self, message: dict[str, Any]) -> int:
        part = message.get("id")
        if isinstance(part, bool) or not isinstance(part, int):
            raise ParameterError(f"id must be an integer part id; got {part!r}")
        tracks = self.tracks
        known = [int(i) for i, lost in zip(tracks.ids, tracks.lost, strict=True) if not lost]
        if part not in known:
            raise ParameterError(f"no part {part} on the plate; the parts seen now: {known}")
        return part

    def _point(self, message: dict[str, Any], key: str) -> FloatArray:
        """A point of a message in plate metres: ``{key: [x, y]}`` [m] or ``{key + "_px": [u, v]}``
        in the camera image [px]; refused off the plate (a part's radius from the edge)."""
        out: FloatArray = self._points(message, key, 1)[0]
        return out

    def _path(self, message: dict[str, Any]) -> FloatArray:
        return self._points(message, "path", 2)

    def _points(self, message: dict[str, Any], key: str, least: int) -> FloatArray:
        if key in message:
            raw, pixels = message[key], False
        elif key + "_px" in message:
            raw, pixels = message[key + "_px"], True
        else:
            raise ParameterError(f"a {message['type']!r} message needs {key!r} [m] or {key + '_px'!r} [px]")
        try:
            p = np.asarray(raw, dtype=np.float64).reshape(-1, 2)
        except (TypeError, ValueError):
            raise ParameterError(f"{key} must be [x, y] or a list of them; got {raw!r}") from None
        if len(p) < least or len(p) > 2000 or not np.all(np.isfinite(p)):
            raise ParameterError(f"{key} must hold {least} to 2000 finite points; got {len(p)}")
        if pixels:
            p = self.table.to_plate(p)
        inner = self.plate_size / 2 - self.part_radius
        off = np.any(np.abs(p) > inner, axis=1)
        if off.any():
            x, y = p[np.argmax(off)]
            raise ParameterError(
                f"{key} is off the plate at ({1e3 * x:.0f}, {1e3 * y:.0f}) mm: "
                f"points must be within {1e3 * inner:.0f} mm of the centre in x and y"
            )
        return p

    # -- what the page shows ----------------------------------------------------------------------
    def view(self) -> dict[str, Any]:
        """The state for the page, in camera pixels and plate metres (JSON-ready)."""
        t = self.tracks
        table = self.table
        parts = [
            {
                "id": int(i),
                "label": lab,
                "lost": bool(lost),
                "px": None if lost else [float(v) for v in px],
                "m": None if lost else [float(v) for v in pos],
            }
            for i, lab, lost, px, pos in zip(t.ids, t.labels, t.lost, t.pixels, t.positions, strict=True)
        ]
        goals = []
        for i, c in self.parts.describe().items():
            if "goal" in c:
                goals.append({"id": i, "px": table.to_camera(np.array([c["goal"]]))[0].tolist()})
            else:
                goals.append(
                    {
                        "id": i,
                        "path_px": table.to_camera(np.array(c["path"])).tolist(),
                        "done": c["progress"] / c["length"],
                    }
                )
        h = self.plate_size / 2
        corners = table.to_camera(np.array([[-h, -h], [h, -h], [h, h], [-h, h]])).tolist()
        return {
            "type": "state",
            "mode": self.mode,
            "paused": self.paused,
            "moving": self.moving,
            "message": self.message,
            "parts": parts,
            "goals": goals,
            "plate_px": corners,
            "radius_px": self.part_radius * float(table.pixels_per_metre),
            "plate_time": self.plate_time,
            "pulses": self.pulses_played,
            "gather": self.can_gather,
            "frame": self.frame_seq,
            "field_px": getattr(self, "_field_px", []),
            "finished": list(self.parts.finished[-8:]),
        }

    # -- the control thread -----------------------------------------------------------------------
    def _read(self) -> NDArray[np.uint8]:
        ok, frame = self.camera.read()
        if not ok or frame is None:
            raise ParameterError("the camera returned no frame")
        return np.asarray(frame)

    def _encode(self, frame: NDArray[np.uint8]) -> None:
        import cv2

        ok, jpeg = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, 80])
        if ok:
            self.jpeg, self.frame_seq = jpeg.tobytes(), self.frame_seq + 1

    def _watch(self) -> None:
        while not self._closed.wait(0.05):
            busy = self.task is not None and not self.paused
            if busy and time.monotonic() - self._beat > self.watchdog:
                self.stop(f"no heartbeat from the page for {self.watchdog:g} s")

    def _run(self) -> None:
        cycle, last_cycle, shown = 0, 0.0, 0.0
        while not self._closed.is_set():
            try:
                frame = self._read()
                tracks = self.tracker.update(frame)
                self.tracks, self.frame = tracks, frame
                if time.monotonic() - shown >= 1.0 / self.frame_rate:
                    self._encode(frame)
                    shown = time.monotonic()
                with self._lock:
                    task = None if self.paused else self.task
                if task is None:
                    self._closed.wait(0.05)
                    continue
                state = State(cycle, self.plate_time, tracks.ids, tracks.positions, tracks.labels, last_cycle)
                with self._lock:  # no command lands between the task found done and the desk idle
                    if self.task is not task:  # stopped or replaced since it was read
                        continue
                    if task.done(state):
                        self.message = f"done: {self.mode}"
                        self.task, self.mode = None, "idle"
                        continue
                pulses = self._plan(state, task)
                last_cycle = self._play(pulses)
                cycle += 1
            except UpmError as error:  # shown on the page; the plate stops
                with self._lock:
                    if not self._halt.is_set():  # a pulse cut short by STOP says nothing new
                        self.task, self.mode = None, "stopped"
                        self.message = f"stopped: {error}"
                self._closed.wait(0.2)

    def _plan(self, state: State, task: Any) -> list[Pulse]:
        steps = np.asarray(task.steps(state), dtype=np.float64)  # once a cycle, as the loop does
        steps[~np.all(np.isfinite(state.positions), axis=1)] = 0.0
        pulses = plan_cycle(self.planner, task, state, steps, self.MIN_CYCLE)
        expected = getattr(self.planner, "expected", None)
        if expected is not None and pulses:
            self.tracker.expect(*expected)
        self._field_px = self._field(pulses)
        return pulses

    def _field(self, pulses: Sequence[Pulse]) -> list[list[float]]:
        """Arrows ``[u, v, du, dv]`` [px] of the cycle's average force field on a 7 x 7 grid."""
        from ..viz.recorder import field_on_grid

        h = 0.85 * self.plate_size / 2
        axis = np.linspace(-h, h, 7)
        grid = np.stack(np.meshgrid(axis, axis), axis=-1).reshape(-1, 2)
        f = field_on_grid([p for p in pulses if p.kind != "rest"], grid)
        if f is None:
            return []
        ends = self.table.to_camera(grid + f * (axis[1] - axis[0]))
        starts = self.table.to_camera(grid)
        arrows: list[list[float]] = np.concatenate([starts, ends - starts], axis=1).tolist()
        return arrows

    def _play(self, pulses: Sequence[Pulse]) -> float:
        """Play the pulses in real time; STOP ends the one playing and the rests at once."""
        played = 0.0
        for pulse in pulses:
            if self._halt.is_set() or self.paused:
                break
            started = time.monotonic()
            self.moving = True
            try:
                self.device.execute([pulse])
                if self.realtime:  # a simulated plate: its motors run for the pulse's on-time
                    self._halt.wait(max(pulse.on_time - (time.monotonic() - started), 0.0))
            finally:
                if self._halt.is_set() and self.stop_device is not None:
                    # a pulse that started while STOP was on its way: STOP again, it is idempotent
                    self.stop_device()
                self.moving = False
            self.pulses_played += pulse.kind != "rest"
            played += pulse.duration
            rest = pulse.duration - (time.monotonic() - started) if self.realtime else pulse.rest
            self._halt.wait(max(rest, 0.0))  # the parts settle; the motors are off
        self.plate_time += played
        return played
