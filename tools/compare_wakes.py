"""The FLORIS comparison table of docs/farm.md: steady per-turbine winds and farm power of the 3 × 3, both wind cases.

    nice -n 10 .venv/bin/python tools/compare_wakes.py [--speeds 8,11,14] [--ti 0.10]
    nice -n 10 .venv/bin/python tools/compare_wakes.py --running [--speeds 9] [--runs 4] [--seed 202]

For each wind case and free-stream speed it prints, per turbine, the steady wind of the row model (``wake_model =
"rows"``, the paper's), of direct FLORIS 4.7 runs (Gauss and Jensen, the benchmark turbine's curves) and of the
farm plant's FLORIS tables (the plant's steady state, ``plant_sim.farm.wakes.steady_winds``), then the farm power
of each. The row model's C_T is momentum theory on the benchmark's C_p; FLORIS's and the tables' is
``wwcore.thrust``'s. Nothing here is random.

``--running`` runs the farm plant itself (Gauss wakes, turbulence and controllers on, the shared slow turbulence
off) for 600 s per run and compares each turbine's mean wind over 300–600 s with FLORIS's steady one, with and
without the wake-added turbulence: the largest difference per run and the mean difference per turbine.
"""

from __future__ import annotations

import argparse
import tempfile

import numpy as np

from plant_sim.farm import FarmBatch
from plant_sim.farm.floris_wakes import floris_model
from plant_sim.farm.operating_curve import rated_curve
from plant_sim.farm.wakes import plant_wake_tables, steady_winds
from plant_sim.farm.wind import CURVE_WINDS, static_power_curve, static_row_winds
from wwcore.scenario.farm import FarmPlant
from wwcore.scenario.wind import WindSpec
from wwcore.turbine_params import BENCHMARK


def running(speeds: list[float], ti: float, runs: int, seed: int, seconds: float = 600.0) -> None:
    """The running plant's long-mean winds against FLORIS (module docstring)."""
    wind_of = {u: WindSpec(mean=[(0.0, u)], turbulence_intensity=ti) for u in speeds}
    with tempfile.TemporaryDirectory() as cache:
        for u in speeds:
            for case in (1, 2):
                for added in (True, False):
                    spec = FarmPlant(wind_case=case, wake_model="gauss", coherent_ti=0.0, wake_added_turbulence=added)
                    fm = floris_model(spec.resolved_layout(), "gauss", BENCHMARK, [spec.direction_deg], [u], ti)
                    fm.run()
                    plant = FarmBatch(
                        spec, wind_of[u], [], seed=seed, runs=tuple(range(runs)), duration_s=seconds,
                        wake_cache_dir=cache,
                    )  # fmt: skip
                    total, count = 0.0, 0
                    for k in range(round(seconds / plant.dt)):
                        frame = plant.measure()
                        plant.control(None)
                        if frame.sample and (k + 1) * plant.dt > seconds / 2:
                            total, count = total + plant.truth()["row_wind"].reshape(runs, 9), count + 1
                        plant.advance()
                    diff = total / count - fm.turbine_average_velocities[0]
                    print(
                        f"U {u:g} m/s, case {case}, wake-added turbulence {added}: max |plant − FLORIS| per run "
                        f"{np.round(np.abs(diff).max(axis=1), 3)} m/s; mean per turbine {np.round(diff.mean(0), 3)}",
                        flush=True,
                    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speeds", default=None, help="free-stream speeds, m/s (default 8,11,14; --running: 9)")
    parser.add_argument("--ti", type=float, default=0.10, help="ambient turbulence intensity")
    parser.add_argument("--running", action="store_true", help="run the plant (see the module docstring)")
    parser.add_argument("--runs", type=int, default=4, help="--running: Monte Carlo runs")
    parser.add_argument("--seed", type=int, default=202, help="--running: master seed")
    args = parser.parse_args()
    speeds = [float(v) for v in (args.speeds or ("9" if args.running else "8,11,14")).split(",")]
    if args.running:
        running(speeds, args.ti, args.runs, args.seed)
        return
    winds, power, _ = rated_curve(BENCHMARK)
    with tempfile.TemporaryDirectory() as cache:
        for case in (1, 2):
            rows_spec = FarmPlant(wind_case=case)
            print(f"\n### Wind case {case} ({rows_spec.direction_deg:g} deg), TI {args.ti:g}\n")
            header = "| U (m/s) | model | " + " | ".join(f"wt{t}" for t in range(1, 10)) + " | farm MW |"
            print(header)
            print("|" + "---|" * (header.count("|") - 1))
            for u in speeds:
                lines = {}
                v_rows = static_row_winds(rows_spec, BENCHMARK, np.array([u]))[0][rows_spec.row_of()]
                p_rows = np.interp(v_rows, CURVE_WINDS, static_power_curve(BENCHMARK)).sum()
                lines["rows (paper)"] = (v_rows, p_rows)
                for model in ("gauss", "jensen"):
                    spec = FarmPlant(wind_case=case, wake_model=model)
                    fm = floris_model(spec.resolved_layout(), model, BENCHMARK, [spec.direction_deg], [u], args.ti)
                    fm.run()
                    lines[f"FLORIS {model}"] = (fm.turbine_average_velocities[0], fm.get_farm_power()[0])
                    tables = plant_wake_tables(spec, WindSpec(turbulence_intensity=args.ti), BENCHMARK, cache)
                    v, _ = steady_winds(tables, spec.direction_deg, np.full((1, 9), u), BENCHMARK)
                    lines[f"plant {model}"] = (v[0], np.interp(v[0], winds, power).sum())
                for name, (v, p) in lines.items():
                    cells = " | ".join(f"{x:.2f}" for x in v)
                    print(f"| {u:g} | {name} | {cells} | {p / 1e6:.2f} |")


if __name__ == "__main__":
    main()
