"""Monte Carlo runs split into fixed-size chunks, simulated on all cores, with one progress bar.

Chunks depend only on the number of runs (never on the number of cores), and every run draws its random
numbers from its own stream, so the same scenario, runs and seed give the same numbers on any machine.

``Branch`` forks a running chunk so that a copy continues from its state (the turbine evaluation's fault-free
twins, which start at each fault window).
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import pickle
import queue as queue_module
import signal
import traceback
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from multiprocessing.connection import Pipe
from typing import Any, Generic, TypeVar

from tqdm import tqdm

R = TypeVar("R")
ProgressHook = Callable[[float], None]
"""Called by a worker with the simulated seconds it advanced (per run batch) since the last call."""

DEFAULT_CHUNK = 25


def chunk_runs(runs: int, chunk: int = DEFAULT_CHUNK) -> list[list[int]]:
    """Run indices split into chunks of at most ``chunk`` runs, spread evenly.

    The split depends on the number of runs only, and every row draws from its own streams, so the numbers do not
    depend on it (``tests/test_parallel.py``).
    """
    n_chunks = max(1, -(-runs // chunk))
    return [list(range(runs))[i::n_chunks] for i in range(n_chunks)]


def _call(worker: Callable[..., R], run_ids: list[int], queue: Any, args: tuple) -> R:
    def hook(seconds: float) -> None:
        queue.put(seconds * len(run_ids))

    return worker(run_ids, hook, *args)


def run_chunks(
    worker: Callable[..., R],
    runs: int,
    total_seconds: float,
    args: tuple = (),
    chunk: int = DEFAULT_CHUNK,
    workers: int | None = None,
    label: str = "simulating",
    show_progress: bool = True,
    variants: Sequence[tuple] | None = None,
    variant_seconds: Sequence[float] | None = None,
) -> list[R]:
    """Call ``worker(run_ids, progress_hook, *args)`` for every chunk; results in chunk order.

    ``total_seconds`` is the simulated time of one run; the bar counts run-seconds over all runs. With
    ``variants`` (argument tuples) every chunk runs once per variant: results variant by variant, chunks in order.
    ``variant_seconds`` is each variant's simulated time per run where it is not ``total_seconds``.
    """
    chunks = chunk_runs(runs, chunk)
    tasks = [(run_ids, a) for a in (variants or [args]) for run_ids in chunks]
    workers = min(len(tasks), workers or os.cpu_count() or 1)
    total = runs * (sum(variant_seconds) if variant_seconds else total_seconds * len(variants or [args]))
    bar = tqdm(total=total, unit="run-s", desc=label, disable=not show_progress, smoothing=0.1)
    try:
        if workers == 1:
            results = []
            for run_ids, a in tasks:
                size = len(run_ids)
                results.append(worker(run_ids, lambda seconds, size=size: bar.update(seconds * size), *a))
            return results
        ctx = mp.get_context("fork")
        with ctx.Manager() as manager, ProcessPoolExecutor(workers, mp_context=ctx) as pool:
            queue = manager.Queue()
            futures = [pool.submit(_call, worker, run_ids, queue, a) for run_ids, a in tasks]
            while not all(f.done() for f in futures):
                with contextlib.suppress(queue_module.Empty):
                    bar.update(queue.get(timeout=0.2))
            while not queue.empty():
                bar.update(queue.get())
            return [f.result() for f in futures]
    finally:
        bar.close()


def concat_runs(parts: Sequence[Sequence[int]]) -> list[int]:
    return [run for part in parts for run in part]


class Branch(Generic[R]):
    """``body()`` run in a forked copy of this process, which starts from this moment's state; ``result()``
    returns its value (it must pickle) or raises its failure with the child's traceback.

    Plain ``os.fork`` rather than ``multiprocessing.Process``: chunks already run in a process pool, whose daemonic
    workers may not start ``multiprocessing`` children, and a fork needs no copy or pickle of the state it
    continues from. The child leaves with ``os._exit``, so it runs none of the parent's exit handlers.
    """

    def __init__(self, body: Callable[[], R]):
        receiver, sender = Pipe(duplex=False)
        self.pid = os.fork()
        if self.pid == 0:
            receiver.close()
            code = 0
            try:
                outcome: tuple[str, Any] = ("ok", body())
            except BaseException:  # every failure goes back to the parent, which raises it
                outcome, code = ("error", traceback.format_exc()), 1
            try:
                sender.send_bytes(pickle.dumps(outcome, protocol=pickle.HIGHEST_PROTOCOL))
            finally:
                os._exit(code)
        sender.close()
        self._receiver = receiver

    def result(self) -> R:
        try:
            status, value = pickle.loads(self._receiver.recv_bytes())
        except EOFError:
            status, value = "error", f"the branch process {self.pid} ended without a result"
        finally:
            self._receiver.close()
            os.waitpid(self.pid, 0)
        if status != "ok":
            raise RuntimeError(f"branch process failed:\n{value}")
        return value

    def abandon(self) -> None:
        """Stop the child and reap it (after a failure in the parent)."""
        with contextlib.suppress(ProcessLookupError):
            os.kill(self.pid, signal.SIGKILL)
        self._receiver.close()
        os.waitpid(self.pid, 0)
