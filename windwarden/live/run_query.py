"""The run description a supervisor-side process (supervisor, shard, coordinator) asks the plant for."""

from __future__ import annotations

import logging
import threading
import time

import zenoh

from windwarden.kinds import RunInfo
from windwarden.live.transport import LivenessWatch, QueryFailedError, query_json
from wwcore.keys import KeyTree, Process

log = logging.getLogger(__name__)


def query_run(session: zenoh.Session, keys: KeyTree, timeout: float) -> RunInfo | None:
    """The plant's ``plant.run`` answer, or None (no plant answering, or an answer that is not a run)."""
    try:
        return RunInfo.from_json(query_json(session, keys.run, "plant.run", timeout=timeout))
    except (QueryFailedError, KeyError, TypeError, ValueError) as error:
        log.info("no run description from the plant: %s", error)
        return None


def wait_for_run(
    session: zenoh.Session, keys: KeyTree, watch: LivenessWatch, plant_wait_s: float, stop: threading.Event
) -> RunInfo | None:
    """The run description once a plant is alive and answers; None when ``stop`` is set or no plant answered within
    ``plant_wait_s`` (0: wait for ever)."""
    deadline = None if plant_wait_s == 0 else time.monotonic() + plant_wait_s
    while not stop.is_set():
        if watch.is_alive(Process.PLANT):
            info = query_run(session, keys, 2.0)
            if info is not None:
                return info
        if deadline is not None and time.monotonic() > deadline:
            return None
        watch.wait_for(Process.PLANT, True, timeout=0.5)
        stop.wait(0.1)
    return None


def confirm_run(session: zenoh.Session, keys: KeyTree, run_key: int) -> RunInfo | None:
    """The plant's run description if the plant says ``run_key`` is its run identity, else None."""
    info = query_run(session, keys, 1.0)
    return info if info is not None and info.run_key == run_key else None


def plant_has_measured(session: zenoh.Session, keys: KeyTree, run_key: int, tick: int) -> bool:
    """The plant's status says it has measured tick ``tick`` of run ``run_key``."""
    try:
        status = query_json(session, keys.plant_status, "plant.status", timeout=1.0)
    except QueryFailedError:
        return False
    return status.get("run_key") == run_key and isinstance(status.get("tick"), int) and tick <= status["tick"]
