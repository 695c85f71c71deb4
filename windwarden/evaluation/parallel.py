"""Monte Carlo runs split into chunks, simulated on local processes or on a Dask cluster, with one progress bar.

Chunks depend only on the number of runs and the plant kind's largest chunk (``chunk_runs``), never on the
machine, ``--workers`` or the cluster. Every run draws its random numbers from its own streams, but its last bits
depend on where it sits in its batch: the step code's matrix products go through BLAS, whose kernels handle rows in
pairs and the odd last row of a batch on its own (``docs/decisions.md``, "Evaluation chunks"). A chunk plan that
followed the cores would therefore give other numbers on another machine; this one gives the same scenario, runs
and seed the same numbers with any number of workers, locally or on a cluster, as the evaluators gather the
chunks' results in chunk order (``tests/test_parallel.py``, ``tests/test_cluster.py``).

Local chunks run in forked processes, at most one per available core (``usage.available_cores``) unless
``--workers`` says otherwise; with ``--scheduler`` they go to a Dask cluster (``windwarden.evaluation.cluster``).
``Branch`` (``windwarden.evaluation.branch``) is exported here too, for the evaluators.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import queue as queue_module
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any, TypeVar

from tqdm import tqdm

from windwarden.evaluation.branch import Branch
from windwarden.evaluation.cluster import run_on_cluster
from windwarden.evaluation.kinds import EvalOptions
from windwarden.evaluation.tasks import Task
from windwarden.evaluation.usage import available_cores

__all__ = ["Branch", "ProgressHook", "Task", "chunk_runs", "concat_runs", "run_chunks"]

R = TypeVar("R")
ProgressHook = Callable[[float], None]
"""Called by a worker with the simulated seconds it advanced (per run batch) since the last call."""

DEFAULT_CHUNK = 25
PARALLEL_CHUNKS = 2
"""Runs ≥ 2 are split into a multiple of this many chunks, so a two-core machine (the reference machine, CI)
has both cores busy; a larger machine runs the same chunks (module docstring)."""


def chunk_runs(runs: int, max_chunk: int = DEFAULT_CHUNK) -> list[list[int]]:
    """Run indices split into the fewest chunks of at most ``max_chunk`` runs whose number is a multiple of
    ``PARALLEL_CHUNKS`` (at most one chunk per run), spread evenly: run r goes to chunk r mod n_chunks.

    The plan depends on ``runs`` and ``max_chunk`` only, never on the machine (module docstring).
    """
    n_chunks = max(1, min(runs, PARALLEL_CHUNKS * -(-runs // (PARALLEL_CHUNKS * max_chunk))))
    return [list(range(i, runs, n_chunks)) for i in range(n_chunks)]


def run_chunks(
    worker: Callable[..., R],
    runs: int,
    total_seconds: float,
    options: EvalOptions,
    args: tuple = (),
    max_chunk: int = DEFAULT_CHUNK,
    label: str = "simulating",
) -> list[R]:
    """Call ``worker(run_ids, progress_hook, *args)`` for every chunk; results in chunk order.

    ``total_seconds`` is the simulated time of one run; the bar counts run-seconds over all runs.
    ``options.scheduler`` sends the chunks to that Dask scheduler; otherwise they run on at most
    ``options.workers`` local processes (default: one per available core).
    """
    tasks = [Task(ids, args, total_seconds * len(ids)) for ids in chunk_runs(runs, max_chunk)]
    bar = tqdm(
        total=sum(t.run_seconds for t in tasks), unit="run-s", desc=label, disable=not options.progress, smoothing=0.1
    )
    try:
        if options.scheduler is not None:
            return run_on_cluster(options.scheduler, worker, tasks, bar, options.plugins)
        return _run_local(worker, tasks, min(len(tasks), options.workers or available_cores()), bar)
    finally:
        bar.close()


def _run_local(worker: Callable[..., R], tasks: list[Task], workers: int, bar: tqdm) -> list[R]:
    if workers == 1:
        results = []
        for task in tasks:
            size = len(task.run_ids)
            results.append(worker(task.run_ids, lambda seconds, size=size: bar.update(seconds * size), *task.args))
        return results
    ctx = mp.get_context("fork")  # the workers inherit the parent's plug-ins and imports
    with ctx.Manager() as manager, ProcessPoolExecutor(workers, mp_context=ctx) as pool:
        queue = manager.Queue()
        futures = [pool.submit(_call, worker, task.run_ids, queue, task.args) for task in tasks]
        while not all(f.done() for f in futures):
            with contextlib.suppress(queue_module.Empty):
                bar.update(queue.get(timeout=0.2))
        while not queue.empty():
            bar.update(queue.get())
        return [f.result() for f in futures]


def _call(worker: Callable[..., R], run_ids: list[int], queue: Any, args: tuple) -> R:
    def hook(seconds: float) -> None:
        queue.put(seconds * len(run_ids))

    return worker(run_ids, hook, *args)


def concat_runs(parts: Sequence[Sequence[int]]) -> list[int]:
    return [run for part in parts for run in part]
