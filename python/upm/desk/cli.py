"""``upm desk``: the simulated plate (or a board and a camera) served to a page on 127.0.0.1."""

from __future__ import annotations

import argparse
import time
from typing import Any

from .._errors import ParameterError
from .session import Desk

__all__ = ["arguments", "hardware", "run", "simulated"]


def arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``upm desk``."""
    parser.add_argument("--host", default="127.0.0.1", help="address to serve on (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=8765, help="port (default 8765)")
    parser.add_argument(
        "--board",
        default=None,
        metavar="URL",
        help="a real board (serial port or pyserial URL) instead of the simulated plate",
    )
    parser.add_argument(
        "--camera",
        default=None,
        metavar="N|tcp://HOST:PORT",
        help="with --board: an OpenCV camera index or a RemoteCamera address",
    )
    parser.add_argument(
        "--six-axis",
        action="store_true",
        help="the simulated plate moves out of its plane (field pulses; Gather)",
    )
    parser.add_argument("--seed", type=int, default=1, help="layout of the simulated parts")
    parser.add_argument(
        "--part-radius", type=float, default=0.0195, help="with --board: the parts' radius [m]"
    )
    parser.add_argument(
        "--watchdog", type=float, default=1.0, help="seconds without the page before the plate stops"
    )
    parser.add_argument(
        "--calibration",
        default=None,
        metavar="FILE",
        help="with --board: the camera calibration (upm calibrate); default: the plate found by its outline",
    )


def simulated(*, six_axis: bool = False, seed: int = 1, contacts: bool = True, **options: Any) -> Desk:
    """A desk on the simulated plate with the sort8 demo's eight chips: the predictive planner on
    the planar plate, or field pulses (FieldPlanner) on a six-actuator one (``six_axis``)."""
    from ..control import FieldPlanner, PredictivePlanner, SimulatedDevice, SimulatedDevice6
    from ..experiments.registry import loop_setup
    from ..plate.drive import DriveLimits
    from ..plate.plant import SimulatedUPM

    setup: Any = loop_setup("sort8", False, seed)
    limits = DriveLimits()
    plant = SimulatedUPM(
        plate=limits.plate,
        axes=limits.axes,
        stroke=limits.stroke,
        parts=setup.parts,
        seed=seed,
        part_radius=setup.radius if contacts else None,
    )
    camera = plant.camera(setup.labels, seed=seed)
    if six_axis:
        device: Any = SimulatedDevice6(plant, seed=seed)
        planner: Any = FieldPlanner()
    else:
        device = SimulatedDevice(plant)
        planner = PredictivePlanner(limits, mu=0.3, part_radius=setup.radius if contacts else None)
    desk = Desk(device, camera, planner, part_radius=setup.radius, gather=six_axis, **options)
    desk.plant = plant  # type: ignore[attr-defined]  # the truth, for tests and reports
    return desk


def hardware(board_url: str, camera: str | None, watchdog: float = 1.0, part_radius: float = 0.0195,
             calibration: str | None = None) -> Desk:  # fmt: skip
    """A desk on a board (``board_url``: a serial port or pyserial URL) and a camera (an OpenCV
    index, or ``tcp://host:port`` of a :class:`upm.vision.RemoteCamera`): the predictive planner
    on a four-motor board, field pulses on a six-axis one; STOP sends the board STOP.
    ``calibration``: the file ``upm calibrate`` wrote (pixels to the plate through the lens)."""
    from ..vision.calibration import Calibration

    lens = None if calibration is None else Calibration.load(calibration)  # refused before the board opens
    from ..board import Board
    from ..control import BoardDevice, FieldPlanner, PredictivePlanner

    if camera is None:
        raise ParameterError("--board needs --camera (an OpenCV camera index or tcp://host:port)")
    link = Board(board_url)
    device = BoardDevice(link, wait_rest=False)  # the desk waits out the rests, STOP ends them
    if camera.isdigit():
        import cv2

        cam: Any = cv2.VideoCapture(int(camera))
        if not cam.isOpened():
            raise ParameterError(f"--camera: cannot open camera {camera}")
    else:
        from ..vision import RemoteCamera

        cam = RemoteCamera(camera)
    planner = FieldPlanner() if link.six_axis else PredictivePlanner(device.limits, mu=0.3)
    return Desk(
        device,
        cam,
        planner,
        part_radius=part_radius,
        realtime=False,
        stop_device=link.stop,
        resume_device=link.clear_stop,
        gather=link.six_axis,
        watchdog=watchdog,
        table=lens,
    )


def run(args: argparse.Namespace) -> int:
    """Serve the desk until Ctrl-C."""
    from .server import DeskServer

    if args.board is not None:
        desk = hardware(args.board, args.camera, args.watchdog, args.part_radius, args.calibration)
    elif args.calibration is not None:
        raise ParameterError("--calibration is for a real camera (--board and --camera)")
    else:
        desk = simulated(six_axis=args.six_axis, seed=args.seed, watchdog=args.watchdog)
    desk.start()
    server = DeskServer(desk, host=args.host, port=args.port)
    print(f"upm desk: open {server.url}  (Ctrl-C to stop)", flush=True)
    try:
        while True:
            time.sleep(1)
    except KeyboardInterrupt:
        return 0
    finally:
        server.close()
