"""What every live process does the same way: logging to stderr, stopping on SIGINT/SIGTERM or when ``windwarden up``
goes away, its Zenoh session (an unreachable router is a clean error), its niceness."""

from __future__ import annotations

import contextlib
import ctypes
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

log = logging.getLogger("windwarden.live")


def setup_logging(name: str) -> None:
    level = os.environ.get("WINDWARDEN_LOG_LEVEL", "INFO").upper()
    logging.basicConfig(
        level=level, stream=sys.stderr, format=f"%(asctime)s {name} %(levelname)s %(name)s: %(message)s"
    )


def on_signals(stop: Callable[[], None]) -> None:
    """SIGINT and SIGTERM ask ``stop`` (called on a fresh thread: a handler must not take locks)."""

    def handler(signum: int, frame: Any) -> None:
        threading.Thread(target=stop, name="stop", daemon=True).start()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)


@contextlib.contextmanager
def zenoh_session(settings: Any) -> Iterator[Any]:
    """The process's Zenoh session; an unreachable router is a clean error (exit 1), not a traceback."""
    import zenoh  # loaded on first use, so that the command line starts without Zenoh

    from windwarden.live.transport import open_session

    try:
        session = open_session(settings)
    except zenoh.ZError as error:
        raise ServiceError(
            f"cannot join Zenoh at {settings.connect or settings.listen or '(scouting)'}: {error}"
        ) from None
    with session:
        yield session


class ServiceError(Exception):
    """A service could not start (exit code 1)."""


def apply_nice(settings: Any) -> None:
    """Run at the configured niceness; say so, and carry on, when the system does not allow it."""
    if settings.nice is None:
        return
    try:
        os.setpriority(os.PRIO_PROCESS, 0, settings.nice)
        log.info("running at niceness %d", settings.nice)
    except OSError as error:
        log.warning(
            "cannot set niceness %d (%s): running at %d", settings.nice, error, os.getpriority(os.PRIO_PROCESS, 0)
        )


def exit_with_parent(stop: Callable[[], None]) -> None:
    """When started by ``windwarden up`` (``WINDWARDEN_PARENT_PID``), call ``stop`` if that process goes away: on
    Linux the kernel sends SIGTERM the moment it dies (``PR_SET_PDEATHSIG``, handled by ``on_signals``); a thread
    that polls the parent pid every 0.5 s covers other systems."""
    parent = os.environ.get("WINDWARDEN_PARENT_PID")
    if not parent or not parent.isdigit():
        return
    _sigterm_when_parent_dies()
    if os.getppid() != int(parent):  # it died before we asked
        stop()
        return

    def watch() -> None:
        while os.getppid() == int(parent):
            time.sleep(0.5)
        log.warning("windwarden up (pid %s) is gone: stopping", parent)
        stop()

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def _sigterm_when_parent_dies() -> None:
    if not sys.platform.startswith("linux"):
        return

    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGTERM), 0, 0, 0)  # PR_SET_PDEATHSIG = 1
