"""Benchmark of the wake tables: first build, second start (cache), and the farm-rate combination, beside FLORIS.

    nice -n 10 .venv/bin/python tools/bench_wakes.py [--sizes 9,80,150] [--model gauss] [--repeats 2000]

For each farm (9: seed 001's 3 × 3; 80: Horns Rev 1; 150: a 10 × 15 grid, 7 D, rows along 110°) it reports:
the build of the full-circle tables with an empty cache (wall time, entries, MB), the second start (the same call
loading the cache file), one ``waked`` call for one farm (each turbine's C_T, and a per-pair delayed C_T matrix)
and for a batch of 20 farms with their own directions, and one direct FLORIS run of the same farm at one
condition (set + run), with the ratio FLORIS / tables from the same run. Wall times on a shared machine are
indicative; the ratios travel better.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time

import numpy as np

from plant_sim.farm.floris_wakes import WakeSettings, floris_model, wake_tables
from wwcore.layout import HORNS_REV_1, SEED001_LAYOUT, GridLayout
from wwcore.turbine_params import BENCHMARK

LAYOUTS = {
    9: SEED001_LAYOUT,
    80: HORNS_REV_1,
    150: GridLayout(rows=10, columns=15, orientation_deg=110.0),
}


def per_call(fn, repeats: int) -> float:
    """Median of five batches of ``repeats`` calls, seconds per call."""
    fn()
    times = []
    for _ in range(5):
        start = time.perf_counter()
        for _ in range(repeats):
            fn()
        times.append((time.perf_counter() - start) / repeats)
    return statistics.median(times)


def bench(size: int, settings: WakeSettings, repeats: int, rng: np.random.Generator) -> str:
    """One table row for a farm of ``size`` turbines."""
    layout = LAYOUTS[size].resolve(2.0 * BENCHMARK.radius)
    n = layout.n_turbines
    with tempfile.TemporaryDirectory() as cache:
        start = time.perf_counter()
        wake_tables(layout, settings, BENCHMARK, cache)
        build = time.perf_counter() - start
        start = time.perf_counter()
        tables = wake_tables(layout, settings, BENCHMARK, cache)
        load = time.perf_counter() - start
    ct = rng.uniform(0.3, 0.8, n)
    pair = rng.uniform(0.3, 0.8, (n, n))
    state = {"theta": 270.0}

    def one(thrust):
        state["theta"] += 1e-3  # a slowly veering wind: the table interval changes now and then
        return tables.waked(state["theta"], thrust, 10.0)

    t_turbine = per_call(lambda: one(ct), repeats)
    t_pair = per_call(lambda: one(pair), repeats)
    directions = 270.0 + rng.uniform(-5.0, 5.0, 20)
    batch_ct = np.tile(ct, (20, 1))
    t_batch = per_call(lambda: tables.waked(directions, batch_ct, 10.0), max(1, repeats // 20)) / 20
    fm = floris_model(layout, settings.model, BENCHMARK, np.array([270.3]), np.array([10.0]), 0.10)

    def floris_run():
        fm.set(wind_directions=np.array([270.3]), wind_speeds=np.array([10.0]), turbulence_intensities=[0.10])
        fm.run()

    t_floris = per_call(floris_run, 5)
    return (
        f"| {n} | {build:.1f} | {load:.3f} | {tables.n_entries} | {tables.nbytes / 1e6:.1f} | "
        f"{t_turbine * 1e6:.0f} / {t_pair * 1e6:.0f} | {t_batch * 1e6:.0f} | {t_floris * 1e3:.1f} | "
        f"{t_floris / t_turbine:.0f} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="9,80", help="comma-separated farm sizes among 9, 80, 150")
    parser.add_argument("--model", default="gauss", choices=["gauss", "jensen"])
    parser.add_argument("--repeats", type=int, default=500)
    args = parser.parse_args()
    settings = WakeSettings(model=args.model)
    print(f"model {args.model}, {settings.direction_step_deg:g} deg steps, full circle")
    print(
        "| N | first build s | second start s | entries | MB | waked µs (C_T per turbine / per pair) | "
        "batch of 20 µs per farm | FLORIS run ms | FLORIS / waked |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    rng = np.random.default_rng(1)
    for size in (int(s) for s in args.sizes.split(",")):
        print(bench(size, settings, args.repeats, rng), flush=True)


if __name__ == "__main__":
    main()
