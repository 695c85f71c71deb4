"""Scorecards as rich tables for the terminal, readable at 100 columns.

Two tables of the detection figures (``docs/scorecards.md``): how each fault window was detected and isolated,
then what its flags did afterwards (lost, flaps, the end); the windows' names, the abbreviations, the false alarms
and the scoring policy in the caption; then the plant kind's own metrics. Rows stay on one line at ``WIDTH``: the
tables refer to a fault window by its number (``#1``, ``#2``, …) and name each window once, under the first table.
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


def window_numbers(scorecard: dict[str, Any]) -> dict[str, str]:
    """Each fault window's name → its number in the tables (``#1``, ``#2``, …), in the scorecard's order. The
    names (up to ~90 characters for a double fault) are listed once under the first table: a column of them would
    fold every row over several lines at 100 columns."""
    return {f["name"]: f"#{i}" for i, f in enumerate(scorecard.get("faults", []), start=1)}


def faults_table(scorecard: dict[str, Any]) -> Table:
    """Detection and isolation per fault window; the caption names the windows and has the false alarms and the
    policy."""
    table = _table(
        f"{scorecard['scenario']}: {scorecard['runs']} runs, seed {scorecard['seed']}",
        [("target", 1, 10)],
        [
            ("#", 3),
            ("window s", 9),
            ("det. %", 5),
            ("delay s mean / max", 11),
            ("isol. % first flag", 6),
            ("isol. % of time", 6),
            ("wrong isol. %", 6),
        ],
    )
    table.columns.insert(0, table.columns.pop(1))  # the window's number first, then its target
    numbers = window_numbers(scorecard)
    for f in scorecard["faults"]:
        cells = [numbers[f["name"]], f["target"].replace("+", "+ "), f"{f['start_s']:g}–{f['end_s']:g}"]
        if "detected_pct" not in f:
            table.add_row(*cells, "–", "–", "–", "–", "–")  # why: in the window's line of the caption
            continue
        table.add_row(
            *cells,
            _fmt(f["detected_pct"]),
            _pair(f["delay_s_mean"], f["delay_s_max"]),
            _fmt(f["isolated_pct"]),
            _fmt(f["isolated_time_pct"]),
            _fmt(f["wrong_isolation_pct"]),
        )
    table.caption = "\n".join([*_window_legend(scorecard, numbers), _ABBREVIATIONS, _caption(scorecard)])
    return table


_ABBREVIATIONS = (
    "det.: detected; isol.: isolated (the right target flagged), on the first flag and as a share of the "
    "window's time; wrong isol.: windows whose first flag named another target"
)


def _window_legend(scorecard: dict[str, Any], numbers: dict[str, str]) -> list[str]:
    return [
        f"{numbers[f['name']]} {f['name']}" + ("" if "detected_pct" in f else f" ({f.get('note', 'not scored')})")
        for f in scorecard["faults"]
    ]


def after_detection_table(scorecard: dict[str, Any]) -> Table:
    """Per fault window (by its number): flags lost while the fault acted, flaps, wrong isolations, and the end."""
    table = _table(
        None,
        [],
        [
            ("#", 3),
            ("lost %", 6),
            ("losses", 6),
            ("flaps mean / max", 9),
            ("wrong isolations", 10),
            ("end recognised %", 10),
            ("end delay s mean / max", 11),
        ],
    )
    numbers = window_numbers(scorecard)
    for f in scorecard["faults"]:
        if "detected_pct" not in f:
            continue
        table.add_row(
            numbers[f["name"]],
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


LONG_TEXT = 24  # characters: a text metric longer than this (a rule's description) goes under the table


def metrics_table(metrics: dict[str, Any], title: str = "metrics", numbers: dict[str, str] | None = None) -> Table:
    """Every metric as a dotted path and its value, one line each; a fault window's name in a path is written as
    its number (``window_numbers``); a long text value (a rule's description) is written under the table."""
    numbers = numbers or {}
    table = Table(title=title, caption_justify="left")
    table.add_column("metric", overflow="fold")
    table.add_column("value", justify="right", no_wrap=True)
    notes: list[str] = []

    def walk(prefix: str, node: Any) -> None:
        if isinstance(node, dict):
            for key, value in node.items():
                key = numbers.get(str(key), str(key))
                walk(f"{prefix}.{key}" if prefix else key, value)
        elif isinstance(node, list):
            for i, value in enumerate(node):
                walk(f"{prefix}[{i}]", value)
        elif isinstance(node, str) and len(node) > LONG_TEXT:
            notes.append(f"{prefix}: {node}")
            table.add_row(prefix, f"(note {len(notes)})")
        else:
            table.add_row(prefix, _fmt(node, 4))

    walk("", metrics)
    if notes:
        table.caption = "\n".join(f"note {i}: {text}" for i, text in enumerate(notes, start=1))
    return table


def render(scorecard: dict[str, Any]) -> Group:
    parts: list[Any] = [faults_table(scorecard)]
    if any("detected_pct" in f for f in scorecard["faults"]):
        parts.append(after_detection_table(scorecard))
    if scorecard.get("metrics"):
        parts.append(metrics_table(scorecard["metrics"], numbers=window_numbers(scorecard)))
    return Group(*parts)
