"""The figures of a set of random scenarios, pooled per fault case over scenarios, windows and runs.

Every figure comes from the scenarios' own scorecards (``scoring.score_detection`` through each plant kind's
evaluator); pooling weighs each window by its runs: detected % = detected window-runs over all window-runs,
delays are means over detected window-runs, false alarms are counts over the summed quiet time.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from typing import Any

from rich.table import Table

from windwarden.evaluation.scoring_policy import FARM as FARM_POLICY

SPEED_CASES = (
    "speed-rotor-offset",
    "speed-generator-offset",
    "speed-rotor-gain",
    "speed-generator-gain",
    "speed-double",
)


def case_of(name: str) -> str:
    """The case of a generated fault or of a window's joined name: the name's second word (``r3 <case> …``)."""
    return name.split(" ")[1]


def _pool(entries: Sequence[tuple[dict[str, Any], int]]) -> dict[str, Any]:
    """Window entries (scorecard ``faults`` rows) with their runs, pooled."""
    n = sum(runs for _, runs in entries)

    def count(key: str) -> float:
        return sum((e.get(key) or 0.0) * runs / 100.0 for e, runs in entries)

    detected = count("detected_pct")
    timed = [
        (e["delay_s_mean"], e["detected_pct"] * runs / 100.0)
        for e, runs in entries
        if e.get("delay_s_mean") is not None
    ]
    weight = sum(w for _, w in timed)
    maxima = [e["delay_s_max"] for e, _ in entries if e.get("delay_s_max") is not None]
    ended = [(e, runs) for e, runs in entries if e.get("end_recognised_pct") is not None]
    return {
        "windows": len(entries),
        "window_runs": n,
        "detected_pct": 100.0 * detected / n if n else None,
        "isolated_pct": 100.0 * count("isolated_pct") / n if n else None,
        "isolated_time_pct": 100.0 * count("isolated_time_pct") / n if n else None,
        "delay_s_mean": sum(d * w for d, w in timed) / weight if weight else None,
        "delay_s_max": max(maxima) if maxima else None,
        "wrong_isolation_pct": 100.0 * count("wrong_isolation_pct") / n if n else None,
        "lost_pct": 100.0 * count("lost_pct") / n if n else None,
        "flaps_mean": sum((e.get("flaps_mean") or 0.0) * runs for e, runs in entries) / n if n else None,
        "end_recognised_pct": (
            100.0 * sum(e["end_recognised_pct"] * r / 100.0 for e, r in ended) / sum(r for _, r in ended)
            if ended
            else None
        ),
    }


def summarise(kind: str, cards: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Per case and for all speed-sensor cases together (turbine): detection figures; the kind's own metrics
    (turbine: FTE RMSE over its fault-free twin's per window; hydro: reconstruction error per fault); false
    alarms (and the farm's false positives of the three fault types per 1000 farm-seconds)."""
    by_case: dict[str, list[tuple[dict[str, Any], int]]] = defaultdict(list)
    ratios: dict[str, list[float]] = defaultdict(list)
    errors: dict[str, list[float]] = defaultdict(list)
    fa = {"count": 0, "observed_s": 0.0, "flagged_s": 0.0}
    twin = {"count": 0, "observed_s": 0.0}
    fp = {"count": 0, "farm_s": 0.0}
    for card in cards:
        for entry in card["faults"]:
            if "detected_pct" in entry:
                by_case[case_of(entry["name"])].append((entry, card["runs"]))
        for name, rmse in card.get("metrics", {}).get("wind_rmse", {}).items():
            if name != "fault_free" and rmse.get("fte_fault_free"):
                ratios[case_of(name)].append(rmse["fte"] / rmse["fte_fault_free"])
        for rec in card.get("metrics", {}).get("reconstruction", []):
            errors[case_of(rec["fault"])].append(rec["error_pct"])
        for key in fa:
            fa[key] += card["false_alarms"][key]
        if "false_alarms_twin" in card:
            twin["count"] += card["false_alarms_twin"]["count"]
            twin["observed_s"] += card["false_alarms_twin"]["observed_s"]
        if kind == "farm":
            fp["count"] += sum(row["false_positives"] for row in card["metrics"]["detection"].values())
            fp["farm_s"] += card["runs"] * max(card["duration_s"] - FARM_POLICY.warmup_s, 0.0)
    cases = {}
    for case in sorted(by_case):
        row = _pool(by_case[case])
        if ratios.get(case):
            row["fte_ratio_mean"] = sum(ratios[case]) / len(ratios[case])
            row["fte_ratio_max"] = max(ratios[case])
        if errors.get(case):
            row["reconstruction_error_pct_mean"] = sum(errors[case]) / len(errors[case])
            row["reconstruction_error_pct_max"] = max(errors[case])
        cases[case] = row
    out: dict[str, Any] = {"cases": cases}
    if kind == "turbine":
        speed = [x for case in SPEED_CASES for x in by_case.get(case, [])]
        out["speed_sensors"] = _pool(speed) if speed else None
        speed_ratios = [x for case in SPEED_CASES for x in ratios.get(case, [])]
        if out["speed_sensors"] and speed_ratios:
            out["speed_sensors"]["fte_ratio_mean"] = sum(speed_ratios) / len(speed_ratios)
            out["speed_sensors"]["fte_ratio_max"] = max(speed_ratios)
    observed = fa["observed_s"]
    out["false_alarms"] = {
        **fa,
        "per_1000s": 1000.0 * fa["count"] / observed if observed else 0.0,
        "flagged_s_per_1000s": 1000.0 * fa["flagged_s"] / observed if observed else 0.0,
    }
    if twin["observed_s"]:
        out["false_alarms_twin"] = {**twin, "per_1000s": 1000.0 * twin["count"] / twin["observed_s"]}
    if kind == "farm":
        out["false_positives"] = {**fp, "per_1000_farm_s": 1000.0 * fp["count"] / fp["farm_s"] if fp["farm_s"] else 0.0}
    return out


def _f(value: float | None, digits: int = 3) -> str:
    return "–" if value is None else f"{value:.{digits}g}"


def _pct(value: float | None) -> str:
    return "–" if value is None else f"{value:.1f}"


COLUMNS = (
    "case",
    "windows (window-runs)",
    "detected %",
    "isolated % (first flag)",
    "delay s mean / max",
    "wrong isolation %",
    "lost %",
    "flaps per window",
    "FTE / twin RMSE mean / max",
    "reconstruction error % mean / max",
)


def _cells(case: str, row: dict[str, Any]) -> list[str]:
    fte = "–" if "fte_ratio_mean" not in row else f"{row['fte_ratio_mean']:.3f} / {row['fte_ratio_max']:.3f}"
    rec = "–"
    if "reconstruction_error_pct_mean" in row:
        rec = f"{row['reconstruction_error_pct_mean']:.2f} / {row['reconstruction_error_pct_max']:.2f}"
    return [
        case,
        f"{row['windows']} ({row['window_runs']})",
        _pct(row["detected_pct"]),
        _pct(row["isolated_pct"]),
        f"{_f(row['delay_s_mean'])} / {_f(row['delay_s_max'])}",
        _pct(row["wrong_isolation_pct"]),
        _pct(row["lost_pct"]),
        _f(row["flaps_mean"], 2),
        fte,
        rec,
    ]


def _rows(summary: dict[str, Any]) -> list[list[str]]:
    rows = [_cells(case, row) for case, row in summary["cases"].items()]
    if summary.get("speed_sensors"):
        rows.append(_cells("all speed-sensor faults", summary["speed_sensors"]))
    return rows


def _caption(card: dict[str, Any]) -> str:
    s = card["summary"]
    fa = s["false_alarms"]
    text = (
        f"{card['scenario']}: {len(card['scenarios'])} scenarios, {card['runs']} runs, seed {card['seed']}. "
        f"False alarms {fa['per_1000s']:.3f} per 1000 s ({fa['count']} in {fa['observed_s']:.0f} s), flagged "
        f"{fa['flagged_s_per_1000s']:.2f} s per 1000 s"
    )
    if "false_alarms_twin" in s:
        text += f"; fault-free twins {s['false_alarms_twin']['count']} in {s['false_alarms_twin']['observed_s']:.0f} s"
    if "false_positives" in s:
        p = s["false_positives"]
        text += f"; false positives {p['per_1000_farm_s']:.3f} per 1000 farm-s ({p['count']} in {p['farm_s']:.0f} s)"
    return text + "."


def markdown(card: dict[str, Any]) -> str:
    lines = [_caption(card), "", "| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(cells) + " |" for cells in _rows(card["summary"])]
    return "\n".join(lines) + "\n"


def console_table(card: dict[str, Any]) -> Table:
    table = Table(title=f"random scenarios, {card['scenario']}", caption=_caption(card))
    for column in COLUMNS:
        table.add_column(column)
    for cells in _rows(card["summary"]):
        table.add_row(*cells)
    return table
