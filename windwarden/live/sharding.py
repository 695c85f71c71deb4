"""What a supervisor shard and the farm coordinator put on the wire, and what they make of it (no transport here).

A shard (``windwarden.live.shard``) steps the per-turbine part of the farm supervisor on its turbines
(``service.farm.shard.FarmShard``) and, on each 10 Hz farm sample, sends one ``farm.summary`` frame, a row per
turbine: the sample as the plant sent it and its detector's verdict (``summary_records``). The coordinator
(``windwarden.live.coordinator``) assembles the farm's sample and diagnosis from every turbine's summary
(``farm_sample``), runs the farm-wide part (``FarmSupervisor.decide``: the dispatch, eqs. (18)–(26), the
accommodation, the events) and sends every turbine's references back as one ``farm.refs`` frame on the dispatch key;
the shard answers each sensor tick with the newest of them, re-stamped (``held_records``), as one supervisor does.

A shard that stops summarising is lost to the coordinator (``ShardRoster``): when its summaries are missing from
``lost_after_samples`` farm samples the other shards summarised (killed, hung, cut off), when its status falls silent
for ``silent_after_s`` (every shard gone), or when its status says it stopped. Its turbines are then held: the
coordinator decides on their last summaries (``held_summaries``), sends them nothing, and the plant keeps their last
references (``FarmKind.hold_unserved``); the sample names them (``farm_sample``), so the dispatch counts them as
fixed producers at those references and shares the rest of the demand over the served turbines. A lost shard
rejoins once it reports ready for the run again and sends a summary of a newer farm sample.
"""

from __future__ import annotations

import bisect
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from service.farm.interfaces import FarmDiagnosis, FarmSample
from windwarden.kinds.base import records_from_batch
from wwcore.wire import FARM_REFS, FARM_SUMMARY, DropReason, MessageSchema, WireError


def summary_records(sensors: np.ndarray, sample: FarmSample, diagnosis: FarmDiagnosis) -> np.ndarray:
    """``farm.summary`` rows of a shard's turbines: ``sensors`` (their ``farm.sensors`` rows of a farm sample, as
    received: SCADA means not untrimmed), ``sample`` and ``diagnosis`` (the shard's, same rows)."""
    values = {
        "tick": sensors["tick"],
        "t": sensors["t"],
        "run": sensors["run"],
        "sample_index": sample.j,
        "sample_t": sample.t,
        "scada": sensors["scada"],
        "zone": sensors["zone"],
        "power_ref_used": sensors["power_ref_used"],
        "mast": sensors["mast"],
        "demand": sensors["demand"],
        "mast_direction": sensors["mast_direction"],
        "flags": diagnosis.faulty,
        "statistic": diagnosis.statistics,
        "threshold": diagnosis.thresholds,
    }
    return records_from_batch(FARM_SUMMARY, values, [int(t) for t in sensors["turbine"]])


def farm_sample(summaries: np.ndarray, held: np.ndarray | None = None) -> tuple[FarmSample, FarmDiagnosis]:
    """The farm's sample (as the plant sent it) and its detectors' diagnosis from one farm's summaries of one tick,
    rows in the farm's turbine order; the met mast and the demand from the first row, as
    ``FarmKind.frame_from_records`` takes them. ``held`` (rows,) bool: the rows ``held_summaries`` held (a lost
    shard's turbines), which the sample names (``FarmSample.held``) so the dispatch leaves them out of its sharing."""
    sample = FarmSample(
        j=int(summaries["sample_index"][0]),
        t=float(summaries["sample_t"][0]),
        scada=np.array(summaries["scada"]),
        zone=np.array(summaries["zone"]),
        power_ref_used=np.array(summaries["power_ref_used"]),
        mast=np.array(summaries["mast"][:1]),
        demand=np.array(summaries["demand"][:1]),
        mast_direction=np.array(summaries["mast_direction"][:1]),
        held=None if held is None or not held.any() else held.copy(),
    )
    diagnosis = FarmDiagnosis(
        np.array(summaries["flags"]), np.array(summaries["statistic"]), np.array(summaries["threshold"])
    )
    return sample, diagnosis


SHARED_FIELDS = ("run", "sample_index", "sample_t", "mast", "demand", "mast_direction")
"""The fields every row of one farm sample's summaries carries alike (``mismatch`` checks them)."""
SAMPLE_FIELDS = ("tick", "t", *SHARED_FIELDS)
"""The fields of a summary that are the farm sample's: its tick and time, and ``SHARED_FIELDS``."""


def held_summaries(summaries: np.ndarray, served: np.ndarray, last: np.ndarray | None) -> np.ndarray | None:
    """One farm sample's summaries in which the rows not ``served`` (a lost shard's turbines) are their rows of
    ``last`` (the last sample decided: SCADA means, zone, power reference used, the verdict), with this sample's
    ``SAMPLE_FIELDS``: the dispatch sees those turbines as they were when their shard was lost, and their flags do
    not change (no event). None when there is no earlier sample to hold them at."""
    if last is None or not served.any():
        return None
    out = summaries.copy()
    held = ~served
    out[held] = last[held]
    first = int(np.flatnonzero(served)[0])
    for name in SAMPLE_FIELDS:
        out[name][held] = summaries[name][first]
    return out


@dataclass
class ShardState:
    """A shard's last status as the coordinator heard it."""

    run_id: str | None
    turbines: list[int]
    ready: bool
    heard: float  # the roster's clock when it came


@dataclass
class LostShard:
    turbines: list[int]
    reason: str
    at: float  # the roster's clock when it was found lost
    tick: int  # the newest farm-sample tick summarised then


class ShardRoster:
    """Which shards serve the coordinator's run, which are lost, and when (the module docstring's rules).

    ``admitted`` are the shards the coordinator decides for and dispatches to (the plan the plant takes): each
    reported ready for the run; before the run is ``started`` (every turbine owned, each once) a shard that turns
    not ready just leaves, after it a shard that stops is ``lost`` and its turbines are held. ``check()`` applies the
    rules and returns the changes, ``(name, alive, reason)``. Not thread-safe: the coordinator holds its lock."""

    def __init__(self, lost_after_samples: int, silent_after_s: float, clock: Callable[[], float] = time.monotonic):
        self.lost_after_samples = lost_after_samples
        self.silent_after_s = silent_after_s
        self.clock = clock
        self.shards: dict[str, ShardState] = {}
        self.run_id: str | None = None
        self.start(None)

    def start(self, run_id: str | None) -> None:
        """A new run: nobody admitted or lost yet (the shards' statuses are kept)."""
        self.run_id = run_id
        self.admitted: set[str] = set()
        self.lost: dict[str, LostShard] = {}
        self.started = False
        self.lost_total = 0
        self.rejoined_total = 0
        self._summarised: dict[str, int] = {}  # shard → newest farm-sample tick it summarised (or was admitted at)
        self._ticks: list[int] = []  # the newest farm-sample ticks any shard summarised, ascending

    def heard_status(self, name: str, run_id: str | None, turbines: list[int], ready: bool) -> None:
        self.shards[name] = ShardState(run_id, turbines, ready, self.clock())

    def heard_summary(self, name: str, tick: int) -> None:
        """A summary of farm-sample tick ``tick`` from shard ``name`` (of this run, well formed)."""
        self._summarised[name] = max(tick, self._summarised.get(name, -1))
        i = bisect.bisect_left(self._ticks, tick)
        if i == len(self._ticks) or self._ticks[i] != tick:
            self._ticks.insert(i, tick)
            del self._ticks[: -(2 * self.lost_after_samples + 16)]

    def newest(self) -> int:
        return self._ticks[-1] if self._ticks else -1

    def missed(self, name: str) -> int:
        """Farm samples others summarised since ``name``'s newest summary (or its admission)."""
        since = self._summarised.get(name, self.newest())
        return len(self._ticks) - bisect.bisect_right(self._ticks, since)

    def _ready(self, name: str) -> bool:
        state = self.shards.get(name)
        return state is not None and state.ready and self.run_id is not None and state.run_id == self.run_id

    def _admit(self, name: str) -> None:
        self.admitted.add(name)
        self._summarised[name] = self.newest()  # misses count from now

    def turbines_of(self, names: set[str]) -> list[int]:
        return sorted({t for name in names for t in self.shards[name].turbines})

    def held(self) -> list[int]:
        """The lost shards' turbines no admitted shard owns."""
        lost = {t for shard in self.lost.values() for t in shard.turbines}
        return sorted(lost - set(self.turbines_of(self.admitted)))

    def coverage(self, turbines: list[int]) -> str | None:
        """Why the admitted shards do not serve the run's ``turbines`` (each once; the lost shards' turbines held),
        or None."""
        owner: dict[int, str] = {}
        twice = []
        for name in sorted(self.admitted):
            for turbine in self.shards[name].turbines:
                if turbine in owner:
                    twice.append(f"turbine {turbine} ({owner[turbine]} and {name})")
                owner[turbine] = name
        missing = sorted(set(turbines) - set(owner) - set(self.held()))
        if twice:
            return "owned twice: " + ", ".join(twice)
        if missing:
            return f"no ready shard owns turbines {missing}"
        if not self.admitted:
            return "every shard is lost"
        return None

    def check(self, turbines: list[int]) -> list[tuple[str, bool, str]]:
        """Admit the shards ready for the run, find the lost ones and the ones back (module docstring)."""
        changes: list[tuple[str, bool, str]] = []
        now = self.clock()
        for name in sorted(self.shards):
            ready = self._ready(name)
            if name in self.lost:
                lost = self.lost[name]
                back = ready and self.shards[name].heard > lost.at and self._summarised.get(name, -1) > lost.tick
                if back:
                    del self.lost[name]
                    self._admit(name)
                    self.rejoined_total += 1
                    changes.append((name, True, f"summarises again (farm-sample tick {self._summarised[name]})"))
            elif name not in self.admitted:
                if ready:
                    self._admit(name)
            elif not self.started:
                if not ready:
                    self.admitted.discard(name)
            else:
                reason = self._lost_reason(name, ready, now)
                if reason is not None:
                    self.admitted.discard(name)
                    self.lost[name] = LostShard(list(self.shards[name].turbines), reason, now, self.newest())
                    self.lost_total += 1
                    changes.append((name, False, reason))
        if not self.started and self.coverage(turbines) is None:
            self.started = True
        return changes

    def _lost_reason(self, name: str, ready: bool, now: float) -> str | None:
        if not ready:
            return "its status says it is not ready for the run (stopped)"
        silent = now - self.shards[name].heard
        if silent > self.silent_after_s:
            return f"no status for {silent:.1f} s"
        missed = self.missed(name)
        if missed >= self.lost_after_samples:
            return f"no summary for {missed} farm samples the other shards summarised"
        return None


def mismatch(summaries: np.ndarray) -> str | None:
    """Why the rows of one tick's summaries cannot be one farm sample (rows of different samples or runs), or None."""
    for name in SHARED_FIELDS:
        column = summaries[name]
        if (column != column[0]).any():
            return f"the summaries of tick {int(summaries['tick'][0])} differ in {name}"
    return None


def held_records(last: np.ndarray | None, tick: int, turbines: list[int]) -> np.ndarray:
    """The ``farm.refs`` rows answering sensor tick ``tick``: the coordinator's newest (``last``) re-stamped, as
    ``FarmSupervisor.step`` re-stamps its references between farm samples; before the first farm sample, rows
    with no reference (``computed_tick`` −1: the turbines keep their own)."""
    if last is None:
        values = {"tick": tick, "computed_tick": -1, "power_ref": np.nan, "held_torque": np.nan}
        return records_from_batch(FARM_REFS, values, turbines)
    out = last.copy()
    out["tick"] = tick
    return out


def pitch_trim_of(dispatch: np.ndarray) -> np.ndarray | None:
    """The pitch trim (rows, 3) deg the coordinator commands in ``dispatch`` rows; None when it commands none (as
    ``FarmSupervisor`` keeps ``refs.pitch_trim`` None then)."""
    trim = np.array(dispatch["pitch_trim"])
    return trim if trim.any() else None


def checked(schema: MessageSchema, payload: bytes) -> DropReason | None:
    """Why a receiver must refuse the frame ``payload`` before it is assembled (undecodable, or a field the receiver
    computes with not finite or out of its range on any row: ``MessageSchema.refusal``), or None."""
    try:
        rows = schema.decode_frame(payload)
    except WireError as error:
        return DropReason(error.reason)
    return schema.refusal(rows)
