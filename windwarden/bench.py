"""``windwarden bench``: throughput of the batch step code, as ratios measured in one run.

``windwarden bench turbine`` times plant + supervisor of the benchmark turbine for a batch of 1 run and a
batch of N runs over the same simulated span and reports simulated seconds per wall-clock second for each,
the run-seconds per wall second of the batch (its speed-up from vectorisation), and the time split between
the four calls of the step contract. No timing assertion lives in the tests; this command is the measurement.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np
from rich.console import Console
from rich.table import Table

from wwcore.scenario import load_scenario

console = Console()


def _turbine_batch(scenario_name: str, runs: int, seconds: float, seed: int, twins: bool) -> dict[str, float]:
    from plant_sim.turbine import TurbineBatch
    from service.turbine.supervisor import TurbineSupervisor

    scenario = load_scenario(scenario_name)
    plant = TurbineBatch(
        scenario.plant, scenario.wind, scenario.faults, seed=seed, runs=list(range(runs)), fault_free_twins=twins
    )
    supervisor = TurbineSupervisor(plant.n, noise_convention=scenario.plant.noise_convention)
    refs = None
    spent = np.zeros(4)
    ticks = round(seconds / plant.dt)
    clock = time.perf_counter
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
    wall = float(spent.sum())
    return {
        "rows": plant.n,
        "wall_s": wall,
        "sim_per_wall": seconds / wall,
        "run_s_per_wall": runs * seconds / wall,
        "ms_per_tick": 1e3 * wall / ticks,
        "split": dict(
            zip(("measure", "control", "supervise", "advance"), (spent / wall).round(3).tolist(), strict=True)
        ),
    }


def bench_turbine(args: argparse.Namespace) -> int:
    table = Table(title=f"turbine step throughput: {args.scenario}, {args.seconds:g} s simulated per batch")
    for column in (
        "batch",
        "rows",
        "wall s",
        "sim s / wall s",
        "run-s / wall s",
        "ms / tick",
        "measure|control|supervise|advance",
    ):
        table.add_column(column, justify="right")
    results = {}
    for runs in (1, args.runs):
        r = _turbine_batch(args.scenario, runs, args.seconds, args.seed, args.twins)
        results[runs] = r
        split = " | ".join(f"{v:.0%}" for v in r["split"].values())
        table.add_row(
            f"{runs} run" + ("s" if runs > 1 else ""),
            str(r["rows"]),
            f"{r['wall_s']:.1f}",
            f"{r['sim_per_wall']:.1f}",
            f"{r['run_s_per_wall']:.0f}",
            f"{r['ms_per_tick']:.3f}",
            split,
        )
    console.print(table)
    one, many = results[1], results[args.runs]
    speedup = many["run_s_per_wall"] / one["run_s_per_wall"]
    minutes = 4400 / many["sim_per_wall"] / 60
    console.print(
        f"batching {args.runs} runs: ×{speedup:.1f} run-seconds per wall second over one run; "
        f"one process would take {minutes:.1f} min for {args.runs} runs × 4400 s "
        f"({'with' if args.twins else 'without'} fault-free twins). `windwarden eval` runs up to 50 turbine runs "
        "(and their twins) in one process, one such chunk per core."
    )
    return 0


BENCHMARKS: dict[str, tuple[str, Callable[[argparse.ArgumentParser], None], Callable[[argparse.Namespace], int]]] = {}


def _turbine_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scenario", default="ftwse-2012")
    p.add_argument("--runs", type=int, default=50, help="runs in the second batch (default 50)")
    p.add_argument("--seconds", type=float, default=60.0, help="simulated seconds per batch (default 60)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--twins", action="store_true", help="add the fault-free twin rows the evaluator uses")


BENCHMARKS["turbine"] = ("plant + supervisor of the benchmark turbine, 1 run vs a batch", _turbine_args, bench_turbine)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="measure the throughput of the step code (ratios from one run)")
    targets = p.add_subparsers(dest="target", required=True)
    for name, (help_text, add_args, func) in BENCHMARKS.items():
        t = targets.add_parser(name, help=help_text)
        add_args(t)
        t.set_defaults(func=func)
