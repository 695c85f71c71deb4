"""The one-line run status of ``windwarden up``: simulated time, real-time factor, active faults and flags.

Built from what ``up`` already receives as a viewer: the plant's status (``plant/status``, 2 Hz: simulated time,
duration, real-time factor, state) and the events (faults injected and cleared by the plant, targets flagged and
recovered by the supervisor). On a terminal the line stays below the event lines and updates in place (rich
``Live``, twice a second; it is gone when the run ends and the report prints). When the output is not a terminal (a
pipe, a log file, a test capturing it) the same line is printed as a plain line every ``PLAIN_EVERY_S`` of wall
time, so a log shows progress without flooding, and every other line ``up`` prints stays as it is.

Example::

    t 123.4/600 s (21 %)  ×1.00 real time  faults 1: T1 omega_r_m1  flags 1 (3 raised): T1 omega_r_m1
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from rich.console import Console
from rich.live import Live
from rich.text import Text

from wwcore.events import Event, EventType

PLAIN_EVERY_S = 10.0  # s of wall time between two plain status lines when the output is not a terminal
REFRESH_PER_S = 2.0  # in-place updates per second on a terminal (the plant's status comes at 2 Hz)
SHOWN_NAMES = 3  # active faults or flags named on the line; the rest are counted


@dataclass
class RunStatus:
    """What the status line shows, updated from the plant's status and the events."""

    t: float | None = None  # s, simulated time
    duration_s: float | None = None  # s, the scenario's duration
    real_time_factor: float | None = None  # simulated s per wall s
    state: str = "starting"  # the plant's state (waiting, running, ended)
    faults: dict[tuple[int, int, str, str], None] = field(default_factory=dict)  # (run, turbine, target, label)
    flags: dict[tuple[int, int, str], None] = field(default_factory=dict)  # (run, turbine, target), in order
    raised: int = 0  # detections since the start

    def on_status(self, body: Mapping[str, Any]) -> None:
        """Take a ``plant.status`` body; fields it lacks or carries as null keep their last value."""
        for key in ("t", "duration_s", "real_time_factor"):
            value = body.get(key)
            if isinstance(value, int | float) and not isinstance(value, bool):
                setattr(self, key, float(value))
        if isinstance(body.get("state"), str):
            self.state = body["state"]

    def on_event(self, event: Event) -> None:
        target = event.target or ""
        if event.type == EventType.FAULT_INJECTED:
            self.faults[(event.run, event.turbine, target, str(event.detail.get("label", "")))] = None
        elif event.type == EventType.FAULT_CLEARED:
            self.faults.pop((event.run, event.turbine, target, str(event.detail.get("label", ""))), None)
        elif event.type == EventType.DETECTION:
            self.flags[(event.run, event.turbine, target)] = None
            self.raised += 1
        elif event.type == EventType.RECOVERY:
            self.flags.pop((event.run, event.turbine, target), None)
        if self.t is None or event.t > self.t:
            self.t = event.t


def _names(keys: list[tuple[Any, ...]]) -> str:
    """``T<k> target`` of the first ``SHOWN_NAMES`` keys ((run, turbine, target, ...)), ``+n`` for the rest."""
    shown = [f"T{turbine} {target}".strip() for _, turbine, target, *_ in keys[:SHOWN_NAMES]]
    more = len(keys) - SHOWN_NAMES
    return ", ".join(shown) + (f" +{more}" if more > 0 else "")


def format_status(status: RunStatus, width: int | None = 100) -> str:
    """The status as one line of at most ``width`` characters (cut with an ellipsis; None: never cut)."""
    if status.t is None:
        clock = "t –"
    elif status.duration_s:
        clock = f"t {status.t:.1f}/{status.duration_s:g} s ({100.0 * status.t / status.duration_s:.0f} %)"
    else:
        clock = f"t {status.t:.1f} s"
    parts = [clock]
    if status.state not in ("running", "starting"):
        parts.append(status.state)
    if status.real_time_factor is not None:
        parts.append(f"×{status.real_time_factor:.2f} real time")
    faults = list(status.faults)
    parts.append(f"faults {len(faults)}" + (f": {_names(faults)}" if faults else ""))
    flags = list(status.flags)
    parts.append(f"flags {len(flags)} ({status.raised} raised)" + (f": {_names(flags)}" if flags else ""))
    line = "  ".join(parts)
    return line if width is None or len(line) <= width else line[: max(width - 1, 0)] + "…"


class StatusDisplay:
    """The status line on ``console``: in place on a terminal, else a plain line every ``every_s`` (``tick``).

    ``on_status`` and ``on_event`` may be called from any thread (Zenoh's callbacks); ``tick`` from the loop that
    watches the run."""

    def __init__(
        self,
        console: Console,
        every_s: float = PLAIN_EVERY_S,
        clock: Callable[[], float] = time.monotonic,
    ):
        self.console = console
        self.status = RunStatus()
        self.every_s = every_s
        self.clock = clock
        self._lock = threading.Lock()
        self._last_plain: float | None = None
        self._live: Live | None = None

    @property
    def in_place(self) -> bool:
        return self.console.is_terminal

    def line(self) -> str:
        """The line: as wide as the terminal at most; off a terminal (a log) never cut."""
        with self._lock:
            return format_status(self.status, max(self.console.width - 1, 20) if self.in_place else None)

    def on_status(self, body: Mapping[str, Any]) -> None:
        with self._lock:
            self.status.on_status(body)

    def on_event(self, event: Event) -> None:
        with self._lock:
            self.status.on_event(event)

    def start(self) -> None:
        """Show the line in place on a terminal; elsewhere the first plain line comes ``every_s`` from now."""
        self._last_plain = self.clock()
        if self.in_place and self._live is None:
            self._live = Live(
                get_renderable=lambda: Text(self.line(), no_wrap=True, overflow="ellipsis"),
                console=self.console,
                refresh_per_second=REFRESH_PER_S,
                transient=True,
            )
            self._live.start()

    def tick(self) -> None:
        """Off a terminal, print the line if ``every_s`` has passed since the last one."""
        if self.in_place or self._last_plain is None:
            return
        now = self.clock()
        if now - self._last_plain >= self.every_s:
            self._last_plain = now
            self.console.print(self.line(), markup=False, highlight=False)

    def stop(self) -> None:
        if self._live is not None:
            self._live.stop()
            self._live = None
        self._last_plain = None
