"""Sensor frames dropped at random on their way into a live supervisor (real time ×2, a router on loopback).

About 5 % of the frames are lost, in bursts of 1–10 ticks, between the Zenoh subscriber and the supervisor's queue
(where a congested best-effort link loses them). The supervisor bridges every gap, restarts nothing and raises no
false alarm; the stuck sensor is still detected and isolated: the figures lockstep gives for this scenario
(``tests/live/test_gaps.py``, where the same drops fed as consecutive frames corrupt observer 1's estimate).
"""

from __future__ import annotations

import queue
import threading
import types

import numpy as np

from tests.live.helpers import LiveNodes, router, scenario
from tests.live.test_gaps import AROUND_RATED
from windwarden.live import supervisor_node
from windwarden.live.finalize import finalize_scorecard


class LossyInbox:
    """The supervisor's sensor queue, losing frames in bursts (1–10 frames, ~5 % of them)."""

    def __init__(self, fraction: float = 0.05, longest: int = 10, seed: int = 11):
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._rng = np.random.default_rng(seed)
        self._start = fraction / ((longest + 1) / 2)
        self._longest = longest
        self._burst = 0
        self._lock = threading.Lock()
        self.seen = self.lost = 0

    def put(self, payload: bytes) -> None:
        with self._lock:
            self.seen += 1
            if self._burst == 0 and self.seen > 100 and self._rng.random() < self._start:
                self._burst = int(self._rng.integers(1, self._longest + 1))
            if self._burst:
                self._burst -= 1
                self.lost += 1
                return
        self._queue.put(payload)

    def get(self, timeout: float | None = None) -> bytes:
        return self._queue.get(timeout=timeout)

    def get_nowait(self) -> bytes:
        return self._queue.get_nowait()

    def qsize(self) -> int:
        return self._queue.qsize()

    def empty(self) -> bool:
        return self._queue.empty()


def test_random_frame_drops_raise_no_false_alarm(tmp_path, monkeypatch):
    inbox = LossyInbox()
    lossy_queue = types.SimpleNamespace(SimpleQueue=lambda: inbox, Empty=queue.Empty)
    monkeypatch.setattr(supervisor_node, "queue", lossy_queue)
    scn = scenario(AROUND_RATED, duration_s=50.0)
    run_dir = tmp_path / "run"
    with router() as endpoint, LiveNodes(endpoint, scn, run_dir, mode="realtime", speed=2.0, seed=3) as nodes:
        assert nodes.wait(120) == 0
        status = nodes.supervisor.status()
    card = finalize_scorecard(run_dir)
    assert 0.02 < inbox.lost / inbox.seen < 0.08, (inbox.lost, inbox.seen)
    assert status["gaps"] > 20 and status["bridged_ticks"] >= inbox.lost * 0.9
    assert status["observer_restarts"] == 0
    assert card["false_alarms"]["count"] == 0, card["false_alarms"]
    assert [(f["detected_pct"], f["isolated_pct"]) for f in card["faults"]] == [(100.0, 100.0)]
    print(f"\n{inbox.lost} of {inbox.seen} frames lost, {status['gaps']} gaps, {status['bridged_ticks']} ticks bridged")
