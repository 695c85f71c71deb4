"""``windwarden bench``: throughput of the batch step code, as ratios measured in one run.

``windwarden bench turbine`` times plant + supervisor of the benchmark turbine, and ``windwarden bench farm`` the
3 × 3 farm, for a batch of 1 run and a batch of N runs over the same simulated span, each with the numpy reference
and with the compiled backend (``wwcore.backend``), in one process, the two taking turns every 100 ticks (a change
of the machine's load then hits both alike). It reports simulated seconds per wall-clock second, run-seconds per
wall second (the batch's gain from vectorisation), turbine-seconds per wall second (every row is one turbine: a
farm run counts each of its turbines, so ``--scenario farm-hornsrev1`` and the 3 × 3 compare per turbine), the time
split between the four calls of the step contract (the farm, stepped a farm sample at a time as its evaluation
steps it: between plant and supervisor), and the compiled backend's speed-up over numpy per batch: the
ratio is what to compare across machines and loads, the absolute figures only on a quiet machine. The compiled code
is loaded (or compiled, on a first use) before the clock starts; that time is printed apart.
No timing assertion lives in the tests; this command is the measurement.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np
from rich.console import Console
from rich.table import Table

from wwcore.backend import BACKENDS
from wwcore.scenario import Scenario, load_scenario

console = Console()
CALLS = ("measure", "control", "supervise", "advance")
SAMPLE_CALLS = ("plant", "supervise")  # a plant stepped a farm sample at a time (``FarmBatch.run_sample``)


def turbine_pair(scenario_name: str, runs: int, seed: int, twins: bool, backend: str):
    """The benchmark turbine's batch of ``runs`` runs of a scenario and its supervisor, both on ``backend``."""
    from plant_sim.turbine import TurbineBatch
    from service.turbine.supervisor import TurbineSupervisor

    scenario = load_scenario(scenario_name)
    plant = TurbineBatch(
        scenario.plant,
        scenario.wind,
        scenario.faults,
        seed=seed,
        runs=list(range(runs)),
        fault_free_twins=twins,
        backend=backend,
    )
    supervisor = TurbineSupervisor(plant.n, noise_convention=scenario.plant.noise_convention, backend=backend)
    return plant, supervisor


def farm_pair(scenario: str | Scenario, runs: int, seed: int, twins: bool, backend: str, seconds: float):
    """A farm scenario's (a name or file, or the scenario itself) batch of ``runs`` runs, ``seconds`` long, and its
    supervisor as the scenario chooses it, both on ``backend``."""
    from plant_sim.farm import FarmBatch
    from service.farm.supervisor import FarmSupervisor

    scenario = load_scenario(scenario) if isinstance(scenario, str) else scenario
    plant = FarmBatch(
        scenario.plant,
        scenario.wind,
        scenario.faults,
        seed=seed,
        duration_s=seconds + 1.0,
        runs=list(range(runs)),
        fault_free_twins=twins,
        backend=backend,
    )
    sup = scenario.supervisor
    supervisor = FarmSupervisor(
        scenario.plant.site(plant.dt),
        plant.n,
        detector=sup.detector,
        controller=sup.controller,
        options=sup.params,
        backend=backend,
    )
    return plant, supervisor


class _Stepper:
    """A plant and its supervisor stepped in blocks of ticks, with the time spent in each call of the contract.

    A plant that runs a farm sample's ticks at once (``FarmBatch.run_sample``, as the farm evaluation steps it) is
    stepped that way, its supervisor given each block's last frame; the time then splits into plant and supervisor
    (``SAMPLE_CALLS``). ``clock`` reads the time (wall; ``time.process_time`` for CPU time)."""

    def __init__(self, plant, supervisor):
        self.plant, self.supervisor = plant, supervisor
        self.refs = None
        self.by_sample = hasattr(plant, "run_sample")
        self.calls = SAMPLE_CALLS if self.by_sample else CALLS
        self.spent = np.zeros(len(self.calls))
        self.ticks = 0
        self.clock = time.perf_counter

    def run(self, ticks: int) -> None:
        if self.by_sample:
            self._run_samples(ticks)
            return
        plant, supervisor, refs, spent = self.plant, self.supervisor, self.refs, self.spent
        clock = self.clock
        for _ in range(ticks):
            t0 = clock()
            frame = plant.measure()
            t1 = clock()
            plant.control(refs)
            t2 = clock()
            refs = supervisor.step(frame)
            t3 = clock()
            plant.advance()
            spent += (t1 - t0, t2 - t1, t3 - t2, clock() - t3)
        self.refs = refs
        self.ticks += ticks

    def _run_samples(self, ticks: int) -> None:
        plant, supervisor, refs, spent = self.plant, self.supervisor, self.refs, self.spent
        clock = self.clock
        end = plant.k + ticks
        while plant.k < end:
            t0 = clock()
            block = plant.run_sample(refs, end - plant.k, states=False)
            t1 = clock()
            refs = supervisor.step(block.frame)
            spent += (t1 - t0, clock() - t1)
        self.refs = refs
        self.ticks += ticks

    def figures(self, runs: int) -> dict[str, float]:
        wall = float(self.spent.sum())
        seconds = self.ticks * self.plant.dt
        return {
            "rows": self.plant.n,
            "wall_s": wall,
            "sim_per_wall": seconds / wall,
            "run_s_per_wall": runs * seconds / wall,
            "turbine_s_per_wall": self.plant.n * seconds / wall,  # every row is one turbine (twins included)
            "ms_per_tick": 1e3 * wall / self.ticks,
            "split": self.spent / wall,
        }


BLOCK_TICKS = 100  # the two backends take turns every this many ticks, so a change of load hits both alike


def _bench(args: argparse.Namespace, title: str, make: Callable[[int, str], tuple]) -> int:
    t0 = time.perf_counter()
    # one batch of one run and one of two, each of the timed length, before the clock starts, so that every kernel
    # the timed batches reach is loaded from the cache or compiled: the detectors' kernels start after their warm-up,
    # a fault's after its onset, and a batch of several rows passes some kernels arrays of another layout than one
    for runs in dict.fromkeys((1, min(2, args.runs))):
        warm = _Stepper(*make(runs, "numba"))
        warm.run(round(args.seconds / warm.plant.dt))
    console.print(f"compiled kernels of a tick ready in {time.perf_counter() - t0:.1f} s (cache load or compilation)")
    table = Table(title=f"{title}: {args.scenario}, {args.seconds:g} s simulated per batch, seed {args.seed}")
    for column in (
        "batch",
        "backend",
        "rows",
        "wall s",
        "sim s / wall s",
        "run-s / wall s",
        "turbine-s / wall s",
        "ms / tick",
        "|".join(warm.calls),
    ):
        table.add_column(column, justify="right")
    speedups = {}
    results = {}
    for runs in dict.fromkeys((1, args.runs)):
        steppers = {backend: _Stepper(*make(runs, backend)) for backend in BACKENDS}
        ticks = round(args.seconds / steppers["numpy"].plant.dt)
        for first in range(0, ticks, BLOCK_TICKS):  # the same ticks, in turns
            for stepper in steppers.values():
                stepper.run(min(BLOCK_TICKS, ticks - first))
        for backend in BACKENDS:
            r = results[runs, backend] = steppers[backend].figures(runs)
            table.add_row(
                f"{runs} run" + ("s" if runs > 1 else ""),
                backend,
                str(r["rows"]),
                f"{r['wall_s']:.1f}",
                f"{r['sim_per_wall']:.1f}",
                f"{r['run_s_per_wall']:.0f}",
                f"{r['turbine_s_per_wall']:.0f}",
                f"{r['ms_per_tick']:.3f}",
                " | ".join(f"{v:.0%}" for v in r["split"]),
            )
        speedups[runs] = results[runs, "numba"]["sim_per_wall"] / results[runs, "numpy"]["sim_per_wall"]
    console.print(table)
    for runs, ratio in speedups.items():
        console.print(
            f"{runs} run{'s' if runs > 1 else ''}: numba ×{ratio:.2f} simulated seconds per wall second over numpy"
        )
    if args.runs > 1:
        for backend in BACKENDS:
            gain = results[args.runs, backend]["run_s_per_wall"] / results[1, backend]["run_s_per_wall"]
            console.print(
                f"{backend}: batching {args.runs} runs gives ×{gain:.1f} run-seconds per wall second over one"
            )
    return 0


def bench_turbine(args: argparse.Namespace) -> int:
    return _bench(
        args,
        "turbine step throughput",
        lambda runs, backend: turbine_pair(args.scenario, runs, args.seed, args.twins, backend),
    )


def bench_farm(args: argparse.Namespace) -> int:
    return _bench(
        args,
        "farm step throughput",
        lambda runs, backend: farm_pair(args.scenario, runs, args.seed, args.twins, backend, args.seconds),
    )


BENCHMARKS: dict[str, tuple[str, Callable[[argparse.ArgumentParser], None], Callable[[argparse.Namespace], int]]] = {}


def _common_args(p: argparse.ArgumentParser, scenario: str, runs: int, seconds: float) -> None:
    p.add_argument("--scenario", default=scenario)
    p.add_argument("--runs", type=int, default=runs, help=f"runs in the second batch (default {runs})")
    p.add_argument("--seconds", type=float, default=seconds, help=f"simulated seconds per batch (default {seconds:g})")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--twins", action="store_true", help="add the fault-free twin rows the evaluator uses")


BENCHMARKS["turbine"] = (
    "plant + supervisor of the benchmark turbine, 1 run vs a batch, numpy vs numba",
    lambda p: _common_args(p, "ftwse-2012", 50, 60.0),
    bench_turbine,
)
BENCHMARKS["farm"] = (
    "plant + supervisor of the 3 × 3 farm, 1 run vs a batch, numpy vs numba",
    lambda p: _common_args(p, "farm-case1", 10, 30.0),
    bench_farm,
)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="measure the throughput of the step code (ratios from one run)")
    targets = p.add_subparsers(dest="target", required=True)
    for name, (help_text, add_args, func) in BENCHMARKS.items():
        t = targets.add_parser(name, help=help_text)
        add_args(t)
        t.set_defaults(func=func)
