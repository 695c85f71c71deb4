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

**A lost shard** (``sharding.ShardRoster``): once the run has started, a shard whose summaries are missing from
``shard_lost_samples`` farm samples the other shards summarised (10: 1 s of farm time at ×1), whose status has been
silent for ``shard_silent_s`` (3 s), or whose status says it stopped, is lost: a ``liveliness`` event names it and its
turbines, the status lists it (``lost_shards``, ``held_turbines``, ``shards_lost``), and the farm samples are decided
without it: its turbines' rows are held at their last summary (``sharding.held_summaries``: the dispatch sees them as
they were, their flags do not change) and the sample names them held (``FarmSample.held``): the dispatch counts them
as fixed producers at the references it sent them last and shares the demand less theirs over the served turbines
(the status' ``held_power_ref_w`` and ``served_demand_w``). Nothing is dispatched to the lost shard, and the plan in
the status leaves it out, so the plant completes each tick without its turbines and keeps their last references
(``FarmKind.hold_unserved``), the ones the dispatch counts. It rejoins (an event, ``shards_rejoined``) when it
reports ready for the run again and summarises a newer sample; from the next sample complete without held rows the
dispatch shares over every turbine again.
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
from pydantic import Field

from service.farm.shard import coordinator_supervisor
from service.farm.supervisor import FarmSupervisor
from windwarden.kinds import RunInfo, kind_for
from windwarden.live.config import SupervisorSettings
from windwarden.live.mailbox import TickMailbox
from windwarden.live.run_query import query_run, wait_for_run
from windwarden.live.runfolder import EVENTS, EventLog
from windwarden.live.sharding import ShardRoster, checked, farm_sample, held_summaries, mismatch
from windwarden.live.timing import LatencyStats
from windwarden.live.transport import JsonQueryable, LivenessWatch, declare_publisher
from wwcore.events import Event, EventType
from wwcore.keys import COMMAND_QOS, EVENT_QOS, Process
from wwcore.wire import FARM_REFS, FARM_SUMMARY, DropCounter, DropReason, WireError, decode_json, encode_json

log = logging.getLogger(__name__)
WAKE = None  # put in the summary queue to have the main loop look at the shards and the plant


class CoordinatorSettings(SupervisorSettings):
    """``windwarden coordinate``."""

    shard_lost_samples: int = Field(
        default=10,
        ge=2,
        le=600,
        description="a shard whose summaries miss this many farm samples the others summarised is lost (10 Hz)",
    )
    shard_silent_s: float = Field(
        default=3.0, ge=1.0, le=60.0, description="s without a shard's status (2 Hz) before it is lost"
    )


class CoordinatorNode:
    """Coordinates the shards of one plant's run (and of the next run) until ``stop()``."""

    def __init__(self, session: zenoh.Session, settings: CoordinatorSettings):
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
        self.roster = ShardRoster(settings.shard_lost_samples, settings.shard_silent_s)
        self.coverage_problem: str | None = "no shard yet"
        self._last_summaries: np.ndarray | None = None  # the last sample decided, every turbine's row
        self._last_out: np.ndarray | None = None  # its references, every turbine's row
        self._expecting: set[str] = set()  # the shards whose summaries complete a farm sample
        self._decided_at = -np.inf  # time.monotonic() of the last farm sample decided
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
        head = FARM_SUMMARY.decode_frame(payload)[0]
        with self._lock:
            roster = self.roster
            if self.info is not None and int(head["run"]) == self.info.run_key and name in roster.shards:
                roster.heard_summary(name, int(head["tick"]))
            if name in roster.lost:  # not decided with until it rejoins (the main loop's check)
                self._inbox.put(WAKE)
                return
            state = roster.shards.get(name)
            mine = state is not None and self.info is not None and state.run_id == self.info.run_id
            turbines = state.turbines if mine else []
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
            self.roster.heard_status(name, body.get("run_id"), turbines, body.get("ready") is True)
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
            self._last_summaries = self._last_out = None
            self.summaries = TickMailbox(FARM_SUMMARY, self.turbines, self.drops, "summary", self._summary_window)
            self._expecting = set()  # a new mailbox expects every turbine
            if new_run:
                self.roster.start(info.run_id)
        if new_run:
            if self.events is not None:
                self.events.close()
            folder: Path = self.settings.folder(info.run_id)
            self.events = EventLog(folder / EVENTS, self._publish_event)
        self._check_shards()
        self.publish_status(force=True)

    def _check_shards(self) -> bool:
        """Admit the shards ready for the run, find the lost and the rejoined ones (an event each, the summaries
        expected from the shards admitted), and whether they serve every turbine of the run (else
        ``coverage_problem``); True when the coordinator is ready."""
        with self._lock:
            if self.info is None:
                self.coverage_problem = "no run yet"
                return False
            roster = self.roster
            changes = roster.check(self.turbines)
            problem = roster.coverage(self.turbines)
            changed = problem != self.coverage_problem
            self.coverage_problem = problem
            if roster.started and roster.admitted != self._expecting and self.summaries is not None:
                self._expecting = set(roster.admitted)  # a tick is complete with the summaries of these
                self.summaries.expect(self.summaries.owned_mask(roster.turbines_of(roster.admitted)))
            held = roster.held()
            noticed_t = max(roster.newest(), 0) * self.info.dt  # the newest farm sample summarised: when it was noticed
            held_refs = self._held_refs(held)
            # written before the lock is released, so whoever reads the status as lost finds its event
            for name, alive, reason in changes:
                turbines = self.roster.shards[name].turbines
                detail = {
                    "process": "shard",
                    "shard": name,
                    "turbines": list(turbines),
                    "alive": alive,
                    "reason": reason,
                    "held_turbines": held,
                    "held_power_ref_w": held_refs,  # what the plant keeps for them and the dispatch counts on
                    "noticed_by": "coordinator",
                }
                (log.info if alive else log.warning)(
                    "shard %s (turbines %s) %s: %s", name, turbines, "rejoined" if alive else "lost", reason
                )
                if self.events is not None:
                    self.events.write([Event(noticed_t, EventType.LIVELINESS, detail=detail)])
        if changed:
            log.info("shards: %s", problem or f"every turbine of run {self.info.run_id} is served")
        if changes:
            self.publish_status(force=True)  # the plant takes the new plan from it
        rejoined = {name for name, alive, _ in changes if alive}
        if rejoined and self._last_out is not None:
            for name, rows in self._plan():
                if name in rejoined:
                    self._dispatch(name, self._last_out[rows])  # a rejoined shard has references at once
        return problem is None

    def _held_refs(self, held: list[int]) -> list[float | None]:
        """The power reference (W) the coordinator sent each of the ``held`` turbines last (None: none yet): the one
        the plant keeps for it and the dispatch counts on while it is held."""
        if self._last_out is None:
            return [None] * len(held)
        position = {t: i for i, t in enumerate(self.turbines)}
        refs = [float(self._last_out["power_ref"][position[t]]) for t in held if t in position]
        return [r if np.isfinite(r) else None for r in refs]

    # -- status ----------------------------------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        with self._lock:
            roster = self.roster
            held = roster.held()
            turbines = []
            if self.supervisor is not None:
                turbines = self.kind.status(self.supervisor, None, self.turbines)
                detector = (self.info.supervisor.detector or "analytic") + " (in the shards)"
                for entry in turbines:
                    entry["detector"] = detector
                    entry["supervised"] = entry["turbine"] not in held
            shards = {
                name: {
                    "run_id": state.run_id,
                    "turbines": list(state.turbines),
                    "ready": name in roster.admitted,  # the plan the plant takes
                    "lost": name in roster.lost,
                }
                for name, state in roster.shards.items()
            }
            lost = {
                name: {"turbines": shard.turbines, "reason": shard.reason, "since_tick": shard.tick}
                for name, shard in roster.lost.items()
            }
            counts = roster.lost_total, roster.rejoined_total
            dispatch = self._held_dispatch()
        return {
            "run_id": None if self.info is None else self.info.run_id,
            "ready": self.supervisor is not None and self.coverage_problem is None,
            "kind": None if self.info is None else self.info.kind,
            "tick": None if self.last_tick < 0 else self.last_tick,
            "t": self.last_t,
            "stream_fresh": time.monotonic() - self._decided_at <= self.settings.stale_after_s,
            "plant_alive": self.watch.is_alive(Process.PLANT),
            "sharded": True,
            "shards": shards,
            "coverage": self.coverage_problem or ("degraded: turbines held" if held else "complete"),
            "lost_shards": lost,
            "held_turbines": held,
            **dispatch,
            "shards_lost": counts[0],
            "shards_rejoined": counts[1],
            "samples": self.samples,
            "step": self.step_time.summary(recent=1000),
            "dropped": self.drops.as_dict(),
            "turbines": turbines,
        }

    def _held_dispatch(self) -> dict[str, float | None]:
        """What the last sample decided made of the held turbines (under the lock): ``held_power_ref_w``, the sum
        of their references (what the plant keeps them at), and ``served_demand_w``, the demand less it, which the
        served turbines were given; None before any sample."""
        sup = self.supervisor
        if sup is None or sup.sample is None or sup.refs is None:
            return {"held_power_ref_w": None, "served_demand_w": None}
        held = sup.sample.held
        held_power = 0.0 if held is None else float(sup.refs.power_ref[held].sum())
        return {"held_power_ref_w": held_power, "served_demand_w": float(sup.sample.demand[0]) - held_power}

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
                item = WAKE
            if item is WAKE and self._plant_appeared.is_set():
                self._plant_appeared.clear()
                self._follow_plant()
            now_ready = self._check_shards()
            self.publish_status(force=now_ready != ready)  # the handshake: the plant starts on it
            ready = now_ready
            for arrival in self.summaries.drain():
                self._on_sample(arrival.tick, arrival.records, arrival.served)
        return 0

    def _follow_plant(self) -> None:
        info = query_run(self.session, self.keys, 2.0)
        if info is not None and self.info is not None and info.run_key != self.info.run_key:
            self.start_run(info)

    def _on_sample(self, tick: int, records: np.ndarray, served: np.ndarray | None = None) -> None:
        if tick <= self.last_tick:  # a sample that waited for a lost shard, older than one decided since: never decided
            self.drops.add("summary", DropReason.INCOMPLETE)
            return
        if served is not None:  # a lost shard's turbines: held at their last summary
            records = held_summaries(records, served, self._last_summaries)
            if records is None:
                self.drops.add("summary", DropReason.INCOMPLETE)
                log.warning("farm sample of tick %d not decided: a shard was lost before any sample was", tick)
                return
        problem = mismatch(records)
        if problem is None and int(records["run"][0]) != self.info.run_key:
            problem = f"summaries of tick {tick} are of another run"
        if problem is not None:
            self.drops.add("summary", DropReason.FOREIGN_RUN if "run" in problem else DropReason.BAD_BODY)
            log.warning("summaries refused: %s", problem)
            return
        self._last_summaries = records
        self._decided_at = time.monotonic()
        started = time.perf_counter()
        sample, diagnosis = farm_sample(records, None if served is None else ~served)
        with self._lock:
            sup = self.supervisor
            refs = sup.decide(tick, sup.untrimmed(sample), diagnosis)
            events = sup.drain_events()
            out = self.kind.refs_records(refs, sup, self.turbines)
        self.step_time.add(time.perf_counter() - started)
        self.last_tick, self.last_t, self.samples = tick, float(records["t"][0]), self.samples + 1
        if events and self.events is not None:
            self.events.write(events)  # before the references, as one supervisor does
        self._last_out = out
        for name, rows in self._plan():
            self._dispatch(name, out[rows])

    def _dispatch(self, name: str, rows: np.ndarray) -> None:
        if name not in self._dispatch_pubs:
            self._dispatch_pubs[name] = declare_publisher(self.session, self.keys.dispatch(name), COMMAND_QOS)
        self._dispatch_pubs[name].put(FARM_REFS.encode_frame(rows))

    def _plan(self) -> list[tuple[str, np.ndarray]]:
        """Each shard admitted for the run (ready, not lost), with the rows of its turbines in the run's order."""
        position = {t: i for i, t in enumerate(self.turbines)}
        with self._lock:
            shards = [(name, self.roster.shards[name].turbines) for name in sorted(self.roster.admitted)]
        rows = [(name, [position[t] for t in owned if t in position]) for name, owned in shards]
        return [(name, np.array(positions, dtype=np.intp)) for name, positions in rows]
