"""Per-tick assembly of per-turbine wire records: a tick is complete when every turbine's record has arrived.

Used on both sides: the plant collects the supervisor's refs, the supervisor collects the plant's sensors. The
producer side runs on Zenoh threads (``put``), the consumer in the node's main loop (``drain``/``wait_for``).

A second row for a (tick, turbine) that is still being assembled is refused (``repeated_tick``: the first one
stays), and a node may pass ``window``, a check of the tick run before a row is kept: the plant refuses refs for
ticks it has not measured yet there, so a flood of forged ticks can neither evict real rows nor end a lockstep
wait.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from wwcore.wire import DropCounter, DropReason, MessageSchema, WireError, stack_records


def backlog_ticks(queued_messages: int, turbines: int) -> float:
    """Ticks queued behind the one being stepped: every tick brings one sensor message per turbine."""
    return queued_messages / max(turbines, 1)


TickWindow = Callable[[int], "DropReason | None"]
"""A node's check of a tick before a row of it is kept: None to keep it, else the reason to refuse it."""

KEEP_PARTIAL = 200  # ticks an incomplete tick may wait for its missing rows


@dataclass
class Arrival:
    tick: int
    records: np.ndarray  # one record per turbine, in the order of the node's turbine list
    at: float  # time.perf_counter() when the last row arrived


class TickMailbox:
    def __init__(
        self,
        schema: MessageSchema,
        turbines: list[int],
        drops: DropCounter,
        stream: str,
        window: TickWindow | None = None,
    ):
        self.schema = schema
        self.window = window
        self.order = {t: i for i, t in enumerate(dict.fromkeys(turbines))}
        self.n = len(self.order)
        self.drops = drops
        self.stream = stream
        self.cond = threading.Condition()
        self._partial: dict[int, dict[int, np.void]] = {}
        self._complete: deque[Arrival] = deque()
        self.received = 0

    def put(self, payload: bytes) -> None:
        """Decode one message (any thread); bad ones are dropped and counted."""
        now = time.perf_counter()
        try:
            record = self.schema.decode(payload)
        except WireError as error:
            self.drops.add(self.stream, error.reason)
            return
        turbine, tick = int(record["turbine"]), int(record["tick"])
        if turbine not in self.order:
            self.drops.add(self.stream, "unknown_turbine")
            return
        refused = None if self.window is None else self.window(tick)
        if refused is not None:
            self.drops.add(self.stream, refused)
            return
        with self.cond:
            self.received += 1
            rows = self._partial.setdefault(tick, {})
            if turbine in rows:
                self.drops.add(self.stream, DropReason.REPEATED_TICK)
                return
            rows[turbine] = record
            if len(rows) == self.n:
                del self._partial[tick]
                ordered = sorted(rows.items(), key=lambda item: self.order[item[0]])
                self._complete.append(Arrival(tick, stack_records([r for _, r in ordered]), now))
                self.cond.notify_all()
            if len(self._partial) > KEEP_PARTIAL:
                for old in sorted(self._partial)[: len(self._partial) - KEEP_PARTIAL]:
                    del self._partial[old]
                    self.drops.add(self.stream, DropReason.INCOMPLETE)

    def drain(self) -> list[Arrival]:
        with self.cond:
            out = list(self._complete)
            self._complete.clear()
            return out

    def arrived(self, tick: int) -> bool:
        """A complete tick ``tick`` is waiting to be drained (call under the lock: from a ``wait_for`` predicate)."""
        return any(a.tick == tick for a in self._complete)

    def pending(self) -> int:
        with self.cond:
            return len(self._complete)

    def wait_for(self, predicate: Callable[[], bool], timeout: float | None) -> bool:
        """Wait until ``predicate()`` (evaluated under the lock) or ``timeout``; True if it became true."""
        with self.cond:
            return self.cond.wait_for(predicate, timeout)

    def wake(self) -> None:
        with self.cond:
            self.cond.notify_all()
