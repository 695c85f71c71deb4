"""The fault-tolerant wind estimate through speed-sensor faults, over a wind × sensor × kind × size grid.

Per cell (one fault, or one simultaneous pair, at one mean wind; ``runs`` windows with fresh wind, noise and
start time each): detected %, first-flag isolated %, mean delay, detections per window, flaps per window (a flag
on the fault's targets dropping while the fault is on) mean/max, windows with a wrong target flagged %, ends
recognised % and worst end delay, and the FTE's RMSE over its fault-free twin's (mean and worst over the runs).
Definitions: ``windwarden/evaluation/fte_faults.py``. Sizes: offsets in σ of the sensor's noise, drifts in σ/s,
gains as factors, fixed values as a fraction of the operating speed at the mean wind.

    nice -n 10 .venv/bin/python tools/fte_through_faults.py --seed 7301 --runs 4
    .venv/bin/python tools/fte_through_faults.py --winds 6.5 --sensors r1 --kinds offset --runs 2 --json out.json
"""

from __future__ import annotations

import argparse
import json
import sys
import tomllib
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict

from windwarden.evaluation import fte_faults as ff


def _floats(text: str) -> tuple[float, ...]:
    return tuple(float(v) for v in text.split(",") if v)


def print_groups(records: list[dict]) -> None:
    """The summary per wind and sensor group (``fte_faults.summarise_groups``)."""
    print(
        f"\n{'wind':>5} {'group':<10} {'windows':>7} {'det%':>5} {'iso1%':>5} {'flap%':>5} {'fmax':>4} "
        f"{'multi%':>6} {'FTE/twin':>8} {'worst':>6} {'>1.1':>4}"
    )
    for g in ff.summarise_groups(records):
        print(
            f"{g['wind']:>5g} {g['group']:<10} {g['windows']:>7d} {g['detected_pct']:>5.0f} {g['isolated_pct']:>5.0f} "
            f"{g['flapping_pct']:>5.0f} {g['flaps_max']:>4d} {g['multiple_detections_pct']:>6.0f} "
            f"{g['ratio_mean']:>8.3f} {g['ratio_max']:>6.3f} {g['over_threshold']:>4d}"
        )


def _no_progress(seconds: float) -> None:
    """``simulate_wind``'s progress hook: this tool reports per wind instead."""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--winds", type=_floats, default=ff.DEFAULT_WINDS, help="mean winds, m/s (comma-separated)")
    ap.add_argument("--sensors", default="r1,r2,g1,g2", help="speed sensors of the single faults")
    ap.add_argument("--kinds", default=",".join(ff.DEFAULT_SIZES), help="kinds of the single faults")
    ap.add_argument("--no-pairs", action="store_true", help="leave out the double faults")
    ap.add_argument("--sizes", default="", help="override the sizes of the kinds, e.g. 'offset=5,-5;gain=1.05'")
    ap.add_argument("--runs", type=int, default=4, help="windows per cell")
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--window", type=float, default=100.0, help="fault window length, s")
    ap.add_argument("--detector")
    ap.add_argument("--estimator")
    ap.add_argument("--params", default="", help="supervisor options as TOML, e.g. 'power_speed = false'")
    ap.add_argument("--noise-convention", default="sigma", choices=("sigma", "variance"))
    ap.add_argument("--workers", type=int, default=2, help="processes, one mean wind each")
    ap.add_argument("--json", help="write every window's figures to this file")
    args = ap.parse_args(argv)
    kinds = [k for k in args.kinds.split(",") if k]
    unknown = [k for k in kinds if k not in ff.DEFAULT_SIZES]
    if unknown or args.runs < 1:
        ap.error(f"unknown kinds {unknown}" if unknown else "--runs must be ≥ 1")
    sizes = {k: ff.DEFAULT_SIZES[k] for k in kinds}
    for part in (p for p in args.sizes.split(";") if p):
        kind, values = part.split("=")
        sizes[kind] = tuple(float(v) for v in values.split(","))
    cells = ff.grid(
        [s for s in args.sensors.split(",") if s],
        sizes,
        () if args.no_pairs else ff.DEFAULT_PAIRS,
    )
    options = tomllib.loads(args.params)
    winds = list(args.winds)
    wind_args = [
        (cells, w, args.seed, args.window, args.detector, args.estimator, options, args.noise_convention) for w in winds
    ]
    run_ids = list(range(args.runs))
    with ProcessPoolExecutor(max(1, min(args.workers, len(winds)))) as pool:  # one task per mean wind
        futures = [pool.submit(ff.simulate_wind, run_ids, _no_progress, *a) for a in wind_args]
        results = []
        for w, future in zip(winds, futures, strict=True):
            results.append(future.result())
            print(f"wind {w:g} m/s done", file=sys.stderr, flush=True)
    print(f"seed {args.seed}, {args.runs} windows of {args.window:g} s per cell, options {options or '{}'}")
    header = (
        f"{'wind':>5} {'fault':<30} {'det%':>5} {'iso1%':>5} {'delay':>6} {'onsets':>6} {'flaps':>6} {'fmax':>4} "
        f"{'wrong%':>6} {'end%':>5} {'endmax':>6} {'FTE/twin':>8} {'worst':>6}"
    )
    print(header)
    summaries = [s for r in results for s in ff.summarise(r)]
    for s in summaries:
        delay = "-" if s.delay_s_mean is None else f"{s.delay_s_mean:.3f}"
        end = "-" if s.end_recognised_pct is None else f"{s.end_recognised_pct:.0f}"
        end_max = "-" if s.end_delay_s_max is None else f"{s.end_delay_s_max:.2f}"
        print(
            f"{s.wind:>5g} {s.label:<30} {s.detected_pct:>5.0f} {s.isolated_pct:>5.0f} {delay:>6} "
            f"{s.detections_mean:>6.2f} {s.flaps_mean:>6.2f} {s.flaps_max:>4d} {s.wrong_pct:>6.0f} {end:>5} "
            f"{end_max:>6} {s.ratio_mean:>8.3f} {s.ratio_max:>6.3f}"
        )
    records = [{"wind": r.wind, "label": r.cells[w.cell].label, **asdict(w)} for r in results for w in r.windows]
    print_groups(records)
    alarms = sum(r.twin_false_alarms for r in results)
    observed = sum(r.twin_observed_s for r in results)
    detected = [s for s in summaries if s.detected_pct > 0]
    print(
        f"twins: {alarms} false alarms in {observed:.0f} s ({1000 * alarms / observed:.3f} per 1000 s); "
        f"detected cells: {len(detected)}/{len(summaries)}, worst FTE/twin among them "
        f"{max((s.ratio_max for s in detected), default=float('nan')):.3f}, "
        f"most flaps {max((s.flaps_max for s in summaries), default=0)}"
    )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(
                {
                    "args": {k: v for k, v in vars(args).items() if k != "json"},
                    "cells": [asdict(s) for s in summaries],
                    "windows": records,
                    "twin_false_alarms": alarms,
                    "twin_observed_s": observed,
                },
                f,
                indent=1,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
