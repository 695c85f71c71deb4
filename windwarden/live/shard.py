"""A supervisor shard: the per-turbine part of the farm supervisor for some of the farm's turbines
(``windwarden supervise --turbines 1-40``), beside a farm coordinator (``windwarden coordinate``).

It learns the run from the plant's ``plant/run`` queryable as the supervisor does, builds the per-turbine part
(``service.farm.shard.FarmShard``: the ``analytic`` detector on its turbines' rows, the farm's false-alarm budget),
subscribes to the plant's sensor frames (one per tick, every turbine's row; it steps its own turbines' rows) and, per
sensor frame:

* on a 10 Hz farm sample: steps its detector and sends one ``farm.summary`` frame of its turbines to the coordinator
  (``summary/<name>``); the sample's refs go out when the coordinator's ``farm.refs`` frame of that tick arrives on
  ``dispatch/<name>`` (in lockstep the plant waits for them), or with the references held so far when the next sensor
  frame comes first (real time: counted as ``coordinator_late``, the new rows are used from the next tick) or after
  ``coordinator_timeout_s`` (``coordinator_timeouts``);
* between farm samples: its refs at once.

The refs, one frame per tick of the shard's turbines on ``refs/<name>``, are the newest dispatch rows of its
turbines re-stamped with the tick (``sharding.held_records``), as one supervisor re-stamps its references between
farm samples. The plant takes a shard's rows only for the turbines the coordinator's plan gives it; a shard that
joins a running farm (restarted after it was lost: its first frame is not tick 0) sends no refs before its first
summary, on which the coordinator takes it back into the plan (``sharding.ShardRoster``).

Dispatch frames are refused whole and counted (``dropped``) when they do not decode, when a field the plant acts on
is not finite or out of its range (``FARM_REFS.refusal``), when they are for another tick than the one awaited, or
name a turbine the shard does not own or name one twice (``TickMailbox``). Sensor frames are sequenced as the
supervisor sequences them (``guard.FrameSequencer``); the farm holds over gaps. The shard publishes its readiness on
``shard/<name>/status``; the coordinator tells the plant the supervisor is ready once every turbine of the run has a
ready shard. The events (detections, dispatch modes) are the coordinator's.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from typing import Any

import numpy as np
import zenoh
from pydantic import Field

from service.farm.shard import FarmShard
from windwarden.kinds import RunInfo, kind_for
from windwarden.live.config import SupervisorSettings
from windwarden.live.guard import FrameSequencer
from windwarden.live.mailbox import TickMailbox, backlog_ticks
from windwarden.live.run_query import confirm_run, plant_has_measured, query_run, wait_for_run
from windwarden.live.sharding import checked, held_records, pitch_trim_of, summary_records
from windwarden.live.timing import LatencyStats
from windwarden.live.transport import LivenessWatch, declare_publisher
from wwcore.keys import COMMAND_QOS, EVENT_QOS, Process
from wwcore.wire import FARM_REFS, FARM_SENSORS, FARM_SUMMARY, DropCounter, DropReason, encode_json

log = logging.getLogger(__name__)
PLANT_APPEARED = None  # put in the sensor queue by the liveliness callback
DISPATCHED = object()  # put in the sensor queue when dispatch rows arrive


class ShardSettings(SupervisorSettings):
    """``windwarden supervise --turbines``."""

    turbines: str = Field(default="", description="the turbines this shard owns, e.g. 1-40 or 1,3,5-9")
    coordinator_timeout_s: float = Field(
        default=2.0, gt=0.0, description="s to wait for the coordinator's references of a farm sample"
    )


def shard_name(turbines: tuple[int, ...]) -> str:
    """One key chunk naming a shard by its turbines: ``1-40``, or ``1_3_5`` when they are not a range."""
    if list(turbines) == list(range(turbines[0], turbines[-1] + 1)):
        return f"{turbines[0]}-{turbines[-1]}"
    return "_".join(str(t) for t in turbines)


class ShardNode:
    """Serves its turbines of one plant (and of the next run) until ``stop()``."""

    def __init__(self, session: zenoh.Session, settings: ShardSettings, turbines: tuple[int, ...]):
        self.session = session
        self.settings = settings
        self.keys = settings.keys
        self.owned = tuple(turbines)
        self.name = shard_name(self.owned)
        self.drops = DropCounter()
        self.step_time = LatencyStats()
        self.wait_time = LatencyStats()  # summary out → the coordinator's rows in
        self._stop = threading.Event()
        self._inbox: queue.SimpleQueue[Any] = queue.SimpleQueue()  # sensor payloads and the two markers
        self.info: RunInfo | None = None
        self.shard: FarmShard | None = None
        self.ready = False
        self.last_tick: int | None = None
        self.frames = 0
        self.timeouts = 0  # farm samples the coordinator did not answer in time
        self.last_dispatch: np.ndarray | None = None
        self.late = 0  # farm samples answered with the held references because the next frame came first
        self._pending: int | None = None  # a farm-sample tick whose refs wait for the coordinator's rows
        self._pending_since = 0.0
        self._newest_sample = -1  # the newest farm-sample tick whose summaries went out
        self._dispatch_tick = -1  # the farm-sample tick of ``last_dispatch``
        self._joined_late = False  # its first frame of the run was not tick 0 (a restarted shard)
        self._last_status = 0.0
        s = session
        self._status_pub = declare_publisher(s, self.keys.shard_status(self.name), EVENT_QOS)
        self._refs_pub = declare_publisher(s, self.keys.refs(self.name), COMMAND_QOS)
        self._summary_pub = declare_publisher(s, self.keys.summary(self.name), COMMAND_QOS)
        self.dispatch = TickMailbox(FARM_REFS, list(self.owned), self.drops, "dispatch", self._dispatch_window)
        self._rows = np.arange(len(self.owned))  # the shard's turbines' rows in a sensor frame of the run's turbines
        self._dispatch_sub = s.declare_subscriber(self.keys.dispatch(self.name), self._on_dispatch)
        self._sensor_sub: zenoh.Subscriber | None = None
        self.sequencer = FrameSequencer(settings.max_gap_ticks, self.drops, self._confirm_run, self._confirm_tick)
        self.watch = LivenessWatch(s, self.keys.alive_all, self._on_liveliness)

    def stop(self) -> None:
        self._stop.set()
        self._inbox.put(PLANT_APPEARED)
        self.dispatch.wake()

    def close(self) -> None:
        self.ready = False
        self.publish_status(force=True)
        self.watch.undeclare()
        self._dispatch_sub.undeclare()
        if self._sensor_sub is not None:
            self._sensor_sub.undeclare()

    # -- inputs (Zenoh threads) ------------------------------------------------------------------------------------
    def _on_dispatch(self, sample: zenoh.Sample) -> None:
        payload = sample.payload.to_bytes()
        reason = checked(FARM_REFS, payload)
        if reason is not None:
            self.drops.add("dispatch", reason)
            return
        self.dispatch.put(payload)
        self._inbox.put(DISPATCHED)

    def _dispatch_window(self, tick: int) -> DropReason | None:
        """Rows are taken for a farm sample whose summaries went out, newer than the rows held."""
        if tick > self._newest_sample:
            return DropReason.FUTURE_TICK
        return DropReason.STALE_TICK if tick <= self._dispatch_tick else None

    def _on_liveliness(self, process: str, alive: bool) -> None:
        if process == Process.PLANT and alive:
            self._inbox.put(PLANT_APPEARED)

    # -- run set-up ------------------------------------------------------------------------------------------------
    def start_run(self, info: RunInfo) -> None:
        """(Re)build the per-turbine part for the run ``info``; ``ShardingError`` (a ``ValueError``) if this shard
        cannot serve it (not a farm, a farm-wide detector, turbines the farm does not have)."""
        if info.kind != "farm":
            raise ValueError(f"a supervisor shard serves a farm, not a {info.kind!r} plant")
        sup = info.supervisor
        self.shard = FarmShard(
            info.site, self.owned, detector=sup.detector, controller=sup.controller, options=dict(sup.params)
        )
        self.info = info
        self.kind = kind_for(info.kind)
        turbines = list(info.turbines)
        missing = sorted(set(self.owned) - set(turbines))
        if missing:
            raise ValueError(f"the farm of run {info.run_id} has no turbines {missing}")
        self._rows = np.array([turbines.index(t) for t in self.owned])
        self.mailbox = TickMailbox(FARM_SENSORS, turbines, self.drops, "sensors")
        self.last_dispatch = None
        self.last_tick = None
        self._pending, self._newest_sample, self._dispatch_tick = None, -1, -1
        self._joined_late = False
        self.sequencer.start(info.run_key)
        if self._sensor_sub is None:  # subscribing last: the coordinator tells the plant once every shard is ready
            self._sensor_sub = self.session.declare_subscriber(self.keys.sensors, self._on_sensors)
        self.ready = True
        self.publish_status(force=True)

    def _on_sensors(self, sample: zenoh.Sample) -> None:
        self._inbox.put(sample.payload.to_bytes())

    def _confirm_run(self, run: int) -> RunInfo | None:
        return confirm_run(self.session, self.keys, run)

    def _confirm_tick(self, tick: int) -> bool:
        return plant_has_measured(self.session, self.keys, self.info.run_key, tick)

    # -- status ----------------------------------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "run_id": None if self.info is None else self.info.run_id,
            "turbines": list(self.owned),
            "ready": self.ready,
            "tick": self.last_tick,
            "frames": self.frames,
            "coordinator_timeouts": self.timeouts,
            "coordinator_late": self.late,
            "step": self.step_time.summary(recent=1000),
            "coordinator_wait": self.wait_time.summary(recent=1000),
            "dropped": self.drops.as_dict(),
        }

    def publish_status(self, force: bool = False) -> None:
        now = time.monotonic()
        if force or now - self._last_status >= self.settings.status_every_s:
            self._last_status = now
            self._status_pub.put(encode_json("shard.status", self.status()))

    # -- the loop --------------------------------------------------------------------------------------------------
    def run(self) -> int:
        info = wait_for_run(self.session, self.keys, self.watch, self.settings.plant_wait_s, self._stop)
        if info is None:
            return 0 if self._stop.is_set() else 1
        self.start_run(info)
        while not self._stop.is_set():
            timeout = self.settings.status_every_s
            if self._pending is not None:
                timeout = max(self._pending_since + self.settings.coordinator_timeout_s - time.perf_counter(), 0.0)
            try:
                item = self._inbox.get(timeout=timeout)
            except queue.Empty:
                if self._pending is not None:  # the coordinator did not answer in time: hold the last references
                    self.timeouts += 1
                    log.warning("no references from the coordinator for tick %d in time", self._pending)
                    self._answer(self._pending)
                self.publish_status()
                continue
            if item is PLANT_APPEARED:
                self._follow_plant()
            elif item is DISPATCHED:
                self._take_dispatch()
            else:
                self.mailbox.put(item)
                self._skip_backlog()
                for arrival in self.mailbox.drain():
                    if self._pending is not None:  # real time: the next frame is here first; answer with what we have
                        self.late += 1
                        self._answer(self._pending)
                    self._on_frame(arrival.records[self._rows])
            self.publish_status()
        return 0

    def _skip_backlog(self) -> None:
        """Far behind (more than ``max_backlog_ticks`` of its turbines' frames queued): drop what is queued and go
        on from the next frame (the sequencer then confirms the tick with the plant and restarts the detector)."""
        if backlog_ticks(self._inbox.qsize()) <= self.settings.max_backlog_ticks:
            return
        self.drops.add("sensors", "backlog")
        while True:
            try:
                item = self._inbox.get_nowait()
            except queue.Empty:
                return
            if item is DISPATCHED:
                self._take_dispatch()
            elif item is PLANT_APPEARED:
                self._inbox.put(item)
                return

    def _follow_plant(self) -> None:
        if self._stop.is_set():
            return
        info = query_run(self.session, self.keys, 2.0)
        if info is not None and self.info is not None and info.run_key != self.info.run_key:
            self.start_run(info)

    def _on_frame(self, records: np.ndarray) -> None:
        """Step a complete sensor frame of the shard's turbines: on a farm sample, the detector and the summaries
        (its refs go out when the coordinator's rows arrive); between samples, the held references at once."""
        decision, _ = self.sequencer.decide(records)
        if decision == FrameSequencer.DROP:
            return
        if decision in (FrameSequencer.NEW_RUN, FrameSequencer.RESTART):
            self.start_run(self.sequencer.confirmed if decision == FrameSequencer.NEW_RUN else self.info)
        tick = int(records["tick"][0])
        if self.last_tick is None:
            self._joined_late = tick > 0
        self.last_tick = tick
        self.sequencer.stepped(tick)
        self.frames += 1
        if not bool(records["sample"][0]):
            self._answer(tick)
            return
        started = time.perf_counter()
        frame = self.kind.frame_from_records(records)
        diagnosis = self.shard.step(frame)
        summaries = summary_records(records, self.shard.sample, diagnosis)
        self.step_time.add(time.perf_counter() - started)
        self._newest_sample = tick
        self._pending, self._pending_since = tick, time.perf_counter()
        self._summary_pub.put(FARM_SUMMARY.encode_frame(summaries))

    def _take_dispatch(self) -> None:
        """The coordinator's rows that arrived: the newest become the references; those of the pending farm sample
        answer it."""
        for arrival in self.dispatch.drain():
            if arrival.tick <= self._dispatch_tick:
                continue  # an older sample's rows after a newer one's (real time)
            self._dispatch_tick = arrival.tick
            self.last_dispatch = arrival.records
            self.shard.pitch_trim = pitch_trim_of(arrival.records)
            if arrival.tick == self._pending:
                self.wait_time.add(arrival.at - self._pending_since)
                self._answer(arrival.tick)

    def _answer(self, tick: int) -> None:
        """Publish the refs of sensor tick ``tick``: the newest dispatch rows, re-stamped."""
        if tick == self._pending:
            self._pending = None
        if self._joined_late and self._newest_sample < 0:
            return  # the coordinator (re)admits a shard joining a running farm on its first summary: the plant's
            # plan has no place for its refs before that (they would be refused as not_owned)
        out = held_records(self.last_dispatch, tick, list(self.owned))
        self._refs_pub.put(FARM_REFS.encode_frame(out))
