"""The supervisor process: observers and FDI behind Zenoh, one ``supervisor.step`` per complete sensor tick.

It learns the run from the plant's ``plant/run`` queryable (kind, turbines, published parameters, algorithms;
never faults or truth), builds the supervisor with the constructor batch mode uses, and then, per tick:
``frame`` from the sensor records → ``refs = supervisor.step(frame)`` → the supervisor's events appended to
``events.jsonl`` and published → ``refs`` published, one frame of every turbine's row on ``refs/supervisor``
(reliable, blocking) → the display's share (``_display``: buffered rows, at most one bounded Rerun send). Events
go out before refs, so when the plant holds ``refs_k`` every event up to tick k is in the log; the display comes
after the refs, so a tick's refs never wait on it.

Degradation (DESIGN.md): when no sensors arrive for ``stale_after_s`` or the plant's liveliness token goes, the
stream is marked stale (an event) and nothing more is published from it. Which frames are stepped is decided by
``guard.FrameSequencer``: the observers start afresh only for a new run identity the plant confirms, or after a gap
of more than ``max_gap_ticks`` that the plant's own tick confirms; old, repeated, foreign and unconfirmed frames are
dropped, counted and logged (rate-limited); a shorter gap is bridged (``supervisor.bridge`` on interpolated frames,
``wwcore.stepping``) or, for a supervisor without ``bridge``, held.
"""

from __future__ import annotations

import gc
import logging
import queue
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import zenoh

from windwarden.kinds import PlantKind, RunInfo, kind_for
from windwarden.live.config import SupervisorSettings
from windwarden.live.guard import FrameSequencer, RefusalLog, bridge_gap
from windwarden.live.mailbox import TickMailbox, backlog_ticks
from windwarden.live.readings import ReadingHold
from windwarden.live.run_query import confirm_run, plant_has_measured, query_run, wait_for_run
from windwarden.live.runfolder import EVENTS, EventLog
from windwarden.live.timing import LatencyStats
from windwarden.live.transport import JsonQueryable, LivenessWatch, declare_publisher
from wwcore.events import Event, EventType
from wwcore.keys import COMMAND_QOS, EVENT_QOS, Process
from wwcore.wire import DropCounter, DropReason, WireError, decode_json, encode_json

log = logging.getLogger(__name__)
PLANT_APPEARED = None  # put in the sensor queue by the liveliness callback: the main loop handles it in turn


class SupervisorNode:
    """Serves one plant (and the next one, if the plant restarts) until ``stop()``."""

    def __init__(self, session: zenoh.Session, settings: SupervisorSettings, display_factory: Any | None = None):
        self.session = session
        self.settings = settings
        self.keys = settings.keys
        self.display_factory = display_factory
        self.display: Any | None = None
        self.drops = DropCounter()
        self.step_time = LatencyStats()
        self._stop = threading.Event()
        self._lock = threading.Lock()  # step vs status queries
        self._inbox: queue.SimpleQueue[bytes] = queue.SimpleQueue()
        self._run_ended = threading.Event()
        self.info: RunInfo | None = None
        self.kind: PlantKind | None = None
        self.supervisor: Any | None = None
        self.events: EventLog | None = None
        self.last_tick: int | None = None
        self.last_t = 0.0
        self.last_refs: np.ndarray | None = None
        self.fresh: bool | None = None
        self.frames = 0
        self.resets = 0
        self.gaps = 0
        self.bridged = 0  # ticks bridged across gaps
        self.last_records: np.ndarray | None = None
        self.readings: ReadingHold | None = None  # non-finite readings held, per run (``_start_run``)
        self.sequencer = FrameSequencer(settings.max_gap_ticks, self.drops, self._confirm_run, self._confirm_tick)
        self.refusals = RefusalLog(self.drops, "sensors", Process.SUPERVISOR.value, self._write)
        self._last_status = 0.0
        s = session
        self._events_pub = declare_publisher(s, self.keys.supervisor_events, EVENT_QOS)
        self._status_pub = declare_publisher(s, self.keys.supervisor_status, EVENT_QOS)  # carries the handshake
        self._refs_pub = declare_publisher(s, self.keys.refs(Process.SUPERVISOR), COMMAND_QOS)
        self._sensors_sub: zenoh.Subscriber | None = None  # declared once the supervisor is built (see _start_run)
        self._events_sub = s.declare_subscriber(self.keys.plant_events, self._on_event_sample)
        self._status_q = JsonQueryable(
            s, self.keys.supervisor_status, "supervisor.status", lambda body: self.status(), self.drops
        )
        self.watch = LivenessWatch(s, self.keys.alive_all, self._on_liveliness)
        self._token = s.liveliness().declare_token(self.keys.alive(Process.SUPERVISOR))

    def stop(self) -> None:
        self._stop.set()

    def close(self) -> None:
        self._status_q.close()
        self._token.undeclare()
        self.watch.undeclare()
        if self._sensors_sub is not None:
            self._sensors_sub.undeclare()
        self._events_sub.undeclare()
        if self.events is not None:
            self.events.close()
        if self.display is not None:
            self.display.close()

    # -- events -----------------------------------------------------------------------------------------------------
    def _publish_event(self, event: Event) -> None:
        self._events_pub.put(encode_json("events", event.to_json()))
        if self.display is not None:
            self.display.event(event)

    def _write(self, events: list[Event]) -> None:
        if events and self.events is not None:
            self.events.write(events)

    def _on_liveliness(self, process: str, alive: bool) -> None:
        if process != Process.PLANT:
            return
        self._write(
            [
                Event(
                    self.last_t,
                    EventType.LIVELINESS,
                    detail={"process": process, "alive": alive, "noticed_by": Process.SUPERVISOR.value},
                )
            ]
        )
        if not alive:
            self._mark(False)
        else:  # a plant appeared: the main loop asks it which run it is (``_follow_plant``)
            self._inbox.put(PLANT_APPEARED)

    def _on_event_sample(self, sample: zenoh.Sample) -> None:
        try:
            body = decode_json("events", sample.payload.to_bytes())
        except WireError as error:
            self.drops.add("events", error.reason)
            return
        detail = body.get("detail") or {}
        ended = body.get("type") == EventType.RUN.value and detail.get("phase") == "end"
        if ended and self.info is not None and detail.get("run_id") == self.info.run_id:
            self._run_ended.set()

    def _mark(self, fresh: bool, reset: bool = False) -> None:
        """Stream freshness transitions, logged once each."""
        if fresh == self.fresh:
            return
        if self.fresh is not None or not fresh:
            detail = {"stream": "sensors", "fresh": fresh, "noticed_by": Process.SUPERVISOR.value}
            if reset:
                detail["observers_restarted"] = True
            self._write([Event(self.last_t, EventType.STREAM, detail=detail)])
        self.fresh = fresh

    # -- run set-up -------------------------------------------------------------------------------------------------
    def _start_run(self, info: RunInfo) -> None:
        """(Re)build the supervisor, its event log and its display for the run ``info``."""
        new_run = self.info is None or info.run_id != self.info.run_id
        self.info = info
        self.kind = kind_for(info.kind)
        with self._lock:
            self.supervisor = self.kind.make_supervisor(info)
            self.last_refs = None
        self.turbines = list(info.turbines)
        self.mailbox = TickMailbox(self.kind.sensors, self.turbines, self.drops, "sensors")
        if new_run or self.readings is None:
            self.readings = ReadingHold(self.kind.sensors)
        else:
            self.readings.restart()  # observers restarted: nothing to hold from before; the counts stay
        if new_run:
            if self.events is not None:
                self.events.close()
            folder: Path = self.settings.folder(info.run_id)
            self.events = EventLog(folder / EVENTS, self._publish_event)
            self._run_ended.clear()
            if self.display_factory is not None:
                if self.display is not None:
                    self.display.close()
                self.display = self.display_factory(info)
        self.last_tick = None
        self.last_records = None
        self.sequencer.start(info.run_key)
        self._bridge = getattr(self.supervisor, "bridge", None)
        gc.collect()
        gc.freeze()  # what was built so far is never collected: shorter GC pauses while stepping
        if self._sensors_sub is None:
            # Subscribing last tells the plant (its publishers match) that this supervisor is ready for tick 0.
            self._sensors_sub = self.session.declare_subscriber(
                self.keys.sensors, lambda sample: self._inbox.put(sample.payload.to_bytes())
            )
        # The handshake: this status (sent after the subscription, on the same link) tells the plant that
        # its next sensor sample reaches a built supervisor. Zenoh's matching status alone does not
        # guarantee that: a sample sent right after it turns true can still be lost.
        self._publish_status(force=True)

    # -- status -----------------------------------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        with self._lock:
            turbines = (
                self.kind.status(self.supervisor, self.last_refs, self.turbines) if self.supervisor is not None else []
            )
        return {
            "run_id": None if self.info is None else self.info.run_id,
            "ready": self._sensors_sub is not None and self.supervisor is not None,
            "kind": None if self.info is None else self.info.kind,
            "tick": self.last_tick,
            "t": self.last_t,
            "stream_fresh": bool(self.fresh),
            "plant_alive": self.watch.is_alive(Process.PLANT),
            "frames": self.frames,
            "gaps": self.gaps,
            "bridged_ticks": self.bridged,
            "observer_restarts": self.resets,
            "held_readings": dict(sorted(self.readings.held.items())) if self.readings is not None else {},
            "refused": self.refusals.counts(),
            "step": self.step_time.summary(recent=1000),
            "dropped": self.drops.as_dict(),
            "display": None if self.display is None else self.display.counters(),
            "turbines": turbines,
        }

    def _publish_status(self, force: bool = False) -> None:
        now = time.monotonic()
        if force or now - self._last_status >= self.settings.status_every_s:
            self._last_status = now
            self._status_pub.put(encode_json("supervisor.status", self.status()))

    # -- the loop ---------------------------------------------------------------------------------------------------
    def run(self) -> int:
        info = wait_for_run(self.session, self.keys, self.watch, self.settings.plant_wait_s, self._stop)
        if info is None:
            return 0 if self._stop.is_set() else 1
        self._start_run(info)
        while not self._stop.is_set():
            if self.settings.exit_with_run and self._run_ended.is_set() and self._inbox.empty():
                break
            try:
                payload = self._inbox.get(timeout=self.settings.stale_after_s)
            except queue.Empty:
                self._mark(False)
                self._publish_status()
                continue
            if payload is PLANT_APPEARED:
                self._follow_plant()
                continue
            self.mailbox.put(payload)
            for arrival in self.mailbox.drain():
                self._on_frame(arrival.records)
            self._publish_status()
        return 0

    def _follow_plant(self) -> None:
        """A plant has appeared: if it runs a new run (its run identity is not the current one), build for it now,
        so a plant that waits for a ready supervisor before its first tick (lockstep) need not wait."""
        info = query_run(self.session, self.keys, 2.0)
        if info is None:
            return  # its frames will tell (``FrameSequencer``)
        if self.info is not None and info.run_key != self.info.run_key:
            self._start_run(info)
            self.resets += 1

    def _confirm_run(self, run: int) -> RunInfo | None:
        return confirm_run(self.session, self.keys, run)

    def _confirm_tick(self, tick: int) -> bool:
        return plant_has_measured(self.session, self.keys, self.info.run_key, tick)

    def _on_frame(self, records: np.ndarray) -> None:
        kind = self.kind
        tick = int(records["tick"][0])
        decision, missing = self.sequencer.decide(records)
        self.refusals.poll(self.last_t)
        if decision == FrameSequencer.DROP:
            return
        restart = decision in (FrameSequencer.NEW_RUN, FrameSequencer.RESTART)
        if restart:
            self._start_run(self.sequencer.confirmed if decision == FrameSequencer.NEW_RUN else self.info)
            self.resets += 1
            kind = self.kind
        records = self._hold_non_finite(records)
        if records is None:
            return
        if not restart and missing:
            self.gaps += 1
            self._bridge_gap(records)
        if backlog_ticks(self._inbox.qsize()) > self.settings.max_backlog_ticks:
            # far behind: skip to the newest, start afresh on the next
            self.drops.add("sensors", "backlog")
            while not self._inbox.empty():
                self._inbox.get_nowait()
        self._mark(True, reset=restart)
        frame = kind.frame_from_records(records)
        started = time.perf_counter()
        with self._lock:
            refs = self.supervisor.step(frame)
            events = self.supervisor.drain_events()
            out = kind.refs_records(refs, self.supervisor, self.turbines)
            self.last_refs = out
        self.step_time.add(time.perf_counter() - started)
        self.last_tick, self.last_t = tick, float(records["t"][0])
        self.last_records = records
        self.sequencer.stepped(tick)
        self.frames += 1
        self._write(events)  # before the refs: holding refs_k means the log has every event up to tick k
        self._refs_pub.put(kind.refs.encode_frame(out))
        if self.display is not None:
            self._display(tick, records, out)

    def _hold_non_finite(self, records: np.ndarray) -> np.ndarray | None:
        """``records`` with non-finite readings held (``readings.ReadingHold``), or None: refused and counted. The
        first hold of a channel in a run is logged as a ``stream`` event."""
        channels = len(self.readings.held)
        held = self.readings.take(records)
        if held is None:
            self.drops.add("sensors", DropReason.NON_FINITE)
            return None
        if len(self.readings.held) > channels:  # a channel held for the first time (the counter keeps its order)
            new = list(self.readings.held)[channels:]
            t = float(held["t"][0])
            detail = {"stream": "sensors", "held_non_finite": new, "noticed_by": Process.SUPERVISOR.value}
            self._write([Event(t, EventType.STREAM, detail=detail)])
        return held

    def _display(self, tick: int, records: np.ndarray, out: np.ndarray) -> None:
        """The display's share of a tick, after its refs are out: every ``display_every``-th tick one buffered row
        of every turbine (vectorised; the per-turbine status only for panels that show it), then one unit of
        buffered rows to Rerun, unless the next sensor frame is already waiting: then the sending waits for a tick
        with time to spare (``dashboards.live``: counted as deferred; rows are never dropped)."""
        if tick % self.settings.display_every == 0:
            self.display.supervisor_rows(records, out, self.status_rows)
        if self._inbox.empty():
            self.display.pump()
        else:
            self.display.defer()

    def _bridge_gap(self, records: np.ndarray) -> None:
        """Advance the supervisor through the ticks missing before ``records`` (held if it cannot bridge)."""
        if self.last_records is not None:
            with self._lock:
                self.bridged += bridge_gap(self._bridge, self.kind, self.last_records, records)

    def status_rows(self) -> list[dict[str, Any]]:
        return self.kind.status(self.supervisor, self.last_refs, self.turbines)
