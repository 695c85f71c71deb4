"""One fault window of a turbine scenario, tick by tick, beside its fault-free twin (how docs/turbine.md's "The
random set's worst windows" were diagnosed).

The runs are simulated as ``windwarden eval`` simulates one chunk (the same batch, so with a scenario's eval seed and
run count the same numbers: a random set's ``scorecard.json`` gives both per scenario), and the twin is forked at the
window's first tick as ``windwarden eval`` forks it (``parallel.Branch``). Printed: per run, the window's FTE RMSE,
its twin's and their ratio, the true wind's mean, and the supervisor's events in the window; with ``--ticks RUN``,
every ``--every`` ticks of that run from ``--before`` seconds before the start: the true wind, the FTE and the
twin's, the observer that fed each, the flagged (F) and suspected (s) speed sensors in r1 r2 g1 g2 order, and the
filtered aerodynamic torque of the observer in use and of the twin's.

    .venv/bin/python tools/trace_fault_window.py out/rnd/scenarios/random-turbine-3071826478.toml \\
        --seed 50873052 --runs 4 --window 7 --ticks 2 --every 5
"""

from __future__ import annotations

import argparse
from functools import partial

import numpy as np

from plant_sim.turbine import TurbineBatch
from service.turbine.supervisor import TurbineSupervisor
from windwarden.evaluation.parallel import Branch
from windwarden.evaluation.scoring import windows_from_faults
from windwarden.evaluation.turbine import batch_and_supervisor
from wwcore.channels import SPEED_SENSORS, TARGET_INDEX
from wwcore.scenario import load_scenario
from wwcore.stepping import run_ticks

SPEED_COLUMNS = [TARGET_INDEX[s] for s in SPEED_SENSORS]
KEYS = ("t", "truth", "fte", "selected", "flags", "torque")


def _recorder(plant: TurbineBatch, supervisor: TurbineSupervisor, first_k: int):
    """A ``stepped`` hook that appends this tick's values from tick ``first_k`` on, and the lists it fills."""
    log: dict[str, list] = {k: [] for k in KEYS}
    rows = np.arange(plant.n)

    def record(k: int, frame, refs) -> None:
        if k < first_k:
            return
        est, diagnosis = supervisor.estimates, supervisor.diagnosis
        suspect = diagnosis.faulty if diagnosis.suspect is None else diagnosis.suspect
        code = np.where(diagnosis.faulty[:, SPEED_COLUMNS], 2, np.where(suspect[:, SPEED_COLUMNS], 1, 0))
        log["t"].append(frame.t)
        log["truth"].append(plant.true_rotor_wind().copy())
        log["fte"].append(est.wind.copy())
        log["selected"].append(est.selected.copy())
        log["flags"].append(code)
        log["torque"].append(supervisor.estimator.recovery.filtered[rows, np.maximum(est.selected, 0)].copy())

    return log, record


def trace(path: str, seed: int, runs: int, window: int, before_s: float, after_s: float) -> dict:
    scenario = load_scenario(path)
    plant, supervisor = batch_and_supervisor(
        scenario, seed, list(range(runs)), options=dict(scenario.supervisor.params)
    )
    spans = windows_from_faults(scenario.faults, scenario.duration_s)
    if not 0 <= window < len(spans):
        raise SystemExit(f"--window must be 0 … {len(spans) - 1} (the scenario's fault windows)")
    w = spans[window]
    first, end = round(w.start_s / plant.dt), round(w.end_s / plant.dt)
    last = min(end + round(after_s / plant.dt), round(scenario.duration_s / plant.dt))

    def twin(refs) -> dict:
        plant.end_all_faults()
        log, record = _recorder(plant, supervisor, first)
        run_ticks(plant, supervisor, range(first, last), refs, stepped=record)
        return {k: np.array(v) for k, v in log.items()}

    log, record = _recorder(plant, supervisor, first - round(before_s / plant.dt))
    branches: list[Branch] = []

    def fork(k: int, refs) -> None:
        if k == first:
            branches.append(Branch(partial(twin, refs)))

    run_ticks(plant, supervisor, range(last), before=fork, stepped=record)
    events = [e for e in supervisor.drain_events() if w.start_s - before_s <= e.t <= w.end_s + after_s]
    return {
        "window": w,
        "run": {k: np.array(v) for k, v in log.items()},
        "twin": branches[0].result(),
        "events": events,
        "names": supervisor.estimator.names,
        "first": first,
        "end": end,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenario", help="a turbine scenario file")
    ap.add_argument("--seed", type=int, required=True, help="the eval seed")
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--window", type=int, required=True, help="the fault window's index (0 = the first)")
    ap.add_argument("--ticks", type=int, help="print this run's ticks")
    ap.add_argument("--every", type=int, default=1, help="ticks between printed lines")
    ap.add_argument("--before", type=float, default=0.5, help="s before the window's start to print")
    ap.add_argument("--after", type=float, default=3.0, help="s after its end to simulate")
    args = ap.parse_args(argv)
    out = trace(args.scenario, args.seed, args.runs, args.window, args.before, args.after)
    run, twin, names, w = out["run"], out["twin"], out["names"], out["window"]
    dt = 0.01
    offset = int(np.searchsorted(run["t"], twin["t"][0] - 0.5 * dt))
    inside = np.round(twin["t"] / dt) < out["end"]
    err = run["fte"][offset : offset + len(twin["t"])] - run["truth"][offset : offset + len(twin["t"])]
    err_twin = twin["fte"] - twin["truth"]
    print(f"{w.name}: {w.start_s} – {w.end_s} s")
    for r in range(err.shape[1]):
        rmse, rmse_twin = (float(np.sqrt(np.mean(e[inside, r] ** 2))) for e in (err, err_twin))
        wind = float(twin["truth"][inside, r].mean())
        print(
            f"run {r}: FTE RMSE {rmse:.3f} m/s, twin {rmse_twin:.3f}, ratio {rmse / rmse_twin:.3f}, wind {wind:.2f} m/s"
        )
    pooled = np.sqrt(np.mean(err[inside] ** 2) / np.mean(err_twin[inside] ** 2))
    print(f"pooled ratio {pooled:.4f}")
    for e in out["events"]:
        print(f"  {e.t:.2f} run {e.run} {e.type.value} {e.target or ''} {e.detail or ''}")
    if args.ticks is not None:
        r = args.ticks
        print("       t   wind    FTE   twin  observer    twin's  r1r2g1g2  torque kN m  twin's")
        for i in range(0, len(run["t"]), args.every):
            j = i - offset
            if 0 <= j < len(twin["t"]):
                twin_fte, twin_observer = f"{twin['fte'][j, r]:6.2f}", names[twin["selected"][j, r]]
                twin_torque = f"{twin['torque'][j, r] / 1e3:7.0f}"
            else:
                twin_fte, twin_observer, twin_torque = "", "", ""
            flags = "".join(".sF"[c] for c in run["flags"][i, r])
            print(
                f"{run['t'][i]:8.2f} {run['truth'][i, r]:6.2f} {run['fte'][i, r]:6.2f} {twin_fte:>6}"
                f" {names[run['selected'][i, r]]:>9} {twin_observer:>9}  {flags:8}  {run['torque'][i, r] / 1e3:11.0f}"
                f"  {twin_torque:>6}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
