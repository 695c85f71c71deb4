"""Zenoh at the edge: sessions, publishers with the registry's QoS, liveliness watching, JSON queryables.

Every process opens one session (``open_session``) configured from ``ZenohSettings``: explicit endpoints,
multicast scouting off unless asked for, a short link lease so a hung peer is declared gone in under a second,
and the process's role credentials for a router with access control (``windwarden.live.access``): a user name and
password (``WINDWARDEN_ZENOH_USER``, ``WINDWARDEN_ZENOH_PASSWORD_FILE``) and/or a TLS client certificate.
"""

from __future__ import annotations

import json
import logging
import queue
import threading
import time
from collections.abc import Callable
from typing import Any

import zenoh

from windwarden.live.config import ZenohSettings
from wwcore.keys import Qos
from wwcore.wire import DropCounter, WireError, decode_json, encode_json

log = logging.getLogger(__name__)


def zenoh_config(settings: ZenohSettings, mode: str | None = None) -> zenoh.Config:
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(mode or settings.zenoh_mode))
    conf.insert_json5("scouting/multicast/enabled", json.dumps(settings.multicast))
    if settings.connect_endpoints:
        conf.insert_json5("connect/endpoints", json.dumps(settings.connect_endpoints))
        timeout = -1 if settings.connect_timeout_s < 0 else round(1000 * settings.connect_timeout_s)
        conf.insert_json5("connect/timeout_ms", json.dumps({"client": timeout, "peer": timeout}))
    if settings.listen_endpoints:
        conf.insert_json5("listen/endpoints", json.dumps(settings.listen_endpoints))
    # A peer that sends nothing for lease_ms is gone (keep-alives every lease/4): liveliness within a second.
    conf.insert_json5("transport/link/tx/lease", str(settings.lease_ms))
    conf.insert_json5("transport/link/tx/keep_alive", "4")
    credentials = settings.credentials()
    if credentials is not None:  # the role's user name and password (never logged: the config is not printed)
        conf.insert_json5("transport/auth/usrpwd/user", json.dumps(credentials[0]))
        conf.insert_json5("transport/auth/usrpwd/password", json.dumps(credentials[1]))
    if settings.zenoh_tls_ca is not None:
        tls: dict[str, Any] = {"root_ca_certificate": str(settings.zenoh_tls_ca)}
        if settings.zenoh_tls_cert is not None and settings.zenoh_tls_key is not None:
            tls |= {
                "connect_certificate": str(settings.zenoh_tls_cert),
                "connect_private_key": str(settings.zenoh_tls_key),
                "enable_mtls": True,
            }
        conf.insert_json5("transport/link/tls", json.dumps(tls))
    return conf


def open_session(settings: ZenohSettings, mode: str | None = None) -> zenoh.Session:
    return zenoh.open(zenoh_config(settings, mode))


def declare_publisher(session: zenoh.Session, key: str, qos: Qos) -> zenoh.Publisher:
    """A publisher with the QoS the registry gives its stream."""
    return session.declare_publisher(
        key,
        congestion_control=zenoh.CongestionControl.BLOCK if qos.block else zenoh.CongestionControl.DROP,
        reliability=zenoh.Reliability.RELIABLE if qos.reliable else zenoh.Reliability.BEST_EFFORT,
        priority=getattr(zenoh.Priority, qos.priority),
        express=qos.express,
    )


class LivenessWatch:
    """Which processes of the farm hold a liveliness token, with a callback on every change.

    ``on_change(process, alive)`` runs on a Zenoh thread; keep it short (log an event, set a flag).
    """

    def __init__(self, session: zenoh.Session, key_all: str, on_change: Callable[[str, bool], None] | None = None):
        self._cond = threading.Condition()
        self.alive: set[str] = set()
        self.on_change = on_change
        self._sub = session.liveliness().declare_subscriber(key_all, self._on_sample, history=True)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        process = str(sample.key_expr).rsplit("/", 1)[-1]
        alive = sample.kind == zenoh.SampleKind.PUT
        with self._cond:
            changed = (process in self.alive) != alive
            (self.alive.add if alive else self.alive.discard)(process)
            self._cond.notify_all()
        if changed and self.on_change is not None:
            try:
                self.on_change(process, alive)
            except Exception:  # a failing observer must not take the Zenoh thread down
                log.exception("liveliness callback failed")

    def is_alive(self, process: str) -> bool:
        with self._cond:
            return process in self.alive

    def wait_for(self, process: str, alive: bool = True, timeout: float | None = None) -> bool:
        with self._cond:
            return self._cond.wait_for(lambda: (process in self.alive) == alive, timeout)

    def undeclare(self) -> None:
        self._sub.undeclare()


class JsonQueryable:
    """A queryable answering JSON requests of one schema from a worker thread (never on a Zenoh thread).

    ``handler(body) -> reply body`` may raise ``QueryError`` to answer with an error reply.
    """

    def __init__(
        self,
        session: zenoh.Session,
        key: str,
        schema: str,
        handler: Callable[[dict[str, Any]], dict],
        drops: DropCounter | None = None,
    ):
        self.key = key
        self.schema = schema
        self.handler = handler
        self.drops = drops
        self._queue: queue.SimpleQueue[zenoh.Query | None] = queue.SimpleQueue()
        self._queryable = session.declare_queryable(key, self._queue.put)
        self._thread = threading.Thread(target=self._serve, name=f"query:{key}", daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while True:
            query = self._queue.get()
            if query is None:
                return
            try:
                payload = query.payload.to_bytes() if query.payload is not None else b""
                body = decode_json(self.schema, payload) if payload else {}
                reply = self.handler(body)
                query.reply(self.key, encode_json(self.schema, reply))
            except WireError as error:
                if self.drops is not None:
                    self.drops.add(self.schema, error.reason)
                query.reply_err(json.dumps({"error": str(error)}).encode())
            except QueryError as error:
                query.reply_err(
                    json.dumps({"error": str(error), "status": error.status, "problems": error.problems}).encode()
                )
            except Exception as error:  # reported to the caller, never fatal for the node
                log.exception("query on %s failed", self.key)
                query.reply_err(json.dumps({"error": f"internal error: {error}", "status": 500}).encode())
            finally:
                query.drop()

    def close(self) -> None:
        self._queryable.undeclare()
        self._queue.put(None)
        self._thread.join(timeout=2.0)


class QueryError(Exception):
    """An error answer to a query: HTTP-like ``status`` and (field, message) ``problems``."""

    def __init__(self, message: str, status: int = 400, problems: list[tuple[str, str]] | None = None):
        super().__init__(message)
        self.status = status
        self.problems = [list(p) for p in problems or []]


class QueryFailedError(Exception):
    """``query_json`` got no answer, or an error answer (``status``, ``body``)."""

    def __init__(self, message: str, status: int = 503, body: dict[str, Any] | None = None):
        super().__init__(message)
        self.status = status
        self.body = body or {}


def query_json(
    session: zenoh.Session, key: str, schema: str, body: dict[str, Any] | None = None, timeout: float = 2.0
) -> dict[str, Any]:
    """Ask the queryable on ``key`` and return its reply body; ``QueryFailedError`` on no reply or an error reply."""
    payload = encode_json(schema, body) if body is not None else None
    replies = session.get(key, payload=payload, timeout=timeout)
    for reply in replies:
        if reply.ok is not None:
            try:
                return decode_json(schema, reply.ok.payload.to_bytes())
            except WireError as error:
                raise QueryFailedError(f"bad reply from {key}: {error}", 502) from None
        err = reply.err
        try:
            data = json.loads(err.payload.to_bytes()) if err is not None else {}
        except json.JSONDecodeError:
            data = {}
        raise QueryFailedError(str(data.get("error", "error reply")), int(data.get("status", 502)), data)
    raise QueryFailedError(f"no answer on {key} within {timeout:g} s", 503)


def wait_until(predicate: Callable[[], bool], timeout: float, interval: float = 0.05) -> bool:
    """Poll ``predicate`` until true or ``timeout`` (for state only observable by polling, e.g. matching)."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() >= deadline:
            return False
        time.sleep(interval)
    return True
