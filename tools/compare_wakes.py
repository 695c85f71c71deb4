"""The FLORIS comparison table of docs/farm.md: steady per-turbine winds and farm power of the 3 × 3, both wind cases.

    nice -n 10 .venv/bin/python tools/compare_wakes.py [--speeds 8,11,14] [--ti 0.10]

For each wind case and free-stream speed it prints, per turbine, the steady wind of the row model (``wake_model =
"rows"``, the paper's), of direct FLORIS 4.7 runs (Gauss and Jensen, the benchmark turbine's curves) and of the
farm plant's FLORIS tables (the plant's steady state, ``plant_sim.farm.wakes.steady_winds``), then the farm power
of each. The row model's C_T is momentum theory on the benchmark's C_p; FLORIS's and the tables' is
``wwcore.thrust``'s. Nothing here is random.
"""

from __future__ import annotations

import argparse
import tempfile

import numpy as np

from plant_sim.farm.floris_wakes import floris_model
from plant_sim.farm.operating_curve import rated_curve
from plant_sim.farm.wakes import plant_wake_tables, steady_winds
from plant_sim.farm.wind import CURVE_WINDS, static_power_curve, static_row_winds
from wwcore.scenario.farm import FarmPlant
from wwcore.scenario.wind import WindSpec
from wwcore.turbine_params import BENCHMARK


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speeds", default="8,11,14", help="free-stream speeds, m/s")
    parser.add_argument("--ti", type=float, default=0.10, help="ambient turbulence intensity")
    args = parser.parse_args()
    speeds = [float(v) for v in args.speeds.split(",")]
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
