"""The cores an evaluation may use, and the wall time, CPU time and peak memory of it and every process it started.

Peak memory is measured two ways, because neither alone is the whole answer:

* ``peak_rss_sum_bytes``, ``peak_pss_sum_bytes``: the resident set (RSS) and proportional set (PSS: a page shared
  by k processes counts 1/k in each) summed over this process and all its descendants (the chunk processes and the
  turbine's forked twins), sampled every ``interval_s`` by a thread. The RSS sum counts the pages a fork shares
  with its parent once per process, so it overstates what the machine holds; the PSS sum (Linux) does not. A
  peak shorter than the interval can be missed.
* ``largest_process_peak_rss_bytes``: the largest resident set any single process reached (``getrusage``
  ``ru_maxrss`` of this process and of its waited-for descendants), exact, never missed, but per process.

On a Dask cluster (``--scheduler``) the workers are other machines' processes: each chunk reports its worker's
``ru_maxrss`` (that worker process's lifetime peak, earlier tasks included) and the largest is kept
(``note_remote_peak``). The figures describe this machine and this run: ``eval --out`` writes them to
``execution.json`` beside ``scorecard.json``, whose numbers they never join (two scorecards of the same scenario,
runs and seed are equal file for file, wherever they ran).
"""

from __future__ import annotations

import contextlib
import os
import resource
import sys
import threading
import time
from contextvars import ContextVar
from pathlib import Path
from typing import Any

import psutil

from windwarden.evaluation.kinds import EvalOptions
from windwarden.evaluation.provenance import environment

KIB = 1024  # ru_maxrss unit on Linux (bytes on macOS)
SAMPLE_INTERVAL_S = 2.0
"""Between memory samples. A sample of four processes costs ~20 ms of CPU (the kernel walks their page tables
for the PSS; measured with two 50-run farm chunks): 1 % of a core at this interval, 4 % at 0.5 s. An evaluation's
memory grows over minutes, and each process's exact peak comes from ``getrusage`` anyway."""
_MONITOR: ContextVar[ResourceMonitor | None] = ContextVar("resource_monitor", default=None)


class ResourceMonitor:
    """``with ResourceMonitor() as usage: ...`` then ``usage.report()``."""

    def __init__(self, interval_s: float = SAMPLE_INTERVAL_S):
        self.interval_s = interval_s
        self.peak_rss_sum = 0
        self.peak_pss_sum = 0
        self.remote_peak = 0  # largest worker_peak_rss_bytes a cluster chunk reported
        self.remote_workers: set[str] = set()
        self.samples = 0
        self._process = psutil.Process(os.getpid())
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="resource-monitor", daemon=True)
        self._lock = threading.Lock()

    def __enter__(self) -> ResourceMonitor:
        self._token = _MONITOR.set(self)
        self._wall0 = time.perf_counter()
        self._cpu0 = _cpu_seconds()
        self.sample()
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()
        self.wall_s = time.perf_counter() - self._wall0
        self.cpu_s = _cpu_seconds() - self._cpu0
        _MONITOR.reset(self._token)

    def _run(self) -> None:
        while not self._stop.wait(self.interval_s):
            self.sample()

    def sample(self) -> None:
        """Add one sample of the summed RSS and PSS of this process and its descendants."""
        rss = pss = 0
        with contextlib.suppress(psutil.Error):
            processes = [self._process, *self._process.children(recursive=True)]
            for process in processes:
                with contextlib.suppress(psutil.Error):  # a child may end while it is read
                    if hasattr(process, "memory_full_info") and sys.platform == "linux":
                        info = process.memory_full_info()
                        pss += info.pss
                    else:
                        info = process.memory_info()
                    rss += info.rss
        with self._lock:
            self.peak_rss_sum = max(self.peak_rss_sum, rss)
            self.peak_pss_sum = max(self.peak_pss_sum, pss)
            self.samples += 1

    def note_remote(self, peak: dict[str, Any]) -> None:
        """Keep the largest of a cluster chunk's figures (``cluster.run_task``)."""
        with self._lock:
            self.remote_workers.add(str(peak["worker"]))
            self.remote_peak = max(self.remote_peak, int(peak["worker_peak_rss_bytes"]))

    def report(self) -> dict[str, Any]:
        """The figures, as the scorecard's ``execution`` section holds them."""
        unit = 1 if sys.platform == "darwin" else KIB
        largest = max(
            resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
        )
        out: dict[str, Any] = {
            "wall_s": round(self.wall_s, 3),
            "cpu_s": round(self.cpu_s, 3),
            "peak_rss_sum_bytes": self.peak_rss_sum,
            "peak_pss_sum_bytes": self.peak_pss_sum or None,
            "largest_process_peak_rss_bytes": largest * unit,
            "memory_sample_interval_s": self.interval_s,
        }
        if self.remote_workers:
            out["cluster"] = {"workers_used": len(self.remote_workers), "worker_peak_rss_bytes": self.remote_peak}
        return out


def note_remote_peak(peak: dict[str, Any]) -> None:
    """Keep a cluster chunk's memory figures in the monitor of the running evaluation, if any."""
    monitor = _MONITOR.get()
    if monitor is not None:
        monitor.note_remote(peak)


def available_cores() -> int:
    """Cores this process may run on: its CPU affinity, and a container's CPU quota (cgroup v2 ``cpu.max``)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    with contextlib.suppress(OSError, ValueError):
        quota, period = Path("/sys/fs/cgroup/cpu.max").read_text().split()[:2]
        if quota != "max":
            cores = min(cores, max(1, int(int(quota) // int(period))))
    return max(1, cores)


def _cpu_seconds() -> float:
    """User + system CPU time of this process and its waited-for descendants."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def gib(n_bytes: float | None) -> str:
    return "–" if n_bytes is None else f"{n_bytes / 2**30:.2f} GiB"


def execution_record(options: EvalOptions, usage: dict[str, Any]) -> dict[str, Any]:
    """``execution.json``: where and how the runs went, what they cost, and what the numbers depend on besides
    the scenario, runs and seed (``provenance.environment``)."""
    where = (
        {"backend": "dask", "scheduler": options.scheduler}
        if options.scheduler is not None
        else {"backend": "local processes", "workers": options.workers, "available_cores": available_cores()}
    )
    return {**where, **usage, "environment": environment()}


def execution_line(execution: dict[str, Any]) -> str:
    """One line for the terminal: wall and CPU time, peak memory."""
    line = (
        f"wall {execution['wall_s']:.1f} s, CPU {execution['cpu_s']:.1f} s; peak memory of all processes "
        f"{gib(execution['peak_rss_sum_bytes'])} RSS summed (PSS {gib(execution['peak_pss_sum_bytes'])}), "
        f"largest process {gib(execution['largest_process_peak_rss_bytes'])}"
    )
    if "cluster" in execution:
        cluster = execution["cluster"]
        line += f"; cluster: {cluster['workers_used']} workers, largest {gib(cluster['worker_peak_rss_bytes'])}"
    return line
