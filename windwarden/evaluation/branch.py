"""``Branch``: a copy of a running chunk that continues from this moment's state (the turbine evaluation's
fault-free twins, which start at each fault window), as a forked process or, where forking is unsafe, in this
process (``branch_mode``)."""

from __future__ import annotations

import contextlib
import copy
import os
import pickle
import signal
import traceback
from collections.abc import Callable, Iterator
from contextvars import ContextVar
from multiprocessing.connection import Pipe
from typing import Any, Generic, Literal, TypeVar

R = TypeVar("R")

BranchMode = Literal["fork", "copy"]
_BRANCH_MODE: ContextVar[BranchMode] = ContextVar("branch_mode", default="fork" if hasattr(os, "fork") else "copy")


@contextlib.contextmanager
def branch_mode(mode: BranchMode) -> Iterator[None]:
    """Within the block, ``Branch`` forks (``"fork"``) or runs its copy in this process (``"copy"``)."""
    token = _BRANCH_MODE.set(mode)
    try:
        yield
    finally:
        _BRANCH_MODE.reset(token)


class Branch(Generic[R]):
    """``body()`` run on a copy of this process's state as of this moment; ``result()`` returns its value (it
    must pickle) or raises its failure with the copy's traceback.

    ``"fork"`` (the default where ``os.fork`` exists): plain ``os.fork`` rather than ``multiprocessing.Process``,
    since chunks already run in a process pool, whose daemonic workers may not start ``multiprocessing``
    children, and a fork needs no copy or pickle of the state it continues from; the copy runs beside the parent
    and leaves with ``os._exit``, so it runs none of the parent's exit handlers. ``"copy"`` (``branch_mode``;
    where forking is unsafe, as in a Dask worker that runs several tasks in threads): ``body`` is deep-copied
    (with the objects it continues from) and run to its end at once, in this process. Both start from the same
    state and give the same numbers (``tests/test_parallel.py``).
    """

    def __init__(self, body: Callable[[], R]):
        self._receiver = None
        self.pid = 0
        if _BRANCH_MODE.get() == "copy":
            self._outcome = _outcome_of(copy.deepcopy(body), Exception)  # an interrupt goes on up
            return
        receiver, sender = Pipe(duplex=False)
        self.pid = os.fork()
        if self.pid == 0:
            receiver.close()
            outcome = _outcome_of(body, BaseException)  # every failure goes back to the parent
            try:
                sender.send_bytes(pickle.dumps(outcome, protocol=pickle.HIGHEST_PROTOCOL))
            finally:
                os._exit(0 if outcome[0] == "ok" else 1)
        sender.close()
        self._receiver = receiver

    def result(self) -> R:
        if self._receiver is None:
            status, value = self._outcome
        else:
            try:
                status, value = pickle.loads(self._receiver.recv_bytes())
            except EOFError:
                status, value = "error", f"the branch process {self.pid} ended without a result"
            finally:
                self._receiver.close()
                os.waitpid(self.pid, 0)
        if status != "ok":
            raise RuntimeError(f"branch failed:\n{value}")
        return value

    def abandon(self) -> None:
        """Stop the forked copy and reap it (after a failure in the parent)."""
        if self._receiver is None:
            return
        with contextlib.suppress(ProcessLookupError):
            os.kill(self.pid, signal.SIGKILL)
        self._receiver.close()
        os.waitpid(self.pid, 0)


def _outcome_of(body: Callable[[], R], caught: type[BaseException]) -> tuple[str, Any]:
    """("ok", value) or ("error", traceback) for the failures of kind ``caught``; ``result()`` raises them."""
    try:
        return "ok", body()
    except caught:
        return "error", traceback.format_exc()
