"""The figures of a set of random scenarios, pooled per fault case over scenarios, windows and runs.

Every figure comes from the scenarios' own scorecards (``scoring.score_detection`` through each plant kind's
evaluator); pooling weighs each window by its runs: detected % = detected window-runs over all window-runs,
delays are means over detected window-runs, false alarms are counts over the summed quiet time.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from typing import Any

from rich import box
from rich.console import Group
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
    clean_ratios: dict[str, list[float]] = defaultdict(list)
    fault_free_wind: list[dict[str, Any]] = []
    errors: dict[str, list[float]] = defaultdict(list)
    fa = {"count": 0, "observed_s": 0.0, "flagged_s": 0.0}
    twin = {"count": 0, "observed_s": 0.0}
    clean = {"count": 0, "observed_s": 0.0}
    fp = {"count": 0, "farm_s": 0.0}
    for card in cards:
        for entry in card["faults"]:
            if "detected_pct" in entry:
                by_case[case_of(entry["name"])].append((entry, card["runs"]))
        for name, rmse in card.get("metrics", {}).get("wind_rmse", {}).items():
            if name != "fault_free" and rmse.get("fte_fault_free"):
                ratios[case_of(name)].append(rmse["fte"] / rmse["fte_fault_free"])
            if name != "fault_free" and rmse.get("fte_clean"):
                clean_ratios[case_of(name)].append(rmse["fte"] / rmse["fte_clean"])
            if name == "fault_free" and rmse.get("fte_clean"):
                fault_free_wind.append({"scenario": card["scenario"], **rmse, "ratio": rmse["fte"] / rmse["fte_clean"]})
        for rec in card.get("metrics", {}).get("reconstruction", []):
            errors[case_of(rec["fault"])].append(rec["error_pct"])
        for key in fa:
            fa[key] += card["false_alarms"][key]
        for pooled, key in ((twin, "false_alarms_twin"), (clean, "false_alarms_clean")):
            if key in card:
                pooled["count"] += card[key]["count"]
                pooled["observed_s"] += card[key]["observed_s"]
        if kind == "farm":
            fp["count"] += sum(row["false_positives"] for row in card["metrics"]["detection"].values())
            fp["farm_s"] += card["runs"] * max(card["duration_s"] - FARM_POLICY.warmup_s, 0.0)
    cases = {}
    for case in sorted(by_case):
        row = _pool(by_case[case])
        if ratios.get(case):
            row["fte_ratio_mean"] = sum(ratios[case]) / len(ratios[case])
            row["fte_ratio_max"] = max(ratios[case])
        if clean_ratios.get(case):
            row["fte_clean_ratio_mean"] = sum(clean_ratios[case]) / len(clean_ratios[case])
            row["fte_clean_ratio_max"] = max(clean_ratios[case])
        if errors.get(case):
            row["reconstruction_error_pct_mean"] = sum(errors[case]) / len(errors[case])
            row["reconstruction_error_pct_max"] = max(errors[case])
        cases[case] = row
    out: dict[str, Any] = {"cases": cases}
    if kind == "turbine":
        speed = [x for case in SPEED_CASES for x in by_case.get(case, [])]
        out["speed_sensors"] = _pool(speed) if speed else None
        for key, by in (("fte_ratio", ratios), ("fte_clean_ratio", clean_ratios)):
            speed_ratios = [x for case in SPEED_CASES for x in by.get(case, [])]
            if out["speed_sensors"] and speed_ratios:
                out["speed_sensors"][f"{key}_mean"] = sum(speed_ratios) / len(speed_ratios)
                out["speed_sensors"][f"{key}_max"] = max(speed_ratios)
        if fault_free_wind:
            out["fault_free_wind"] = fault_free_wind
    observed = fa["observed_s"]
    out["false_alarms"] = {
        **fa,
        "per_1000s": 1000.0 * fa["count"] / observed if observed else 0.0,
        "flagged_s_per_1000s": 1000.0 * fa["flagged_s"] / observed if observed else 0.0,
    }
    for pooled, key in ((twin, "false_alarms_twin"), (clean, "false_alarms_clean")):
        if pooled["observed_s"]:
            out[key] = {**pooled, "per_1000s": 1000.0 * pooled["count"] / pooled["observed_s"]}
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
    "FTE / clean run RMSE mean / max",
    "reconstruction error % mean / max",
)


def _cells(case: str, row: dict[str, Any]) -> list[str]:
    fte = "–" if "fte_ratio_mean" not in row else f"{row['fte_ratio_mean']:.3f} / {row['fte_ratio_max']:.3f}"
    fte_clean = "–"
    if "fte_clean_ratio_mean" in row:
        fte_clean = f"{row['fte_clean_ratio_mean']:.3f} / {row['fte_clean_ratio_max']:.3f}"
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
        fte_clean,
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
    if "false_alarms_clean" in s:
        text += f"; clean runs {s['false_alarms_clean']['count']} in {s['false_alarms_clean']['observed_s']:.0f} s"
    if "false_positives" in s:
        p = s["false_positives"]
        text += f"; false positives {p['per_1000_farm_s']:.3f} per 1000 farm-s ({p['count']} in {p['farm_s']:.0f} s)"
    return text + "."


def fault_free_lines(summary: dict[str, Any]) -> list[str]:
    """One line per scenario: the FTE's RMSE over the fault-free time, the clean run's and the anemometer's. A
    clean run worse than the anemometer is an estimate that fails without any fault; FTE over clean above 1 is
    what earlier faults left behind."""
    lines = []
    for row in summary.get("fault_free_wind", []):
        worse = row["fte_clean"] > row["anemometer"]
        warn = "  (the clean run's estimate is worse than the anemometer)" if worse else ""
        lines.append(
            f"{row['scenario']}: fault-free time, FTE {row['fte']:.2f} m/s, clean run {row['fte_clean']:.2f} m/s "
            f"(× {row['ratio']:.3f}), anemometer {row['anemometer']:.2f} m/s{warn}"
        )
    return lines


def markdown(card: dict[str, Any]) -> str:
    lines = [_caption(card), "", "| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(cells) + " |" for cells in _rows(card["summary"])]
    free = fault_free_lines(card["summary"])
    if free:
        lines += ["", "Wind estimate RMSE over the fault-free time, per scenario:", ""] + [f"- {x}" for x in free]
    return "\n".join(lines) + "\n"


CONSOLE_HEADERS = dict(
    zip(
        COLUMNS,
        (
            "case",
            "windows (runs)",
            "det. %",
            "isol. % first flag",
            "delay s mean / max",
            "wrong isol. %",
            "lost %",
            "flaps per window",
            "FTE / twin RMSE mean / max",
            "FTE / clean RMSE mean / max",
            "recon. error % mean / max",
        ),
        strict=True,
    )
)


def _console_part(rows: list[list[str]], columns: list[int], **kw: Any) -> Table:
    keep = [i for i in columns if i == 0 or any(r[i] != "–" for r in rows)]
    table = Table(caption_justify="left", title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False, **kw)
    for i in keep:
        table.add_column(CONSOLE_HEADERS[COLUMNS[i]], no_wrap=i == 0, justify="left" if i == 0 else "right")
    for cells in rows:
        table.add_row(*(cells[i] for i in keep))
    return table


def console_table(card: dict[str, Any]) -> Group:
    """The summary in two tables within 100 columns (detection, then what followed), with shorter headers (the
    caption spells them out) and without the column the plant kind leaves empty (the FTE ratio is the turbine's,
    the reconstruction error the hydrostatic turbine's)."""
    rows = _rows(card["summary"])
    legend = "det.: detected; isol.: isolated; windows (runs): fault windows (window-runs); recon.: reconstruction"
    free = "\n".join(fault_free_lines(card["summary"]))
    return Group(
        _console_part(rows, [0, 1, 2, 3, 4, 5], title=f"random scenarios, {card['scenario']}"),
        _console_part(rows, [0, 6, 7, 8, 9, 10], caption=f"{_caption(card)}\n{legend}" + (f"\n{free}" if free else "")),
    )
