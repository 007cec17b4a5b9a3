"""The desk's web server (starlette on uvicorn): the page, its script, and one WebSocket per page.

Over the socket the server sends the desk's state as JSON about ten times a second and each new
camera frame as a binary JPEG message (at the desk's frame rate); the page sends commands as JSON
(:data:`upm.desk.session.COMMANDS`). A bad command is answered ``{"type": "error", "message": ...}``
and changes nothing. When the last page disconnects, the plate stops.
"""

from __future__ import annotations

import asyncio
import json
import sys
import threading
import time
from importlib import resources
from typing import Any

from .._errors import ParameterError
from .._extras import need
from .session import Desk

__all__ = ["DeskServer", "app"]

LOCAL = ("127.0.0.1", "localhost", "::1")


def app(desk: Desk, *, state_rate: float = 10.0) -> Any:
    """The ASGI application serving ``desk``."""
    need("starlette", "desk", "the desk", "starlette")
    from starlette.applications import Starlette
    from starlette.responses import HTMLResponse, Response
    from starlette.routing import Route, WebSocketRoute
    from starlette.websockets import WebSocket, WebSocketDisconnect

    static = resources.files("upm.desk") / "static"
    clients: set[int] = set()

    async def page(request: Any) -> Any:
        return HTMLResponse((static / "index.html").read_text())

    async def script(request: Any) -> Any:
        return Response((static / "desk.js").read_text(), media_type="text/javascript")

    async def socket(ws: WebSocket) -> None:
        await ws.accept()
        clients.add(id(ws))
        desk.command({"type": "heartbeat"})

        async def send() -> None:
            frame = -1
            while True:
                if desk.frame_seq != frame:
                    frame = desk.frame_seq
                    await ws.send_bytes(desk.jpeg)
                await ws.send_text(json.dumps(desk.view()))
                await asyncio.sleep(1.0 / state_rate)

        sender = asyncio.create_task(send())
        try:
            while True:
                text = await ws.receive_text()
                try:
                    message = json.loads(text)
                except ValueError as error:
                    await ws.send_text(
                        json.dumps({"type": "error", "message": f"malformed message: {error}"})
                    )
                    continue
                try:  # commands may wait for the plate to stop: off the event loop
                    done = await asyncio.to_thread(desk.command, message)
                except ParameterError as error:
                    await ws.send_text(json.dumps({"type": "error", "message": str(error)}))
                    continue
                if message.get("type") != "heartbeat":
                    await ws.send_text(json.dumps({"type": "ack", "message": done}))
        except WebSocketDisconnect:
            pass
        finally:
            sender.cancel()
            clients.discard(id(ws))
            if not clients:
                await asyncio.to_thread(desk.stop, "the page closed")

    return Starlette(routes=[Route("/", page), Route("/desk.js", script), WebSocketRoute("/ws", socket)])


class DeskServer:
    """Serve a :class:`Desk` on ``host:port`` from a background thread (``url``, ``close()``)."""

    def __init__(self, desk: Desk, *, host: str = "127.0.0.1", port: int = 8765) -> None:
        uvicorn = need("uvicorn", "desk", "the desk", "uvicorn")
        if host not in LOCAL:
            print(
                f"upm desk: WARNING: serving on {host}: anyone who can reach it can move the plate",
                file=sys.stderr,
            )
        self.desk = desk
        config = uvicorn.Config(app(desk), host=host, port=port, log_level="warning", ws="websockets-sansio")
        self.server = uvicorn.Server(config)
        self.url = f"http://{'[' + host + ']' if ':' in host else host}:{port}/"
        self._thread = threading.Thread(target=self.server.run, name="upm-desk-server", daemon=True)
        self._thread.start()
        deadline = time.monotonic() + 20
        while not self.server.started:
            if not self._thread.is_alive() or time.monotonic() > deadline:
                raise ParameterError(
                    f"the desk's server did not start on {host}:{port} (is the port in use?)"
                )
            time.sleep(0.02)

    def close(self) -> None:
        self.server.should_exit = True
        self._thread.join(10)
        self.desk.close()

    def __enter__(self) -> DeskServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
