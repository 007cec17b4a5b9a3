"""``RemoteCamera``: frames from a camera served over TCP (the board emulator's ``--camera-port``),
read like an OpenCV ``VideoCapture``. The wire format is in :mod:`upm.board.emulator`."""

from __future__ import annotations

import socket
import struct

import numpy as np
from numpy.typing import NDArray

from .._errors import VisionError

__all__ = ["RemoteCamera"]


class RemoteCamera:
    """A camera at ``address`` (``"tcp://host:port"`` or ``"host:port"``).

    ``read()`` returns ``(True, frame)`` or ``(False, None)`` once the server has gone;
    :meth:`truth` returns the simulation's true part positions [m] (NaN: fell off), and
    :meth:`max_excursion` the largest plate-corner excursion of the simulated plate [m].
    """

    def __init__(self, address: str, timeout: float = 10.0) -> None:
        host, _, port = address.removeprefix("tcp://").rpartition(":")
        if not host or not port.isdigit():
            raise VisionError(f"address must be tcp://host:port; got {address!r}")
        try:
            self._sock: socket.socket | None = socket.create_connection((host, int(port)), timeout=timeout)
        except OSError as error:
            raise VisionError(f"cannot reach the camera at {address!r}: {error}") from error
        self.address = address

    def _recv(self, n: int) -> bytes:
        assert self._sock is not None
        chunks, got = [], 0
        while got < n:
            chunk = self._sock.recv(min(n - got, 1 << 20))
            if not chunk:
                raise ConnectionError("the camera closed the connection")
            chunks.append(chunk)
            got += len(chunk)
        return b"".join(chunks)

    def _ask(self, request: bytes, magic: bytes) -> None:
        if self._sock is None:
            raise VisionError("the camera is released")
        self._sock.sendall(request)
        if self._recv(4) != magic:
            raise VisionError(f"the camera at {self.address!r} answered something else than {magic!r}")

    def read(self) -> tuple[bool, NDArray[np.uint8] | None]:
        try:
            self._ask(b"F", b"UPMF")
            h, w, c = struct.unpack("<3I", self._recv(12))
            data = self._recv(h * w * c)
        except (ConnectionError, OSError):
            self.release()
            return False, None
        frame = np.frombuffer(data, dtype=np.uint8).reshape((h, w, c) if c > 1 else (h, w))
        return True, frame.copy()

    def truth(self) -> NDArray[np.float64]:
        """The true part positions ``(M, 2)`` [m] (simulation only)."""
        try:
            self._ask(b"P", b"UPMP")
            (n,) = struct.unpack("<I", self._recv(4))
            data = self._recv(16 * n)
        except (ConnectionError, OSError) as error:
            raise VisionError(f"the camera at {self.address!r} is gone: {error}") from error
        return np.frombuffer(data, dtype="<f8").reshape(n, 2).astype(np.float64)

    def max_excursion(self) -> float:
        """The largest plate-corner excursion the simulated plate has made [m] (simulation only)."""
        try:
            self._ask(b"S", b"UPMS")
            (value,) = struct.unpack("<d", self._recv(8))
        except (ConnectionError, OSError) as error:
            raise VisionError(f"the camera at {self.address!r} is gone: {error}") from error
        return float(value)

    def isOpened(self) -> bool:
        return self._sock is not None

    def release(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def __enter__(self) -> RemoteCamera:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()
