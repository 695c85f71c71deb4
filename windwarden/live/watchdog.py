"""The watchdog of ``windwarden up``: when ``up`` dies without stopping its children, it stops them and closes the run.

``up`` starts it first, in a session of its own, with the read end of a pipe as its standard input; only ``up`` holds
the write end. ``up`` writes one JSON line per child it starts (``{"name", "pid", "start"}``: the pid and its start
time, so a pid the system has reused is never signalled) and ``{"done": true}`` once it has stopped them all and
finalised the run. End of file without ``done`` means ``up`` is gone (SIGKILL, a crash): the watchdog then does what
``up`` would have done, in the same order — SIGTERM to the process group of the plant, the supervisor and the API
(they also get SIGTERM from the kernel when ``up`` dies: ``cli.exit_with_parent``), SIGKILL to what is left after
``STOP_TIMEOUT_S``; then the Rerun viewer and recorder, which have no such hook; then the scorecard from
``events.jsonl`` (``finalize.finalize_scorecard``: partial if the plant left no final ``live.json``) and the
recording compacted so that ``rerun rrd verify`` passes — and exits. Its log is ``logs/watchdog.log``.

Run as ``python -m windwarden.live.watchdog RUN_DIR``.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO

log = logging.getLogger("windwarden.watchdog")
STOP_TIMEOUT_S = 15.0
RERUN_CHILDREN = ("viewer", "recorder")  # stopped last, after the processes that log to them


def process_start(pid: int) -> int | None:
    """The start time of process ``pid`` in clock ticks since boot (``/proc/<pid>/stat`` field 22), None if gone."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = stat[stat.rindex(")") + 2 :].split()  # after "pid (comm) "
    return None if fields[0] == "Z" else int(fields[19])  # a zombie is gone: only its exit status is left


@dataclass
class Tracked:
    name: str
    pid: int
    start: int | None

    def alive(self) -> bool:
        return self.start is not None and process_start(self.pid) == self.start

    def signal_group(self, sig: int) -> None:
        if self.alive():
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(self.pid, sig)  # each child leads its own session: its group is its pid


class WatchdogLink:
    """``up``'s end: starts the watchdog and tells it about each child."""

    def __init__(self, run_dir: Path, log: Path):
        read, self._write = os.pipe()  # both ends close on exec: no other child inherits the write end
        with log.open("ab") as out:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "windwarden.live.watchdog", str(run_dir)],
                stdin=read,
                stdout=out,
                stderr=subprocess.STDOUT,
                start_new_session=True,  # Ctrl-C in the terminal and a kill of up's group do not reach it
            )
        os.close(read)
        self._out: IO[str] | None = os.fdopen(self._write, "w", buffering=1)

    def child(self, name: str, pid: int) -> None:
        self._send({"name": name, "pid": pid, "start": process_start(pid)})

    def done(self) -> None:
        """Everything is stopped and finalised: the watchdog exits without doing anything."""
        self._send({"done": True})
        self.close()

    def close(self) -> None:
        if self._out is not None:
            with contextlib.suppress(OSError):
                self._out.close()
            self._out = None

    def _send(self, message: dict) -> None:
        if self._out is not None:
            with contextlib.suppress(OSError):
                self._out.write(json.dumps(message) + "\n")


def stop_in_order(tracked: list[Tracked], timeout: float = STOP_TIMEOUT_S) -> None:
    """SIGTERM the services' groups, then the Rerun processes' (SIGKILL whatever outlives ``timeout``)."""
    services = [t for t in tracked if t.name not in RERUN_CHILDREN]
    rerun = [t for t in tracked if t.name in RERUN_CHILDREN]
    for group in (services, rerun):
        for t in group:
            t.signal_group(signal.SIGTERM)
        deadline = time.monotonic() + timeout
        while any(t.alive() for t in group) and time.monotonic() < deadline:
            time.sleep(0.05)
        for t in group:
            t.signal_group(signal.SIGKILL)


def clean_up(run_dir: Path, tracked: list[Tracked]) -> None:
    from windwarden.live.finalize import finalize_recording, finalize_scorecard
    from windwarden.live.runfolder import write_json

    log.warning("windwarden up is gone: stopping %s", ", ".join(f"{t.name} ({t.pid})" for t in tracked))
    stop_in_order(tracked)
    card = finalize_scorecard(run_dir)
    verified = finalize_recording(run_dir)
    summary_path = run_dir / "up.json"
    try:
        summary = json.loads(summary_path.read_text())
    except (OSError, ValueError):
        summary = {}
    live = (card or {}).get("live", {})
    summary |= {
        "ended": time.time(),
        "completed": bool(live.get("completed")),
        "partial": bool(live.get("partial", card is None)),
        "finalized_by": "watchdog",
        "recording_verified": verified,
    }
    write_json(summary_path, summary)
    log.warning("scorecard %s, recording verified: %s", "written" if card else "not written (no run)", verified)


def main(argv: list[str]) -> int:
    run_dir = Path(argv[0])
    tracked: dict[str, Tracked] = {}
    for line in sys.stdin:
        try:
            message = json.loads(line)
        except ValueError:
            continue
        if message.get("done"):
            return 0
        tracked[message["name"]] = Tracked(message["name"], int(message["pid"]), message.get("start"))
    clean_up(run_dir, list(tracked.values()))
    return 0


if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # only the end of its pipe stops it
    logging.basicConfig(level=logging.INFO, format="%(asctime)s watchdog %(levelname)s: %(message)s")
    sys.exit(main(sys.argv[1:]))
