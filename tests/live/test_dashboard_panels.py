"""The dashboard's residual scale and its views, without a viewer: statistic / threshold drawn linear to the trip
line at 1 and 1 + log₁₀ above, inside a fixed axis with room for the legend; signal views without in-plot legends."""

from __future__ import annotations

import numpy as np
import pytest
import rerun.blueprint as rrb

from dashboards.blueprints import blueprint
from dashboards.panels import MARGIN_DISPLAY_MAX, PANELS, RESIDUAL_AXIS, display_margin


def _prop(view: rrb.TimeSeriesView, archetype: str, field: str) -> list:
    return getattr(view.properties[archetype], field).as_arrow_array().to_pylist()


def test_the_residual_scale_is_linear_to_the_trip_line_and_logarithmic_above():
    shown = display_margin([0.0, 0.5, 1.0, 10.0, 100.0, 1000.0, 9000.0, np.inf])
    assert shown == pytest.approx([0.0, 0.5, 1.0, 2.0, 3.0, 4.0, MARGIN_DISPLAY_MAX, MARGIN_DISPLAY_MAX])
    assert np.isnan(display_margin(np.nan)) and display_margin(2.0) == pytest.approx(1.0 + np.log10(2.0))


def test_the_residual_scale_is_monotonic_and_continuous_at_the_trip_line():
    grid = np.geomspace(1e-3, 1e5, 2001)
    shown = display_margin(grid)
    assert np.all(np.diff(shown) >= 0.0) and np.all(np.diff(shown[grid < 1e3]) > 0.0)
    assert display_margin(1.0 + 1e-9) - display_margin(1.0 - 1e-9) == pytest.approx(0.0, abs=1e-8)
    assert np.sum(shown <= 1.0) == np.sum(grid <= 1.0)  # below the trip line ⇔ drawn below it


def test_the_trip_line_and_every_trace_fit_the_residual_axis_with_room_for_the_legend():
    low, high = RESIDUAL_AXIS
    assert low <= 0.0 and high > MARGIN_DISPLAY_MAX
    assert (1.0 - low) / (high - low) >= 0.1  # the trip line is at least a tenth of the way up, not in the floor
    assert (high - MARGIN_DISPLAY_MAX) / (high - low) >= 0.3  # the band the legend sits in


def test_the_farm_rows_draw_each_cusum_over_its_threshold():
    refs = {"statistic": [5.0, 9000.0 * 7.0, np.nan], "threshold": [10.0, 7.0, 3.0], "power_ref": 1e6}
    row = PANELS["farm"].supervisor(None, refs, {})["detector/supervisor"]
    assert row["debris"] == pytest.approx(0.5)
    assert row["pitch_misalignment"] == MARGIN_DISPLAY_MAX
    assert np.isnan(row["drivetrain"]) and row["threshold"] == 1.0


def test_the_turbine_rows_keep_a_missing_margin_as_nan():
    status = {"margins": {"observer 1": 0.25, "observer 2": 100.0, "observer 3": None}}
    refs = {"omega_g": 1.0, "omega_r": 1.0, "wind": 1.0, "wind_nfte": 1.0, "nfte_set": True}
    row = PANELS["turbine"].supervisor(None, refs, status)["residuals/supervisor"]
    assert row["observer 1"] == 0.25 and row["observer 2"] == pytest.approx(3.0)
    assert np.isnan(row["observer 3"]) and row["threshold"] == 1.0


@pytest.mark.parametrize("kind", sorted(PANELS))
def test_residual_views_fix_their_axis_and_signal_views_hide_the_legend(kind):
    panel = PANELS[kind]
    views = panel.views(1) + (panel.overview([1, 2]) if panel.overview is not None else [])
    series = [v for v in views if isinstance(v, rrb.TimeSeriesView)]
    residual = [v for v in series if "ScalarAxis" in v.properties]
    assert residual, "every kind has a residual view"
    for view in series:
        if view in residual:
            assert _prop(view, "ScalarAxis", "range") == [list(RESIDUAL_AXIS)]
            assert "trips above 1" in str(view.name)
            if _prop(view, "PlotLegend", "visible") == [True]:
                assert _prop(view, "PlotLegend", "corner") == [rrb.Corner2D.LeftTop.value]
        else:
            assert _prop(view, "PlotLegend", "visible") == [False]
    assert blueprint(kind, [1, 2]) is not None
