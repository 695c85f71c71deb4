"""Scorecards as rich tables for the terminal."""

from __future__ import annotations

from typing import Any

from rich.console import Group
from rich.table import Table


def _fmt(value: Any, digits: int = 3) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        return f"{value:.{digits}g}" if abs(value) < 1e4 else f"{value:.4g}"
    return str(value)


def faults_table(scorecard: dict[str, Any]) -> Table:
    table = Table(title=f"{scorecard['scenario']}: {scorecard['runs']} runs, seed {scorecard['seed']}")
    for column in (
        "fault",
        "target",
        "window s",
        "detected %",
        "isolated %",
        "delay mean s",
        "delay max s",
        "end mean s",
    ):
        table.add_column(column, justify="left" if column in ("fault", "target") else "right")
    for f in scorecard["faults"]:
        table.add_row(
            f["name"],
            f["target"],
            f"{f['start_s']:g}–{f['end_s']:g}",
            _fmt(f["detected_pct"]),
            _fmt(f["isolated_pct"]),
            _fmt(f["delay_s_mean"]),
            _fmt(f["delay_s_max"]),
            _fmt(f.get("end_delay_s_mean")),
        )
    table.caption = f"false alarms: {scorecard['false_alarms_per_1000s']:.3g} per 1000 s"
    return table


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
    if scorecard.get("metrics"):
        parts.append(metrics_table(scorecard["metrics"]))
    return Group(*parts)
