"""The ``eval`` command's choices (``EvalOptions``) and what a plant kind's evaluator returns (``Evaluation``).

A plant kind's evaluator (``windwarden.kinds``: ``kind_for(name).evaluate(scenario, runs, seed, options)``) runs
its plant and supervisor in batch mode (``wwcore.stepping``), usually through ``parallel.run_chunks``, and
returns the scorecard (JSON-ready, the schema in ``docs/scorecards.md``) and the plots it can draw.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class EvalOptions:
    """Choices of the ``eval`` command that are not part of the scenario."""

    detector: str | None = None  # overrides scenario.supervisor.detector
    estimator: str | None = None  # overrides scenario.supervisor.estimator
    controller: str | None = None  # farm: dispatch | pi
    accommodation: bool = True  # farm: fault accommodation of eqs. (23)–(26)
    compensation: bool = True  # hydro: virtual actuator of eq. (36)
    compare: bool = False  # write the paper-comparison tables where the kind has them
    twins: bool = True  # turbine: run a fault-free twin of every run for the "fault-free RMSE" references
    workers: int | None = None  # local processes; None: one per available core (``usage.available_cores``)
    scheduler: str | None = None  # address of a Dask scheduler that runs the chunks instead (``docs/cluster.md``)
    plugins: tuple[str, ...] = ()  # the ``--plugin`` modules and files, loaded on a cluster's workers too
    progress: bool = True


@dataclass
class Evaluation:
    """What an evaluator returns: the scorecard and a function that draws its plots into a folder."""

    scorecard: dict[str, Any]
    plot: Callable[[Path], list[Path]] = field(default=lambda out: [])
    extra_files: dict[str, str] = field(default_factory=dict)  # file name → text (markdown tables, …)


SWITCHES: dict[str, tuple[str, frozenset[str]]] = {
    "accommodation": ("--no-accommodation", frozenset({"farm"})),
    "compensation": ("--no-compensation", frozenset({"hydro"})),
    "compare": ("--compare", frozenset({"farm"})),
    "twins": ("--no-twins", frozenset({"turbine", "farm"})),
}
"""``EvalOptions`` field → (the ``eval`` flag that changes it, the plant kinds whose evaluator uses it)."""


def unused_switches(kind: str, options: EvalOptions) -> list[tuple[str, str]]:
    """The flags given that a ``kind`` evaluation would ignore or that contradict each other, as (flag, message)
    pairs; empty when none."""
    defaults = EvalOptions()
    unused = [
        (flag, f"a {kind} scenario does not use it (it applies to {', '.join(sorted(kinds))} scenarios)")
        for name, (flag, kinds) in SWITCHES.items()
        if kind not in kinds and getattr(options, name) != getattr(defaults, name)
    ]
    if options.scheduler is not None and options.workers is not None:
        unused.append(("--workers", "counts local processes; a cluster's workers are set where they start"))
    return unused
