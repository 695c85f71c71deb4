"""What the live display costs a node per tick, in one process, without the network: the supervisor's or the
plant's ``LiveRecording`` fed the frames of a real run of a farm scenario (Horns Rev 1's 80 turbines by default),
``display_every`` = 10, for N simulated seconds, sinking to a temporary ``.rrd`` file.

Reports the time of the rows of a display tick (with the per-turbine status the supervisor builds for panels
that read it), of ``pump()`` per tick, their sum per tick as a share of the 10 ms tick, and the process's CPU time
per simulated second (the file sink's threads included). Run back to back on two versions of the display, it ranks
them on a loaded machine too (both see the same load), where ``tools/bench_live.py``'s latencies follow the load.

    .venv/bin/python tools/bench_display.py --role supervisor
    .venv/bin/python tools/bench_display.py --role plant --scenario farm-case1 --seconds 30
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from dashboards.live import LiveRecording
from windwarden.kinds import RunInfo, kind_for
from wwcore.scenario import load_scenario

DISPLAY_EVERY = 10
DISTINCT_FRAMES = 400  # frames of the real run, replayed with new ticks and times


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--role", choices=("supervisor", "plant"), default="supervisor")
    parser.add_argument("--scenario", default="farm-hornsrev1", help="a farm scenario")
    parser.add_argument("--seconds", type=float, default=60.0, help="simulated seconds at 100 ticks per second")
    args = parser.parse_args()
    scenario = load_scenario(args.scenario)
    kind = kind_for(scenario.plant.kind)
    plant = kind.make_plant(scenario, 1)
    turbines = kind.turbines(plant)
    info = RunInfo.of(scenario, turbines, float(plant.dt), "bench", "realtime", 1.0, run_key=1)
    supervisor = kind.make_supervisor(info)
    frames = []
    for k in range(DISTINCT_FRAMES):
        frame = plant.measure()
        records = kind.frame_records(frame, turbines)
        refs = supervisor.step(kind.frame_from_records(records))
        plant.control(None)
        truth = kind.truth_records(plant, frame, turbines) if k % DISPLAY_EVERY == 0 else None
        plant.advance()
        frames.append((records.copy(), kind.refs_records(refs, supervisor, turbines).copy(), truth))
    with tempfile.TemporaryDirectory() as folder:
        display = LiveRecording(
            scenario.plant.kind,
            args.role,
            "bench-display",
            path=str(Path(folder) / "display.rrd"),
            n_turbines=len(turbines),
            plant_section=scenario.plant,
            display_every=DISPLAY_EVERY,
        )
        rows, pumps = [], []
        ticks = round(args.seconds / float(plant.dt))
        cpu = time.process_time()
        for k in range(ticks):
            records, out, truth = frames[k % DISTINCT_FRAMES]
            records = records.copy()
            records["tick"], records["t"] = k, k * float(plant.dt)
            started = time.perf_counter()
            if k % DISPLAY_EVERY == 0:
                if args.role == "plant":
                    display.plant_rows(records, truth)
                else:
                    display.supervisor_rows(records, out, lambda out=out: kind.status(supervisor, out, turbines))
                rows.append(time.perf_counter() - started)
                started = time.perf_counter()
            display.pump()
            pumps.append(time.perf_counter() - started)
        cpu = time.process_time() - cpu
        counters = display.counters()
        display.close()
    per_tick = np.array(pumps) * 1e3
    per_tick[::DISPLAY_EVERY] += np.array(rows) * 1e3
    warm = slice(DISPLAY_EVERY * 10, None)  # the first second declares the series (static, once)

    def spread(values: np.ndarray) -> dict[str, float]:
        return {q: round(float(np.percentile(values, p)), 3) for q, p in (("p50", 50), ("p99", 99))} | {
            "max": round(float(values.max()), 3)
        }

    report = {
        "scenario": args.scenario,
        "role": args.role,
        "turbines": len(turbines),
        "ticks": ticks,
        "rows_per_display_tick_ms": spread(np.array(rows[10:]) * 1e3),
        "pump_per_tick_ms": spread(np.array(pumps)[warm] * 1e3),
        "display_per_tick_ms": spread(per_tick[warm]),
        "display_per_tick_p99_share_of_10ms": round(float(np.percentile(per_tick[warm], 99)) / 10.0, 3),
        "cpu_ms_per_simulated_s": round(1e3 * cpu / args.seconds, 1),
        "counters": counters,
    }
    print(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
