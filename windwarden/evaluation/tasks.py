"""A chunk of Monte Carlo runs as the local pool (``parallel``) and a Dask cluster (``cluster``) both run it."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Task:
    """One chunk of runs with the worker's arguments, and the run-seconds it simulates (for the progress bar)."""

    run_ids: list[int]
    args: tuple
    run_seconds: float
