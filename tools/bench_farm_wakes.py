"""Benchmark of the farm plant with each wake model: start-up and simulated turbine-seconds per wall-second.

    nice -n 10 .venv/bin/python tools/bench_farm_wakes.py [--seconds 20] [--runs 1,20] [--horns-rev]

For the 3 × 3 in wind case 2 (and, with ``--horns-rev``, Horns Rev 1's 80 turbines at 270°, FLORIS wakes only)
it builds a ``FarmBatch`` per wake model and batch size (the wake tables built once beforehand into a temporary
cache, so the start-up shown is a second start) and runs the plant alone (no supervisor) for ``--seconds``. It
prints the start-up, the throughput and its ratio to the row model's from the same run. Wall times on a shared
machine are indicative; the ratios travel better.
"""

from __future__ import annotations

import argparse
import tempfile
import time

from plant_sim.farm import FarmBatch
from plant_sim.farm.wakes import plant_wake_tables
from wwcore.scenario.farm import FarmDemand, FarmPlant
from wwcore.scenario.wind import WindSpec
from wwcore.turbine_params import BENCHMARK

WIND = WindSpec(mean=[(0.0, 10.0)], turbulence_intensity=0.10)


def run(spec: FarmPlant, runs: int, seconds: float, cache: str) -> tuple[float, float]:
    """(start-up s, simulated turbine-seconds per wall-second) of the plant alone."""
    start = time.perf_counter()
    plant = FarmBatch(spec, WIND, [], seed=1, runs=tuple(range(runs)), duration_s=seconds, wake_cache_dir=cache)
    ready = time.perf_counter()
    for _ in range(round(seconds / plant.dt)):
        plant.measure()
        plant.control(None)
        plant.advance()
    return ready - start, plant.n * seconds / (time.perf_counter() - ready)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="simulated seconds per case")
    parser.add_argument("--runs", default="1,20", help="comma-separated Monte Carlo batch sizes")
    parser.add_argument("--horns-rev", action="store_true", help="also Horns Rev 1 (80 turbines, one farm)")
    args = parser.parse_args()
    demand = FarmDemand(mode="available_fraction", fraction=0.8)
    cases = [(f"3x3 case 2, {m}", FarmPlant(wind_case=2, wake_model=m, demand=demand)) for m in ("rows", "gauss")]
    cases.append(("3x3 case 2, jensen", FarmPlant(wind_case=2, wake_model="jensen", demand=demand)))
    hr1 = FarmPlant(
        wake_model="gauss", layout={"kind": "file", "name": "hornsrev1"}, wind_direction_deg=270.0, demand=demand
    )
    with tempfile.TemporaryDirectory() as cache:
        for _, spec in cases[1:] + ([("", hr1)] if args.horns_rev else []):
            plant_wake_tables(spec, WIND, BENCHMARK, cache)  # the first build, not timed here (bench_wakes.py)
        print("| farm, wake model | runs | start-up s | turbine-s per wall-s | ratio to rows |")
        print("|---|---|---|---|---|")
        for runs in (int(r) for r in args.runs.split(",")):
            rows_rate = None
            for name, spec in cases:
                startup, rate = run(spec, runs, args.seconds, cache)
                rows_rate = rows_rate or rate
                print(f"| {name} | {runs} | {startup:.2f} | {rate:.0f} | {rate / rows_rate:.2f} |", flush=True)
        if args.horns_rev:
            startup, rate = run(hr1, 1, args.seconds, cache)
            print(f"| Horns Rev 1 (80), gauss | 1 | {startup:.2f} | {rate:.0f} | – |")


if __name__ == "__main__":
    main()
