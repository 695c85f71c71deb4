"""Test-wide settings: Rerun must not collect usage data from tests (the Makefile also disables it), and the
`system` marker that decides which phase of `make test` runs a test.

A system test starts a whole system: a Zenoh session or router (nodes, the API's connection), a real HTTP server
(uvicorn), or a child process (``windwarden up``/``router``, the recorder, Docker, a browser). Their timeouts and
latency checks assume one system on an otherwise idle machine, so `make test` runs them one at a time after the
rest has run in parallel. Every test in ``tests/live`` and ``tests/security`` is a system test unless it (its
module, class or function) is marked ``in_process``; a test elsewhere must be marked ``system`` to start one. The
guard below holds both ways: a test not marked ``system`` that opens a Zenoh session, starts uvicorn or a child
process fails, naming what it started, so a marker cannot be forgotten silently. The children allowed are
one-shot readers that start nothing: a fresh interpreter running a snippet (``sys.executable -c``, the import
checks), ``rerun rrd`` reading a recording file and ``uname -p`` (``platform.processor()``).
"""

from __future__ import annotations

import functools
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import uvicorn
import zenoh

TESTS = Path(__file__).parent
SYSTEM_DIRS = (TESTS / "live", TESTS / "security")  # the Makefile's SYSTEM_TESTS


def pytest_sessionstart(session: pytest.Session) -> None:
    rerun = shutil.which("rerun", path=os.path.dirname(os.path.realpath(sys.executable)))
    if rerun:
        subprocess.run([rerun, "analytics", "disable"], capture_output=True, check=False, timeout=30)


@pytest.hookimpl(tryfirst=True)  # before `-m` selects on the markers
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        path = Path(item.path)
        in_system_dir = any(path.is_relative_to(d) for d in SYSTEM_DIRS)
        in_process = item.get_closest_marker("in_process") is not None
        if in_process and item.get_closest_marker("system") is not None:
            raise pytest.UsageError(f"{item.nodeid} is marked both system and in_process")
        if in_process and not in_system_dir:
            raise pytest.UsageError(f"{item.nodeid}: in_process only means something in tests/live and tests/security")
        if in_system_dir and not in_process:
            item.add_marker(pytest.mark.system)
        elif not in_system_dir and item.get_closest_marker("system") is not None:
            # `make test` runs system tests from tests/live and tests/security only: one elsewhere would never run
            raise pytest.UsageError(f"{item.nodeid} is marked system outside tests/live and tests/security")


class SystemGuard:
    """What a test not marked ``system`` started, recorded and refused while it sets up, runs and tears down."""

    def __init__(self) -> None:
        self.item: pytest.Item | None = None  # the running test when it is not a system test
        self.started: list[str] = []

    def refuse(self, what: str) -> None:
        if self.item is not None:
            self.started.append(what)
            raise RuntimeError(
                f"{self.item.nodeid} is not marked system but started {what}: mark it system (tests/live, "
                "tests/security) or take the system out"
            )

    def audit(self, event: str, args: tuple) -> None:
        if event != "subprocess.Popen" or self.item is None:
            return
        argv = [os.fsdecode(a) for a in (args[1] if isinstance(args[1], list | tuple) else [args[1]])]
        fresh_interpreter = argv[:1] == [sys.executable] and argv[1:2] == ["-c"]
        reads_a_recording = bool(argv) and Path(argv[0]).name == "rerun" and argv[1:2] == ["rrd"]
        # platform.processor() asks `uname -p` once per process (a Dask worker does, as it starts)
        asks_the_processor = argv == ["uname", "-p"]
        if not (fresh_interpreter or reads_a_recording or asks_the_processor):
            self.refuse(f"a child process {argv[:3]}")


GUARD = SystemGuard()


def _guarded(function, what):
    @functools.wraps(function)
    def guarded(*args, **kwargs):
        GUARD.refuse(what)
        return function(*args, **kwargs)

    return guarded


def pytest_configure(config: pytest.Config) -> None:
    zenoh.open = _guarded(zenoh.open, "a Zenoh session (zenoh.open)")
    uvicorn.Server.startup = _guarded(uvicorn.Server.startup, "an HTTP server (uvicorn)")
    sys.addaudithook(GUARD.audit)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None):
    GUARD.item = None if item.get_closest_marker("system") else item
    GUARD.started = []
    try:
        return (yield)
    finally:
        GUARD.item = None


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    report = yield
    started, GUARD.started = GUARD.started, []  # each refusal reported once, by the phase it happened in
    if GUARD.item is item and started and report.passed:
        # refused in a thread or caught by the test: fail it all the same
        report.outcome = "failed"
        report.longrepr = f"{item.nodeid} is not marked system but started: {'; '.join(started)}"
    return report


@pytest.fixture
def system_guard() -> SystemGuard:
    """The guard itself, for the test that checks it refuses."""
    return GUARD
