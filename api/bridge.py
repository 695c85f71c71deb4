"""The API's Zenoh side: one session, a liveliness token, the event stream, and queries to plant and supervisor.

Zenoh-python is synchronous: the routes call these methods through a worker thread (``asyncio.to_thread``), and
the event subscriber's callback only appends to a locked list.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from typing import Any

from api.settings import ApiSettings
from windwarden.live.runfolder import EVENTS, read_events
from windwarden.live.transport import LivenessWatch, QueryFailedError, open_session, query_json
from wwcore.events import Event
from wwcore.keys import Process
from wwcore.wire import DropCounter, WireError, decode_json

RUN_INFO_TTL_S = 2.0  # the run description is re-asked at most this often


class EventStore:
    """Events seen on the events key (and, at start, in the run folder), numbered from 0 for ``since`` cursors."""

    def __init__(self, keep: int):
        self._lock = threading.Lock()
        self._events: deque[tuple[int, dict[str, Any]]] = deque(maxlen=keep)
        self._seen: set[tuple] = set()
        self.next_seq = 0

    @staticmethod
    def _key(data: dict[str, Any]) -> tuple:
        return (data.get("wall_time"), data.get("type"), data.get("t"), data.get("target"), data.get("turbine"))

    def add(self, data: dict[str, Any]) -> None:
        with self._lock:
            key = self._key(data)
            if key in self._seen:
                return
            self._seen.add(key)
            self._events.append((self.next_seq, data))
            self.next_seq += 1

    def since(self, cursor: int, limit: int, types: set[str] | None = None) -> tuple[list[dict[str, Any]], int]:
        with self._lock:
            out = [
                {**data, "seq": seq}
                for seq, data in self._events
                if seq >= cursor and (types is None or data.get("type") in types)
            ]
            out = out[:limit]
            nxt = out[-1]["seq"] + 1 if out else max(cursor, self.first_seq())
            return out, nxt

    def first_seq(self) -> int:
        return self._events[0][0] if self._events else self.next_seq

    def count(self) -> int:
        with self._lock:
            return self.next_seq


class Bridge:
    def __init__(self, settings: ApiSettings):
        self.settings = settings
        self.keys = settings.keys
        self.timeout = settings.query_timeout_s
        self.drops = DropCounter()
        self.events = EventStore(settings.events_kept)
        self.session = open_session(settings)
        self._events_sub = self.session.declare_subscriber(self.keys.events_all, self._on_event)
        self.watch = LivenessWatch(self.session, self.keys.alive_all)
        self._token = self.session.liveliness().declare_token(self.keys.alive(Process.API))
        self._info: dict[str, Any] | None = None
        self._info_at = 0.0
        self.started = time.time()
        if settings.run_dir is not None:
            for event in read_events(settings.run_dir / EVENTS):
                self.events.add(event.to_json())

    def close(self) -> None:
        self._token.undeclare()
        self.watch.undeclare()
        self._events_sub.undeclare()
        self.session.close()

    def _on_event(self, sample: Any) -> None:
        try:
            body = decode_json("events", sample.payload.to_bytes())
            Event.from_json(body)  # refuse what would not parse as an event
        except (WireError, KeyError, ValueError, TypeError) as error:
            self.drops.add("events", getattr(error, "reason", "bad_body"))
            return
        self.events.add(body)

    # -- queries (blocking; call from a worker thread) ---------------------------------------------------------
    def alive(self, process: str) -> bool:
        return self.watch.is_alive(process)

    def plant_status(self, timeout: float | None = None) -> dict[str, Any]:
        return query_json(self.session, self.keys.plant_status, "plant.status", timeout=timeout or self.timeout)

    def run_info(self) -> dict[str, Any]:
        """The plant's run description (kind, turbines, duration), cached for ``RUN_INFO_TTL_S``."""
        now = time.monotonic()
        if self._info is None or now - self._info_at > RUN_INFO_TTL_S:
            self._info = query_json(self.session, self.keys.run, "plant.run", timeout=self.timeout)
            self._info_at = now
        return self._info

    def faults(self, body: dict[str, Any]) -> dict[str, Any]:
        return query_json(self.session, self.keys.faults, "plant.faults", body, timeout=self.timeout)

    def supervisor_status(self, timeout: float | None = None) -> dict[str, Any]:
        return query_json(
            self.session, self.keys.supervisor_status, "supervisor.status", timeout=timeout or self.timeout
        )


__all__ = ["Bridge", "EventStore", "QueryFailedError"]
