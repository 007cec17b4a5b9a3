"""``upm replay FILE.rrd``: open a recording in rerun's viewer, serve the web viewer on 127.0.0.1,
or write a screenshot of the web viewer (headless Chromium through Playwright) for reports."""

from __future__ import annotations

import contextlib
import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.parse
import urllib.request
from collections.abc import Iterator
from pathlib import Path

from .._errors import MissingExtraError, ParameterError

__all__ = ["chromium", "free_port", "replay", "screenshot", "serve_web"]


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port free on ``host`` now."""
    with socket.socket() as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def chromium() -> str:
    """The Chromium executable Playwright drives (``UPM_CHROMIUM``, else Debian's ``chromium``);
    :class:`upm.MissingExtraError` saying how to install it when there is none."""
    given = os.environ.get("UPM_CHROMIUM")
    for candidate in ([given] if given else []) + ["chromium", "chromium-browser", "google-chrome"]:
        found = shutil.which(candidate) if candidate else None
        if found:
            return found
    raise MissingExtraError(
        "a headless browser is needed and no Chromium was found: apt-get install chromium "
        "(make test installs it), or set UPM_CHROMIUM to its path"
    )


def _rerun_cli() -> list[str]:
    if shutil.which("rerun", path=str(Path(sys.executable).parent)):
        return [str(Path(sys.executable).parent / "rerun")]
    return [sys.executable, "-m", "rerun"]


def _check(path: str | Path) -> Path:
    path = Path(path)
    if not path.is_file():
        raise ParameterError(f"FILE: no recording at {str(path)!r}")
    if path.suffix != ".rrd":
        raise ParameterError(f"FILE must be a .rrd recording; got {str(path)!r}")
    with path.open("rb") as f:
        head = f.read(4)
    if not (len(head) == 4 and head[:3] == b"RRF" and head[3:].isdigit()):
        # rerun's file header ("RRF" and the format's version): anything else opened the viewer on
        # its welcome page and exited 0
        raise ParameterError(f"FILE: {str(path)!r} is not a rerun recording (no RRF header)")
    return path


@contextlib.contextmanager
def serve_web(path: str | Path, *, host: str = "127.0.0.1", port: int | None = None) -> Iterator[str]:
    """Serve ``path`` in rerun's web viewer on ``host`` while the context is open; yields the URL
    to open (the viewer already pointed at the recording)."""
    path = _check(path)
    web = port or free_port(host)
    grpc = free_port(host)
    env = {**os.environ, "RERUN_ANALYTICS": "0"}
    cmd = [
        *_rerun_cli(),
        str(path),
        "--serve-web",
        "--bind",
        host,
        "--web-viewer-port",
        str(web),
        "--port",
        str(grpc),
        "--hide-welcome-screen",
    ]
    # its own process group: the `rerun` launcher starts the viewer as a child, and both must go
    proc = subprocess.Popen(
        cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env, start_new_session=True
    )
    url = f"http://{host}:{web}/?url=" + urllib.parse.quote(f"rerun+http://{host}:{grpc}/proxy", safe="")
    try:
        deadline = time.monotonic() + 30
        while True:
            try:
                with urllib.request.urlopen(f"http://{host}:{web}/", timeout=1):
                    break
            except OSError:
                if proc.poll() is not None or time.monotonic() > deadline:
                    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
                    raise ParameterError(f"rerun's web viewer did not start: {err[-500:]}") from None
                time.sleep(0.2)
        yield url
    finally:
        _end(proc)


def _end(proc: subprocess.Popen[bytes]) -> None:
    """Stop ``proc`` and everything it started (its process group): TERM, then KILL after 5 s."""
    try:
        os.killpg(proc.pid, signal.SIGTERM)
    except ProcessLookupError:
        return
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:
        proc.poll()  # reap the leader, or the group never looks empty
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            break
        time.sleep(0.05)
    else:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(5)


def screenshot(
    path: str | Path, png: str | Path, *, size: tuple[int, int] = (1600, 900), wait: float = 12.0
) -> Path:
    """A picture of ``path`` in rerun's web viewer (its default layout, at the recording's end),
    rendered by headless Chromium (WebGL in software) and written to ``png``: taken ``wait``
    seconds after the viewer opened, or later, a second at a time (up to ``wait`` more), until
    two pictures a second apart agree (a busy machine renders slower)."""
    from .._extras import need

    need("playwright.sync_api", "desk", "a screenshot of the viewer", "playwright")
    from playwright.sync_api import sync_playwright

    png = Path(png)
    png.parent.mkdir(parents=True, exist_ok=True)
    with serve_web(path) as url, sync_playwright() as pw:
        browser = pw.chromium.launch(
            executable_path=chromium(), args=["--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
        )
        try:
            page = browser.new_page(viewport={"width": size[0], "height": size[1]})
            page.goto(url + "&renderer=webgl")
            page.wait_for_selector("canvas", timeout=30_000)
            time.sleep(wait)  # the viewer streams the recording in, then lays it out
            shot = page.screenshot()
            for _ in range(max(1, math.ceil(wait))):
                time.sleep(1.0)
                again = page.screenshot()
                if again == shot:
                    break
                shot = again
            png.write_bytes(shot)
        finally:
            browser.close()
    return png


def replay(
    path: str | Path,
    *,
    web: bool = False,
    png: str | Path | None = None,
    port: int | None = None,
    wait: float = 20.0,
) -> int:
    """What ``upm replay`` does: the native viewer, the web viewer (``web``; until Ctrl-C) or a
    screenshot (``png``, taken ``wait`` seconds after the viewer opened: a long recording takes
    longer to stream in). Returns the exit code."""
    path = _check(path)
    if png is not None:
        print(f"wrote {screenshot(path, png, wait=wait)}")
        return 0
    if web:
        with serve_web(path, port=port) as url:
            print(f"rerun web viewer: {url}  (Ctrl-C to stop)", flush=True)
            try:
                while True:
                    time.sleep(1)
            except KeyboardInterrupt:
                return 0
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        print(
            "upm replay: no display for the native viewer; use --web (or --screenshot PNG)", file=sys.stderr
        )
        return 2
    return subprocess.call([*_rerun_cli(), str(path)])
