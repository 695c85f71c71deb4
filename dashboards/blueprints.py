"""The live dashboard's layout, declared in code: one tab per turbine, the run's timing and the event log."""

from __future__ import annotations

import rerun.blueprint as rrb

from dashboards.panels import PANELS


def blueprint(kind: str, turbines: list[int]) -> rrb.Blueprint:
    """Per turbine a grid of the kind's views; then the run's timing and the event log."""
    panel = PANELS[kind]
    tabs = [rrb.Grid(*panel.views(t), grid_columns=2, name=f"turbine {t}") for t in turbines]
    if panel.overview is not None:  # a plant of several turbines opens on its overview
        tabs.insert(0, rrb.Grid(*panel.overview(turbines), grid_columns=2, name="farm"))
    run = rrb.Vertical(
        rrb.TimeSeriesView(origin="/run/timing", name="loop: latency ms, overruns"),
        rrb.TextLogView(origin="/events", name="events"),
        name="run",
    )
    return rrb.Blueprint(
        rrb.Tabs(*tabs, run),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed"),
    )
