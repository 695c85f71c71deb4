"""The run folder ``runs/<run-id>/`` and its append-only event log.

Layout::

    scenario.toml     the scenario as run (after --duration)
    run.json          run id, kind, mode, speed, seed, endpoints, start time
    events.jsonl      one JSON event per line, appended by every process (O_APPEND, one write per line)
    faults.json       the faults as they happened (scheduled, injected over REST, cleared early)
    live.json         the plant's figures: ticks run, overruns, loop latency, refused and dropped messages, the
                      continuous metrics; a checkpoint without metrics ("final": false) while the run goes
    scorecard.json    computed from events.jsonl at the end of the run (same scoring code as batch)
    recording.rrd     the Rerun recording of plant and supervisor
    logs/             stdout/stderr of each child process (``windwarden up``)

Several processes append to ``events.jsonl`` at once: each line is written with a single ``os.write`` on a file
opened with ``O_APPEND`` and is kept under ``MAX_LINE`` bytes (4 KiB), so lines never interleave. Lines are
written as the events happen, so a crash of any process loses nothing already written.
"""

from __future__ import annotations

import json
import os
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import replace
from pathlib import Path
from typing import Any

from wwcore.events import Event

MAX_LINE = 4000  # bytes; below the 4 KiB that appends are atomic for on local file systems
EVENTS = "events.jsonl"
SCORECARD = "scorecard.json"
RECORDING = "recording.rrd"
FAULTS = "faults.json"
LIVE = "live.json"
RUN = "run.json"
SCENARIO = "scenario.toml"


class EventLog:
    """Appends events to ``events.jsonl`` and hands each to ``publish`` (the events key), wall time stamped.

    Thread-safe: the main loop and Zenoh callback threads (liveliness) write to the same log.
    """

    def __init__(
        self, path: Path | None, publish: Callable[[Event], None] | None = None, clock: Callable[[], float] = time.time
    ):
        self.path = path
        self.publish = publish
        self.clock = clock
        self._lock = threading.Lock()
        self._fd: int | None = None
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            self._fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        self.written = 0

    def write(self, events: Iterable[Event]) -> list[Event]:
        """Stamp, append and publish ``events`` in order; returns them as written."""
        out = []
        for event in events:
            if event.wall_time is None:
                event = replace(event, wall_time=self.clock())
            line = encode_line(event)
            with self._lock:
                if self._fd is not None:
                    os.write(self._fd, line)
                self.written += 1
            if self.publish is not None:
                self.publish(event)
            out.append(event)
        return out

    def close(self) -> None:
        with self._lock:
            if self._fd is not None:
                os.close(self._fd)
                self._fd = None


def encode_line(event: Event) -> bytes:
    """One event as a JSON line of at most ``MAX_LINE`` bytes (an oversized ``detail`` is cut, and says so)."""
    data = event.to_json()
    line = (json.dumps(data, separators=(",", ":"), default=_jsonable) + "\n").encode()
    if len(line) > MAX_LINE:
        data["detail"] = {"truncated": True}
        data["target"] = str(data.get("target", ""))[:200] or None
        line = (json.dumps(data, separators=(",", ":"), default=_jsonable) + "\n").encode()
    return line


def _jsonable(value: Any) -> Any:
    """numpy scalars and arrays in event details."""
    if hasattr(value, "tolist"):
        return value.tolist()
    return str(value)


def read_events(path: Path) -> list[Event]:
    """Every complete event line of ``path`` in file order (a torn last line from a crash is skipped)."""
    if not path.exists():
        return []
    out = []
    for line in path.read_text().splitlines():
        if not line.strip():
            continue
        try:
            out.append(Event.from_json(json.loads(line)))
        except (json.JSONDecodeError, KeyError, ValueError):
            continue
    return out


def write_run_start(run_dir: Path, scenario_toml: str, run: dict[str, Any], faults: list[dict[str, Any]]) -> None:
    """The files a plant writes before tick 0: the scenario as run, ``run.json`` and the fault listing."""
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / SCENARIO).write_text(scenario_toml)
    write_json(run_dir / RUN, run)
    write_json(run_dir / FAULTS, faults)


def write_json(path: Path, data: Any) -> None:
    """Write ``data`` as JSON atomically (temporary file, then rename)."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=2, default=_jsonable) + "\n")
    tmp.replace(path)
