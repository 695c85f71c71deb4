"""The step contract every plant and every supervisor follows, in batch, lockstep and realtime alike.

One tick k of a plant (sample time ``dt``):

1. ``frame = plant.measure()`` – the sensor readings y_k (with noise and sensor faults) and the controller
   outputs of tick k−1, for all ``n`` turbines of the batch;
2. ``plant.control(refs)`` – the turbine controllers compute u_k from y_k and ``refs``, the supervisor's newest
   references (computed from y_{k−1}; ``None`` when there are none yet or they are stale);
3. ``refs = supervisor.step(frame)`` – the supervisor digests y_k and returns its references for tick k+1;
4. ``plant.advance()`` – the plant integrates from tick k to k+1.

Batch mode runs these four calls in one loop (``run_ticks``); lockstep runs 1–2–4 in the plant process and 3 in the
supervisor process, the plant waiting for refs_k before tick k+1; realtime is lockstep that does not wait past
the tick's deadline. The same objects run in all three, so the same scenario and seed give the same results.

Over the network a sensor frame can be lost (real time: best effort). A supervisor may then be given, before the
frame that follows the gap, ``supervisor.bridge(frame)`` once per missing tick, with ``frame`` interpolated from
the frames either side: it advances its observers through the tick and takes no decision (no test statistic takes
the made-up sample, no event). A supervisor without ``bridge`` holds everything through the gap.
``windwarden.live.guard`` says why and when; batch and lockstep never lose a frame, so they never call it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np

from wwcore.events import Event


class Plant(Protocol):
    dt: float
    n: int
    k: int

    def measure(self) -> Any: ...
    def control(self, refs: Any | None) -> None: ...
    def advance(self) -> None: ...
    def truth(self) -> dict[str, np.ndarray]: ...
    def drain_events(self) -> list[Event]: ...


class Supervisor(Protocol):
    def step(self, frame: Any) -> Any: ...
    def drain_events(self) -> list[Event]: ...


class Bridging(Protocol):
    """A supervisor that can advance through a tick whose frame was lost (optional, see the module docstring)."""

    def bridge(self, frame: Any) -> None: ...


def run_ticks(
    plant: Plant,
    supervisor: Supervisor,
    ticks: range,
    refs: Any | None = None,
    *,
    before: Callable[[int, Any | None], None] | None = None,
    controlled: Callable[[int, Any], None] | None = None,
    stepped: Callable[[int, Any, Any | None], None] | None = None,
    advanced: Callable[[int], None] | None = None,
) -> Any | None:
    """The batch loop: for every tick k of ``ticks``, measure → control → step → advance, starting from ``refs``.

    The hooks are what differs between the loops that run it (scoring, traces, twins, progress), each called at its
    point of tick k: ``before(k, refs)`` before ``measure`` (with the refs tick k will be controlled with);
    ``controlled(k, frame)`` after ``control``; ``stepped(k, frame, refs)`` after ``step`` and before ``advance``
    (the plant's truth still at tick k, ``refs`` the new ones); ``advanced(k)`` after ``advance``. Returns the
    refs of the last tick.
    """
    for k in ticks:
        if before is not None:
            before(k, refs)
        frame = plant.measure()
        plant.control(refs)
        if controlled is not None:
            controlled(k, frame)
        refs = supervisor.step(frame)
        if stepped is not None:
            stepped(k, frame, refs)
        plant.advance()
        if advanced is not None:
            advanced(k)
    return refs
