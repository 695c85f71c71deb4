"""Scorecards as rich tables for the terminal, readable at 100 columns.

Two tables of the detection figures (``docs/scorecards.md``): how each fault window was detected and isolated,
then what its flags did afterwards (lost, flaps, the end); the false alarms and the scoring policy in the caption;
then the plant kind's own metrics.
"""

from __future__ import annotations

from typing import Any

from rich.console import Group
from rich.table import Table

WIDTH = 100  # columns the tables are laid out for; they fill a narrower or a wider terminal as well


def _fmt(value: Any, digits: int = 3) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        return f"{value:.{digits}g}" if abs(value) < 1e4 else f"{value:.4g}"
    return str(value)


def _pair(a: Any, b: Any) -> str:
    return "–" if a is None and b is None else f"{_fmt(a)} / {_fmt(b)}"


def _table(title: str | None, text: list[tuple[str, int, int]], numbers: list[tuple[str, int]]) -> Table:
    """Text columns (name, share of the room left, minimum width) on the left, then number columns (name, width),
    across the terminal (the number columns and the text columns' minimum widths fit in ``WIDTH``)."""
    table = Table(title=title, expand=True, title_justify="left", caption_justify="left", pad_edge=False)
    for name, share, least in text:
        table.add_column(name, ratio=share, min_width=least, overflow="fold")
    for name, width in numbers:
        table.add_column(name, justify="right", width=width)
    return table


def faults_table(scorecard: dict[str, Any]) -> Table:
    """Detection and isolation per fault window; the caption has the false alarms and the policy."""
    table = _table(
        f"{scorecard['scenario']}: {scorecard['runs']} runs, seed {scorecard['seed']}",
        [("fault", 3, 16), ("target", 2, 12)],
        [
            ("detected %", 8),
            ("delay s mean / max", 11),
            ("isolated % first flag", 8),
            ("isolated % of time", 8),
            ("wrong isolation %", 9),
        ],
    )
    for f in scorecard["faults"]:
        target = f["target"].replace("+", "+ ")  # a double fault's targets wrap between them
        if "detected_pct" not in f:
            table.add_row(f["name"], target, f.get("note", "not scored"), "", "", "", "")
            continue
        table.add_row(
            f["name"],
            target,
            _fmt(f["detected_pct"]),
            _pair(f["delay_s_mean"], f["delay_s_max"]),
            _fmt(f["isolated_pct"]),
            _fmt(f["isolated_time_pct"]),
            _fmt(f["wrong_isolation_pct"]),
        )
    table.caption = _caption(scorecard)
    return table


def after_detection_table(scorecard: dict[str, Any]) -> Table:
    """Per fault window: its time, flags lost while the fault acted, flaps, wrong isolations, and the end."""
    table = _table(
        None,
        [("fault", 1, 20)],
        [
            ("window s", 9),
            ("lost %", 6),
            ("losses", 6),
            ("flaps mean / max", 9),
            ("wrong isolations", 10),
            ("end recognised %", 10),
            ("end delay s mean / max", 11),
        ],
    )
    for f in scorecard["faults"]:
        if "detected_pct" not in f:
            continue
        table.add_row(
            f["name"],
            f"{f['start_s']:g}–{f['end_s']:g}",
            _fmt(f["lost_pct"]),
            _fmt(f["lost"]),
            _pair(f["flaps_mean"], f["flaps_max"]),
            _fmt(f["wrong_isolations"]),
            _fmt(f["end_recognised_pct"]),
            _pair(f["end_delay_s_mean"], f["end_delay_s_max"]),
        )
    return table


def _caption(scorecard: dict[str, Any]) -> str:
    fa = scorecard.get("false_alarms", {})
    lines = [
        f"false alarms: {_fmt(scorecard['false_alarms_per_1000s'])} per 1000 s "
        f"({fa.get('count', '–')} in {_fmt(fa.get('observed_s'), 6)} s), "
        f"flagged {_fmt(scorecard.get('false_alarm_flagged_s_per_1000s'))} s per 1000 s"
    ]
    wrong = scorecard.get("wrong_isolations")
    if wrong is not None:
        lines.append(f"wrong isolations in fault windows: {wrong['count']}")
    policy = scorecard.get("scoring")
    if policy is not None:
        lines.append(
            f"scoring: warm-up {policy['warmup_s']:g} s, grace {policy['grace_s']:g} s; time base "
            f"{policy['time_base']} (docs/scorecards.md)"
        )
    return "\n".join(lines)


def metrics_table(metrics: dict[str, Any], title: str = "metrics") -> Table:
    table = Table(title=title)
    table.add_column("metric")
    table.add_column("value", justify="right")

    def walk(prefix: str, node: Any) -> None:
        if isinstance(node, dict):
            for key, value in node.items():
                walk(f"{prefix}.{key}" if prefix else str(key), value)
        elif isinstance(node, list):
            for i, value in enumerate(node):
                walk(f"{prefix}[{i}]", value)
        else:
            table.add_row(prefix, _fmt(node, 4))

    walk("", metrics)
    return table


def render(scorecard: dict[str, Any]) -> Group:
    parts: list[Any] = [faults_table(scorecard)]
    if any("detected_pct" in f for f in scorecard["faults"]):
        parts.append(after_detection_table(scorecard))
    if scorecard.get("metrics"):
        parts.append(metrics_table(scorecard["metrics"]))
    return Group(*parts)
