"""The run's Rerun recorder and viewers, as child processes of the ``rerun`` CLI that ships with rerun-sdk.

* recorder: ``rerun --serve-grpc --save runs/<id>/recording.rrd``, a gRPC proxy on 127.0.0.1 that plant and
  supervisor push to (same recording id: one recording) and that streams everything it receives to the file;
* ``--viewer web``: ``rerun --serve-web <proxy>``, the web viewer, connected to that proxy;
* ``--viewer spawn``: ``rerun --connect <proxy>``, the native viewer, connected to that proxy.

Viewers join late without loss: the proxy keeps the stream for them (up to ``SERVER_MEMORY``).
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import quote

from windwarden.live.finalize import rerun_binary
from windwarden.live.router import free_port

SERVER_MEMORY = "512MiB"


def proxy_url(port: int, host: str = "127.0.0.1") -> str:
    return f"rerun+http://{host}:{port}/proxy"


@dataclass
class RecorderCommand:
    """The argv of the recorder and of the optional viewer, and where they can be reached."""

    recorder: list[str]
    url: str
    viewer: list[str] | None = None
    web_url: str | None = None


def recorder_command(
    recording: Path, viewer: str = "none", grpc_port: int | None = None, web_port: int | None = None
) -> RecorderCommand:
    rerun = rerun_binary()
    port = grpc_port or free_port()
    url = proxy_url(port)
    recorder = [
        rerun,
        "--serve-grpc",
        "--bind",
        "127.0.0.1",
        "--port",
        str(port),
        "--server-memory-limit",
        SERVER_MEMORY,
        "--save",
        str(recording),
    ]
    if viewer == "web":
        web = web_port or free_port()
        cmd = [rerun, "--serve-web", "--bind", "127.0.0.1", "--web-viewer-port", str(web), url]
        return RecorderCommand(recorder, url, cmd, f"http://127.0.0.1:{web}/?url={quote(url, safe='')}")
    if viewer == "spawn":
        return RecorderCommand(recorder, url, [rerun, "--connect", url])
    return RecorderCommand(recorder, url)


def start(argv: list[str], log: Path) -> subprocess.Popen:
    """Start a Rerun child in its own session (Ctrl-C in the terminal reaches ``up`` only)."""
    with log.open("ab") as out:
        return subprocess.Popen(
            argv, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True
        )


def stop(proc: subprocess.Popen, timeout: float = 15.0) -> int:
    """SIGTERM the child's whole process group (its session), then SIGKILL it if it does not go."""
    for sig in (signal.SIGTERM, signal.SIGKILL):
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, sig)
        try:
            return proc.wait(timeout)
        except subprocess.TimeoutExpired:
            continue
    return proc.wait()
