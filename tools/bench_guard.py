"""What the live checks cost per tick, against the work of the tick, measured in one run (ratios, not timings).

For each plant kind, the live reference loop (the kind's object, ``windwarden.kinds``) runs for ``--ticks`` ticks;
every tick it times, with ``perf_counter_ns``, interleaved so that the machine's load weighs on all of them alike:

* the plant's work (``measure``, ``control``, ``advance``) and the supervisor's ``step``;
* the plant's check of the refs message (``guard.RefsGuard.judge``: the tick window, the repeat check and the
  vectorised range check of ``wwcore.wire``);
* the supervisor's decision on the sensor frame (``guard.FrameSequencer.decide``).

It prints the medians in µs and each check as a share of the work it guards. A gap's bridge costs, per missing tick,
about what a step costs (the observers advance); that is measured by ``tools/bench_drops.py``'s runs, not here.

``--scan SCENARIO DURATION`` instead runs a scenario's batch loop and counts the supervisor's own refs the plant
would refuse (the ranges must never refuse a genuine reference; lockstep runs count them as ``dropped``, too).

    .venv/bin/python tools/bench_guard.py --ticks 3000
    .venv/bin/python tools/bench_guard.py --scan ftwse-2012 800 --scan farm-case1 500
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from windwarden.kinds import RunInfo, kind_for
from windwarden.live.guard import FrameSequencer, RefsGuard
from wwcore.scenario import load_scenario
from wwcore.wire import DropCounter

SCENARIOS = {"turbine": "demo", "hydro": "hydro-fig9", "farm": "farm-case1"}


def bench(kind: str, ticks: int) -> dict[str, float]:
    scenario = load_scenario(SCENARIOS[kind])
    plant_kind = kind_for(kind)
    plant = plant_kind.make_plant(scenario, 0)
    turbines = plant_kind.turbines(plant)
    supervisor = plant_kind.make_supervisor(RunInfo.of(scenario, turbines, plant.dt))
    guard = RefsGuard(plant_kind.refs, 10, DropCounter())
    sequencer = FrameSequencer(50, DropCounter(), lambda run: None, lambda tick: False)
    sequencer.start(0)
    clock = time.perf_counter_ns
    cost = {name: np.zeros(ticks) for name in ("plant", "supervisor", "refs check", "frame decision")}
    refs_records = None
    for k in range(ticks):
        t0 = clock()
        frame = plant.measure()
        plant.control(plant_kind.refs_from_records(refs_records) if refs_records is not None else None)
        t1 = clock()
        records = plant_kind.frame_records(frame, turbines)
        t2 = clock()
        decision, _ = sequencer.decide(records)
        t3 = clock()
        sequencer.stepped(k)
        refs = supervisor.step(plant_kind.frame_from_records(records))
        t4 = clock()
        out = plant_kind.refs_records(refs, supervisor, turbines)
        out = np.ascontiguousarray(out)
        t5 = clock()
        verdict = guard.judge(int(out["tick"][0]), out, k + 1)
        t6 = clock()
        plant.advance()
        t7 = clock()
        assert decision == FrameSequencer.STEP and verdict == "take", (decision, verdict)
        refs_records = out
        cost["plant"][k] = (t1 - t0) + (t7 - t6)
        cost["frame decision"][k] = t3 - t2
        cost["supervisor"][k] = t4 - t3
        cost["refs check"][k] = t6 - t5
    return {name: float(np.median(v[ticks // 10 :])) / 1e3 for name, v in cost.items()}


def scan(name: str, duration: float, seed: int = 7) -> dict[str, int]:
    """How many of the supervisor's refs, scenario ``name`` cut to ``duration`` s, the range check refuses."""
    scenario = load_scenario(name)
    if duration < scenario.duration_s:
        faults = [f for f in scenario.faults if f.start_s < duration]
        scenario = scenario.model_copy(update={"duration_s": duration, "faults": faults})
    plant_kind = kind_for(scenario.plant.kind)
    plant = plant_kind.make_plant(scenario, seed)
    turbines = plant_kind.turbines(plant)
    supervisor = plant_kind.make_supervisor(RunInfo.of(scenario, turbines, plant.dt))
    refused: dict[str, int] = {}
    refs = None
    for _ in range(round(scenario.duration_s / plant.dt)):
        frame = plant.measure()
        plant.control(refs)
        refs = supervisor.step(frame)
        reason = plant_kind.refs.refusal(plant_kind.refs_records(refs, supervisor, turbines))
        if reason is not None:
            refused[reason] = refused.get(reason, 0) + 1
        plant.advance()
    return refused


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--ticks", type=int, default=3000)
    parser.add_argument("--kind", choices=list(SCENARIOS), action="append")
    parser.add_argument("--scan", nargs=2, action="append", metavar=("SCENARIO", "DURATION"))
    args = parser.parse_args()
    for name, duration in args.scan or []:
        print(f"{name} ({float(duration):g} s): genuine refs refused {scan(name, float(duration)) or 'none'}")
    if args.scan:
        return
    for kind in args.kind or list(SCENARIOS):
        us = bench(kind, args.ticks)
        print(
            f"{kind:8s} plant {us['plant']:8.1f} µs  supervisor {us['supervisor']:8.1f} µs  "
            f"refs check {us['refs check']:6.1f} µs ({100 * us['refs check'] / us['plant']:.1f} % of the plant's "
            f"tick)  frame decision {us['frame decision']:6.1f} µs "
            f"({100 * us['frame decision'] / us['supervisor']:.1f} % of the step)"
        )


if __name__ == "__main__":
    main()
