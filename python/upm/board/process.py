"""The board emulator's process (:mod:`upm.board.emulator`): serving a
:class:`~upm.board.emulator.BoardEmulator` on a pseudo-terminal or a TCP port, the simulated
plate's overhead camera on another (the wire format is in :mod:`upm.board.emulator`), and the
command line of ``python -m upm.board.emulator`` and ``upm emulate``."""

from __future__ import annotations

import argparse
import json
import os
import select
import socket
import struct
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from ..plate.actuation import Plate
from ..plate.drive import flexures
from ..plate.plant import SimulatedUPM
from ..plate.plate6 import Plate6
from . import protocol as p
from .emulator import BoardEmulator, Faults

__all__ = ["CameraServer", "main", "serve"]


class CameraServer:
    """Serves frames of a virtual camera (and the true part positions) to TCP clients."""

    def __init__(self, camera: Any, port: int = 0) -> None:
        self.camera = camera
        self.server = socket.create_server(("127.0.0.1", port))
        self.server.setblocking(False)
        self.port = int(self.server.getsockname()[1])
        self.clients: list[socket.socket] = []
        self.shot: tuple[np.ndarray, np.ndarray] | None = None  # (the parts it shows, the frame)

    def prepare(self) -> None:
        """Take the next frame now (the parts have just come to rest), as a streaming camera
        would have it ready: the next request gets it at once, if nothing has moved since."""
        _, frame = self.camera.read()
        self.shot = (np.array(self.camera.source.parts, dtype=np.float64), frame)

    def frame(self) -> np.ndarray:
        """The frame for a request: the one taken ahead if nothing has moved since, else a new one."""
        shot, self.shot = self.shot, None
        if shot is not None and np.array_equal(shot[0], self.camera.source.parts, equal_nan=True):
            return shot[1]
        frame: np.ndarray = self.camera.read()[1]
        return frame

    def sockets(self) -> list[socket.socket]:
        return [self.server, *self.clients]

    def handle(self, ready: list[Any]) -> None:
        if self.server in ready:
            try:
                client, _ = self.server.accept()
                client.setblocking(True)
                self.clients.append(client)
            except BlockingIOError:
                pass
        for client in [c for c in self.clients if c in ready]:
            try:
                request = client.recv(1)
                if request == b"F":
                    frame = self.frame()
                    h, w = frame.shape[:2]
                    c = 1 if frame.ndim == 2 else frame.shape[2]
                    client.sendall(
                        b"UPMF" + struct.pack("<3I", h, w, c) + np.ascontiguousarray(frame).tobytes()
                    )
                elif request == b"P":
                    parts = np.ascontiguousarray(self.camera.source.parts, dtype="<f8").reshape(-1, 2)
                    client.sendall(b"UPMP" + struct.pack("<I", len(parts)) + parts.tobytes())
                elif request == b"S":
                    client.sendall(b"UPMS" + struct.pack("<d", float(self.camera.source.max_excursion)))
                else:
                    raise ConnectionError("unknown request")
            except (ConnectionError, OSError):
                client.close()
                self.clients.remove(client)


def serve(
    emulator: BoardEmulator,
    *,
    tcp: int | None = None,
    announce: Callable[[str], object] = print,
    camera: CameraServer | None = None,
) -> None:
    """Run ``emulator`` on a new pseudo-terminal (default) or TCP ``port`` until killed; with
    ``camera``, serve its frames too."""
    if tcp is None:
        import tty

        master, slave = os.openpty()
        # what nobody reads is lost, as on a wire: a blocking write would stall the board (its
        # samples, its watchdog) until a host drained the terminal
        os.set_blocking(master, False)
        tty.setraw(slave)
        announce(os.ttyname(slave))
        if camera is not None:
            announce(f"camera tcp://127.0.0.1:{camera.port}")
        fd_in = fd_out = master
        sock = None
    else:
        server = socket.create_server(("127.0.0.1", tcp))
        announce(f"socket://127.0.0.1:{server.getsockname()[1]}")
        if camera is not None:
            announce(f"camera tcp://127.0.0.1:{camera.port}")
        sock, _ = server.accept()
        sock.setblocking(False)
        fd_in = fd_out = sock.fileno()
    delay = emulator.faults.delay
    pending: list[tuple[float, bytes]] = []
    shot = emulator.pulses  # the pulses done when the camera last took a frame ahead
    while True:
        watched: list[Any] = [fd_in, *(camera.sockets() if camera is not None else [])]
        ready, _, _ = select.select(watched, [], [], 0.002)
        if camera is not None:
            camera.handle(ready)
        now = time.monotonic()
        out = bytearray()
        if fd_in in ready:
            try:
                data = os.read(fd_in, 65536) if sock is None else sock.recv(65536)
            except (BlockingIOError, InterruptedError):
                data = b""
            if sock is not None and data == b"":
                return  # the host closed the connection
            out += emulator.receive(data, now)
        out += emulator.tick(now)
        if out:
            pending.append((now + delay, bytes(out)))
        f = emulator.faults
        if f.stall_after is not None and emulator.t0 is not None:
            since = now - emulator.t0 - f.stall_after
            if 0 <= since < f.stall_for:
                pending.clear()  # stalled: what the board says is lost
        while pending and pending[0][0] <= now:
            chunk = pending.pop(0)[1]
            try:
                os.write(fd_out, chunk) if sock is None else sock.sendall(chunk)
            except (BlockingIOError, OSError):
                pass  # nobody is reading the pty: the bytes are lost, as on a wire
        if camera is not None and emulator.pulses != shot:  # a pulse's parts have come to rest
            shot = emulator.pulses
            camera.prepare()  # while the host waits out the rest: its next frame is ready


def _ranged(kind: type, low: float, high: float, what: str) -> Any:
    """An argparse type: a ``kind`` in ``[low, high]``, or a usage error saying so."""

    def parse(text: str) -> Any:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {what}") from None
        if not (low <= value <= high):  # NaN fails too
            raise argparse.ArgumentTypeError(f"must be {what} in [{low:g}, {high:g}]; got {text}")
        return value

    return parse


_PORT = _ranged(int, 0, 65535, "a TCP port")
_PROBABILITY = _ranged(float, 0.0, 1.0, "a probability")
_SECONDS = _ranged(float, 0.0, 86400.0, "a time in seconds")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="upm emulate", description=__doc__.splitlines()[0])
    parser.add_argument(
        "--tcp", type=_PORT, default=None, help="serve on this TCP port (0: any) instead of a pty"
    )
    parser.add_argument(
        "--watchdog-ms",
        type=_ranged(int, 1, 60000, "milliseconds"),
        default=250,
        help="the watchdog period: motors stop when the host is silent this long (default 250)",
    )
    parser.add_argument(
        "--drop", type=_PROBABILITY, default=0.0, help="probability of dropping an outgoing frame"
    )
    parser.add_argument(
        "--duplicate", type=_PROBABILITY, default=0.0, help="probability of sending an outgoing frame twice"
    )
    parser.add_argument(
        "--corrupt",
        type=_PROBABILITY,
        default=0.0,
        help="probability of flipping a byte of an outgoing frame",
    )
    parser.add_argument("--delay", type=_SECONDS, default=0.0, help="seconds added to every outgoing chunk")
    parser.add_argument(
        "--stall-after", type=_SECONDS, default=None, help="seconds after connection to go silent"
    )
    parser.add_argument("--stall-for", type=_SECONDS, default=0.0, help="seconds of silence")
    parser.add_argument(
        "--seed", type=_ranged(int, 0, 2**63, "a seed"), default=0, help="seed of the faults and sensor noise"
    )
    parser.add_argument(
        "--snr-db",
        type=_ranged(float, -100.0, 300.0, "decibels"),
        default=60.0,
        help="accelerometer signal-to-noise ratio [dB] (default 60)",
    )
    parser.add_argument(
        "--stroke",
        type=_ranged(float, 1e-6, 1.0, "metres"),
        default=None,
        help="largest plate-corner excursion [m] (default 0.01)",
    )
    parser.add_argument(
        "--camera-port",
        type=_PORT,
        default=None,
        help="also serve the overhead camera on this TCP port (0: any)",
    )
    parser.add_argument(
        "--axes",
        type=int,
        choices=(4, 6),
        default=4,
        help="4: the thesis's four-motor plate; 6: a six-actuator plate (protocol v2, "
        "upm.plate6.Plate6; point parts)",
    )
    parser.add_argument(
        "--max-version",
        type=int,
        choices=p.VERSIONS,
        default=p.VERSION,
        help="the highest protocol version spoken",
    )
    parser.add_argument(
        "--scene",
        type=str,
        default=None,
        help='the plate\'s contents, a JSON file: {"parts": [[x, y], ...], "labels": [...], '
        '"mu": 0.3 or one per part, "mu_s", "tilt": [slope_x, slope_y] (rad, a plate not level), '
        '"motor_gain", "motor_phase" (4 each), "camera_latency" (s), "pixel_noise" (px), "lighting_drift", '
        '"friction_map": [[factor, ...], ...] (rows along y over the plate), "stuck": {"part": m/s^2}, '
        '"part_radius": r (colliding disks) or "part_shape": [[x, y], ...], "angles": [...] and optionally '
        '"part_support": [[x, y] x 3] (colliding convex polygons, on three feet), "plate": [m, I, r], '
        '"stroke": 0.01, "camera": {...}, "render": {...}}',
    )
    args = parser.parse_args(argv)
    faults = Faults(
        args.drop, args.duplicate, args.corrupt, args.delay, args.seed, args.stall_after, args.stall_for
    )
    scene: dict[str, Any] = {}
    if args.scene is not None:
        try:
            with open(args.scene) as f:
                scene = json.load(f)
        except (OSError, ValueError) as error:
            parser.error(f"--scene {args.scene}: {error}")
    options: dict[str, Any] = {}
    if "plate" in scene:  # [mass, inertia, lever], on the default flexures
        plate = Plate(*(float(v) for v in scene["plate"]))
        options = {"plate": plate, "axes": flexures(plate.mass, plate.inertia)}
    if "stroke" in scene:  # [m]
        options["stroke"] = float(scene["stroke"])
    if args.stroke is not None:
        options["stroke"] = float(args.stroke)
    if "tilt" in scene:  # the plate's slope [rad] along x and y: not level
        options["tilt"] = tuple(scene["tilt"])
    if "mu_s" in scene:
        options["mu_s"] = scene["mu_s"]
    if "stuck" in scene:  # {part: acceleration [m/s^2]} (JSON keys are strings)
        options["stuck"] = {int(k): v for k, v in scene["stuck"].items()}
    for fault in (
        "motor_gain",
        "motor_phase",
        "camera_latency",
        "pixel_noise",
        "lighting_drift",
        "friction_map",
    ):
        if fault in scene:  # an imperfect machine (SimulatedUPM's options of the same names)
            options[fault] = scene[fault]
    if "part_shape" in scene:  # a convex outline [[x, y], ...] [m]: polygon parts
        from ..physics.polygon import Polygon

        options["part_shape"] = Polygon(scene["part_shape"], support=scene.get("part_support"))
        options["angles"] = scene.get("angles")
    plant = SimulatedUPM(snr_db=args.snr_db, seed=args.seed, parts=scene.get("parts", np.zeros((0, 2))),
                         mu=scene.get("mu", 0.3), part_radius=scene.get("part_radius"),
                         **options)  # fmt: skip
    if args.axes == 6 and (plant.part_radius is not None or plant.part_shape is not None):
        parser.error("--axes 6 moves point parts: leave part_radius and part_shape out of the scene")
    six = Plate6() if args.axes == 6 else None
    emulator = BoardEmulator(plant, watchdog_ms=args.watchdog_ms, faults=faults, plate6=six,
                             max_version=args.max_version)  # fmt: skip
    camera = None
    if args.camera_port is not None:
        from ..vision.synthetic import Camera

        view = plant.camera(scene.get("labels", "penny"), Camera(**scene.get("camera", {})), seed=args.seed,
                            **scene.get("render", {}))  # fmt: skip
        camera = CameraServer(view, args.camera_port)

    def announce(where: str) -> None:
        print(where, flush=True)

    try:
        serve(emulator, tcp=args.tcp, announce=announce, camera=camera)
    except KeyboardInterrupt:
        pass
    return 0
