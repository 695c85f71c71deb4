"""What the live nodes trust: the references the plant takes, the sensor frames the supervisor steps, the gaps.

Access control at the router decides who may publish; these checks are the second line, at the two ends that act
on the messages, and they hold whoever got through.

**Plant, references** (``RefsGuard``, ``RefsSenders``). A refs frame is assembled into its tick only if its sender
(the last chunk of its key) is the one supervisor, or a shard of the sharded supervisor's plan (the coordinator's
status: which shard owns which turbines) and every row is for a turbine the sender owns (``not_owned``), each once
(``duplicate_turbine``), all of one tick (``mixed_ticks``): ``TickMailbox``; a tick needs the rows of the turbines
the plan's senders own (``RefsSenders.served``: a lost shard is out of the plan, and its turbines keep their last
reference, ``FarmKind.hold_unserved``). A tick's refs are taken only if it is
for a tick the plant has measured and not older than its window (k − ``max_ref_age`` ≤ tick ≤ k − 1 when tick k
starts), every field the plant acts on is finite and inside its physical range (``wwcore.wire.WireField.limits``),
and no refs for that tick were taken before. A refused message is counted by reason, changes nothing and leaves the
controller on what it had: the last taken refs while they are in the window, then its fallback (the refs are then
reported stale). A future tick is refused as it arrives (``TickMailbox`` window), so it can neither become "the
newest refs" nor end a lockstep wait. Refs that are only late (older than the window, else good) still count for the
loop latency and the score, as before; they never reach the controller.

**Supervisor, sensor frames** (``FrameSequencer``). Every frame carries the plant's run identity (``run``, drawn at
random by the plant when it starts a run, served on ``plant/run``). The observers restart only when that identity
changes *and the plant confirms it* (a query of ``plant/run``), or after a gap longer than ``max_gap_ticks`` that the
plant's own tick confirms (``plant/status``): so an old, repeated, forged or far-future frame is dropped and
counted, never a reason to restart. Queries are rate-limited: a flood of forged identities costs one query per
``CONFIRM_EVERY_S``.

**Gaps** (``interpolated_records``). Sensor frames travel best effort in real time and some are dropped. A gap of
up to ``max_gap_ticks`` is bridged: the supervisor's ``bridge(frame)`` (``wwcore.stepping``) advances its observers
through each missing tick on a frame interpolated linearly between the frames either side, and its detectors do not
step, so no decision is taken and no test statistic takes a made-up sample (interpolated samples are smooth and
correlated: fed to window tests built for white residuals they raise false alarms, measured in
``docs/live.md``). A supervisor without ``bridge`` (the farm: its detectors and dispatch run on the plant's 10 Hz
SCADA means and keep no state stepped per tick) holds everything through the gap.

**Events** (``RefusalLog``). Each refusal is counted at once (the node's ``DropCounter``: ``dropped`` in the status
routes); a ``stream`` event with ``detail.refused`` = the reason is logged for the first refusal of a reason and
then at most once per ``REFUSAL_EVENT_EVERY_S`` per reason, with the count since the last one.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from wwcore.events import Event, EventType
from wwcore.wire import DropCounter, DropReason, MessageSchema

REFUSAL_EVENT_EVERY_S = 1.0  # s of wall time between two events of one refusal reason
CONFIRM_EVERY_S = 0.5  # s of wall time between two confirmation queries of the supervisor
REFUSALS = frozenset(
    {
        DropReason.NON_FINITE,
        DropReason.OUT_OF_RANGE,
        DropReason.FUTURE_TICK,
        DropReason.STALE_TICK,
        DropReason.REPEATED_TICK,
        DropReason.OLD_TICK,
        DropReason.FOREIGN_RUN,
        DropReason.UNCONFIRMED_TICK,
        DropReason.MIXED_TICKS,
        DropReason.DUPLICATE_TURBINE,
        DropReason.UNKNOWN_TURBINE,
        DropReason.NOT_OWNED,
    }
)
"""Messages that decoded but were refused (the other drop reasons are messages that do not decode)."""
LOGGED_REFUSALS = REFUSALS - {DropReason.STALE_TICK}
"""Refusals that make events: what a healthy system never sends. Late refs (``stale_tick``) are only counted: the
refs stream's own stale/fresh events already tell of a slow supervisor."""


class RefusalLog:
    """Rate-limited events for the messages a node refused (counted in its ``DropCounter``)."""

    def __init__(
        self,
        drops: DropCounter,
        stream: str,
        noticed_by: str,
        write: Callable[[list[Event]], Any],
        every_s: float = REFUSAL_EVENT_EVERY_S,
        clock: Callable[[], float] = time.monotonic,
    ):
        self.drops = drops
        self.stream = stream
        self.noticed_by = noticed_by
        self.write = write
        self.every_s = every_s
        self.clock = clock
        self._seen_version = 0
        self._logged: dict[str, int] = {}  # reason → total at its last event
        self._last_event: dict[str, float] = {}

    def poll(self, t: float) -> None:
        """Log what was refused since the last call, as the rate limit allows (cheap when nothing was)."""
        version = self.drops.version
        if version == self._seen_version:
            return
        now = self.clock()
        pending = False
        events = []
        for reason, total in self.drops.of(self.stream).items():
            if reason not in LOGGED_REFUSALS or total == self._logged.get(reason, 0):
                continue
            if now - self._last_event.get(reason, -np.inf) < self.every_s:
                pending = True
                continue
            detail = {
                "stream": self.stream,
                "refused": reason,
                "count": total - self._logged.get(reason, 0),
                "total": total,
                "noticed_by": self.noticed_by,
            }
            events.append(Event(t, EventType.STREAM, detail=detail))
            self._logged[reason] = total
            self._last_event[reason] = now
        if not pending:
            self._seen_version = version
        if events:
            self.write(events)

    def counts(self) -> dict[str, int]:
        """Refusals by reason (late refs too)."""
        return {r: n for r, n in sorted(self.drops.of(self.stream).items()) if r in REFUSALS}


class Verdict:
    TAKE = "take"  # for the controller, the latency figures and the score
    LATE = "late"  # only for the latency figures and the score: older than the window
    REFUSED = "refused"


class RefsGuard:
    """The plant's check of each refs message (module docstring). ``k`` is the tick the plant is at: set by its
    loop, read by ``window`` on Zenoh threads."""

    def __init__(self, schema: MessageSchema, max_ref_age: int, drops: DropCounter, stream: str = "refs"):
        self.schema = schema
        self.max_ref_age = max_ref_age
        self.drops = drops
        self.stream = stream
        self.k = 0
        self._taken: set[int] = set()

    def window(self, tick: int) -> DropReason | None:
        """At arrival: refs for a tick beyond the one the plant is at cannot be genuine (``TickMailbox`` window)."""
        return DropReason.FUTURE_TICK if tick > self.k else None

    def judge(self, tick: int, records: np.ndarray, k: int) -> str:
        """At tick k's start, for one complete refs message: TAKE, LATE or REFUSED (counted)."""
        reason = DropReason.FUTURE_TICK if tick >= k else self.schema.refusal(records)
        if reason is None and tick in self._taken:
            reason = DropReason.REPEATED_TICK
        if reason is not None:
            self.drops.add(self.stream, reason)
            return Verdict.REFUSED
        self._taken.add(tick)
        if len(self._taken) > 8 * self.max_ref_age + 64:
            horizon = k - 4 * self.max_ref_age - 32
            self._taken = {j for j in self._taken if j >= horizon}
        if tick < k - self.max_ref_age:
            self.drops.add(self.stream, DropReason.STALE_TICK)
            return Verdict.LATE
        return Verdict.TAKE


class RefsSenders:
    """Who may send refs for which turbines (the plant's side of the shard plan): the one supervisor (sender
    ``supervisor``) every turbine; once the status of a sharded supervisor's coordinator names the shards ready for
    the run, each of them its own turbines and nobody else anything. ``owned(sender)`` is the mask ``TickMailbox.put``
    takes (None: every turbine); an unknown sender owns no turbine, so its frames are refused as ``not_owned``."""

    SUPERVISOR = "supervisor"

    def __init__(self, mask_of: Callable[[Iterable[int]], np.ndarray], n_turbines: int, run_id: str):
        self.mask_of = mask_of
        self.run_id = run_id
        self._nobody = np.zeros(n_turbines, dtype=bool)
        self._plan: dict[str, np.ndarray | None] = {self.SUPERVISOR: None}
        self.sharded = False

    def update(self, status: dict[str, Any]) -> None:
        """Take the plan from a ``supervisor.status`` body of this run (others are ignored)."""
        if status.get("run_id") != self.run_id:
            return
        if status.get("sharded") is not True:
            self._plan, self.sharded = {self.SUPERVISOR: None}, False
            return
        plan: dict[str, np.ndarray | None] = {}
        shards = status.get("shards")
        for name, shard in (shards if isinstance(shards, dict) else {}).items():
            if not isinstance(shard, dict) or shard.get("ready") is not True or shard.get("run_id") != self.run_id:
                continue
            turbines = shard.get("turbines")
            if isinstance(turbines, list):
                plan[str(name)] = self.mask_of(t for t in turbines if isinstance(t, int) and not isinstance(t, bool))
        self._plan, self.sharded = plan, True

    def owned(self, sender: str) -> np.ndarray | None:
        return self._plan.get(sender, self._nobody)

    def served(self) -> np.ndarray:
        """The turbines some sender of the plan owns (``TickMailbox.expect``): all with one supervisor; with a
        sharded one, those of the shards still in the coordinator's plan (a lost shard's turbines are not)."""
        served = self._nobody.copy()
        for mask in self._plan.values():
            if mask is None:
                return ~served
            served |= mask
        return served

    def plan(self) -> dict[str, int | None]:
        """Sender → turbines it may send refs for (None: all), for the status."""
        return {name: None if mask is None else int(mask.sum()) for name, mask in self._plan.items()}


class RefsFreshness:
    """Whether tick k has fresh refs (the newest taken is from a tick ≥ k − ``max_ref_age``), counted every tick
    once refs have been fresh; an outage becomes a stream event (``event(False)``, then ``event(True)`` when it
    ends) once it has lasted ``stale_event_ticks``: short hiccups are only counted."""

    def __init__(self, max_ref_age: int, stale_event_ticks: int, event: Callable[[bool], None]):
        self.max_ref_age = max_ref_age
        self.stale_event_ticks = stale_event_ticks
        self.event = event
        self.fresh: bool | None = None  # None until the first refs are taken
        self.stale_ticks = 0  # ticks run on the fallback after refs had been fresh
        self.stale_episodes = 0
        self._run = 0
        self._logged = False

    def update(self, k: int, newest_tick: int | None) -> bool:
        fresh = newest_tick is not None and newest_tick >= k - self.max_ref_age
        if fresh:
            self._run = 0
            if self.fresh is None or (self.fresh is False and self._logged):
                self.event(True)
            self._logged = False
            self.fresh = True
        elif self.fresh is not None:  # stale after having been fresh once
            self.fresh = False
            self.stale_ticks += 1
            self._run += 1
            if self._run == 1:
                self.stale_episodes += 1
            if self._run == self.stale_event_ticks:
                self._logged = True
                self.event(False)
        return fresh


class FrameSequencer:
    """The supervisor's decision for each complete sensor frame: drop it, restart the observers first, bridge a gap
    first, or step it (module docstring). ``confirm_run(run)`` and ``confirm_tick(tick)`` ask the plant."""

    STEP, DROP, RESTART, NEW_RUN = "step", "drop", "restart", "new run"

    def __init__(
        self,
        max_gap_ticks: int,
        drops: DropCounter,
        confirm_run: Callable[[int], Any],
        confirm_tick: Callable[[int], bool],
        clock: Callable[[], float] = time.monotonic,
        stream: str = "sensors",
    ):
        self.max_gap_ticks = max_gap_ticks
        self.drops = drops
        self.confirm_run = confirm_run
        self.confirm_tick = confirm_tick
        self.clock = clock
        self.stream = stream
        self.run: int | None = None
        self.last_tick: int | None = None
        self.confirmed: Any = None  # what confirm_run returned for a new run
        self._last_query = -np.inf

    def start(self, run: int) -> None:
        """A run (re)starts: its next frame is stepped whatever its tick."""
        self.run, self.last_tick = run, None

    def _may_query(self) -> bool:
        now = self.clock()
        if now - self._last_query < CONFIRM_EVERY_S:
            return False
        self._last_query = now
        return True

    def decide(self, records: np.ndarray) -> tuple[str, int]:
        """(decision, missing ticks before this frame). DROP is already counted."""
        runs = records["run"]
        run, tick = int(runs[0]), int(records["tick"][0])
        if len(runs) > 1 and (runs != run).any():  # rows of one tick assembled from two runs
            return self._drop(DropReason.FOREIGN_RUN)
        if run != self.run:
            self.confirmed = self.confirm_run(run) if self._may_query() else None
            return (self.NEW_RUN, 0) if self.confirmed is not None else self._drop(DropReason.FOREIGN_RUN)
        if self.last_tick is None:
            return self.STEP, 0
        gap = tick - self.last_tick
        if gap <= 0:
            return self._drop(DropReason.REPEATED_TICK if gap == 0 else DropReason.OLD_TICK)
        if gap > self.max_gap_ticks:
            if self._may_query() and self.confirm_tick(tick):
                return self.RESTART, 0
            return self._drop(DropReason.UNCONFIRMED_TICK)
        return self.STEP, gap - 1

    def stepped(self, tick: int) -> None:
        self.last_tick = tick

    def _drop(self, reason: DropReason) -> tuple[str, int]:
        self.drops.add(self.stream, reason)
        return self.DROP, 0


def bridge_gap(bridge: Callable[[Any], None] | None, kind: Any, before: np.ndarray, after: np.ndarray) -> int:
    """Advance a supervisor through the ticks missing between two frames with its ``bridge`` (None: it holds);
    returns the number of ticks bridged."""
    if bridge is None:
        return 0
    n = 0
    for missing in interpolated_records(before, after):
        bridge(kind.frame_from_records(missing))
        n += 1
    return n


def interpolated_records(before: np.ndarray, after: np.ndarray) -> Iterable[np.ndarray]:
    """The records of each tick strictly between two frames (one row per turbine each): float fields linear in the
    tick, the tick itself counted, every other field (zone, flags, run) as in ``before``."""
    k0, k1 = int(before["tick"][0]), int(after["tick"][0])
    m = k1 - k0 - 1
    if m <= 0:
        return []
    weight = (np.arange(1, m + 1) / (k1 - k0))[:, None]  # (m, 1): one per missing tick
    out = np.repeat(before[None, :], m, axis=0)  # (m, n)
    for name in before.dtype.names:
        if before.dtype[name].base.kind == "f":
            a, b = before[name], after[name]
            w = weight.reshape(weight.shape + (1,) * (a.ndim - 1))
            out[name] = a + w * (b - a)
    out["tick"] = np.arange(k0 + 1, k1)[:, None]
    return list(out)
