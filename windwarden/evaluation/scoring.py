"""Detection figures from event logs: the part of every scorecard that is the same for all plant kinds.

Definitions (documented in ``docs/scorecards.md``):

* A fault *window* is [start, end) of a scheduled or injected fault on one turbine. Faults that share a window
  and a turbine (seed 000's double faults) are scored as one entry whose target joins their targets with ``+``.
* *Detected*: a detection event on that turbine (any target) in [start, end + grace). *Delay*: the first such
  event's time minus start.
* *Isolated*: at some time in [start, end + grace) the set of targets the supervisor flags on that turbine equals
  the entry's target set exactly.
* *End recognised*: after end, the entry's targets are all unflagged by end + grace; the *end delay* is when
  the last of them was unflagged, minus end.
* *False alarms*: detection events outside every window [start, end + grace) of their turbine, counted over all
  runs and divided by the time outside those windows, per 1000 s. The first ``warmup_s`` of each run (observer
  convergence) is excluded from both count and time.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from wwcore.events import Event, EventType


@dataclass(frozen=True)
class FaultWindow:
    """One scored fault entry."""

    name: str
    targets: tuple[str, ...]
    turbine: int
    start_s: float
    end_s: float

    @property
    def target(self) -> str:
        return "+".join(self.targets)


def windows_from_faults(faults: Sequence[object], duration_s: float) -> list[FaultWindow]:
    """Group faults (objects with target, turbine, start_s, end_s, label) that share turbine and window."""
    groups: dict[tuple[int, float, float], list[object]] = defaultdict(list)
    for fault in faults:
        end = duration_s if fault.end_s is None else min(fault.end_s, duration_s)  # type: ignore[attr-defined]
        groups[(fault.turbine, fault.start_s, end)].append(fault)  # type: ignore[attr-defined]
    out = []
    for (turbine, start, end), members in sorted(groups.items(), key=lambda item: (item[0][1], item[0][0])):
        targets = tuple(dict.fromkeys(m.target for m in members))  # type: ignore[attr-defined]
        name = " + ".join(m.label for m in members)  # type: ignore[attr-defined]
        out.append(FaultWindow(name, targets, turbine, start, end))
    return out


@dataclass
class _Flags:
    """The supervisor's flagged-target set on one turbine of one run, as a step function of time."""

    times: list[float]
    sets: list[frozenset[str]]

    def intervals(self, t0: float, t1: float) -> Iterable[tuple[float, float, frozenset[str]]]:
        for i, (t, flagged) in enumerate(zip(self.times, self.sets, strict=True)):
            nxt = self.times[i + 1] if i + 1 < len(self.times) else np.inf
            lo, hi = max(t, t0), min(nxt, t1)
            if lo < hi or (lo == hi == t0 and t <= t0 < nxt):
                yield lo, hi, flagged


def _flag_history(events: Sequence[Event]) -> dict[tuple[int, int], _Flags]:
    history: dict[tuple[int, int], _Flags] = {}
    for ev in sorted(events, key=lambda e: e.t):
        if ev.type not in (EventType.DETECTION, EventType.RECOVERY) or ev.target is None:
            continue
        key = (ev.run, ev.turbine)
        flags = history.setdefault(key, _Flags([0.0], [frozenset()]))
        current = set(flags.sets[-1])
        if ev.type is EventType.DETECTION:
            current.add(ev.target)
        else:
            current.discard(ev.target)
        if flags.times[-1] == ev.t:
            flags.sets[-1] = frozenset(current)
        else:
            flags.times.append(ev.t)
            flags.sets.append(frozenset(current))
    return history


def _stats(values: list[float]) -> tuple[float | None, float | None]:
    if not values:
        return None, None
    return float(np.mean(values)), float(np.max(values))


def score_faults(
    events: Sequence[Event],
    windows: Sequence[FaultWindow],
    runs: int,
    duration_s: float,
    grace_s: float = 2.0,
    warmup_s: float = 0.0,
    turbines: Sequence[int] = (1,),
) -> tuple[list[dict], float, dict]:
    """Per-window detection figures, the false-alarm rate per 1000 s, and the raw false-alarm counts.

    The false-alarm time base is turbine-seconds: each turbine in ``turbines`` contributes its own time
    outside its own fault windows.
    """
    history = _flag_history(events)
    empty = _Flags([0.0], [frozenset()])
    detections = [e for e in events if e.type is EventType.DETECTION]
    entries = []
    for w in windows:
        want = frozenset(w.targets)
        delays, end_delays = [], []
        isolated = 0
        for run in range(runs):
            flags = history.get((run, w.turbine), empty)
            hits = [
                e.t
                for e in detections
                if e.run == run and e.turbine == w.turbine and w.start_s <= e.t < w.end_s + grace_s
            ]
            if hits:
                delays.append(min(hits) - w.start_s)
            if any(flagged == want for _, _, flagged in flags.intervals(w.start_s, w.end_s + grace_s)):
                isolated += 1
            end_delay = _end_delay(flags, want, w.end_s, grace_s)
            if end_delay is not None and w.end_s < duration_s:
                end_delays.append(end_delay)
        mean, worst = _stats(delays)
        end_mean, end_worst = _stats(end_delays)
        ended = w.end_s < duration_s
        entries.append(
            {
                "name": w.name,
                "target": w.target,
                "turbine": w.turbine,
                "start_s": w.start_s,
                "end_s": w.end_s,
                "detected_pct": 100.0 * len(delays) / runs,
                "isolated_pct": 100.0 * isolated / runs,
                "delay_s_mean": mean,
                "delay_s_max": worst,
                "end_recognised_pct": (100.0 * len(end_delays) / runs) if ended else None,
                "end_delay_s_mean": end_mean,
                "end_delay_s_max": end_worst,
            }
        )
    false_alarms, quiet_time = _false_alarms(detections, windows, runs, duration_s, grace_s, warmup_s, turbines)
    rate = 1000.0 * false_alarms / quiet_time if quiet_time > 0 else 0.0
    return entries, rate, {"count": false_alarms, "observed_s": quiet_time}


def _end_delay(flags: _Flags, want: frozenset[str], end_s: float, grace_s: float) -> float | None:
    """Time after ``end_s`` at which none of ``want`` is flagged any more and stays so until end + grace."""
    last_clear = None
    for lo, _hi, flagged in flags.intervals(end_s, end_s + grace_s):
        if flagged & want:
            last_clear = None
        elif last_clear is None:
            last_clear = lo - end_s
    return last_clear


def _false_alarms(
    detections: Sequence[Event],
    windows: Sequence[FaultWindow],
    runs: int,
    duration_s: float,
    grace_s: float,
    warmup_s: float,
    turbines: Sequence[int],
) -> tuple[int, float]:
    by_turbine: dict[int, list[tuple[float, float]]] = defaultdict(list)
    for w in windows:
        by_turbine[w.turbine].append((w.start_s, w.end_s + grace_s))
    count = 0
    for e in detections:
        if e.t < warmup_s:
            continue
        if not any(lo <= e.t < hi for lo, hi in by_turbine.get(e.turbine, [])):
            count += 1
    quiet = 0.0
    for turbine in sorted(set(turbines)):
        covered = _union_length([(max(lo, warmup_s), min(hi, duration_s)) for lo, hi in by_turbine.get(turbine, [])])
        quiet += runs * max(0.0, duration_s - warmup_s - covered)
    return count, quiet


def _union_length(intervals: list[tuple[float, float]]) -> float:
    total, reach = 0.0, -np.inf
    for lo, hi in sorted(i for i in intervals if i[1] > i[0]):
        if hi <= reach:
            continue
        total += hi - max(lo, reach)
        reach = hi
    return total
