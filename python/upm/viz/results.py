"""Simulation results as rerun recordings (``SimResult.to_rerun``, ``MChipResult.to_rerun``), and
recordings read back (:func:`read_recording`) through rerun's own reader."""

from __future__ import annotations

import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._errors import ParameterError
from .._extras import need
from ..plate.drive import PLATE_SIZE
from .layout import blueprint

__all__ = ["Recording", "mchip_to_rerun", "read_recording", "sim_to_rerun"]


def _stream(path: str | Path, kind: str) -> tuple[Any, Any, Path]:
    rr = need("rerun", "viz", "a rerun recording", "rerun-sdk")
    path = Path(path)
    if path.suffix != ".rrd":
        raise ParameterError(f"path must be a .rrd file; got {str(path)!r}")
    path.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream(f"upm-{kind}", recording_id=str(uuid.uuid4()))
    rec.save(path, default_blueprint=blueprint(kind))
    return rr, rec, path


def _close(rec: Any) -> None:
    rec.flush()
    rec.disconnect()


def sim_to_rerun(
    result: Any,
    path: str | Path,
    *,
    radius: float | None = None,
    labels: Any = None,
    plate_size: float = PLATE_SIZE,
) -> Path:
    """Write a :class:`upm.SimResult` to ``path`` (``.rrd``): parts (``sim/parts``, disks with
    their orientation), velocities, the fraction stuck and the mean speed on the ``frame`` (record
    index) and ``plate_time`` timelines; parts leaving the plate as events. A batch result logs
    each world under ``worlds/{b}/``."""
    rr, rec, path = _stream(path, "sim")
    pos = np.asarray(result.positions)
    batch = pos.ndim == 4
    worlds = pos.shape[0] if batch else 1
    m = pos.shape[-2]
    r = 0.004 if radius is None else float(radius)
    if not (np.isfinite(r) and r > 0):
        raise ParameterError(f"radius must be finite and > 0 [m]; got {radius!r}")
    names = [f"{k}" for k in range(m)] if labels is None else [f"{k} {lab}" for k, lab in enumerate(labels)]
    if len(names) != m:
        raise ParameterError(f"labels must have one entry per part ({m}); got {len(names)}")
    h = plate_size / 2
    rec.log("plate", rr.Transform3D(mat3x3=[[1, 0, 0], [0, -1, 0], [0, 0, 1]]), static=True)
    rec.log("plate/outline", rr.LineStrips2D([[[-h, -h], [h, -h], [h, h], [-h, h], [-h, -h]]]), static=True)
    t = np.asarray(result.t)
    for b in range(worlds):
        pre = f"worlds/{b}/" if batch else ""
        p = pos[b] if batch else pos
        v = np.asarray(result.velocities)[b] if batch else np.asarray(result.velocities)
        ang = np.asarray(result.angles)[b] if batch else np.asarray(result.angles)
        stuck = np.asarray(result.stuck)[b] if batch else np.asarray(result.stuck)
        left_t = np.asarray(result.left_time)[b] if batch else np.asarray(result.left_time)
        for k in range(len(t)):
            rec.set_time("frame", sequence=k)
            rec.set_time("plate_time", duration=float(t[k]))
            on = np.all(np.isfinite(p[k]), axis=1)
            rec.log(
                f"{pre}sim/parts",
                rr.Points2D(
                    p[k][on],
                    radii=r,
                    class_ids=np.arange(m)[on],
                    labels=[n for n, o in zip(names, on, strict=True) if o],
                ),
            )
            rec.log(f"{pre}sim/velocities", rr.Arrows2D(origins=p[k][on], vectors=v[k][on]))
            if radius is not None:
                tip = r * np.stack([np.cos(ang[k]), np.sin(ang[k])], axis=-1)
                rec.log(f"{pre}sim/orientation", rr.Arrows2D(origins=p[k][on], vectors=tip[on]))
            if on.any():
                rec.log(f"series/{pre}sim/stuck", rr.Scalars(float(np.mean(stuck[k][on]))))
                rec.log(f"series/{pre}sim/speed", rr.Scalars(1e3 * float(np.mean(np.hypot(*v[k][on].T)))))
        for j in np.nonzero(np.isfinite(left_t))[0]:
            rec.set_time("plate_time", duration=float(left_t[j]))
            rec.log(f"{pre}events", rr.TextLog(f"part {names[j]} left the plate", level="WARN"))
    _close(rec)
    return path


def mchip_to_rerun(result: Any, path: str | Path) -> Path:
    """Write a :class:`upm.mchip.MChipResult` to ``path`` (``.rrd``): the part as a posed box over
    the resonator array, its path, its centre and every resonator's angle as series, and each
    collision as an event."""
    rr, rec, path = _stream(path, "mchip")
    d = result.design
    size = np.asarray(d.part_size) / 2
    t = np.asarray(result.t)
    rec.log("mchip/path", rr.LineStrips3D([np.asarray(result.position)]), static=True)
    pitch_x, pitch_y = d.slab[0] + d.gap, d.slab[1] + d.gap
    cells = np.array(
        [
            [(c - (d.cols - 1) / 2) * pitch_x, (r_ - (d.rows - 1) / 2) * pitch_y, -d.slab[2] / 2]
            for r_ in range(d.rows)
            for c in range(d.cols)
        ]
    )
    rec.log(
        "mchip/array",
        rr.Boxes3D(centers=cells, half_sizes=np.asarray(d.slab) / 2, colors=[(120, 120, 140)]),
        static=True,
    )
    hits = np.asarray(result.collisions)
    times = hits["time"] if len(hits) else np.zeros(0)
    j = 0
    for k in range(len(t)):
        rec.set_time("frame", sequence=k)
        rec.set_time("plate_time", duration=float(t[k]))
        q = np.asarray(result.orientation[k])
        rec.log(
            "mchip/part",
            rr.Boxes3D(
                centers=[result.position[k]],
                half_sizes=[size],
                quaternions=[rr.Quaternion(xyzw=q)],
                colors=[(200, 170, 60)],
            ),
        )
        for axis, name in enumerate("xyz"):
            rec.log(f"series/mchip/{name}", rr.Scalars(1e3 * float(result.position[k][axis])))
        for n, a in enumerate(np.asarray(result.angles[k])):
            rec.log(f"series/mchip/resonators/{n}", rr.Scalars(1e3 * float(a)))
        while j < len(times) and times[j] <= t[k]:
            e = hits[j]
            rec.log(
                "events",
                rr.TextLog(
                    f"collision with resonator {int(e['resonator'])}: impulse "
                    f"{float(e['impulse_normal']):.3g} N s",
                    level="DEBUG",
                ),
            )
            j += 1
    _close(rec)
    return path


@dataclass(frozen=True)
class Recording:
    """A recording read back: per entity path, a dict of columns (timelines and components), one
    row per logged row, in the order they were logged. ``static`` holds the static rows."""

    entities: dict[str, dict[str, list[Any]]]
    static: dict[str, dict[str, list[Any]]]

    def __getitem__(self, entity: str) -> dict[str, list[Any]]:
        key = entity if entity.startswith("/") else "/" + entity
        if key in self.entities:
            return self.entities[key]
        raise KeyError(f"no entity {entity!r} in the recording; it has {sorted(self.entities)}")

    def __contains__(self, entity: object) -> bool:
        return (
            isinstance(entity, str) and (entity if entity.startswith("/") else "/" + entity) in self.entities
        )

    def rows(self, entity: str) -> int:
        """How many rows were logged at ``entity``."""
        columns = self[entity]
        return len(next(iter(columns.values()))) if columns else 0


def read_recording(path: str | Path) -> Recording:
    """Read an ``.rrd`` file through rerun's reader (``rerun.chunk.RrdReader``) into a
    :class:`Recording`; rows of an entity are sorted by ``frame`` (then as logged)."""
    need("rerun", "viz", "reading a recording", "rerun-sdk")
    from rerun.chunk import RrdReader

    path = Path(path)
    if not path.is_file():
        raise ParameterError(f"path: no recording at {str(path)!r}")
    rows: dict[bool, dict[str, list[dict[str, Any]]]] = {True: {}, False: {}}
    for chunk in RrdReader(path).stream().to_chunks():
        table = chunk.to_record_batch().to_pydict()
        table.pop("rerun.controls.RowId", None)
        into = rows[bool(chunk.is_static)].setdefault(chunk.entity_path, [])
        into.extend({k: v[i] for k, v in table.items()} for i in range(chunk.num_rows))

    def columns(found: dict[str, list[dict[str, Any]]]) -> dict[str, dict[str, list[Any]]]:
        out = {}
        for entity, logged in found.items():
            if all(r.get("frame") is not None for r in logged):
                logged = sorted(logged, key=lambda r: r["frame"])  # stable: as logged within a frame
            names = sorted({k for r in logged for k in r})
            out[entity] = {k: [r.get(k) for r in logged] for k in names}
        return out

    timed, static = columns(rows[False]), columns(rows[True])
    return Recording(timed, static)
