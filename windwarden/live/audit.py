"""Counting what the router refuses: denied messages and refused logins, read from Zenoh's own log.

Zenoh 1.x has no counter for access-control denials. It logs every access decision at TRACE level
(``<zid> on <subject> is unauthorized to Put (ingress) on <key>``, target
``zenoh::net::routing::interceptor::access_control``), then ``Msg intercepted!`` on the same thread when the message
is dropped (a key declared for the first time also gets a block of decisions for every message kind, which drop
nothing and are not followed by it), and every refused login at DEBUG (``UsrPwd extension - Recv OpenSyn.
Invalid password.``, target ``zenoh_transport::unicast::establishment::accept``), all to the process's standard
output. ``RouterAudit`` runs in the router's process: it points file descriptor 1 at a pipe before the router
starts, reads the log on a thread, counts a denial when ``Msg intercepted!`` follows an unauthorized decision on the
same thread, by (role, message, flow, key), and refused logins by reason; it logs the first of each kind (and every
1000th after) as a warning, passes Zenoh's own warnings and errors through to stderr, and writes the counts to a
JSON file once a second while they change, and at the end.

The price: with the audit on, the router formats a log line for every message it routes (two per delivered
sample: ingress and egress); ``tools/bench_live.py --compare-acl`` measures it with the rest of access control.
"""

from __future__ import annotations

import json
import logging
import os
import re
import sys
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

AUDIT_TARGETS = "zenoh::net::routing::interceptor=trace,zenoh_transport::unicast::establishment::accept=debug"
_ANSI = re.compile(r"\x1b\[[0-9;]*m")
_DECISION = re.compile(
    r"(?:Using cached result: )?(?P<zid>[0-9a-f]+)(?: on (?P<subject>\S+))? is (?P<verdict>unauthorized|authorized) "
    r"to (?P<message>[A-Za-z/ ]+?) \((?P<flow>ingress|egress)\) on (?P<key>\S+)"
)
_WHO = re.compile(r"(?:Username|CertCommonName)\(([^)]*)\)")
_LOGIN = {
    "Expected extension": "no credentials",
    "Invalid password": "wrong password",
    "Invalid user": "unknown user",
    "peer sent no certificates": "no client certificate",
}
_LEVEL = re.compile(r"^\S+\s+(TRACE|DEBUG|INFO|WARN|ERROR)\b")
LOG_EVERY = 1000


class RouterAudit:
    """Counts the router's refusals from its log; ``start()`` before the router session opens."""

    def __init__(self, out: Path | None):
        self.out = out
        self._lock = threading.Lock()
        self.denied: Counter[tuple[str, str, str, str]] = Counter()
        self.logins_refused: Counter[str] = Counter()
        self.decisions = 0  # every access decision logged, allowed or not (how much the audit reads)
        self._who: dict[str, str] = {}
        self._pending: dict[str, tuple[str, str, str, str] | None] = {}  # thread → its last unauthorized decision
        self._changed = threading.Event()
        self._stop = threading.Event()

    # -- the log pipe -------------------------------------------------------------------------------------------
    def start(self) -> None:
        """Point fd 1 (Zenoh's log) at a pipe read by this audit; Python's ``print`` keeps the real stdout."""
        import zenoh

        read_fd, write_fd = os.pipe()
        stdout = os.dup(1)
        os.dup2(write_fd, 1)
        os.close(write_fd)
        sys.stdout = os.fdopen(stdout, "w", buffering=1)
        # The audit's own targets after whatever the operator asked for (a later directive wins for its target).
        os.environ["RUST_LOG"] = ",".join(filter(None, [os.environ.get("RUST_LOG") or "warn", AUDIT_TARGETS]))
        zenoh.init_log_from_env_or("warn")
        threading.Thread(target=self._read, args=(read_fd,), name="router-audit", daemon=True).start()
        threading.Thread(target=self._flush_loop, name="router-audit-writer", daemon=True).start()

    def _read(self, fd: int) -> None:
        with os.fdopen(fd, "r", errors="replace") as lines:
            for line in lines:
                self.feed(line)

    def feed(self, line: str) -> None:
        """One line of Zenoh's log."""
        at = line.find("ThreadId(")
        thread = line[at : line.find(")", at) + 1] if at >= 0 else ""
        if "authorized to" in line:
            if "unauthorized" in line or "Using cached" not in line:  # a denial, or a first decision naming the peer
                self._pending[thread] = self._decision(_ANSI.sub("", line))
            else:  # an allowed message: counted, not parsed (the hot path)
                self.decisions += 1
                self._pending[thread] = None
            return
        if "Msg intercepted!" in line:
            denied = self._pending.pop(thread, None)
            if denied is not None:
                self._count(denied)
            return
        self._pending[thread] = None
        plain = _ANSI.sub("", line)
        for text, reason in _LOGIN.items():
            if text in plain:
                with self._lock:
                    self.logins_refused[reason] += 1
                    n = self.logins_refused[reason]
                self._changed.set()
                if n == 1 or n % LOG_EVERY == 0:
                    log.warning("router refused a login: %s (%d so far)", reason, n)
                return
        level = _LEVEL.match(plain)
        if level and level.group(1) in ("WARN", "ERROR"):
            sys.stderr.write(plain)

    def _decision(self, line: str) -> tuple[str, str, str, str] | None:
        """(role, message, flow, key) of an unauthorized decision; None for an allowed one (or no match)."""
        match = _DECISION.search(line)
        if match is None:
            return None
        zid = match["zid"]
        if match["subject"]:
            who = _WHO.search(match["subject"])
            self._who.setdefault(zid, who.group(1) if who else "anonymous")
        self.decisions += 1
        if match["verdict"] == "authorized":
            return None
        return self._who.get(zid, zid), match["message"].lower(), match["flow"], match["key"]

    def _count(self, denied: tuple[str, str, str, str]) -> None:
        with self._lock:
            self.denied[denied] += 1
            n = self.denied[denied]
        self._changed.set()
        if n == 1 or n % LOG_EVERY == 0:
            log.warning("router denied %s: %s %s on %s (%d so far)", *denied, n)

    # -- the counts -----------------------------------------------------------------------------------------------
    def counts(self) -> dict[str, Any]:
        with self._lock:
            denied = [
                {"role": who, "message": message, "flow": flow, "key": key, "count": n}
                for (who, message, flow, key), n in sorted(self.denied.items())
            ]
            return {
                "denied_total": sum(self.denied.values()),
                "denied": denied,
                "logins_refused_total": sum(self.logins_refused.values()),
                "logins_refused": dict(sorted(self.logins_refused.items())),
                "decisions": self.decisions,
                "updated": time.time(),
            }

    def write(self) -> None:
        if self.out is None:
            return
        tmp = self.out.with_name(self.out.name + ".tmp")
        tmp.write_text(json.dumps(self.counts(), indent=2) + "\n")
        tmp.replace(self.out)

    def _flush_loop(self) -> None:
        written = -1
        while not self._stop.is_set():
            if self._changed.is_set() or self.decisions != written:
                self._changed.clear()
                written = self.decisions
                self.write()
            self._stop.wait(1.0)

    def close(self) -> None:
        self._stop.set()
        sys.stdout.flush()
        time.sleep(0.1)  # the last lines still in the pipe
        self.write()
