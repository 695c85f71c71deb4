"""The supervisor's flags as a step function of time, one per run: what every detection figure is read from.

A *flag* is a (turbine, target) pair; DETECTION events raise one, RECOVERY events drop it. Events at the same
instant are one change (a detector that moves its verdict from one sensor to another does so at one instant).
Times are rounded to ``scoring_policy.TIME_DECIMALS`` decimals (microseconds).

Scoring starts at the policy's warm-up: the history begins there with nothing flagged, and every flag raised
earlier that is still up at that moment is raised *at* that moment, so a flag raised in the warm-up and never
cleared is scored like one raised when scoring starts.
"""

from __future__ import annotations

import bisect
import itertools
from collections import defaultdict
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass

from windwarden.evaluation.scoring_policy import TIME_DECIMALS
from wwcore.events import Event, EventType

Flag = tuple[int, str]  # (turbine, target)
NOTHING: frozenset[Flag] = frozenset()


@dataclass(frozen=True)
class Change:
    """What changed at one instant: flags raised, flags dropped, and the flagged set from then on."""

    t: float
    raised: frozenset[Flag]
    dropped: frozenset[Flag]
    flagged: frozenset[Flag]


class FlagHistory:
    """The flagged set of one run from the start of scoring on: ∅, then ``changes[i].flagged`` from its time."""

    def __init__(self, start_s: float, changes: Sequence[Change] = ()):
        self.start_s = start_s
        self.changes = list(changes)
        self._times = [c.t for c in self.changes]

    def flagged_after(self, t: float) -> frozenset[Flag]:
        """The flagged set once every change at times ≤ t has happened."""
        i = bisect.bisect_right(self._times, t)
        return self.changes[i - 1].flagged if i else NOTHING

    def flagged_before(self, t: float) -> frozenset[Flag]:
        """The flagged set just before t (every change at times < t)."""
        i = bisect.bisect_left(self._times, t)
        return self.changes[i - 1].flagged if i else NOTHING

    def between(self, t0: float, t1: float) -> list[Change]:
        """The changes at times in [t0, t1)."""
        return self.changes[bisect.bisect_left(self._times, t0) : bisect.bisect_left(self._times, t1)]

    def pieces(self, t0: float, t1: float, cuts: Iterable[float] = ()) -> Iterator[tuple[float, float, frozenset]]:
        """[t0, t1) cut at every change and at ``cuts``: (lo, hi, flagged set over [lo, hi))."""
        if t1 <= t0:
            return
        edges = sorted({t0, t1, *(c.t for c in self.between(t0, t1)), *(c for c in cuts if t0 < c < t1)})
        for lo, hi in itertools.pairwise(edges):
            yield lo, hi, self.flagged_after(lo)


def scoring_time(t: float) -> float:
    """``t`` rounded to the scoring's time resolution (the nearest float to the rounded decimal)."""
    return round(float(t), TIME_DECIMALS)


def flag_histories(events: Iterable[Event], start_s: float) -> dict[int, FlagHistory]:
    """One ``FlagHistory`` per run that has flag events, scoring from ``start_s`` (the policy's warm-up)."""
    by_run: dict[int, list[tuple[float, int, Event]]] = defaultdict(list)
    for order, ev in enumerate(events):
        if ev.type in (EventType.DETECTION, EventType.RECOVERY) and ev.target is not None:
            by_run[ev.run].append((scoring_time(ev.t), order, ev))
    return {run: _history(sorted(items), start_s) for run, items in by_run.items()}


def _history(items: list[tuple[float, int, Event]], start_s: float) -> FlagHistory:
    state: set[Flag] = set()
    instants: list[tuple[float, frozenset[Flag], frozenset[Flag]]] = []  # (t, before, after)
    i = 0
    while i < len(items) and items[i][0] < start_s:  # the warm-up: only its end state is scored
        _apply(state, items[i][2])
        i += 1
    before: frozenset[Flag] = NOTHING
    if state:
        instants.append((start_s, NOTHING, frozenset(state)))
        before = frozenset(state)
    while i < len(items):
        t = items[i][0]
        while i < len(items) and items[i][0] == t:
            _apply(state, items[i][2])
            i += 1
        after = frozenset(state)
        if instants and instants[-1][0] == t:  # the events at exactly start_s join the warm-up's raises
            t, before, _ = instants.pop()
        if after != before:
            instants.append((t, before, after))
        before = after
    changes = [Change(t, after - prev, prev - after, after) for t, prev, after in instants]
    return FlagHistory(start_s, changes)


def _apply(state: set[Flag], ev: Event) -> None:
    flag = (ev.turbine, str(ev.target))
    if ev.type is EventType.DETECTION:
        state.add(flag)
    else:
        state.discard(flag)
