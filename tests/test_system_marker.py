"""The guard of `make test`'s phases (``tests/conftest.py``): a test not marked ``system`` that starts a Zenoh
session, an HTTP server or a child process is refused and fails; one-shot readers are allowed."""

from __future__ import annotations

import asyncio
import subprocess
import sys

import pytest
import uvicorn
import zenoh

from windwarden.live.finalize import rerun_binary


def test_a_test_not_marked_system_cannot_start_a_system(request, system_guard, tmp_path):
    assert request.node.get_closest_marker("system") is None and system_guard.item is request.node
    with pytest.raises(RuntimeError, match="not marked system but started a Zenoh session"):
        zenoh.open(zenoh.Config())
    with pytest.raises(RuntimeError, match="not marked system but started an HTTP server"):
        asyncio.run(uvicorn.Server(uvicorn.Config(lambda scope, receive, send: None)).startup())
    with pytest.raises(RuntimeError, match="not marked system but started a child process"):
        subprocess.run([sys.executable, "-m", "windwarden", "--help"], capture_output=True, check=False)
    with pytest.raises(RuntimeError, match="not marked system but started a child process"):
        subprocess.run([rerun_binary(), "--help"], capture_output=True, check=False)
    # one-shot readers that start nothing
    assert subprocess.run([sys.executable, "-c", "pass"], check=False).returncode == 0
    subprocess.run([rerun_binary(), "rrd", "verify", str(tmp_path / "none.rrd")], capture_output=True, check=False)
    assert len(system_guard.started) == 4, system_guard.started
    system_guard.started.clear()  # refused on purpose: the test passes (otherwise the guard fails it anyway)
