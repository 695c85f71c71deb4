"""Detectability: detection %, isolation % (first flag) and delay against fault size, per fault type.

For one fault type (``fault_types``) and a grid of sizes, ``sweep`` builds ``layouts`` random scenarios in memory.
Each holds one short window of every size of the grid, in a random order, at random times with quiet time
between them (``fault_types.place_windows``); each window hits a target drawn uniformly (sensor, blade,
turbine, actuator) with a random sign. The turbine and hydro hold a mean wind drawn uniformly over the plant
kind's operating range over each window; a layout visits its drawn winds in ascending or descending order, so
the mean wind moves in small steps, while the random order of the sizes keeps every size's wind uniform. The
farm holds one drawn wind and wind case per layout, since a wind change reaches the back rows minutes after the
mast. Each layout is scored by the plant kind's own evaluator (``windwarden eval``'s batch mode,
``run_chunks``, the scoring policy of ``scoring.py``) over ``ceil(runs / layouts)`` Monte Carlo runs, so each
size is scored on ``layouts`` fault times and winds times that many runs. The figures are those of the
scorecard, pooled per size over layouts.

The sizes at which 50 % and 95 % are detected (and isolated) come from ``detectability_stats``: a probit curve
fitted by maximum likelihood, with a layout-bootstrap interval, beside the measured curve's crossings.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from windwarden.evaluation.detectability_stats import clopper_pearson, threshold_sizes
from windwarden.evaluation.fault_types import (
    FAULT_TYPES,
    WIND_RANGES,
    FaultType,
    draw_winds,
    held_wind,
    place_windows,
)
from windwarden.evaluation.kinds import EvalOptions
from windwarden.evaluation.scoring_policy import policy_for
from windwarden.kinds import kind_for
from wwcore.scenario import Scenario, load_scenario, parse_scenario
from wwcore.scenario.model import FAULT_CHECKS

BASES = {"turbine": "turbine-fault-free", "farm": "farm-fault-free-case1", "hydro": "hydro-fault-free"}
"""Default plant, turbulence and supervisor settings of each kind: its shipped fault-free scenario."""


@dataclass(frozen=True)
class Timing:
    """How a kind's sweep windows are laid out (s): the first starts ``first_s`` plus a draw in [0, extra_gap_s];
    the next ``min_gap_s`` plus such a draw after the previous one ends; the wind holds ``settle_s`` before."""

    first_s: float
    min_gap_s: float
    extra_gap_s: float
    settle_s: float
    reason: str


TIMINGS: dict[str, Timing] = {
    "turbine": Timing(
        30.0,
        25.0,
        10.0,
        10.0,
        "after the 10 s warm-up and the start transient; the gaps of 25–35 s hold the 2 s grace, a ramp of the "
        "mean wind of at least 13 s (the winds of a layout are visited in order, so a step is 21/8 ≈ 2.6 m/s on "
        "average) and 10 s at the next wind",
    ),
    "farm": Timing(
        120.0,
        30.0,
        10.0,
        0.0,
        "after the 60 s warm-up and the 60-s mean of the demand; the gaps of 30–40 s hold the 10 s grace and the "
        "detectors' reverse CUSUM and 3P release",
    ),
    "hydro": Timing(
        10.0,
        12.0,
        8.0,
        5.0,
        "after the 1 s warm-up and the controller's start transient; gaps of 12–20 s hold the 2 s grace, a ramp "
        "of the wind and 5 s at the next wind",
    ),
}


def timing_table() -> str:
    """The layouts' timing as ``docs/detectability.md`` shows it (``tests/test_detectability.py`` compares)."""
    lines = [
        "| kind | window | first window | gap between windows | wind held before a window | why |",
        "|---|---|---|---|---|---|",
    ]
    windows = {t.kind: t.window_s for t in FAULT_TYPES}
    for kind, t in TIMINGS.items():
        held = f"{t.settle_s:g} s" if kind != "farm" else "(one wind per layout)"
        lines.append(
            f"| {kind} | {windows[kind]:g} s | {t.first_s:g} s + U(0, {t.extra_gap_s:g}) s | {t.min_gap_s:g} s + "
            f"U(0, {t.extra_gap_s:g}) s | {held} | {t.reason} |"
        )
    return "\n".join(lines)


@dataclass(frozen=True)
class Layout:
    """One random scenario of a sweep and what each of its windows is."""

    index: int
    scenario: Scenario
    windows: list[dict[str, Any]]  # name, size, target, sign, turbine, start_s, end_s, wind, wind_case


def base_scenario(kind_or_scenario: str) -> Scenario:
    """A plant kind's default base (``BASES``) or a scenario (name or file) whose plant, turbulence and supervisor
    settings the sweep keeps (its faults and mean wind are replaced)."""
    return load_scenario(BASES.get(kind_or_scenario, kind_or_scenario))


def check_sizes(fault_type: FaultType, sizes: Sequence[float], base: Scenario) -> list[str]:
    """Why these sizes cannot be swept on this base (empty when they can): a plant kind the type does not belong
    to, or a size whose fault (either sign) the scenario rules refuse."""
    if fault_type.kind != base.plant.kind:
        return [f"{fault_type.name} is a {fault_type.kind} fault; the base is a {base.plant.kind} plant"]
    problems = []
    convention = getattr(base.plant, "noise_convention", "sigma")
    for size in (min(sizes), max(sizes)):
        for sign in (1.0, -1.0) if fault_type.signed else (1.0,):
            spec = fault_type.fault(
                size, target=fault_type.targets[0], sign=sign, start_s=1.0, end_s=2.0, noise_convention=convention
            )
            for field, message in FAULT_CHECKS[base.plant.kind](spec, base.plant.n_turbines):
                problems.append(f"size {size:g} gives {field} {message}")
    return problems


def _seed(*parts: int) -> int:
    return int(np.random.SeedSequence(list(parts)).generate_state(1)[0])


def type_key(fault_type: FaultType) -> int:
    """A stable integer per fault type name, so each type draws its own layouts from one master seed."""
    return int.from_bytes(fault_type.name.encode()[:8].ljust(8, b"\0"), "little") % (2**31)


def make_layout(
    fault_type: FaultType, sizes: Sequence[float], base: Scenario, seed: int, index: int
) -> tuple[Layout, int]:
    """Layout ``index`` of a sweep and the seed its evaluation uses (both from ``seed``, the type and ``index``)."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, type_key(fault_type), index]))
    kind = base.plant.kind
    timing = TIMINGS[kind]
    order = rng.permutation(len(sizes))
    spans, duration = place_windows(
        rng,
        [fault_type.window_s] * len(sizes),
        first_s=timing.first_s,
        min_gap_s=timing.min_gap_s,
        extra_gap_s=timing.extra_gap_s,
    )
    data = base.model_dump(mode="json", exclude_none=True)
    data.update(
        name=f"{fault_type.name}-layout-{index}",
        description=f"detectability sweep of {fault_type.label}, layout {index}",
        duration_s=duration,
    )
    n_turbines = base.plant.n_turbines
    wind_case = None
    if kind == "farm":
        wind_case = int(rng.integers(1, 3))
        data["plant"]["wind_case"] = wind_case
        winds = draw_winds(rng, kind, 1) * len(sizes)
        data["wind"]["mean"] = [(0.0, winds[0])]
    else:
        # uniform winds visited in ascending or descending order: each size (in random order) still meets a
        # uniformly drawn wind, and the mean wind moves by small steps between windows
        winds = sorted(draw_winds(rng, kind, len(sizes)), reverse=bool(rng.integers(2)))
        data["wind"]["mean"] = held_wind(spans, winds, settle_s=timing.settle_s, after_s=policy_for(kind).grace_s)
    convention = getattr(base.plant, "noise_convention", "sigma")
    faults, windows = [], []
    for slot, (start, end) in enumerate(spans):
        size = float(sizes[order[slot]])
        target, sign = fault_type.draw_target(rng)
        turbine = int(rng.integers(1, n_turbines + 1))
        name = f"w{slot} {fault_type.name} {size:g}"
        faults.append(
            fault_type.fault(
                size,
                target=target,
                sign=sign,
                start_s=start,
                end_s=end,
                turbine=turbine,
                name=name,
                noise_convention=convention,
            ).model_dump(mode="json", exclude_none=True)
        )
        windows.append(
            {
                "name": name,
                "size": size,
                "target": target,
                "sign": sign,
                "turbine": turbine,
                "start_s": start,
                "end_s": end,
                "wind_mps": winds[slot],
                "wind_case": wind_case,
            }
        )
    data["faults"] = faults
    scenario = parse_scenario(data, f"<{data['name']}>")
    return Layout(index, scenario, windows), _seed(seed, type_key(fault_type), index, 1)


def sweep(
    fault_type: FaultType,
    sizes: Sequence[float],
    *,
    runs: int,
    layouts: int,
    seed: int,
    base: Scenario,
    workers: int | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """Score ``fault_type`` at ``sizes`` over ``layouts`` random layouts of ``ceil(runs / layouts)`` runs each.

    Returns the sweep as JSON-ready data: settings, one record per window (its layout, size, target, time,
    wind, and the scorecard's figures of that window), the false alarms of every layout, one row per size, and
    the sizes at 50 % and 95 % (detected and isolated)."""
    sizes = sorted(float(s) for s in sizes)
    per_layout = math.ceil(runs / layouts)
    options = EvalOptions(twins=False, progress=progress, workers=workers)
    records: list[dict[str, Any]] = []
    false_alarms = {"count": 0, "observed_s": 0.0}
    for index in range(layouts):
        layout, eval_seed = make_layout(fault_type, sizes, base, seed, index)
        card = kind_for(layout.scenario.plant.kind).evaluate(layout.scenario, per_layout, eval_seed, options).scorecard
        entries = {e["name"]: e for e in card["faults"]}
        false_alarms["count"] += card["false_alarms"]["count"]
        false_alarms["observed_s"] += card["false_alarms"]["observed_s"]
        for w in layout.windows:
            records.append(
                {
                    "layout": index,
                    "eval_seed": eval_seed,
                    "runs": per_layout,
                    **w,
                    **_figures(entries[w["name"]], per_layout),
                }
            )
    observed = false_alarms["observed_s"]
    false_alarms["per_1000s"] = 1000.0 * false_alarms["count"] / observed if observed > 0 else 0.0
    rows = size_rows(records, sizes, WIND_RANGES[base.plant.kind].rated)
    return {
        "fault_type": fault_type.name,
        "label": fault_type.label,
        "kind": base.plant.kind,
        "base": base.name,
        "unit": fault_type.unit,
        "sigma": fault_type.sigma(getattr(base.plant, "noise_convention", "sigma"))
        if fault_type.rule == "sigma"
        else None,
        "value_unit": fault_type.value_unit,
        "sizes": sizes,
        "runs_per_size": per_layout * layouts,
        "layouts": layouts,
        "runs_per_layout": per_layout,
        "seed": seed,
        "window_s": fault_type.window_s,
        "wind_range_mps": [WIND_RANGES[base.plant.kind].lo, WIND_RANGES[base.plant.kind].hi],
        "rows": rows,
        "thresholds": {what: threshold_sizes(records, sizes, what, seed) for what in ("detected", "isolated")},
        "false_alarms": false_alarms,
        "windows": records,
    }


def _figures(entry: dict[str, Any], runs: int) -> dict[str, Any]:
    """A window's scorecard entry as counts over its runs."""

    def count(key: str) -> int:
        return round((entry.get(key) or 0.0) * runs / 100.0)

    return {
        "detected": count("detected_pct"),
        "isolated": count("isolated_pct"),
        "wrong": count("wrong_isolation_pct"),
        "lost": count("lost_pct"),
        "delay_s_mean": entry.get("delay_s_mean"),
        "delay_s_max": entry.get("delay_s_max"),
        "flaps_mean": entry.get("flaps_mean") or 0.0,
    }


def size_rows(records: Sequence[dict[str, Any]], sizes: Sequence[float], rated: float | None) -> list[dict[str, Any]]:
    """Per size, pooled over layouts: counts, percentages with their 95 % intervals, delays (mean over detected
    window-runs, max), wrong isolations, lost flags, flaps, and detected % below and above rated wind."""
    rows = []
    for size in sizes:
        rs = [r for r in records if r["size"] == size]
        n = sum(r["runs"] for r in rs)
        detected = sum(r["detected"] for r in rs)
        isolated = sum(r["isolated"] for r in rs)
        weighted = [(r["delay_s_mean"], r["detected"]) for r in rs if r["detected"] and r["delay_s_mean"] is not None]
        delay = sum(d * k for d, k in weighted) / sum(k for _, k in weighted) if weighted else None
        maxima = [r["delay_s_max"] for r in rs if r["delay_s_max"] is not None]
        row = {
            "size": size,
            "n": n,
            "detected": detected,
            "detected_pct": 100.0 * detected / n if n else None,
            "detected_ci_pct": [100.0 * x for x in clopper_pearson(detected, n)],
            "isolated": isolated,
            "isolated_pct": 100.0 * isolated / n if n else None,
            "isolated_ci_pct": [100.0 * x for x in clopper_pearson(isolated, n)],
            "delay_s_mean": None if delay is None else round(delay, 6),
            "delay_s_max": max(maxima) if maxima else None,
            "wrong_isolation_pct": 100.0 * sum(r["wrong"] for r in rs) / n if n else None,
            "lost_pct": 100.0 * sum(r["lost"] for r in rs) / n if n else None,
            "flaps_mean": sum(r["flaps_mean"] * r["runs"] for r in rs) / n if n else None,
        }
        if rated is not None:
            for band, keep in (("below_rated", lambda v: v < rated), ("above_rated", lambda v: v >= rated)):
                part = [r for r in rs if keep(r["wind_mps"])]
                m = sum(r["runs"] for r in part)
                row[f"detected_pct_{band}"] = 100.0 * sum(r["detected"] for r in part) / m if m else None
                row[f"n_{band}"] = m
        rows.append(row)
    return rows
