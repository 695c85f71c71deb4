"""Detection figures from event logs: the one place they are decided, for ``windwarden eval`` of every plant kind
and for the live run folder alike (``score_detection``). Its constants are the plant kind's ``ScoringPolicy``.

Definitions (``docs/scorecards.md`` states them with the policy table; ``flag_history`` turns events into flags):

* A fault *window* is [start, end) of a fault, with its *targets*: the (turbine, target) flags that name it.
  Faults on one turbine that share a window (seed 000's double faults) are one window with both targets. Its
  *scored span* is [start, end + grace). At time t the *allowed* flags are the targets of every window whose span
  contains t; the *right* set of a window is its targets plus any other allowed flag (overlapping windows).
* *Detected*: one of the window's targets was raised while the fault acted, in [start, end). *Delay*: that
  raise's time minus the start. A wrong flag is never a detection; a target raised only after the end is late,
  not detected.
* *Isolated (first flag)*: at the first instant in [start, end) that raises one of the window's targets or a
  flag that is not allowed, the flagged set (after every change of that instant) holds all of the window's
  targets and nothing that is not allowed. A window whose first flag is wrong is not isolated, even if the right
  flag follows (it is then detected, with the delay of the right flag, and its wrong flag is counted).
* *Isolated time*: the share of [start, end) during which the flagged set is right in the same sense.
* *Wrong isolations*: flags raised inside the span that are not allowed, counted (per window and in total).
* *Lost*: one of the window's targets dropped after the detection while the fault still acted.
* *Flaps*: raises of a window target inside the span beyond its first (one detection per window is ideal).
* *End recognised*: the window was detected, all its targets were flagged just before the end, and all were
  cleared within the grace and stayed clear to its end; the *end delay* is when the last was cleared, minus the
  end. A lost flag is never a recognised end. Windows that last to the end of the run have no end.
* *False alarms*: flags raised outside every window's span after the warm-up (a flag raised in the warm-up and
  still up counts as raised when scoring starts), per 1000 s of that time; and the time during which any flag of
  a turbine was up there (*flagged time*), per 1000 s. The time base is per turbine (``turbines``).

Every percentage is over all runs, so a window that is never detected shows 0 % isolated and 0 % ended.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from windwarden.evaluation.flag_history import NOTHING, Flag, FlagHistory, flag_histories, scoring_time
from windwarden.evaluation.scoring_policy import TIME_DECIMALS, ScoringPolicy
from wwcore.events import Event


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

    @property
    def flags(self) -> frozenset[Flag]:
        return frozenset((self.turbine, t) for t in self.targets)


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


@dataclass(frozen=True)
class _Span:
    """A window as scored: the fault acts over [start, end) (start no earlier than the warm-up's end), its span
    reaches ``until`` = min(end + grace, duration)."""

    window: FaultWindow
    start: float
    end: float
    until: float


class _Schedule:
    """The windows of a scenario under a policy: which flags are allowed when, and the time outside every span."""

    def __init__(self, windows: Sequence[FaultWindow], policy: ScoringPolicy, duration_s: float):
        self.duration = scoring_time(duration_s)
        self.warmup = policy.warmup_s
        self.spans = []
        for w in windows:
            start, end = scoring_time(w.start_s), scoring_time(min(w.end_s, duration_s))
            until = min(scoring_time(end + policy.grace_s), self.duration)
            self.spans.append(_Span(w, max(start, self.warmup), end, until))
        self._raw = [(scoring_time(s.window.start_s), s.until, s.window.flags) for s in self.spans]
        self.cuts = sorted({t for lo, hi, _ in self._raw for t in (lo, hi)})

    def allowed(self, t: float) -> frozenset[Flag]:
        out: frozenset[Flag] = NOTHING
        for lo, hi, flags in self._raw:
            if lo <= t < hi:
                out = out | flags
        return out

    def in_span(self, t: float) -> bool:
        return any(lo <= t < hi for lo, hi, _ in self._raw)

    def quiet(self) -> list[tuple[float, float]]:
        """[warm-up, duration) without the spans."""
        out, reach = [], self.warmup
        for lo, hi in sorted((max(lo, self.warmup), min(hi, self.duration)) for lo, hi, _ in self._raw):
            if lo > reach:
                out.append((reach, lo))
            reach = max(reach, hi)
        if reach < self.duration:
            out.append((reach, self.duration))
        return out

    def seconds_allowed(self, target: str) -> float:
        """Turbine-seconds after the warm-up during which a flag of ``target`` is allowed (on its window's turbine)."""
        by_turbine: dict[int, list[tuple[float, float]]] = defaultdict(list)
        for lo, hi, flags in self._raw:
            for turbine, name in flags:
                if name == target:
                    by_turbine[turbine].append((max(lo, self.warmup), hi))
        return sum(_union_length(spans) for spans in by_turbine.values())


@dataclass
class _RunFigures:
    """One window in one run."""

    delay: float | None = None
    isolated: bool = False
    isolated_share: float = 0.0
    wrong: int = 0
    lost: int = 0
    flaps: int = 0
    end_delay: float | None = None


def _window_run(h: FlagHistory, span: _Span, schedule: _Schedule) -> _RunFigures:
    want = span.window.flags
    out = _RunFigures()
    acting = h.between(span.start, span.end)
    first = next((c for c in acting if c.raised & want or c.raised - schedule.allowed(c.t)), None)
    out.isolated = first is not None and want <= first.flagged <= schedule.allowed(first.t)
    detection = next((c for c in acting if c.raised & want), None)
    inside = h.between(span.start, span.until)
    out.wrong = sum(len(c.raised - schedule.allowed(c.t)) for c in inside)
    raises = Counter(flag for c in inside for flag in c.raised & want)
    out.flaps = sum(n - 1 for n in raises.values())
    if span.end > span.start:
        pieces = h.pieces(span.start, span.end, schedule.cuts)
        right = sum(hi - lo for lo, hi, f in pieces if want <= f <= schedule.allowed(lo))
        out.isolated_share = right / (span.end - span.start)
    if detection is None:
        return out
    out.delay = detection.t - scoring_time(span.window.start_s)
    out.lost = sum(len(c.dropped & want) for c in h.between(detection.t, span.end))
    if span.end < schedule.duration and want <= h.flagged_before(span.end):
        clear_from = None
        for lo, _hi, flagged in h.pieces(span.end, span.until):
            if flagged & want:
                clear_from = None
            elif clear_from is None:
                clear_from = lo
        out.end_delay = None if clear_from is None else clear_from - span.end
    return out


def _stats(values: Sequence[float]) -> tuple[float | None, float | None]:
    """Mean and max of times, to the scoring's time resolution."""
    if not values:
        return None, None
    return round(float(np.mean(values)), TIME_DECIMALS), round(float(np.max(values)), TIME_DECIMALS)


def _pct(count: int, runs: int) -> float:
    return 100.0 * count / runs


def _entry(span: _Span, figures: list[_RunFigures], runs: int, duration: float) -> dict[str, Any]:
    w = span.window
    entry = {"name": w.name, "target": w.target, "turbine": w.turbine, "start_s": w.start_s, "end_s": w.end_s}
    if span.end <= span.start:  # the whole window lies in the warm-up
        return {**entry, "note": "inside the warm-up: not scored"}
    delays = [f.delay for f in figures if f.delay is not None]
    ends = [f.end_delay for f in figures if f.end_delay is not None]
    flaps = [f.flaps for f in figures]
    ended = span.end < duration
    return {
        **entry,
        "detected_pct": _pct(len(delays), runs),
        "delay_s_mean": _stats(delays)[0],
        "delay_s_max": _stats(delays)[1],
        "isolated_pct": _pct(sum(f.isolated for f in figures), runs),
        "isolated_time_pct": 100.0 * float(np.mean([f.isolated_share for f in figures])),
        "wrong_isolation_pct": _pct(sum(f.wrong > 0 for f in figures), runs),
        "wrong_isolations": sum(f.wrong for f in figures),
        "lost_pct": _pct(sum(f.lost > 0 for f in figures), runs),
        "lost": sum(f.lost for f in figures),
        "flaps_mean": float(np.mean(flaps)),
        "flaps_max": int(np.max(flaps)),
        "end_recognised_pct": _pct(len(ends), runs) if ended else None,
        "end_delay_s_mean": _stats(ends)[0],
        "end_delay_s_max": _stats(ends)[1],
    }


@dataclass
class DetectionScore:
    """Every detection figure of one set of runs; ``card_fields`` is what a scorecard carries."""

    policy: ScoringPolicy
    runs: int
    duration_s: float
    faults: list[dict[str, Any]]
    false_alarms: dict[str, Any]
    wrong_isolations: dict[str, Any]
    delays: list[list[float]] = field(default_factory=list)  # per window, the delay of every detected run
    schedule: _Schedule | None = None

    @property
    def false_alarms_per_1000s(self) -> float:
        return self.false_alarms["per_1000s"]

    def card_fields(self) -> dict[str, Any]:
        """The scorecard's detection fields, the same for every plant kind, batch and live."""
        return {
            "scoring": self.policy.as_dict(),
            "false_alarms_per_1000s": self.false_alarms["per_1000s"],
            "false_alarm_flagged_s_per_1000s": self.false_alarms["flagged_s_per_1000s"],
            "false_alarms": self.false_alarms,
            "wrong_isolations": self.wrong_isolations,
            "faults": self.faults,
        }

    def by_target(self, target: str, plant_seconds: float) -> dict[str, Any]:
        """The figures of one target name over every window that has it (the farm's Table 5 rows): detection over
        those windows (delays pooled over windows and runs); false positives = raises of that target where it is
        not allowed (false alarms and wrong isolations), per 1000 ``plant_seconds`` and per 1000 turbine-seconds
        during which it is not allowed."""
        assert self.schedule is not None
        spans = self.schedule.spans
        rows = [
            (e, d)
            for s, e, d in zip(spans, self.faults, self.delays, strict=True)
            if target in s.window.targets and "detected_pct" in e
        ]
        delays = [x for _, d in rows for x in d]
        detected = [e["detected_pct"] for e, _ in rows]
        count = self.false_alarms["by_target"].get(target, 0) + self.wrong_isolations["by_target"].get(target, 0)
        turbines = self.false_alarms["turbines"]
        scored = turbines * max(self.schedule.duration - self.schedule.warmup, 0.0)
        not_allowed = self.runs * (scored - self.schedule.seconds_allowed(target))
        return {
            "windows": len(rows),
            "detected_pct": float(np.mean(detected)) if detected else None,
            "missed_pct": float(100.0 - np.mean(detected)) if detected else None,
            "isolated_pct": float(np.mean([e["isolated_pct"] for e, _ in rows])) if rows else None,
            "delay_s_mean": _stats(delays)[0],
            "delay_s_max": _stats(delays)[1],
            "false_positives": count,
            "false_positives_per_1000s": 1000.0 * count / plant_seconds if plant_seconds > 0 else 0.0,
            "false_positives_per_1000_turbine_s": 1000.0 * count / not_allowed if not_allowed > 0 else 0.0,
        }


def score_detection(
    events: Iterable[Event],
    windows: Sequence[FaultWindow],
    *,
    runs: int,
    duration_s: float,
    policy: ScoringPolicy,
    turbines: Sequence[int] = (1,),
) -> DetectionScore:
    """Every detection figure of ``runs`` runs (events with ``run`` 0 … runs − 1) of one fault schedule.

    ``turbines`` are the plant's turbines: each contributes its own time to the false-alarm time base.
    """
    schedule = _Schedule(windows, policy, duration_s)
    histories = flag_histories(events, policy.warmup_s)
    empty = FlagHistory(policy.warmup_s)
    per_run = [histories.get(run, empty) for run in range(runs)]
    faults, delays = [], []
    for span in schedule.spans:
        figures = [_window_run(h, span, schedule) for h in per_run]
        faults.append(_entry(span, figures, runs, schedule.duration))
        delays.append([f.delay for f in figures if f.delay is not None])
    false_alarms: Counter[str] = Counter()
    wrong: Counter[str] = Counter()
    flagged_s = 0.0
    quiet = schedule.quiet()
    for h in per_run:
        for c in h.changes:
            if c.t >= schedule.duration:
                continue
            if schedule.in_span(c.t):
                wrong.update(target for _, target in c.raised - schedule.allowed(c.t))
            else:
                false_alarms.update(target for _, target in c.raised)
        for lo, hi in quiet:
            flagged_s += sum((b - a) * len({turbine for turbine, _ in f}) for a, b, f in h.pieces(lo, hi))
    observed = runs * len(turbines) * sum(hi - lo for lo, hi in quiet)
    count = sum(false_alarms.values())
    fa = {
        "count": count,
        "observed_s": observed,
        "per_1000s": 1000.0 * count / observed if observed > 0 else 0.0,
        "flagged_s": flagged_s,
        "flagged_s_per_1000s": 1000.0 * flagged_s / observed if observed > 0 else 0.0,
        "turbines": len(turbines),
        "time_base": policy.time_base,
        "by_target": dict(sorted(false_alarms.items())),
    }
    wrong_fields = {"count": sum(wrong.values()), "by_target": dict(sorted(wrong.items()))}
    return DetectionScore(policy, runs, duration_s, faults, fa, wrong_fields, delays, schedule)


def twin_false_alarms(
    events: Iterable[Event], observed_s: float, policy: ScoringPolicy, segments: Sequence[tuple[float, float]]
) -> dict[str, Any]:
    """Flags raised in fault-free twins, which run over ``segments`` ([start, end) each; a twin's flag history
    starts empty at its segment's start, or at the warm-up's end if later), per 1000 s of ``observed_s``."""
    grouped: dict[int, list[Event]] = defaultdict(list)
    for ev in events:
        t = scoring_time(ev.t)
        for i, (lo, hi) in enumerate(segments):
            if lo <= t < hi:
                grouped[i].append(ev)
                break
    count, flagged_s = 0, 0.0
    for i, group in grouped.items():
        lo, hi = segments[i]
        for h in flag_histories(group, max(lo, policy.warmup_s)).values():
            count += sum(len(c.raised) for c in h.changes if c.t < hi)
            flagged_s += sum((b - a) * len({tb for tb, _ in f}) for a, b, f in h.pieces(h.start_s, hi))
    return {
        "count": count,
        "observed_s": observed_s,
        "per_1000s": 1000.0 * count / observed_s if observed_s > 0 else 0.0,
        "flagged_s": flagged_s,
        "flagged_s_per_1000s": 1000.0 * flagged_s / observed_s if observed_s > 0 else 0.0,
    }


def _union_length(intervals: list[tuple[float, float]]) -> float:
    total, reach = 0.0, -np.inf
    for lo, hi in sorted(i for i in intervals if i[1] > i[0]):
        if hi <= reach:
            continue
        total += hi - max(lo, reach)
        reach = hi
    return total
