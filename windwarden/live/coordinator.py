"""The farm coordinator of a sharded supervisor (``windwarden coordinate``): the farm-wide part of the farm
supervisor, fed by the shards' per-turbine summaries.

It learns the run from the plant's ``plant/run`` queryable, builds the farm-wide part one supervisor would run
(``service.farm.shard.coordinator_supervisor``: the dispatch, eqs. (18)–(26), the accommodation and the events, with
the run's controller and options; a farm-wide detector such as ``paper`` is refused) and, per farm sample whose
``farm.summary`` rows have arrived for every turbine of the run (one frame per shard, each row of a turbine the
shard's status says it owns):

``FarmSample`` and ``FarmDiagnosis`` from the rows (``sharding.farm_sample``) → the commanded pitch trim taken off
(``FarmSupervisor.untrimmed``) → ``FarmSupervisor.decide`` → its events appended to ``events.jsonl`` and published →
to each ready shard one ``farm.refs`` frame of its turbines' rows on ``dispatch/<name>``. Events go out before the
rows, so when the plant holds refs of tick k every event up to tick k is in the log, as with one supervisor.

To the plant it is the supervisor: it holds the ``alive/supervisor`` token, publishes ``supervisor/status`` and
``supervisor/events``, and says ``ready`` only once the shards that report ready for the run (``shard/*/status``)
own every turbine of it, each turbine once. Summary frames are refused whole and counted (``dropped``) when they do
not decode, when a field the coordinator computes with is not finite or out of its range (``FARM_SUMMARY.refusal``),
for a turbine the run does not have or the sending shard does not own, for a tick already decided, or when the rows
of one tick are not of one sample and run.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import zenoh

from service.farm.shard import coordinator_supervisor
from service.farm.supervisor import FarmSupervisor
from windwarden.kinds import RunInfo, kind_for
from windwarden.live.config import SupervisorSettings
from windwarden.live.mailbox import TickMailbox
from windwarden.live.run_query import query_run, wait_for_run
from windwarden.live.runfolder import EVENTS, EventLog
from windwarden.live.sharding import checked, farm_sample, mismatch
from windwarden.live.timing import LatencyStats
from windwarden.live.transport import JsonQueryable, LivenessWatch, declare_publisher
from wwcore.events import Event
from wwcore.keys import COMMAND_QOS, EVENT_QOS, Process
from wwcore.wire import FARM_REFS, FARM_SUMMARY, DropCounter, DropReason, WireError, decode_json, encode_json

log = logging.getLogger(__name__)
WAKE = None  # put in the summary queue to have the main loop look at the shards and the plant


class CoordinatorNode:
    """Coordinates the shards of one plant's run (and of the next run) until ``stop()``."""

    def __init__(self, session: zenoh.Session, settings: SupervisorSettings):
        self.session = session
        self.settings = settings
        self.keys = settings.keys
        self.drops = DropCounter()
        self.step_time = LatencyStats()
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._inbox: queue.SimpleQueue[bytes | None] = queue.SimpleQueue()
        self.info: RunInfo | None = None
        self.supervisor: FarmSupervisor | None = None
        self.turbines: list[int] = []
        self.events: EventLog | None = None
        self.shards: dict[str, dict[str, Any]] = {}  # shard name → its last status
        self.coverage_problem: str | None = "no shard yet"
        self.last_tick = -1
        self.last_t = 0.0
        self.samples = 0
        self._plant_appeared = threading.Event()
        self._last_status = 0.0
        s = session
        self._events_pub = declare_publisher(s, self.keys.supervisor_events, EVENT_QOS)
        self._status_pub = declare_publisher(s, self.keys.supervisor_status, EVENT_QOS)
        self._dispatch_pubs: dict[str, zenoh.Publisher] = {}  # a shard's name → its dispatch publisher
        self.summaries: TickMailbox | None = None
        self._summary_sub = s.declare_subscriber(self.keys.summary("*"), self._on_summary)
        self._shard_sub = s.declare_subscriber(self.keys.shard_status("*"), self._on_shard_status)
        self._status_q = JsonQueryable(
            s, self.keys.supervisor_status, "supervisor.status", lambda body: self.status(), self.drops
        )
        self.watch = LivenessWatch(s, self.keys.alive_all, self._on_liveliness)
        self._token = s.liveliness().declare_token(self.keys.alive(Process.SUPERVISOR))

    def stop(self) -> None:
        self._stop.set()
        self._inbox.put(WAKE)

    def close(self) -> None:
        self._status_q.close()
        self._token.undeclare()
        self.watch.undeclare()
        self._summary_sub.undeclare()
        self._shard_sub.undeclare()
        if self.events is not None:
            self.events.close()

    # -- inputs (Zenoh threads) ------------------------------------------------------------------------------------
    def _on_summary(self, sample: zenoh.Sample) -> None:
        payload = sample.payload.to_bytes()
        reason = checked(FARM_SUMMARY, payload)
        if reason is not None:
            self.drops.add("summary", reason)
            return
        mailbox = self.summaries
        if mailbox is None:
            self.drops.add("summary", "no_run")
            return
        name = self.keys.sender_of(str(sample.key_expr))
        with self._lock:
            shard = self.shards.get(name)
            run_id = None if self.info is None else self.info.run_id
        turbines = shard["turbines"] if shard is not None and shard["run_id"] == run_id else []
        mailbox.put(payload, mailbox.owned_mask(turbines))  # a shard summarises its own turbines only
        self._inbox.put(b"")  # the main loop drains the mailbox

    def _summary_window(self, tick: int) -> DropReason | None:
        return DropReason.OLD_TICK if tick <= self.last_tick else None

    def _on_shard_status(self, sample: zenoh.Sample) -> None:
        try:
            body = decode_json("shard.status", sample.payload.to_bytes())
        except WireError as error:
            self.drops.add("shard.status", error.reason)
            return
        name = str(sample.key_expr).split("/")[-2]
        turbines = body.get("turbines")
        if not isinstance(turbines, list) or not all(isinstance(t, int) and not isinstance(t, bool) for t in turbines):
            self.drops.add("shard.status", DropReason.BAD_BODY)
            return
        with self._lock:
            self.shards[name] = {"run_id": body.get("run_id"), "turbines": turbines, "ready": body.get("ready") is True}
        self._inbox.put(WAKE)

    def _on_liveliness(self, process: str, alive: bool) -> None:
        if process == Process.PLANT and alive:
            self._plant_appeared.set()
            self._inbox.put(WAKE)

    # -- run set-up ------------------------------------------------------------------------------------------------
    def start_run(self, info: RunInfo) -> None:
        """(Re)build the farm-wide part for the run ``info``; ``ShardingError`` (a ``ValueError``) if it cannot be
        sharded (not a farm; a farm-wide detector)."""
        if info.kind != "farm":
            raise ValueError(f"a farm coordinator serves a farm, not a {info.kind!r} plant")
        sup = info.supervisor
        supervisor = coordinator_supervisor(
            info.site, len(info.turbines), detector=sup.detector, controller=sup.controller, options=dict(sup.params)
        )
        new_run = self.info is None or info.run_id != self.info.run_id
        with self._lock:
            self.info, self.supervisor = info, supervisor
            self.kind = kind_for(info.kind)
            self.turbines = list(info.turbines)
            self.last_tick = -1
            self.summaries = TickMailbox(FARM_SUMMARY, self.turbines, self.drops, "summary", self._summary_window)
        if new_run:
            if self.events is not None:
                self.events.close()
            folder: Path = self.settings.folder(info.run_id)
            self.events = EventLog(folder / EVENTS, self._publish_event)
        self._check_coverage()
        self.publish_status(force=True)

    def _check_coverage(self) -> bool:
        """Whether the shards ready for this run own every turbine of it, each once (else ``coverage_problem``)."""
        with self._lock:
            if self.info is None:
                self.coverage_problem = "no run yet"
                return False
            owner: dict[int, str] = {}
            twice = []
            for name, shard in sorted(self.shards.items()):
                if not shard["ready"] or shard["run_id"] != self.info.run_id:
                    continue
                for turbine in shard["turbines"]:
                    if turbine in owner:
                        twice.append(f"turbine {turbine} ({owner[turbine]} and {name})")
                    owner[turbine] = name
            missing = sorted(set(self.turbines) - set(owner))
            if twice:
                problem = "owned twice: " + ", ".join(twice)
            elif missing:
                problem = f"no ready shard owns turbines {missing}"
            else:
                problem = None
            changed = problem != self.coverage_problem
            self.coverage_problem = problem
        if changed:
            log.info("shards: %s", problem or f"every turbine of run {self.info.run_id} is owned")
        return problem is None

    # -- status ----------------------------------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        with self._lock:
            turbines = []
            if self.supervisor is not None:
                turbines = self.kind.status(self.supervisor, None, self.turbines)
                detector = (self.info.supervisor.detector or "analytic") + " (in the shards)"
                for entry in turbines:
                    entry["detector"] = detector
            shards = {name: dict(shard) for name, shard in self.shards.items()}
        return {
            "run_id": None if self.info is None else self.info.run_id,
            "ready": self.supervisor is not None and self.coverage_problem is None,
            "kind": None if self.info is None else self.info.kind,
            "tick": None if self.last_tick < 0 else self.last_tick,
            "t": self.last_t,
            "sharded": True,
            "shards": shards,
            "coverage": self.coverage_problem or "complete",
            "samples": self.samples,
            "step": self.step_time.summary(recent=1000),
            "dropped": self.drops.as_dict(),
            "turbines": turbines,
        }

    def publish_status(self, force: bool = False) -> None:
        now = time.monotonic()
        if force or now - self._last_status >= self.settings.status_every_s:
            self._last_status = now
            self._status_pub.put(encode_json("supervisor.status", self.status()))

    def _publish_event(self, event: Event) -> None:
        self._events_pub.put(encode_json("events", event.to_json()))

    # -- the loop --------------------------------------------------------------------------------------------------
    def run(self) -> int:
        info = wait_for_run(self.session, self.keys, self.watch, self.settings.plant_wait_s, self._stop)
        if info is None:
            return 0 if self._stop.is_set() else 1
        self._plant_appeared.clear()
        self.start_run(info)
        ready = False
        while not self._stop.is_set():
            try:
                item = self._inbox.get(timeout=self.settings.status_every_s)
            except queue.Empty:
                self.publish_status()
                continue
            if item is WAKE:
                if self._plant_appeared.is_set():
                    self._plant_appeared.clear()
                    self._follow_plant()
                now_ready = self._check_coverage()
                self.publish_status(force=now_ready != ready)  # the handshake: the plant starts on it
                ready = now_ready
                continue
            for arrival in self.summaries.drain():
                self._on_sample(arrival.tick, arrival.records)
            self.publish_status()
        return 0

    def _follow_plant(self) -> None:
        info = query_run(self.session, self.keys, 2.0)
        if info is not None and self.info is not None and info.run_key != self.info.run_key:
            self.start_run(info)

    def _on_sample(self, tick: int, records: np.ndarray) -> None:
        problem = mismatch(records)
        if problem is None and int(records["run"][0]) != self.info.run_key:
            problem = f"summaries of tick {tick} are of another run"
        if problem is not None:
            self.drops.add("summary", DropReason.FOREIGN_RUN if "run" in problem else DropReason.BAD_BODY)
            log.warning("summaries refused: %s", problem)
            return
        started = time.perf_counter()
        sample, diagnosis = farm_sample(records)
        with self._lock:
            sup = self.supervisor
            refs = sup.decide(tick, sup.untrimmed(sample), diagnosis)
            events = sup.drain_events()
            out = self.kind.refs_records(refs, sup, self.turbines)
        self.step_time.add(time.perf_counter() - started)
        self.last_tick, self.last_t, self.samples = tick, float(records["t"][0]), self.samples + 1
        if events and self.events is not None:
            self.events.write(events)  # before the references, as one supervisor does
        for name, rows in self._plan():
            if name not in self._dispatch_pubs:
                self._dispatch_pubs[name] = declare_publisher(self.session, self.keys.dispatch(name), COMMAND_QOS)
            self._dispatch_pubs[name].put(FARM_REFS.encode_frame(out[rows]))

    def _plan(self) -> list[tuple[str, np.ndarray]]:
        """Each shard ready for the run, with the rows of its turbines in the run's turbine order."""
        position = {t: i for i, t in enumerate(self.turbines)}
        with self._lock:
            shards = sorted(self.shards.items())
        return [
            (name, np.array([position[t] for t in shard["turbines"] if t in position], dtype=np.intp))
            for name, shard in shards
            if shard["ready"] and shard["run_id"] == self.info.run_id
        ]
