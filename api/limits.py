"""The API's limits as plain functions and state: a token bucket per client, and the caps on a run's faults.

No HTTP here: ``api.guard`` and the fault routes apply them.
"""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from collections.abc import Callable, Iterable
from typing import Any

from api.settings import ApiLimits
from wwcore.scenario import FaultSpec

LIVE_STATES = frozenset({"active", "pending"})  # faults that act now or will


class TokenBuckets:
    """One token bucket per client: ``burst`` tokens, refilled at ``rate`` per second; a request takes one.

    Only the ``max_clients`` most recently seen clients are remembered; a forgotten one starts again with a full
    bucket, which is what it would have had anyway once it has been away for ``burst / rate`` seconds.
    """

    def __init__(self, rate: float, burst: int, max_clients: int, clock: Callable[[], float] = time.monotonic) -> None:
        self.rate = rate
        self.burst = float(burst)
        self.max_clients = max_clients
        self.clock = clock
        self._buckets: OrderedDict[str, tuple[float, float]] = OrderedDict()  # client → (tokens, when)

    def take(self, client: str) -> float:
        """0 if ``client`` may go on (one token taken), else the seconds until it will have a token."""
        now = self.clock()
        tokens, then = self._buckets.pop(client, (self.burst, now))
        tokens = min(self.burst, tokens + max(0.0, now - then) * self.rate)
        wait = 0.0
        if tokens >= 1.0:
            tokens -= 1.0
        else:
            wait = (1.0 - tokens) / self.rate
        self._buckets[client] = (tokens, now)
        while len(self._buckets) > self.max_clients:
            self._buckets.popitem(last=False)
        return wait

    def __len__(self) -> int:
        return len(self._buckets)


def retry_after(wait_s: float) -> str:
    """A ``Retry-After`` value: whole seconds, at least 1."""
    return str(max(1, math.ceil(wait_s)))


def cap_problems(fault: FaultSpec, listing: Iterable[dict[str, Any]], limits: ApiLimits) -> list[tuple[str, str]]:
    """Why ``fault`` would take the run past a cap, as (field, message) pairs; ``listing`` is the plant's fault list.

    Counted: active and pending faults of the fault's turbine and of the whole plant (scheduled ones too), and
    every fault the API has injected in this run (the plant lists them all, so the count survives an API restart).
    """
    listed = list(listing)
    live = [f for f in listed if f.get("state") in LIVE_STATES]
    on_turbine = sum(1 for f in live if f.get("fault", {}).get("turbine", 1) == fault.turbine)
    injected = sum(1 for f in listed if f.get("source") == "api")
    problems = []
    if on_turbine >= limits.api_max_faults_per_turbine:
        problems.append(
            (
                "turbine",
                f"turbine {fault.turbine} has {on_turbine} active or pending faults, the most allowed "
                f"(WINDWARDEN_API_MAX_FAULTS_PER_TURBINE={limits.api_max_faults_per_turbine}); clear one first",
            )
        )
    if len(live) >= limits.api_max_faults:
        problems.append(
            (
                "turbine",
                f"the plant has {len(live)} active or pending faults, the most allowed "
                f"(WINDWARDEN_API_MAX_FAULTS={limits.api_max_faults}); clear one first",
            )
        )
    if injected >= limits.api_max_injections:
        problems.append(
            (
                "name",
                f"{injected} faults have been injected in this run, the most allowed "
                f"(WINDWARDEN_API_MAX_INJECTIONS={limits.api_max_injections}); start a new run",
            )
        )
    return problems
