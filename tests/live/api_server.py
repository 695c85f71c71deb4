"""A real HTTP server for API tests: uvicorn on a free loopback port, in a thread, with the app's lifespan.

For what only a socket shows (declared and chunked bodies, closed connections, many connections at once, client
addresses, a browser). The in-process ``TestClient`` does the rest.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator

import uvicorn
from fastapi import FastAPI

from tests.live.helpers import wait_for
from windwarden.live.router import free_port


@contextlib.contextmanager
def serve(app: FastAPI, host: str = "127.0.0.1") -> Iterator[str]:
    """``app`` served at the yielded base URL until the block ends."""
    port = free_port(host)
    config = uvicorn.Config(app, host=host, port=port, http="h11", lifespan="on", log_level="warning", access_log=False)
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, name="uvicorn", daemon=True)
    thread.start()
    try:
        assert wait_for(lambda: server.started or not thread.is_alive(), 30) and server.started, "uvicorn did not start"
        yield f"http://{host}:{port}"
    finally:
        server.should_exit = True
        thread.join(15)
