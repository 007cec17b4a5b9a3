"""What a demo leaves behind (``upm demo NAME``): its metrics (:func:`demo_metrics`), the camera's
frames with the tracks drawn in (:func:`draw`), and the files in ``out/NAME/``
(:func:`write_outputs`: ``log.npz``, ``animation.gif``, ``paths.png``, ``errors.png``,
``metrics.json``)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from ..control import Log, Loop

__all__ = ["demo_metrics", "draw", "write_outputs"]

FloatArray = NDArray[np.float64]


class Shown(Protocol):
    """What the outputs read of a demo's set-up (:class:`upm.demos.Setup`)."""

    parts: FloatArray
    labels: list[str]
    references: list[FloatArray]
    centers: FloatArray | None


def _finite(statistic: Callable[..., Any], values: FloatArray, *args: Any) -> float:
    return float(statistic(values, *args)) if np.any(np.isfinite(values)) else float("nan")


def _undone(errors: FloatArray) -> float:
    """Share of the progress (decrease of the parts' errors from cycle to cycle) that later
    cycles undid (increases), over the whole run."""
    if len(errors) < 2:
        return float("nan")
    de = np.diff(errors, axis=0)
    de = de[np.isfinite(de)]
    gained = float(np.sum(np.maximum(-de, 0.0)))
    return float(np.sum(np.maximum(de, 0.0))) / gained if gained > 0 else float("nan")


def demo_metrics(name: str, log: Log, setup: Shown, fallen: int, wall: float, board: bool) -> dict[str, Any]:
    errors = log.errors
    final = errors[-1] if len(errors) else np.zeros(0)
    tracking = log.tracking_error()
    pos = log.positions
    m: dict[str, Any] = {
        "demo": name,
        "done": bool(log.done),
        "cycles": len(log.rows) - 1,
        "plate_time": float(log.meta.get("plate_time", 0.0)),
        "wall_time": wall,
        "board": board,
        "fallen": int(fallen),
        "parts": len(setup.parts),
        "final_error": _finite(np.nanmax, final),
        "median_error": _finite(np.nanmedian, errors),
        "max_error": _finite(np.nanmax, errors[1:]),
        "tracking_error_median": _finite(np.nanmedian, tracking),
        "tracking_error_p90": _finite(np.nanpercentile, tracking, 90),
        "vision_ms": 1000 * float(np.mean(log.vision)) if log.vision else 0.0,
        "planning_ms": 1000 * float(np.mean(log.planning)) if log.planning else 0.0,
        "pulses": int(np.sum(log.pulses)),
        "planning_ms_median": 1000 * float(np.median(log.planning)) if log.planning else 0.0,
        # the plate idles while the host sees and plans (planning ahead while it plays is not counted)
        "dead_time": float(np.sum(log.vision) + np.sum(log.planning)),
        "final_error_max": _finite(np.nanmax, final),
        "undone_share": _undone(errors),
        "errors_by_cycle": [[float(v) for v in row] for row in np.nan_to_num(errors, nan=-1.0)],
    }
    if name == "racetrack" and len(pos):
        c = setup.centers[0] if setup.centers is not None else np.zeros(2)
        first = pos[0]
        inner_first = np.argsort(np.hypot(*(first - c).T))  # columns are tracker ids: order by radius
        pos = pos[:, inner_first]
        turn = np.angle(((pos[1:] - c) @ [1, 1j]) / ((pos[:-1] - c) @ [1, 1j]))  # per cycle, each part
        steps = np.hypot(*np.diff(pos, axis=0).transpose(2, 0, 1))
        m["arc_lengths"] = [float(v) for v in np.nansum(steps, axis=0)]
        m["angles"] = [float(v) for v in np.nansum(turn, axis=0)]
        m["radii"] = [float(v) for v in np.hypot(*(pos[0] - c).T)]
    return m


def draw(
    frames: list[NDArray[np.uint8]], cycles: list[int], log: Log, loop: Loop, setup: Shown
) -> list[NDArray[np.uint8]]:
    import cv2

    table = loop.table
    pos = log.positions
    out = []
    colours = [
        (255, 220, 0),
        (0, 200, 255),
        (255, 0, 255),
        (0, 255, 0),
        (255, 128, 0),
        (0, 128, 255),
        (200, 0, 200),
        (128, 255, 128),
        (255, 255, 255),
        (0, 0, 0),
    ]
    refs = [table.to_camera(r) for r in setup.references]
    for frame, c in zip(frames, cycles, strict=True):
        img = np.asarray(
            cv2.cvtColor(frame, cv2.COLOR_BGR2RGB), dtype=np.uint8
        )  # GIF and MP4 writers take RGB
        for r in refs:
            cv2.polylines(
                img, [np.round(r * 4).astype(np.int32)], False, (90, 90, 90), 1, cv2.LINE_AA, shift=2
            )
        for k in range(pos.shape[1]):
            trail = pos[: c + 1, k]
            trail = trail[np.all(np.isfinite(trail), axis=1)]
            if len(trail) > 1:
                px = np.round(table.to_camera(trail) * 4).astype(np.int32)
                cv2.polylines(img, [px], False, colours[k % len(colours)], 1, cv2.LINE_AA, shift=2)
        t = log.time[min(c, len(log.time) - 1)] if log.time else 0.0
        cv2.putText(
            img,
            f"cycle {c}  t = {t:5.1f} s",
            (8, 20),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.5,
            (255, 255, 255),
            1,
            cv2.LINE_AA,
        )
        out.append(img)
    return out


def write_outputs(
    name: str, out: Path, log: Log, loop: Loop, setup: Shown, metrics: dict[str, Any], mp4: bool
) -> list[Path]:
    import imageio.v3 as iio

    from ..viz import plot

    out.mkdir(parents=True, exist_ok=True)
    written = [log.save(out / "log.npz")]
    frames = draw(log.frames, log.frame_cycles, log, loop, setup)
    if frames:
        step = max(1, len(frames) // 150)
        shown = frames[::step] + ([frames[-1]] if (len(frames) - 1) % step else [])
        small = [f[::2, ::2] for f in shown]
        iio.imwrite(out / "animation.gif", np.stack(small), duration=120, loop=0)
        written.append(out / "animation.gif")
        if mp4:
            try:
                import imageio_ffmpeg  # noqa: F401
            except ImportError as error:
                raise ImportError("MP4 needs imageio-ffmpeg: pip install imageio-ffmpeg") from error
            import imageio.v2 as iio2

            with iio2.get_writer(out / "animation.mp4", fps=10) as writer:
                for f in shown:
                    writer.append_data(f)  # type: ignore[attr-defined]
            written.append(out / "animation.mp4")
    for fname, fig in (
        ("paths.png", plot.loop_paths(log, setup.references, setup.centers, setup.labels)),
        ("errors.png", plot.loop_errors(log)),
    ):
        fig.savefig(out / fname, dpi=110)
        import matplotlib.pyplot as plt  # (there: it drew the figure)

        plt.close(fig)  # a caller running demo after demo keeps none of them open
        written.append(out / fname)
    (out / "metrics.json").write_text(json.dumps(metrics, indent=1))
    written.append(out / "metrics.json")
    return written
