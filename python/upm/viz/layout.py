"""Where things live in a upm recording: the entity paths, the timelines, the part colours and the
default layout (a rerun blueprint). docs/viz.md lists the same table for readers.

Plate entities are in the plate frame [m] (x right, y up: ``plate`` carries a transform that
flips y so the viewer's 2-D view, whose y points down, shows the plate the right way up); camera
entities are in image pixels.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["ENTITIES", "TIMELINES", "blueprint", "colors_of"]

#: The timelines every upm recording uses.
TIMELINES = {
    "frame": "cycle of the loop (or record index of a simulation)",
    "plate_time": "plate time [s]: the pulses played so far",
    "wall_time": "wall-clock time of the host",
}

#: Entity path -> what it holds. Stable across versions: replays and scripts may rely on them.
ENTITIES = {
    "camera/image": "EncodedImage: the camera frame (JPEG, at most about 10 per second of wall time)",
    "camera/parts": "Points2D [px]: tracked parts in the image, labelled 'id label'",
    "plate/outline": "LineStrips2D [m]: the plate's edge (static)",
    "plate/parts": "Points2D [m]: tracked parts (radius, label colour, 'id label'); class id: part id",
    "plate/goals": "Points2D [m]: where each part is sent now (goal or moving reference)",
    "plate/task": "LineStrips2D [m]: the task's lines (paths, sorting lines, the gathering circle)",
    "plate/steps/desired": "Arrows2D [m]: the steps asked for this cycle, from each part",
    "plate/steps/achieved": "Arrows2D [m]: the steps measured on the next frame, from where each part was",
    "plate/field": "Arrows2D [m]: the planned pulses' average force field (in-plane pulses) or drift "
    "direction (out-of-plane fields), longest arrow one grid spacing",
    "plate/centers": "Points2D [m]: centres (rotations) or foci (jets) of the planned pulses",
    "series/plate/speed": "Scalars [mm/s]: peak in-plane plate speed of each pulse",
    "series/plate/motion": "Scalars, 2 series: peak excursion of the farthest plate corner [mm] and peak "
    "rotation rate [rad/s] of each pulse",
    "series/motors": "Scalars [N], 4 series X1, X2, Y1, Y2: each motor's peak force (in-plane pulses)",
    "series/timing": "Scalars [ms], 3 series: vision, planning and execution time of the cycle",
    "series/task/error": "Scalars [mm]: the largest error of a tracked part against the task",
    "series/task/seen": "Scalars: parts tracked in this frame",
    "events": "TextLog: parts lost and found, the run's end, frames the recorder dropped",
    "sim/parts": "Points2D [m]: a simulation's parts (SimResult.to_rerun)",
    "sim/velocities": "Arrows2D [m/s]: a simulation's part velocities",
    "sim/orientation": "Arrows2D [m]: a disk's orientation (a radius drawn at its angle)",
    "series/sim/{stuck,speed}": "Scalars: fraction of parts stuck to the plate; mean speed [mm/s]",
    "mchip/part": "Boxes3D [m]: the M-Chip's part, posed (MChipResult.to_rerun)",
    "mchip/path": "LineStrips3D [m]: the part's path (static)",
    "series/mchip/{x,y,z}": "Scalars [mm]: the part's centre",
    "series/mchip/resonators/{k}": "Scalars [mrad]: each resonator's angle",
}


def colors_of(labels: tuple[str, ...] | list[str], palette: Any = None) -> NDArray[np.uint8]:
    """RGB colours of part labels: the palette's reference colour (BGR in the palette), grey for a
    label it does not know."""
    colors = {} if palette is None else dict(getattr(palette, "colors", {}))
    out = np.full((len(labels), 3), 160, dtype=np.uint8)
    for k, lab in enumerate(labels):
        if lab in colors:
            b, g, r = (round(float(c)) for c in colors[lab])
            out[k] = (r, g, b)
    return out


def blueprint(kind: str = "loop") -> Any:
    """The default layout of a recording: for a loop, the camera, the plate and the series side by
    side; for a simulation (``"sim"``) or the M-Chip (``"mchip"``), its view and its series."""
    import rerun.blueprint as rrb

    if kind == "sim":
        main: Any = rrb.Spatial2DView(origin="/", contents=["/plate/**", "/sim/**"], name="plate")
        side: Any = rrb.TimeSeriesView(origin="/series/sim", name="parts")
    elif kind == "mchip":
        main = rrb.Spatial3DView(origin="/mchip", name="M-Chip")
        side = rrb.Vertical(
            rrb.TimeSeriesView(
                origin="/series/mchip",
                contents=["/series/mchip/x", "/series/mchip/y", "/series/mchip/z"],
                name="part [mm]",
            ),
            rrb.TimeSeriesView(origin="/series/mchip/resonators", name="resonators [mrad]"),
        )
    else:
        main = rrb.Horizontal(
            rrb.Spatial2DView(origin="/camera", name="camera"),
            rrb.Spatial2DView(origin="/plate", name="plate"),
        )
        side = rrb.Vertical(
            rrb.TimeSeriesView(
                origin="/series/plate", contents=["/series/plate/speed"], name="plate speed [mm/s]"
            ),
            rrb.TimeSeriesView(
                origin="/series/plate",
                contents=["/series/plate/motion"],
                name="excursion [mm], rotation [rad/s]",
            ),
            rrb.TimeSeriesView(origin="/series/motors", name="motors [N]"),
            rrb.TimeSeriesView(origin="/series/timing", name="cycle [ms]"),
            rrb.TimeSeriesView(
                origin="/series/task", contents=["/series/task/error"], name="task error [mm]"
            ),
            rrb.TextLogView(origin="/events", name="events"),
        )
    return rrb.Blueprint(
        rrb.Horizontal(main, side, column_shares=[3, 2]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline="plate_time", play_state="following"),
    )
