"""Run chunks on a Dask distributed cluster (``windwarden eval --scheduler ADDRESS``, ``docs/cluster.md``).

The client connects to the scheduler (its TLS settings, if any, come from Dask's own configuration), checks
that every worker runs the same windwarden code, numpy and scipy as this process (the numbers depend on them),
submits one task per chunk and gathers the results in chunk order. The progress bar follows the tasks: the
workers report their simulated seconds as Dask events, and a completed future completes its chunk's count.
Nothing about the numbers changes: the chunks are those a local evaluation runs (``parallel.chunk_runs``), so
the scorecard is the local one bit for bit (``tests/test_cluster.py``).

On a worker each task first loads the plug-ins the user gave (``--plugin``): a ``.py`` file travels with the task
(its text and hash) and is imported once per worker process; a module name must be importable there (installed
like windwarden). A worker that already imported another version of the same file refuses the task: its
registries hold the old algorithms, and restarting the workers is the only clean way to drop them.

The fault-free twins of the turbine evaluation run as in-process copies on a worker (``parallel.branch_mode``),
never as forks: a Dask worker always has other threads (its event loop, its other tasks), and a fork while one
of them holds a lock (numpy, BLAS, logging) copies the held lock into the child. Both give the same numbers
(``tests/test_parallel.py``).
"""

from __future__ import annotations

import hashlib
import resource
import sys
import threading
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from tqdm import tqdm

from service.plugins import load_plugins
from windwarden.evaluation import usage
from windwarden.evaluation.branch import branch_mode
from windwarden.evaluation.provenance import environment
from windwarden.evaluation.tasks import Task

R = TypeVar("R")
CONNECT_TIMEOUT_S = 20.0  # for the scheduler to answer, and for a first worker to join it


class ClusterError(RuntimeError):
    """The cluster cannot run this evaluation: unreachable, no workers, other code or plug-ins on a worker."""


def run_on_cluster(
    address: str, worker: Callable[..., R], tasks: list[Task], bar: tqdm, plugin_specs: Sequence[str] = ()
) -> list[R]:
    """``worker(run_ids, hook, *args)`` for every task on the cluster at ``address``; results in task order."""
    from distributed import Client, as_completed  # Dask takes a second to import; a local evaluation never needs it

    plugins = PluginSet.of(plugin_specs)
    try:
        client = Client(address, timeout=CONNECT_TIMEOUT_S)
    except (OSError, ValueError) as error:  # unreachable (or timed out); not an address
        raise ClusterError(f"cannot reach the Dask scheduler at {address}: {error}") from None
    with client:
        try:
            client.wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
        except TimeoutError:
            raise ClusterError(f"no worker joined the scheduler at {address} within {CONNECT_TIMEOUT_S:g} s") from None
        here = environment()
        check_environments(here, client.run(environment, on_error="return"))
        token = uuid.uuid4().hex  # task keys are global on the scheduler: never share one with another client
        progress = _Progress(tasks, bar)
        topic = f"windwarden-progress-{token}"
        client.subscribe_topic(topic, progress.on_event)
        futures = [
            client.submit(
                run_task, worker, task.run_ids, task.args, plugins, here, (topic, i), key=f"windwarden-{i}-{token}"
            )
            for i, task in enumerate(tasks)
        ]
        position = {future.key: i for i, future in enumerate(futures)}
        results: list[Any] = [None] * len(tasks)
        try:
            for future in as_completed(futures):
                i = position[future.key]
                results[i], peak = future.result()
                usage.note_remote_peak(peak)
                progress.done(i)
        except BaseException:
            client.cancel(futures)
            raise
        finally:
            client.unsubscribe_topic(topic)
    return results


class _Progress:
    """The bar follows the tasks: a worker reports each chunk's simulated run-seconds as they pass (a Dask event,
    ``(task, run-seconds)``), and a completed future brings its chunk to its full count. A chunk rerun after a
    lost worker never counts twice."""

    def __init__(self, tasks: list[Task], bar: tqdm):
        self.remaining = [task.run_seconds for task in tasks]
        self.bar = bar
        self.lock = threading.Lock()

    def on_event(self, event: tuple[float, Any]) -> None:
        i, seconds = event[1]
        self._advance(int(i), float(seconds))

    def done(self, i: int) -> None:
        self._advance(i, self.remaining[i])

    def _advance(self, i: int, seconds: float) -> None:
        with self.lock:
            step = min(seconds, self.remaining[i])
            self.remaining[i] -= step
            self.bar.update(step)


@dataclass(frozen=True)
class PluginFile:
    stem: str
    sha256: str
    source: bytes


@dataclass(frozen=True)
class PluginSet:
    """The user's plug-ins as a task carries them: ``.py`` files by their source, modules by name."""

    files: tuple[PluginFile, ...] = ()
    modules: tuple[str, ...] = ()

    @classmethod
    def of(cls, specs: Sequence[str]) -> PluginSet:
        files, modules = [], []
        for spec in specs:
            if spec.endswith(".py"):
                source = Path(spec).read_bytes()
                files.append(PluginFile(Path(spec).stem, hashlib.sha256(source).hexdigest(), source))
            else:
                modules.append(spec)
        return cls(tuple(files), tuple(modules))

    def load(self, folder: Path) -> None:
        """Import the plug-ins in this process (each file once, from ``folder/<hash>/<stem>.py``)."""
        paths = []
        for plugin in self.files:
            loaded = sys.modules.get(f"windwarden_plugin_{plugin.stem}")
            if loaded is not None:
                if _sha256_of(Path(loaded.__file__ or "")) != plugin.sha256:
                    raise ClusterError(
                        f"this worker already imported another version of the plug-in {plugin.stem}.py; restart the "
                        "workers (dask's client.restart(), or the dask worker processes) to load the new one"
                    )
                continue
            path = folder / plugin.sha256 / f"{plugin.stem}.py"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(plugin.source)
            paths.append(str(path))
        load_plugins((*self.modules, *paths))


def _sha256_of(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def run_task(
    worker: Callable[..., R],
    run_ids: list[int],
    args: tuple,
    plugins: PluginSet,
    expected: dict[str, str],
    progress: tuple[str, int],
) -> tuple[R, dict]:
    """On a worker: check its code (a worker may join after the client's check), load the plug-ins, run the chunk
    reporting its progress as ``progress`` = (event topic, task index), and return its result with the peak memory
    of this worker process (``getrusage``: the largest resident set it has had, in bytes)."""
    from distributed import get_worker  # already imported on a worker

    dask_worker = get_worker()
    check_environments(expected, {dask_worker.address: environment()})
    plugins.load(Path(dask_worker.local_directory) / "windwarden-plugins")
    with branch_mode("copy"):
        topic, index = progress
        result = worker(run_ids, lambda seconds: dask_worker.log_event(topic, [index, seconds * len(run_ids)]), *args)
    kib = 1024  # ru_maxrss is in KiB on Linux
    peak = {
        "worker": dask_worker.address,
        "worker_peak_rss_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * kib,
    }
    return result, peak


def check_environments(local: dict[str, str], workers: dict[str, Any]) -> None:
    """Refuse a cluster with a worker whose code or numerical libraries differ from this process's."""
    problems = []
    for address, theirs in sorted(workers.items()):
        if isinstance(theirs, BaseException):  # client.run(..., on_error="return"): windwarden missing, for one
            problems.append(f"  {address}: {type(theirs).__name__}: {theirs}")
            continue
        problems += [
            f"  {address}: {key} {theirs.get(key, 'missing')} (here {mine})"
            for key, mine in local.items()
            if theirs.get(key) != mine
        ]
    if problems:
        raise ClusterError(
            "the cluster's workers must run the same windwarden code, numpy, scipy and Python as this command "
            "(the numbers depend on them):\n" + "\n".join(problems)
        )
