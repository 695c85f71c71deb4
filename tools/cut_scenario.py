"""A short copy of a shipped scenario, to check that a refactoring changes no scorecard (``CHANGELOG.md``).

The copy is the same file cut to ``--duration`` seconds (400 by default), named ``NAME-short``: its faults keep their
order and targets and are packed 45 s apart from 80 s, each at most 30 s long (plus its ramps), and those that no
longer fit are dropped. Both sides of a before/after comparison must run the same copy:

    python tools/cut_scenario.py benchmark-turbine --out /tmp/short
    windwarden eval /tmp/short/benchmark-turbine-short.toml --runs 2 --seed 7 --workers 1 --no-plots --out …
"""

from __future__ import annotations

import argparse
import tomllib
from pathlib import Path

import tomli_w

from wwcore.scenario import load_scenario, shipped_scenarios

FIRST_S = 80.0  # s, start of the first fault (past every kind's warm-up)
SPACING_S = 45.0  # s between two fault starts
LONGEST_S = 30.0  # s, longest fault window (ramps excluded)


def cut(name: str, duration_s: float) -> dict:
    data = tomllib.loads(shipped_scenarios()[name].read_text())
    data["name"] = f"{name}-short"
    data["duration_s"] = duration_s
    starts = sorted({f["start_s"] for f in data.get("faults", [])})
    kept = []
    for fault in data.get("faults", []):
        fault = dict(fault)
        start = FIRST_S + SPACING_S * starts.index(fault["start_s"])
        ramps = 2 * fault.get("ramp_s", 0.0)
        if fault.get("end_s") is not None:
            fault["end_s"] = min(start + min(fault["end_s"] - fault["start_s"], LONGEST_S + ramps), duration_s)
        fault["start_s"] = start
        if start + LONGEST_S + ramps <= duration_s:
            kept.append(fault)
    if "faults" in data:
        data["faults"] = kept
    return data


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="+", help="shipped scenario names")
    parser.add_argument("--duration", type=float, default=400.0, help="s (default 400)")
    parser.add_argument("--out", type=Path, required=True, help="folder for the NAME-short.toml files")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for name in args.names:
        path = args.out / f"{name}-short.toml"
        path.write_text(tomli_w.dumps(cut(name, args.duration)))
        scenario = load_scenario(path)  # refuses a copy that is not a valid scenario
        print(f"{path}: {len(scenario.faults)} faults, {scenario.duration_s:g} s")


if __name__ == "__main__":
    main()
