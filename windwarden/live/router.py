"""The embedded Zenoh router: a Python session in router mode, so one machine needs no ``zenohd``.

``windwarden up`` runs it in its own process; ``windwarden router`` runs it alone. The router listens on explicit
TCP endpoints with multicast scouting off; clients (plant, supervisor, API) connect to it.
"""

from __future__ import annotations

import socket

import zenoh

from windwarden.live.config import ZenohSettings
from windwarden.live.transport import open_session

DEFAULT_PORT = 7447


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port that was free a moment ago (for tests and ``up --listen auto``)."""
    with socket.socket() as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def open_router(listen: list[str], settings: ZenohSettings | None = None) -> zenoh.Session:
    """A router session listening on ``listen``; close it (or use it as a context manager) to stop routing."""
    base = settings or ZenohSettings()
    conf = base.model_copy(update={"listen": ",".join(listen), "connect": "", "zenoh_mode": "router"})
    return open_session(conf)
