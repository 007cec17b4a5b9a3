"""A rerun recording of the closed loop, written off the loop's critical path.

The loop hands each cycle to :meth:`Recorder.cycle`, which only copies what it needs and puts it on
a bounded queue; a background thread encodes the frames (JPEG), computes the planned pulses'
force field and logs everything. When the thread falls behind, camera frames are dropped first
(the queue half full), then whole cycles (the queue full): the loop never waits for the recorder.
Every drop is counted (:attr:`Recorder.dropped_frames`, :attr:`Recorder.dropped_cycles`) and
written into the recording's ``events`` when it closes, so a gap is never silent. On Linux the
thread runs at a low priority (nice 15), so on a busy machine the loop's own threads come first.
"""

from __future__ import annotations

import math
import os
import queue
import threading
import time
import uuid
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._arrays import real
from .._errors import ParameterError
from .._extras import need
from ..plate.drive import PLATE_SIZE, DriveLimits
from ..plate.pulses import Pulse
from .layout import blueprint, colors_of

__all__ = ["Recorder", "field_on_grid", "pulse_series"]

FloatArray = NDArray[np.float64]
_MOTORS = ("X1", "X2", "Y1", "Y2")


@dataclass(frozen=True)
class _Cycle:
    """What the loop saw, asked for and played in one cycle (copies: the loop goes on)."""

    cycle: int
    plate_time: float
    wall: float
    frame: NDArray[np.uint8] | None
    ids: NDArray[np.int64]
    positions: FloatArray
    pixels: FloatArray
    labels: tuple[str, ...]
    lost: NDArray[np.bool_]
    left: tuple[int, ...]
    desired: FloatArray
    achieved: FloatArray
    origins: FloatArray
    errors: FloatArray
    targets: FloatArray | None
    lines: tuple[FloatArray, ...]
    pulses: tuple[Pulse, ...]
    timings: tuple[float, float, float]
    end: str | None


def pulse_series(pulse: Pulse, plate_size: float = PLATE_SIZE, plate: Any = None) -> dict[str, float]:
    """Peaks of one pulse while its envelope is 1: in-plane plate speed [mm/s], rotation rate
    [rad/s], excursion of the plate's farthest corner [mm], and (given ``plate``, for in-plane
    pulses) each motor's force [N], from the pulse's velocity phasors sampled over a whole period."""
    phasors = pulse.phasors()
    w = 2 * math.pi * pulse.frequency
    if pulse.kind == "rest" or w <= 0:
        return {}
    t = np.linspace(0.0, 3.0 / pulse.frequency, 384, endpoint=False)  # a period of 1, 2 and 2/3
    v = np.zeros((len(t), 3))
    d = np.zeros((len(t), 3))
    for h, ph in phasors.items():
        e = np.exp(1j * h * w * t)[:, None]
        v += np.real(ph[None] * e)
        d += np.real(ph[None] / (1j * h * w) * e)
    half = plate_size / 2
    corners = np.array([[half, half], [-half, half], [-half, -half], [half, -half]])
    move = d[:, None, :2] + d[:, None, 2:3] * np.stack([-corners[:, 1], corners[:, 0]], axis=-1)[None]
    out = {
        "speed": 1e3 * float(np.max(np.hypot(v[:, 0], v[:, 1]))),
        "rotation": float(np.max(np.abs(v[:, 2]))),
        "excursion": 1e3 * float(np.max(np.hypot(move[..., 0], move[..., 1]))),
    }
    if plate is not None:
        try:
            channels = pulse.channels(plate)
        except ParameterError:  # out of the plane: the in-plane motors cannot play it
            return out
        for name, c in zip(_MOTORS, channels, strict=True):
            out[name] = float(np.max(np.abs(c.force(t))))
    return out


def field_on_grid(pulses: Sequence[Pulse], points: FloatArray, samples: int = 256) -> FloatArray | None:
    """The pulses' field at ``points (N, 2)`` [m] while their envelopes are 1, weighted by their
    on-times and scaled so the longest arrow is 1 (None for no pulse), at a fixed cost: for an
    in-plane pulse the average force on a part at rest, the mean over ``samples`` times per
    period (three periods of the base, for the 2/3 harmonic of a jet) of the unit surface
    velocity (4.5; :func:`upm.average_field` gives it exactly; the unit velocity jumps where the
    surface velocity passes zero, so the error is about 1 / ``samples`` of mu m g); for an
    out-of-plane pulse the asymptotic velocity field (:func:`upm.asymptotic_field`)."""
    from ..physics.ppod import asymptotic_field

    moving = [p for p in pulses if p.kind != "rest"]
    if not moving:
        return None
    total = np.zeros_like(points)
    for p in moving:
        if p.kind == "field" and p.plate_motion is not None and p.plate_motion.is_spatial:
            total += p.on_time * asymptotic_field(p.plate_motion, points, samples=256, threads=1).velocity
            continue
        t = (np.arange(3 * samples) + 0.5) / (samples * p.frequency)
        u = p.steady().velocity(t)  # (T, 3): the plate's origin and its rotation rate
        vx = u[:, None, 0] - u[:, None, 2] * points[None, :, 1]
        vy = u[:, None, 1] + u[:, None, 2] * points[None, :, 0]
        speed = np.maximum(np.hypot(vx, vy), 1e-300)
        total += p.on_time * np.stack([np.mean(vx / speed, axis=0), np.mean(vy / speed, axis=0)], axis=-1)
    top = float(np.max(np.hypot(total[:, 0], total[:, 1])))
    out: FloatArray = total / top if top > 0 else total
    return out


class Recorder:
    """A rerun recording of a loop (``Loop.run(..., recording=...)``) or of anything else logged
    through :attr:`rec` (the underlying ``rerun.RecordingStream``).

    Parameters
    ----------
    target : str or Path, or "spawn"
        An ``.rrd`` file to write, or ``"spawn"`` to stream to a new viewer.
    application : str
        The recording's application id.
    max_queue : int
        Cycles the background thread may fall behind before cycles are dropped (frames are dropped
        from half of it).
    frame_rate : float
        At most this many camera frames per second of wall time are recorded.
    field_grid : int
        The planned pulses' force field is drawn on ``field_grid x field_grid`` arrows over the
        plate (0: not drawn).
    """

    def __init__(
        self,
        target: str | Path,
        *,
        application: str = "upm",
        max_queue: int = 32,
        frame_rate: float = 10.0,
        field_grid: int = 7,
        jpeg_quality: int = 80,
    ) -> None:
        self._rr = need("rerun", "viz", "a rerun recording", "rerun-sdk")
        if not (isinstance(max_queue, int) and max_queue >= 2):
            raise ParameterError(f"max_queue must be an integer >= 2; got {max_queue!r}")
        real("frame_rate", frame_rate, low=0.0, low_open=True)
        if not (isinstance(field_grid, int) and 0 <= field_grid <= 41):
            raise ParameterError(f"field_grid must be an integer in 0..41; got {field_grid!r}")
        if not (isinstance(jpeg_quality, int) and 1 <= jpeg_quality <= 100):
            raise ParameterError(f"jpeg_quality must be an integer in 1..100; got {jpeg_quality!r}")
        self.rec = self._rr.RecordingStream(application, recording_id=str(uuid.uuid4()))
        self.path: Path | None = None
        if str(target) == "spawn":
            self.rec.spawn(default_blueprint=blueprint("loop"))
        else:
            path = Path(target)
            if path.suffix != ".rrd":
                raise ParameterError(f"recording must be a .rrd file (or 'spawn'); got {str(path)!r}")
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                path.touch()
            except OSError as error:
                raise ParameterError(f"recording: cannot write {str(path)!r}: {error.strerror}") from error
            self.path = path
            self.rec.save(path, default_blueprint=blueprint("loop"))
        self.frame_rate, self.field_grid, self.quality = float(frame_rate), field_grid, jpeg_quality
        self.max_queue = max_queue
        self.dropped_frames = 0
        """Camera frames not recorded because the recorder was behind (beyond the rate limit)."""
        self.dropped_cycles = 0
        """Whole cycles not recorded because the recorder's queue was full."""
        self.cycles = 0
        """Cycles recorded."""
        self.cpu_seconds = 0.0
        """CPU time the background thread has spent recording [s] (its thread time)."""
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=max_queue)
        self._last_frame = -math.inf
        self._error: BaseException | None = None
        self._scene: dict[str, Any] = {
            "radius": 0.01,
            "ppm": 1.0,
            "palette": None,
            "plate_size": PLATE_SIZE,
            "plate": DriveLimits().plate,
        }
        self._missing: set[int] = set()
        self._names: dict[int, str] = {}
        self._thread = threading.Thread(target=self._work, name="upm-recorder", daemon=True)
        self._thread.start()
        self._closed = False

    # -- the loop's side: cheap, never blocks ------------------------------------------------------
    def begin(
        self,
        *,
        part_radius: float,
        pixels_per_metre: float,
        palette: Any = None,
        plate_size: float = PLATE_SIZE,
        limits: DriveLimits | None = None,
    ) -> None:
        """What the recording needs to know of the scene (the loop calls it on its first frame)."""
        scene = {
            "radius": float(part_radius),
            "ppm": float(pixels_per_metre),
            "palette": palette,
            "plate_size": float(plate_size),
            "plate": (limits or DriveLimits()).plate,
        }
        self._queue.put(("begin", scene))

    def cycle(
        self,
        *,
        cycle: int,
        plate_time: float,
        tracks: Any,
        frame: NDArray[np.uint8] | None,
        desired: FloatArray,
        achieved: dict[int, FloatArray],
        origins: dict[int, FloatArray],
        errors: FloatArray,
        targets: FloatArray | None,
        lines: Sequence[FloatArray],
        pulses: Sequence[Pulse],
        timings: tuple[float, float, float],
        end: str | None = None,
    ) -> None:
        """Hand one cycle to the recorder (copies what it keeps; drops rather than waits)."""
        if self._closed:
            raise ParameterError("this recorder is closed")
        now = time.time()
        backlog = self._queue.qsize()
        keep = frame is not None and (end is not None or now - self._last_frame >= 1.0 / self.frame_rate)
        if keep and backlog >= self.max_queue // 2:
            keep = False
            self.dropped_frames += 1
        if keep:
            self._last_frame = now
        ids = np.asarray(tracks.ids, dtype=np.int64).copy()
        nan = np.full((len(ids), 2), np.nan)
        ach, org = nan.copy(), nan.copy()
        for k, i in enumerate(ids):
            if int(i) in achieved and int(i) in origins:
                ach[k], org[k] = achieved[int(i)], origins[int(i)]
        item = _Cycle(
            cycle,
            float(plate_time),
            now,
            None if not keep or frame is None else np.array(frame, copy=True),
            ids,
            np.array(tracks.positions, dtype=np.float64),
            np.array(tracks.pixels, dtype=np.float64),
            tuple(tracks.labels),
            np.array(tracks.lost, dtype=bool),
            tuple(int(i) for i in tracks.left),
            np.array(desired, dtype=np.float64),
            ach,
            org,
            np.array(errors, dtype=np.float64),
            None if targets is None else np.array(targets, dtype=np.float64),
            tuple(np.array(x, dtype=np.float64) for x in lines),
            tuple(pulses),
            timings,
            end,
        )
        try:
            self._queue.put_nowait(("cycle", item))
        except queue.Full:
            self.dropped_cycles += 1

    def close(self) -> None:
        """Log what is still queued, the drop counts, and close the file (blocks until written)."""
        if self._closed:
            return
        self._closed = True
        self._queue.put(("close", None))
        self._thread.join()
        self.rec.set_time("wall_time", timestamp=time.time())
        if self.dropped_frames or self.dropped_cycles:
            self.rec.log(
                "events",
                self._rr.TextLog(
                    f"recorder fell behind: {self.dropped_frames} frames and "
                    f"{self.dropped_cycles} cycles not recorded",
                    level="WARN",
                ),
            )
        self.rec.flush()
        self.rec.disconnect()
        if self._error is not None:
            raise ParameterError(f"the recording failed: {self._error}") from self._error

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- the background thread ---------------------------------------------------------------------
    def _work(self) -> None:
        try:  # Linux: a thread is a task with its own nice value; the loop's threads come first
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), 15)
        except (AttributeError, OSError):  # elsewhere, or not allowed: the queue still bounds the cost
            pass
        while True:
            kind, item = self._queue.get()
            if kind == "close":
                return
            if self._error is not None:
                continue  # keep draining so the loop never blocks; close() reports the error
            started = time.thread_time()
            try:
                if kind == "begin":
                    self._begin(item)
                else:
                    self._log(item)
                    self.cycles += 1
            except Exception as error:
                self._error = error
            self.cpu_seconds += time.thread_time() - started

    def _begin(self, scene: dict[str, Any]) -> None:
        rr = self._rr
        self._scene = scene
        h = scene["plate_size"] / 2
        self.rec.log("plate", rr.Transform3D(mat3x3=[[1, 0, 0], [0, -1, 0], [0, 0, 1]]), static=True)
        edge = [[-h, -h], [h, -h], [h, h], [-h, h], [-h, -h]]
        self.rec.log("plate/outline", rr.LineStrips2D([edge], colors=[(90, 90, 90)]), static=True)
        self.rec.log("series/motors", rr.SeriesLines(names=list(_MOTORS)), static=True)
        self.rec.log("series/timing", rr.SeriesLines(names=["vision", "planning", "execution"]), static=True)
        self.rec.log(
            "series/plate/motion", rr.SeriesLines(names=["excursion [mm]", "rotation [rad/s]"]), static=True
        )

    def _log(self, c: _Cycle) -> None:
        rr, rec, scene = self._rr, self.rec, self._scene
        rec.set_time("frame", sequence=c.cycle)
        rec.set_time("plate_time", duration=c.plate_time)
        rec.set_time("wall_time", timestamp=c.wall)
        for k, i in enumerate(c.ids):
            self._names[int(i)] = f"{int(i)} {c.labels[k]}"
        names = [self._names[int(i)] for i in c.ids]
        colors = colors_of(list(c.labels), scene["palette"])
        seen = ~c.lost & np.all(np.isfinite(c.positions), axis=1)
        if c.frame is not None:
            import cv2

            ok, jpeg = cv2.imencode(".jpg", c.frame, [cv2.IMWRITE_JPEG_QUALITY, self.quality])
            if ok:
                rec.log("camera/image", rr.EncodedImage(contents=jpeg.tobytes(), media_type="image/jpeg"))
        rec.log(
            "camera/parts",
            rr.Points2D(
                c.pixels[seen],
                radii=scene["radius"] * scene["ppm"],
                colors=colors[seen],
                labels=[n for n, s in zip(names, seen, strict=True) if s],
                class_ids=c.ids[seen],
            ),
        )
        rec.log(
            "plate/parts",
            rr.Points2D(
                c.positions[seen],
                radii=scene["radius"],
                colors=colors[seen],
                labels=[n for n, s in zip(names, seen, strict=True) if s],
                class_ids=c.ids[seen],
                show_labels=True,
            ),
        )
        if c.targets is not None:
            aim = np.all(np.isfinite(c.targets), axis=1)
            rec.log(
                "plate/goals", rr.Points2D(c.targets[aim], radii=0.3 * scene["radius"], colors=colors[aim])
            )
        rec.log("plate/task", rr.LineStrips2D(list(c.lines), colors=[(230, 200, 60)]))
        asked = seen & np.all(np.isfinite(c.desired), axis=1)
        rec.log(
            "plate/steps/desired",
            rr.Arrows2D(origins=c.positions[asked], vectors=c.desired[asked], colors=[(80, 160, 255)]),
        )
        got = np.all(np.isfinite(c.achieved), axis=1)
        rec.log(
            "plate/steps/achieved",
            rr.Arrows2D(origins=c.origins[got], vectors=c.achieved[got], colors=[(255, 120, 60)]),
        )
        played = [p for p in c.pulses if p.kind != "rest"]
        rec.log(
            "plate/centers",
            rr.Points2D(
                np.array([p.center for p in played]).reshape(-1, 2), radii=0.004, colors=[(220, 40, 40)]
            ),
        )
        self._field(played)
        self._series(c, played, seen)
        self._events(c, names)

    def _field(self, played: list[Pulse]) -> None:
        """The played pulses' force field on a grid over the plate (skipped when behind)."""
        n = self.field_grid
        if not n or not played or self._queue.qsize() >= self.max_queue // 2:
            return  # behind: the field is the costliest thing here, skip it this cycle
        h = 0.9 * self._scene["plate_size"] / 2
        axis = np.linspace(-h, h, n)
        grid = np.stack(np.meshgrid(axis, axis), axis=-1).reshape(-1, 2)
        f = field_on_grid(played, grid)
        if f is not None:
            self.rec.log(
                "plate/field",
                self._rr.Arrows2D(origins=grid, vectors=f * (axis[1] - axis[0]), colors=[(120, 200, 120)]),
            )

    def _series(self, c: _Cycle, played: list[Pulse], seen: NDArray[np.bool_]) -> None:
        rr, rec = self._rr, self.rec
        rec.log("series/timing", rr.Scalars(1e3 * np.asarray(c.timings)))
        err = c.errors[np.isfinite(c.errors)]
        if len(err):
            rec.log("series/task/error", rr.Scalars(1e3 * float(np.max(err))))
        rec.log("series/task/seen", rr.Scalars(float(np.sum(seen))))
        start = c.plate_time
        for p in played:  # each pulse at the plate time it starts
            rec.set_time("plate_time", duration=start)
            peaks = pulse_series(p, self._scene["plate_size"], self._scene["plate"])
            rec.log("series/plate/speed", rr.Scalars(peaks["speed"]))
            rec.log("series/plate/motion", rr.Scalars([peaks["excursion"], peaks["rotation"]]))
            if _MOTORS[0] in peaks:
                rec.log("series/motors", rr.Scalars([peaks[m] for m in _MOTORS]))
            start += p.duration
        rec.set_time("plate_time", duration=c.plate_time)

    def _events(self, c: _Cycle, names: list[str]) -> None:
        rr, rec = self._rr, self.rec
        for k, i in enumerate(c.ids):
            i = int(i)
            if c.lost[k] and i not in self._missing:
                self._missing.add(i)
                rec.log("events", rr.TextLog(f"part {names[k]} lost from view", level="WARN"))
            elif not c.lost[k] and i in self._missing:
                self._missing.discard(i)
                rec.log("events", rr.TextLog(f"part {names[k]} seen again", level="INFO"))
        for i in c.left:
            rec.log(
                "events",
                rr.TextLog(f"part {self._names.get(i, i)} dropped: lost for too long", level="ERROR"),
            )
        if c.end is not None:
            rec.log("events", rr.TextLog(f"run ended: {c.end}", level="INFO"))
