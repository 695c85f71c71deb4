"""Per-tick assembly of wire frames: a tick is complete when a row has arrived for every turbine of the node's list.

Used on both sides: the plant collects the supervisor's refs frames (one per tick from one supervisor, one per shard
from a sharded one: the tick is the union of their rows), the supervisor collects the plant's sensor frames (one
per tick, every turbine), the coordinator the shards' summary frames. The producer side runs on Zenoh threads
(``put``), the consumer in the node's main loop (``drain``/``wait_for``).

A frame is taken whole or refused whole (counted, changing nothing): it does not decode; its rows are of two ticks
or name a turbine twice (``wwcore.wire.frame_problem``); a row is for a turbine the node's list does not have
(``unknown_turbine``) or that the sender may not speak for (``owned``: ``not_owned``); a row is for a (tick,
turbine) already being assembled (``repeated_tick``: the first one stays); or ``window``, a node's check of the
tick, refuses it (the plant refuses refs for ticks it has not measured yet there, so a flood of forged ticks can
neither evict real rows nor end a lockstep wait).

Which turbines a tick needs (``expect``): every turbine of the list, unless a sharded supervisor has lost a shard.
Then the plant expects the turbines of the shards still in the plan, and the coordinator the summaries of the shards
still alive; a tick is complete once those rows are in, and its ``Arrival.served`` says which rows arrived (the
others are the turbine number and tick only, for the consumer to fill: ``FarmKind.hold_unserved``,
``sharding.held_summaries``).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from wwcore.wire import DropCounter, DropReason, MessageSchema, WireError, frame_problem


def backlog_ticks(queued_frames: int, frames_per_tick: int = 1) -> float:
    """Ticks queued behind the one being stepped: every tick brings ``frames_per_tick`` frames (the plant's sensor
    frame: one)."""
    return queued_frames / max(frames_per_tick, 1)


TickWindow = Callable[[int], "DropReason | None"]
"""A node's check of a tick before a frame of it is kept: None to keep it, else the reason to refuse it."""

KEEP_PARTIAL = 200  # ticks an incomplete tick may wait for its missing rows


@dataclass
class Arrival:
    tick: int
    records: np.ndarray  # one record per turbine, in the order of the node's turbine list
    at: float  # time.perf_counter() when the last row arrived
    served: np.ndarray | None = None  # rows that arrived, when a tick completed without some (``expect``)


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
        self.turbines = list(dict.fromkeys(turbines))
        self.n = len(self.turbines)
        top = max(self.turbines, default=0)
        self._position = np.full(top + 1, -1, dtype=np.intp)  # turbine number → its row in a complete tick
        self._position[self.turbines] = np.arange(self.n)
        self._in_order = np.array(self.turbines, dtype=np.int64)  # a whole tick's turbine column, in the list's order
        self._every_row = np.arange(self.n)
        self.drops = drops
        self.stream = stream
        self.cond = threading.Condition()
        self._partial: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # tick → (rows, filled)
        self._complete: deque[Arrival] = deque()
        self._expected = np.ones(self.n, dtype=bool)  # the rows a tick needs to be complete
        self.received = 0

    def expect(self, mask: np.ndarray) -> None:
        """Ticks are complete once the rows of ``mask`` (over the node's turbines) are in; ticks waiting only for
        rows outside it complete now, oldest first. A mask of no row is ignored: nobody sends, nothing completes."""
        mask = np.asarray(mask, dtype=bool)
        if not mask.any():
            return
        with self.cond:
            self._expected = mask.copy()
            for tick in sorted(self._partial):
                out, filled = self._partial[tick]
                if filled[mask].all():
                    del self._partial[tick]
                    self._complete.append(self._arrival(tick, out, filled, time.perf_counter()))
                    self.cond.notify_all()

    def _arrival(self, tick: int, out: np.ndarray, filled: np.ndarray, at: float) -> Arrival:
        return Arrival(tick, out, at, None if filled.all() else filled.copy())

    def owned_mask(self, turbines: Iterable[int]) -> np.ndarray:
        """The ``owned`` argument of ``put`` for a sender that may speak for ``turbines`` (others of the list are
        not its)."""
        mask = np.zeros(self.n, dtype=bool)
        positions = [self._position[t] for t in turbines if 0 <= t < len(self._position)]
        mask[[p for p in positions if p >= 0]] = True
        return mask

    def _whole_tick_in_order(self, rows: np.ndarray) -> bool:
        """The frame holds every turbine of the list once, in the list's order: what a plant or a single supervisor
        sends every tick. Its turbines are then known, distinct and at rows 0 … n − 1, so the general checks
        (``frame_problem``'s duplicate search, the position lookup) have nothing to find."""
        return len(rows) == self.n and np.array_equal(rows["turbine"], self._in_order)

    def _refusal(self, rows: np.ndarray, owned: np.ndarray | None) -> tuple[DropReason | None, np.ndarray]:
        if self._whole_tick_in_order(rows):
            ticks = rows["tick"]
            if (ticks != ticks[0]).any():
                return DropReason.MIXED_TICKS, rows
            if owned is not None and not owned.all():
                return DropReason.NOT_OWNED, self._every_row
            refused = None if self.window is None else self.window(int(ticks[0]))
            return refused, self._every_row
        problem = frame_problem(rows)
        if problem is not None:
            return problem, rows
        turbines = rows["turbine"].astype(np.intp)
        if int(turbines.max()) >= len(self._position):
            return DropReason.UNKNOWN_TURBINE, turbines
        positions = self._position[turbines]
        if (positions < 0).any():
            return DropReason.UNKNOWN_TURBINE, positions
        if owned is not None and not owned[positions].all():
            return DropReason.NOT_OWNED, positions
        refused = None if self.window is None else self.window(int(rows["tick"][0]))
        return refused, positions

    def put(self, payload: bytes, owned: np.ndarray | None = None) -> None:
        """Decode one frame (any thread) and take its rows, or refuse and count it (module docstring). ``owned``:
        a mask over the node's turbines (``owned_mask``), the rows the sender may send; None: any."""
        now = time.perf_counter()
        try:
            rows = self.schema.decode_frame(payload)
        except WireError as error:
            self.drops.add(self.stream, error.reason)
            return
        refused, positions = self._refusal(rows, owned)
        if refused is not None:
            self.drops.add(self.stream, refused)
            return
        tick = int(rows["tick"][0])
        with self.cond:
            partial = self._partial.get(tick)
            if partial is None and len(positions) == self.n:  # a whole tick in one frame
                self.received += 1
                if positions is self._every_row:  # in the list's order already: one copy, no scatter
                    out = rows.copy()
                else:
                    out = np.empty(self.n, dtype=self.schema.dtype)
                    out[positions] = rows
                self._complete.append(Arrival(tick, out, now))
                self.cond.notify_all()
                return
            if partial is None:
                out = np.zeros(self.n, dtype=self.schema.dtype)
                out["turbine"], out["tick"] = self.turbines, tick  # what a row that never arrives still says
                partial = self._partial[tick] = (out, np.zeros(self.n, bool))
            out, filled = partial
            if filled[positions].any():
                self.drops.add(self.stream, DropReason.REPEATED_TICK)
                return
            self.received += 1
            out[positions] = rows
            filled[positions] = True
            if filled[self._expected].all():
                del self._partial[tick]
                self._complete.append(self._arrival(tick, out, filled, now))
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
