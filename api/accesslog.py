"""The access log and the request counters: every HTTP request, refused or not, one JSON line in the run folder.

``AccessLog`` is the outermost of the API's own ASGI middlewares, so it sees what ``api.guard`` refuses (401,
413, 429, 503) as well as what the routes answer. A line::

    {"time": "2026-01-01T12:00:00.123Z", "client": "127.0.0.1:50312", "method": "POST", "path": "/faults",
     "route": "/faults", "status": 429, "bytes": 83, "bytes_in": 0, "duration_ms": 0.41, "refused": "rate_limited"}

``bytes`` is the response body, ``bytes_in`` the request body read (0 when it was refused unread), ``refused``
the reason for a 4xx (or the API's own 503), else null. Raw paths are cut at 512 characters. Requests the HTTP
server itself rejects before they reach the app (a request line or headers over its limits, broken HTTP) are not
in it.
"""

from __future__ import annotations

import json
import time
from collections import Counter
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import IO, Any

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from api.routing import RouteTemplates

MAX_PATH_CHARS = 512
MAX_QUERY_CHARS = 256
METHODS = frozenset({"GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"})  # others are counted as "other"
REFUSALS = {
    400: "bad_request",
    401: "unauthorized",
    403: "forbidden",
    404: "not_found",
    405: "method_not_allowed",
    408: "body_timeout",
    409: "conflict",
    413: "body_too_large",
    422: "invalid",
    429: "rate_limited",
}
"""The reason a refused request is counted under, by status, unless the code that refused it names one
(``scope["state"]["refused"]``: e.g. ``fault_cap`` for a 409, ``overloaded`` for the API's own 503)."""


@dataclass
class ApiCounters:
    """What ``/metrics`` reports of the API itself. Touched only on the event loop."""

    requests: Counter[tuple[str, str, int]] = field(default_factory=Counter)  # (method, route, status)
    refusals: Counter[str] = field(default_factory=Counter)  # reason
    injections: Counter[str] = field(default_factory=Counter)  # accepted / refused


class AccessLogFile:
    """Appends JSON lines; once the file would pass ``max_bytes`` it is renamed to ``<name>.1`` and started anew."""

    def __init__(self, path: Path, max_bytes: int):
        self.path = path
        self.max_bytes = max_bytes
        self._file: IO[str] | None = None
        self._size = 0

    def _open(self) -> IO[str]:
        if self._file is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file = self.path.open("a", encoding="ascii", buffering=1)
            self._size = self._file.tell()
        return self._file

    def write(self, record: dict[str, Any]) -> None:
        line = json.dumps(record, ensure_ascii=True, separators=(",", ":")) + "\n"
        out = self._open()
        if self._size > 0 and self._size + len(line) > self.max_bytes:
            out.close()
            self.path.replace(self.path.with_name(self.path.name + ".1"))
            self._file = None
            out = self._open()
        out.write(line)
        self._size += len(line)

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None


def _cut(text: str, limit: int) -> str:
    return text if len(text) <= limit else f"{text[:limit]}…[+{len(text) - limit} chars]"


def refusal(scope: Scope, status: int) -> str | None:
    named = scope.get("state", {}).get("refused")
    return named if named is not None else REFUSALS.get(status)


class AccessLog:
    """ASGI middleware: times, sizes and logs each HTTP request, and counts it (and its refusal) for ``/metrics``."""

    def __init__(self, app: ASGIApp, log: AccessLogFile | None, counters: ApiCounters, routes: RouteTemplates):
        self.app = app
        self.log = log
        self.counters = counters
        self.routes = routes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        started = time.perf_counter()
        scope.setdefault("state", {})
        sent = {"status": 0, "bytes": 0}

        async def counting_send(message: Message) -> None:
            if message["type"] == "http.response.start":
                sent["status"] = message["status"]
            elif message["type"] == "http.response.body":
                sent["bytes"] += len(message.get("body", b""))
            await send(message)

        try:
            await self.app(scope, receive, counting_send)
        except BaseException:
            sent["status"] = sent["status"] or 500
            raise
        finally:
            self._record(scope, sent["status"] or 500, sent["bytes"], time.perf_counter() - started)

    def _record(self, scope: Scope, status: int, nbytes: int, duration_s: float) -> None:
        route = self.routes.of(scope)
        reason = refusal(scope, status)
        method = scope["method"] if scope["method"] in METHODS else "other"  # metric labels stay bounded
        self.counters.requests[(method, route, status)] += 1
        if reason is not None:
            self.counters.refusals[reason] += 1
        if self.log is None:
            return
        client = scope.get("client")
        query = scope.get("query_string", b"").decode("latin-1")
        record: dict[str, Any] = {
            "time": datetime.now(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z"),
            "client": f"{client[0]}:{client[1]}" if client else None,
            "method": _cut(scope["method"], 32),
            "path": _cut(scope["path"], MAX_PATH_CHARS),
            "route": route,
            "status": status,
            "bytes": nbytes,
            "bytes_in": scope["state"].get("bytes_in", 0),
            "duration_ms": round(duration_s * 1e3, 3),
            "refused": reason,
        }
        if query:
            record["query"] = _cut(query, MAX_QUERY_CHARS)
        self.log.write(record)
