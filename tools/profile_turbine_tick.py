"""Where one turbine run's tick goes: ``windwarden bench turbine``'s plant and supervisor for ``ftwse-2012`` on the
compiled backend, warmed up, timed unprofiled over ``--ticks`` ticks (µs a tick, wall and CPU time), then the same
number of ticks under cProfile, sorted by own time (how docs/cluster.md's "What is left" profiles were taken; the
profiler slows Python calls more than kernels, so read shares and call counts per tick, not microseconds).
``--calls N`` first times the plant's three calls of the contract by the CPU clock read around each (``measure``,
``control``, ``advance``; best of N blocks of 1 000 ticks, the clock's own reads included).

    .venv/bin/python tools/profile_turbine_tick.py --rows 1 --ticks 3000
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time

import numpy as np

from windwarden.bench import _Stepper, turbine_pair


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rows", type=int, default=1, help="runs stepped side by side")
    parser.add_argument("--warmup", type=int, default=500, help="ticks run before timing")
    parser.add_argument("--ticks", type=int, default=2000, help="ticks timed, then profiled")
    parser.add_argument("--top", type=int, default=35, help="lines of the profile printed")
    parser.add_argument("--backend", choices=("numba", "numpy"), default="numba")
    parser.add_argument("--calls", type=int, default=0, help="blocks of 1 000 ticks timing the plant's calls")
    args = parser.parse_args()
    plant, supervisor = turbine_pair("ftwse-2012", args.rows, 0, False, args.backend)
    stepper = _Stepper(plant, supervisor)
    stepper.run(args.warmup)
    start, cpu = time.perf_counter(), time.process_time()
    stepper.run(args.ticks)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    print(f"unprofiled: {1e6 * wall / args.ticks:.1f} µs a tick, {1e6 * cpu / args.ticks:.1f} µs of CPU time a tick")
    if args.calls:
        plant_calls(stepper, args.calls)
    profile = cProfile.Profile()
    profile.enable()
    stepper.run(args.ticks)
    profile.disable()
    stats = pstats.Stats(profile)
    print(f"Python calls a tick: {stats.total_calls / args.ticks:.1f}")
    stats.sort_stats("tottime").print_stats(args.top)


def plant_calls(stepper: _Stepper, blocks: int) -> None:
    """The plant's ``measure``, ``control`` and ``advance``, µs of CPU a call: best of ``blocks`` blocks of 1 000
    ticks, the stepper's clock the process's CPU clock (its reads, about 0.5 µs a call here, included)."""
    stepper.clock = time.process_time
    best = np.full(len(stepper.calls), np.inf)
    for _ in range(blocks):
        stepper.spent[:] = 0.0
        stepper.run(1000)
        best = np.minimum(best, 1e3 * stepper.spent)
    stepper.clock = time.perf_counter
    plant = {name: value for name, value in zip(stepper.calls, best, strict=True) if name != "supervise"}
    print("the plant's calls, µs of CPU a call (best of blocks):", ", ".join(f"{k} {v:.2f}" for k, v in plant.items()))


if __name__ == "__main__":
    main()
