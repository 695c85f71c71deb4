"""The plant process: the simulator behind Zenoh, paced in real time or in lockstep with the supervisor.

Tick k (the step contract of ``wwcore.stepping``, the same calls as batch mode):

1. apply the fault commands that arrived (inject/clear over the ``plant/faults`` queryable);
2. take the refs that arrived, before ``sensors_k`` leaves (so tick k is controlled with refs from tick ≤ k − 1,
   as in batch mode), each checked by ``guard.RefsGuard`` (finite, in range, for a tick in the window, not a
   repeat; refused ones counted and logged); the newest taken is used if computed from tick ≥ k − ``max_ref_age``,
   else the turbine controller falls back to its own sensors and its last good reference; then at most one bounded
   send of buffered display rows to Rerun (``_pump_display``), so display work never sits inside the round trip;
3. ``frame = plant.measure()``; publish ``sensors_k``, one frame of every turbine's row (with the run identity);
   ``plant.control(refs)``;
4. every ``display_every``-th tick: truth and one buffered display row of every turbine; ``plant.advance()``;
   append and publish the plant's events;
5. lockstep: wait for ``refs_k`` (unless the supervisor is gone or has gone mute: then fall back, log, go on);
   realtime: sleep until the deadline t₀ + (k+1)·dt/speed; a tick whose work ends after it is an overrun.

The sensor→refs latency of tick k is the time from publishing ``sensors_k`` to the arrival of ``refs_k`` (every
turbine's row: the supervisor's one frame, or the last of the shards' frames).
"""

from __future__ import annotations

import gc
import logging
import queue
import secrets
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future
from pathlib import Path
from typing import Any

import zenoh

from windwarden.kinds import RunInfo, kind_for
from windwarden.live.config import PlantSettings
from windwarden.live.faults import FaultBook, InjectionRefusedError
from windwarden.live.guard import RefsFreshness, RefsGuard, RefsSenders, RefusalLog, Verdict
from windwarden.live.mailbox import TickMailbox
from windwarden.live.runfolder import EVENTS, FAULTS, LIVE, EventLog, write_json, write_run_start
from windwarden.live.timing import LatencyStats, Pacer
from windwarden.live.transport import JsonQueryable, LivenessWatch, QueryError, declare_publisher
from wwcore.events import Event, EventType
from wwcore.keys import COMMAND_QOS, DISPLAY_QOS, EVENT_QOS, SENSORS_QOS, Process
from wwcore.scenario import FaultSpec, Scenario, dump_scenario
from wwcore.wire import DropCounter, WireError, decode_json, encode_json

log = logging.getLogger(__name__)

COMMAND_TIMEOUT_S = 5.0  # a fault command not applied by the main loop within this is answered with an error
FINAL_REFS_WAIT_S = 1.0  # realtime: how long the plant waits for the refs of its last tick
CHECKPOINT_EVERY_S = 1.0  # s of wall time between two checkpoints of live.json


class PlantNode:
    """One plant run. ``run()`` blocks until the scenario's end or ``stop()``; returns the process exit code."""

    def __init__(
        self,
        session: zenoh.Session,
        settings: PlantSettings,
        scenario: Scenario,
        run_id: str,
        run_dir: Path,
        display: Any | None = None,
    ):
        self.session = session
        self.settings = settings
        self.scenario = scenario
        self.run_id = run_id
        self.run_dir = run_dir
        self.display = display
        self.keys = settings.keys
        self.kind = kind_for(scenario.plant.kind)
        self.plant = self.kind.make_plant(scenario, settings.seed)
        self.turbines = self.kind.turbines(self.plant)
        self.dt = float(self.plant.dt)
        self.n_steps = round(scenario.duration_s / self.dt)
        self.run_key = secrets.randbits(52)  # the run identity on every frame: a new one for every run
        self.info = RunInfo.of(
            scenario, self.turbines, self.dt, run_id, settings.mode, settings.speed, run_key=self.run_key
        )
        self.book = FaultBook(
            scenario.plant.kind, scenario.plant.n_turbines, scenario.duration_s, list(scenario.faults)
        )
        self.score = self.kind.score(scenario, self.n_steps, self.dt)
        self.drops = DropCounter()
        self.guard = RefsGuard(self.kind.refs, settings.max_ref_age, self.drops)
        self.latency = LatencyStats()
        self.pacer = Pacer(self.dt, settings.speed)
        self._stop = threading.Event()
        self._commands: queue.SimpleQueue[tuple[Callable[[], dict], Future]] = queue.SimpleQueue()
        self._sent_at: dict[int, float] = {}
        self.k = 0
        self.state = "starting"
        self.freshness = RefsFreshness(settings.max_ref_age, settings.stale_event_ticks, self._stream_event)
        self.latest_refs: Any | None = None
        self.latest_refs_tick = -1
        self.refs_received = 0
        self.mute = False  # lockstep: the supervisor is alive but stopped answering; do not wait until it does
        self.wall_start = time.time()
        self._loop_start = time.perf_counter()  # reset when tick 0 starts
        self._last_status = 0.0
        self._last_checkpoint = 0.0
        self._open_transport()

    # -- set-up -------------------------------------------------------------------------------------------------
    def _open_transport(self) -> None:
        s, keys = self.session, self.keys
        self.events = EventLog(self.run_dir / EVENTS, self._publish_event)
        self.refusals = RefusalLog(self.drops, "refs", Process.PLANT.value, self.events.write)
        self._events_pub = declare_publisher(s, keys.plant_events, EVENT_QOS)
        self._status_pub = declare_publisher(s, keys.plant_status, DISPLAY_QOS)
        sensors_qos = COMMAND_QOS if self.settings.mode == "lockstep" else SENSORS_QOS
        self._sensor_pub = declare_publisher(s, keys.sensors, sensors_qos)
        self._truth_pub = declare_publisher(s, keys.truth, DISPLAY_QOS)
        self.mailbox = TickMailbox(self.kind.refs, self.turbines, self.drops, "refs", self.guard.window)
        self.senders = RefsSenders(self.mailbox.owned_mask, self.mailbox.n, self.run_id)
        self._refs_sub = s.declare_subscriber(keys.refs("*"), self._on_refs)
        self._queryables = [
            JsonQueryable(s, keys.run, "plant.run", lambda body: self.info.to_json(), self.drops),
            JsonQueryable(s, keys.faults, "plant.faults", self._on_fault_query, self.drops),
            JsonQueryable(s, keys.plant_status, "plant.status", lambda body: self.status(), self.drops),
        ]
        self._supervisor_ready_flag = False
        self._sup_status_sub = s.declare_subscriber(keys.supervisor_status, self._on_supervisor_status)
        self.watch = LivenessWatch(s, keys.alive_all, self._on_liveliness)
        self._token = s.liveliness().declare_token(keys.alive(Process.PLANT))

    def close(self) -> None:
        for q in self._queryables:
            q.close()
        self._token.undeclare()
        self.watch.undeclare()
        self._refs_sub.undeclare()
        self._sup_status_sub.undeclare()
        self.events.close()
        if self.display is not None:
            self.display.close()

    def stop(self) -> None:
        """Ask the loop to end after the current tick (from a signal handler or another thread)."""
        self._stop.set()
        self.mailbox.wake()

    # -- events, liveliness -------------------------------------------------------------------------------------
    def _publish_event(self, event: Event) -> None:
        self._events_pub.put(encode_json("events", event.to_json()))
        if self.display is not None:
            self.display.event(event)

    def _on_liveliness(self, process: str, alive: bool) -> None:
        if process not in (Process.SUPERVISOR, Process.API):
            return
        detail = {"process": process, "alive": alive, "noticed_by": Process.PLANT.value}
        self.events.write([Event(self.plant.t, EventType.LIVELINESS, detail=detail)])
        if process == Process.SUPERVISOR:
            self.mute = False
            if not alive:
                self._supervisor_ready_flag = False
            self.mailbox.wake()

    def _on_refs(self, sample: zenoh.Sample) -> None:
        """A refs frame: its rows are assembled into their tick as far as its sender owns them (``RefsSenders``)."""
        sender = self.keys.sender_of(str(sample.key_expr))
        self.mailbox.put(sample.payload.to_bytes(), self.senders.owned(sender))

    def _on_supervisor_status(self, sample: zenoh.Sample) -> None:
        """The supervisor's handshake: ready for this run (subscribed and built); a sharded one's plan."""
        try:
            body = decode_json("supervisor.status", sample.payload.to_bytes())
        except WireError as error:
            self.drops.add("supervisor.status", error.reason)
            return
        self.senders.update(body)
        self.mailbox.expect(self.senders.served())  # a lost shard's turbines: the tick completes without them
        ready = bool(body.get("ready")) and body.get("run_id") == self.run_id
        if ready != self._supervisor_ready_flag:
            self._supervisor_ready_flag = ready
            self.mailbox.wake()

    # -- fault commands (queryable thread → main loop) ----------------------------------------------------------
    def _on_fault_query(self, body: dict[str, Any]) -> dict[str, Any]:
        op = body.get("op", "list")
        if op == "list":
            return {"ok": True, "t": self.plant.t, "faults": self.book.listing(self.plant.t)}
        if op == "inject":
            try:
                fault = FaultSpec.model_validate(body.get("fault"))
            except ValueError as error:
                raise QueryError(f"bad fault: {error}", 422) from None
            return self._run_in_loop(lambda: self._inject(fault))
        if op == "clear":
            label = body.get("label")
            if not isinstance(label, str):
                raise QueryError("clear needs a label", 422, [("label", "missing")])
            return self._run_in_loop(lambda: self._clear(label))
        raise QueryError(f"unknown op {op!r}", 400)

    def _run_in_loop(self, command: Callable[[], dict]) -> dict[str, Any]:
        if self.state == "ended":
            raise QueryError("the run has ended", 409)
        future: Future = Future()
        self._commands.put((command, future))
        try:
            return future.result(timeout=COMMAND_TIMEOUT_S)
        except InjectionRefusedError as refused:
            raise QueryError(str(refused), refused.status, refused.problems) from None
        except TimeoutError:
            raise QueryError("the plant did not apply the command in time", 503) from None

    def _apply_commands(self) -> None:
        while True:
            try:
                command, future = self._commands.get_nowait()
            except queue.Empty:
                return
            try:
                future.set_result(command())
            except Exception as error:  # InjectionRefusedError, or a plant that refuses: goes back to the caller
                future.set_exception(error)

    def _inject(self, fault: FaultSpec) -> dict[str, Any]:
        t = self.plant.t
        spec = self.book.prepare(fault, t)
        try:
            self.kind.inject(self.plant, spec)
        except (KeyError, ValueError) as error:
            raise InjectionRefusedError([("fault", str(error))]) from None
        record = self.book.add(spec, "api")
        write_json(self.run_dir / FAULTS, self.book.listing(t))
        return {"ok": True, "t": t, "fault": record.to_json(t)}

    def _clear(self, label: str) -> dict[str, Any]:
        t = self.plant.t
        record = self.book.check_clear(label, t)
        try:
            self.kind.clear(self.plant, label)
        except (KeyError, ValueError) as error:
            raise InjectionRefusedError([("label", f"cannot clear {label!r}: {error}")], 409) from None
        self.book.mark_cleared(record, t)
        write_json(self.run_dir / FAULTS, self.book.listing(t))
        return {"ok": True, "t": t, "fault": record.to_json(t)}

    # -- status ---------------------------------------------------------------------------------------------------
    def status(self, exact: bool = False) -> dict[str, Any]:
        wall = time.time() - self.wall_start
        run_wall = time.perf_counter() - self._loop_start if self.state in ("running", "ended") else 0.0
        t = self.plant.t
        return {
            "run_id": self.run_id,
            "scenario": self.scenario.name,
            "kind": self.scenario.plant.kind,
            "turbines": sorted(set(self.turbines)),
            "mode": self.settings.mode,
            "speed": self.settings.speed,
            "state": self.state,
            "t": t,
            "tick": self.plant.k,
            "duration_s": self.scenario.duration_s,
            "dt": self.dt,
            "real_time_factor": (t / run_wall) if run_wall > 0 else None,
            "ticks": self.pacer.ticks,
            "overruns": self.pacer.overruns,
            "overrun_pct": self.pacer.overrun_pct,
            "resyncs": self.pacer.resyncs,
            "latency": self.latency.summary(exact=exact),
            "latency_recent": self.latency.summary(recent=1000),
            "refs_fresh": self.freshness.fresh,
            "refs_stale_ticks": self.freshness.stale_ticks,
            "refs_stale_episodes": self.freshness.stale_episodes,
            "refs_received": self.refs_received,
            "refs_refused": self.refusals.counts(),
            "refs_senders": self.senders.plan(),
            "refs_unserved": [t for t, s in zip(self.mailbox.turbines, self.senders.served(), strict=True) if not s],
            "run_key": self.run_key,
            "supervisor_alive": self.watch.is_alive(Process.SUPERVISOR),
            "dropped": self.drops.as_dict(),
            "display": None if self.display is None else self.display.counters(),
            "wall_s": wall,
        }

    def _publish_status(self, force: bool = False) -> None:
        now = time.monotonic()
        if self.state == "running" and now - self._last_checkpoint >= CHECKPOINT_EVERY_S:
            self._last_checkpoint = now
            write_json(self.run_dir / LIVE, self._live_record(final=False))
        if force or now - self._last_status >= self.settings.status_every_s:
            self._last_status = now
            status = self.status()
            self._status_pub.put(encode_json("plant.status", status))
            if self.display is not None:
                self.display.timing(self.plant.t, status)

    # -- the loop -------------------------------------------------------------------------------------------------
    def _supervisor_ready(self) -> bool:
        return self.watch.is_alive(Process.SUPERVISOR) and self._supervisor_ready_flag

    def _wait_for_supervisor(self) -> None:
        deadline = time.monotonic() + self.settings.supervisor_wait_s
        while not self._stop.is_set() and time.monotonic() < deadline and not self._supervisor_ready():
            self._apply_commands()
            self._publish_status()
            self.mailbox.wait_for(self._supervisor_ready, timeout=0.05)
        if not self._supervisor_ready() and not self._stop.is_set():
            log.warning(
                "no supervisor after %.0f s: starting on the turbine's own controller", self.settings.supervisor_wait_s
            )

    def _take_refs(self) -> None:
        """Fold arrived refs into the latest refs, the latency figures and the score, as ``guard`` allows."""
        k = self.plant.k
        for arrival in self.mailbox.drain():
            records = arrival.records
            if arrival.served is not None:  # turbines no sender serves keep their last reference
                records = self.kind.hold_unserved(records, arrival.served, self.latest_refs)
            verdict = self.guard.judge(arrival.tick, records, k)
            if verdict == Verdict.REFUSED:
                continue
            self.refs_received += 1
            self.mute = False
            sent = self._sent_at.pop(arrival.tick, None)
            if sent is not None:
                self.latency.add(arrival.at - sent)
            self.score.on_refs(arrival.tick, records)
            if verdict == Verdict.TAKE and arrival.tick > self.latest_refs_tick:
                self.latest_refs_tick = arrival.tick
                self.latest_refs = records
        if len(self._sent_at) > 4000:
            cutoff = self.plant.k - 2000
            self._sent_at = {k: v for k, v in self._sent_at.items() if k >= cutoff}
        self.refusals.poll(self.plant.t)

    def _refs_for(self, k: int) -> Any | None:
        """The refs tick k uses, or None (stale: the controller falls back)."""
        fresh = self.freshness.update(k, self.latest_refs_tick if self.latest_refs is not None else None)
        return self.kind.refs_from_records(self.latest_refs) if fresh else None

    def _stream_event(self, fresh: bool) -> None:
        detail = {"stream": "refs", "fresh": fresh, "noticed_by": Process.PLANT.value}
        self.events.write([Event(self.plant.t, EventType.STREAM, detail=detail)])

    def _lockstep_wait(self, k: int) -> None:
        """Block until refs_k arrive, unless the supervisor is gone or mute (then fall back and go on)."""
        if self.mute or not self._supervisor_ready():
            return
        got = self.mailbox.wait_for(
            lambda: self.mailbox.arrived(k) or self._stop.is_set() or not self.watch.is_alive(Process.SUPERVISOR),
            self.settings.lockstep_timeout_s,
        )
        if not got:
            self.mute = True
            log.warning(
                "lockstep: no refs for tick %d within %.1f s; continuing on the fallback",
                k,
                self.settings.lockstep_timeout_s,
            )

    def _write_run_folder(self) -> None:
        s = self.settings
        run = {
            "run_id": self.run_id,
            "run_key": self.run_key,
            "scenario": self.scenario.name,
            "kind": self.scenario.plant.kind,
            "seed": s.seed,
            "mode": s.mode,
            "speed": s.speed,
            "dt": self.dt,
            "farm": s.farm,
            "started": self.wall_start,
            "connect": s.connect_endpoints,
            "rerun_url": s.rerun_url,
        }
        write_run_start(self.run_dir, dump_scenario(self.scenario), run, self.book.listing(0.0))

    def _live_record(self, final: bool) -> dict[str, Any]:
        """``live.json``: the run's figures. Rewritten every ``CHECKPOINT_EVERY_S`` while the run goes (``final``
        False: no metrics, the accumulators stay in memory), so a plant that is killed still leaves how far it
        ran; ``finalize.finalize_scorecard`` then scores the events of that stretch and marks the card partial."""
        live = {
            "run_id": self.run_id,
            "final": final,
            "completed": final and self.plant.k >= self.n_steps,
            "ticks_run": self.plant.k,
            "n_steps": self.n_steps,
            "timing": self.status(exact=final),
            "faults": self.book.listing(self.plant.t),
            "effective_faults": [f.model_dump(mode="json", exclude_none=True) for f in self.book.effective()],
        }
        if final:
            live["metrics"] = self.score.result(self.book.effective())
        return live

    def run(self) -> int:
        self._write_run_folder()
        self.state = "waiting"
        self._wait_for_supervisor()
        gc.collect()
        gc.freeze()  # the set-up's objects are never collected: shorter GC pauses in the loop
        realtime = self.settings.mode == "realtime"
        every = self.settings.display_every
        plant, kind, score = self.plant, self.kind, self.score
        self._loop_start = time.perf_counter()
        self.state = "running"
        self.events.write(
            [Event(0.0, EventType.RUN, detail={"phase": "start", "run_id": self.run_id, "mode": self.settings.mode})]
        )
        self.pacer.start(0)
        for k in range(self.n_steps):
            if self._stop.is_set():
                break
            self.k = self.guard.k = k
            self._apply_commands()
            self._take_refs()  # before sensors_k go out: tick k is controlled with refs from tick ≤ k − 1 only
            refs = self._refs_for(k)
            self._pump_display(k, realtime)  # before sensors_k go out: never inside the sensor→refs round trip
            frame = plant.measure()
            records = kind.frame_records(frame, self.turbines)
            records["run"] = self.run_key
            self._sent_at[k] = time.perf_counter()
            self._sensor_pub.put(kind.sensors.encode_frame(records))
            plant.control(refs)
            score.on_tick(k, frame, plant)
            if k % every == 0:
                truth = kind.truth_records(plant, frame, self.turbines)
                self._truth_pub.put(kind.truth.encode_frame(truth))
                if self.display is not None:
                    self.display.plant_rows(records, truth)
            plant.advance()
            new_events = plant.drain_events()
            if new_events:
                self.events.write(new_events)
            self._publish_status()
            if realtime:
                self.pacer.end_tick(k)
            else:
                self._lockstep_wait(k)
                self.pacer.ticks += 1
        self._finish()
        return 0

    def _pump_display(self, k: int, realtime: bool) -> None:
        """One unit of buffered display rows to Rerun (``dashboards.live``), at the start of the tick, before its
        sensors go out, so the display is never inside the sensor→refs round trip; skipped (counted as deferred)
        when less than half the tick is left, as when the loop catches up after an overrun."""
        if self.display is None:
            return
        if realtime and time.perf_counter() > self.pacer.deadline(k) - 0.5 * self.pacer.period:
            self.display.defer()
        else:
            self.display.pump()

    def _finish(self) -> None:
        last = self.plant.k - 1
        if self.settings.mode == "realtime" and self._supervisor_ready():
            self.mailbox.wait_for(lambda: self.mailbox.arrived(last), FINAL_REFS_WAIT_S)
        self._take_refs()
        self.state = "ended"
        live = self._live_record(final=True)
        completed = live["completed"]
        write_json(self.run_dir / LIVE, live)
        write_json(self.run_dir / FAULTS, self.book.listing(self.plant.t))
        self.events.write(
            [Event(self.plant.t, EventType.RUN, detail={"phase": "end", "run_id": self.run_id, "completed": completed})]
        )
        self._publish_status(force=True)
        if self.display is not None:
            self.display.flush()
