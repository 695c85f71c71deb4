"""False alarms from lost sensor frames: lockstep, gaps bridged (what the supervisor does), gaps fed as consecutive.

For each scenario and seed, three runs of the live reference loop (``windwarden.live.batch.run_batch``, the step
contract without a network: lockstep equals it bit for bit): no frame lost; frames lost at random (bursts of 1 to
``--longest`` ticks starting at random, ``--fraction`` of the ticks on average; the drop pattern has its own seed,
``1000 + seed``) with each gap bridged (``guard.bridge_gap``); the same drops with the frames after a gap fed as if
consecutive; with ``--step``, the same drops with the whole supervisor (detectors included) stepped on the
interpolated frames. It prints, per run, the false alarms (onsets outside fault windows) and the detected/isolated
share of the faults.

    .venv/bin/python tools/bench_drops.py demo --seeds 101 102 103
    .venv/bin/python tools/bench_drops.py turbine-fault-free --duration 600 --seeds 101
    .venv/bin/python tools/bench_drops.py hydro-noise farm-fault-free-case1 --duration 300 --seeds 101
"""

from __future__ import annotations

import argparse

import numpy as np

from windwarden.live.batch import random_drops, run_batch
from wwcore.scenario import load_scenario

TICK_S = 0.01  # s, every plant kind's sample time (wwcore.turbine_params, wwcore.hydro_params)


def summary(card: dict) -> str:
    raw = card.get("false_alarms") or card["metrics"]["detection"]["false_alarms"]
    faults = card["faults"]
    detected = np.mean([f["detected_pct"] for f in faults]) if faults else float("nan")
    isolated = np.mean([f["isolated_pct"] for f in faults]) if faults else float("nan")
    return f"false alarms {raw['count']:3d}  detected {detected:5.1f} %  isolated {isolated:5.1f} %"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("scenarios", nargs="+")
    parser.add_argument("--seeds", type=int, nargs="+", default=[101])
    parser.add_argument("--duration", type=float, default=None, help="s, cut each scenario to this")
    parser.add_argument("--fraction", type=float, default=0.05, help="share of the frames lost")
    parser.add_argument("--longest", type=int, default=10, help="ticks, the longest burst of lost frames")
    parser.add_argument("--step", action="store_true", help="also step the detectors on interpolated frames")
    args = parser.parse_args()
    for name in args.scenarios:
        scn = load_scenario(name)
        if args.duration is not None and args.duration < scn.duration_s:
            faults = [f for f in scn.faults if f.start_s < args.duration]
            scn = scn.model_copy(update={"duration_s": args.duration, "faults": faults})
        for seed in args.seeds:
            lockstep = run_batch(scn, seed).scorecard
            n = round(scn.duration_s / TICK_S)
            drop = random_drops(n, args.fraction, args.longest, 1000 + seed)
            bridged = run_batch(scn, seed, drop).scorecard
            runs = [("lockstep", lockstep), ("bridged", bridged)]
            runs.append(("consecutive", run_batch(scn, seed, drop, gaps="consecutive").scorecard))
            if args.step:
                runs.append(("all stepped", run_batch(scn, seed, drop, gaps="step").scorecard))
            head = f"{name} seed {seed} ({scn.duration_s:g} s, {100 * drop.mean():.1f} % of frames lost)"
            print(head, flush=True)
            for label, card in runs:
                print(f"  {label:12s} {summary(card)}", flush=True)


if __name__ == "__main__":
    main()
