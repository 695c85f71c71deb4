"""The dashboard's residual scale and its views, without a viewer: statistic / threshold drawn linear to the trip
line at 1 and 1 + log₁₀ above, inside a fixed axis with room for the legend; signal views without in-plot legends."""

from __future__ import annotations

import numpy as np
import pytest
import rerun.blueprint as rrb

from dashboards.blueprints import blueprint
from dashboards.panels import MARGIN_DISPLAY_MAX, PANELS, RESIDUAL_AXIS, display_margin
from wwcore.wire import (
    FARM_REFS,
    FARM_SENSORS,
    FARM_TRUTH,
    HYDRO_REFS,
    HYDRO_SENSORS,
    HYDRO_TRUTH,
    TURBINE_REFS,
    TURBINE_SENSORS,
    TURBINE_TRUTH,
)

pytestmark = pytest.mark.in_process  # no network, no process: the parallel phase (tests/conftest.py)


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
    refs = FARM_REFS.empty(2)
    refs["statistic"] = [[5.0, 9000.0 * 7.0, np.nan], [1.0, 2.0, 3.0]]
    refs["threshold"] = [[10.0, 7.0, 3.0], [1.0, 1.0, 30.0]]
    refs["power_ref"] = [1e6, 2e6]
    rows = PANELS["farm"].supervisor(None, refs, None)
    row = rows["detector/supervisor"]
    assert row["debris"] == pytest.approx([0.5, 1.0])
    assert row["pitch_misalignment"] == pytest.approx([MARGIN_DISPLAY_MAX, 1.0 + np.log10(2.0)])
    assert np.isnan(row["drivetrain"][0]) and row["drivetrain"][1] == pytest.approx(0.1) and row["threshold"] == 1.0
    assert rows["power/supervisor"]["reference"] == pytest.approx([1.0, 2.0])
    assert not PANELS["farm"].uses_status  # every farm series is in the refs rows: no status is built for it


def test_the_turbine_rows_keep_a_missing_margin_as_nan():
    status = [{"margins": {"observer 1": 0.25, "observer 2": 100.0, "observer 3": None}}]
    refs = TURBINE_REFS.empty(1)
    refs["nfte_set"], refs["wind_nfte"], refs["wind"] = False, 7.0, 8.0
    rows = PANELS["turbine"].supervisor(None, refs, status)
    row = rows["residuals/supervisor"]
    assert row["observer 1"] == [0.25] and row["observer 2"] == pytest.approx([3.0])
    assert np.isnan(row["observer 3"][0]) and row["threshold"] == 1.0
    assert np.isnan(rows["wind/supervisor"]["NFTE"][0]) and rows["wind/supervisor"]["FTE"] == [8.0]


@pytest.mark.parametrize("kind", sorted(PANELS))
def test_the_rows_of_many_turbines_are_those_of_each_turbine_alone(kind):
    """The panels build every turbine's columns at once (numpy over the frame's rows): the same values as the
    same panel on each turbine's row alone, in the frame's order."""
    schemas = {
        "turbine": (TURBINE_SENSORS, TURBINE_TRUTH, TURBINE_REFS),
        "hydro": (HYDRO_SENSORS, HYDRO_TRUTH, HYDRO_REFS),
        "farm": (FARM_SENSORS, FARM_TRUTH, FARM_REFS),
    }[kind]
    rng = np.random.default_rng(5)
    sensors, truth, refs = (schema.empty(4) for schema in schemas)
    for records in (sensors, truth, refs):
        for name in records.dtype.names:
            if records.dtype[name].base.kind == "f":
                records[name] = rng.uniform(0.5, 2.0, records[name].shape)
    refs["nfte_set" if kind == "turbine" else "turbine"] = [1, 0, 1, 0] if kind == "turbine" else [4, 2, 9, 1]
    status = [{"margins": {"a": float(i), "b": None}, "thresholds": {"u_p": 1.0 + i, "u_M": None}} for i in range(4)]
    panel = PANELS[kind]
    whole = panel.plant(sensors, truth) | panel.supervisor(sensors, refs, status)
    for i in range(4):
        alone = panel.plant(sensors[i : i + 1], truth[i : i + 1]) | panel.supervisor(
            sensors[i : i + 1], refs[i : i + 1], status[i : i + 1]
        )
        assert alone.keys() == whole.keys()
        for group, columns in whole.items():
            for name, values in columns.items():
                expected = np.broadcast_to(np.asarray(alone[group][name], dtype=float), (1,))[0]
                got = np.broadcast_to(np.asarray(values, dtype=float), (4,))[i]
                assert got == pytest.approx(expected, nan_ok=True), (group, name, i)
    no_truth = panel.plant(sensors, None)
    assert all(np.broadcast_to(v, (4,)).shape == (4,) for columns in no_truth.values() for v in columns.values())


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


def test_the_turbine_residual_view_names_its_colours_instead_of_a_legend_over_eleven_traces():
    """Eleven observers' statistics in one view: a legend that lists them fills the band above the traces and
    runs over them, so the view names its colours in the title and hovering a trace names its observer."""
    (view,) = [
        v for v in PANELS["turbine"].views(1) if isinstance(v, rrb.TimeSeriesView) and "ScalarAxis" in v.properties
    ]
    assert _prop(view, "PlotLegend", "visible") == [False]
    assert "observer (grey)" in str(view.name) and "trip line (red)" in str(view.name)
