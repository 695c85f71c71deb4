"""The listing of ``windwarden scenarios``: one line per scenario (name, plant, duration, faults) and its
description under it, indented and wrapped to the terminal's width. A description (up to ~200 characters) in a
table column would fold every row over several lines at 100 columns."""

from __future__ import annotations

from rich.console import Group, RenderableType
from rich.padding import Padding
from rich.text import Text

from wwcore.scenario import Scenario

HEADER = ("name", "plant", "duration s", "faults")


def scenarios_listing(scenarios: dict[str, Scenario], title: str = "shipped scenarios") -> Group:
    """``scenarios``: name → scenario, listed in name order."""
    rows = [
        (name, s.plant.kind, f"{s.duration_s:g}", str(len(s.faults)), s.description or "–")
        for name, s in sorted(scenarios.items())
    ]
    widths = [max(len(r[i]) for r in [HEADER, *rows]) for i in range(len(HEADER))]

    def line(cells: tuple[str, ...], style: str = "") -> Text:
        name, plant, duration, faults = (
            c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths, strict=True))
        )
        return Text("  ".join((name, plant, duration, faults)), style=style, no_wrap=True)

    parts: list[RenderableType] = [Text(title, style="italic"), line(HEADER, "bold")]
    for *cells, description in rows:
        parts += [line(tuple(cells)), Padding(Text(description, style="dim"), (0, 0, 0, 4))]
    return Group(*parts)
