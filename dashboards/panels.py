"""What each plant kind shows: which series each process logs, their styles, and the views of its panel.

One ``Panel`` per kind, chosen by name (``PANELS``). A panel maps the wire records a process already holds (sensor,
truth and refs records of ``wwcore.wire``, the supervisor's per-turbine status) to groups of scalar series under
``/turbine/<id>/…``: the plant's ``…/plant`` and the supervisor's ``…/supervisor`` entities side by side in one
view. It also lays out the views of one turbine. The farm kind adds its panel (and a farm overview).

**Residual views** show each test statistic over its threshold, so every detector trips at 1, drawn by
``display_margin``: linear up to the trip line at 1, 1 + log₁₀ above it (2 = 10×, 3 = 100× the threshold), at most
``MARGIN_DISPLAY_MAX`` (1000×). A CUSUM that has run to 9 000× its threshold would otherwise squash the trip line
and everything below it into the bottom pixel. Their y axis is fixed to ``RESIDUAL_AXIS``: the traces stay in
[0, 4] and the legend sits in the band above them. **Signal views** name their series and colours in the title
and hide the in-plot legend, which would cover the traces (hovering a trace names it).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import rerun.blueprint as rrb

from dashboards.farm_map import FarmGeometry, geometry_of, map_view
from wwcore.channels import SENSOR_INDEX
from wwcore.hydro_params import FAULT_TARGETS

Rows = dict[str, dict[str, float]]
"""One row of every series group of the whole plant: group path under ``/farm/`` → series name → value."""
Columns = dict[str, dict[str, Any]]
"""One row of every series group for each of n turbines at once: group path under ``/turbine/<id>/`` → series name
→ n values (an array, or one number for all). A group is one entity per turbine holding several scalar series; its
names stay the same from row to row. Built with numpy over the frame's rows, never a Python loop over turbines."""
WINDOW_S = 120.0  # s of simulation time the time-series views follow behind the cursor
MARGIN_DISPLAY_MAX = 4.0  # 1 + log10(1000): statistics above 1000× their threshold are drawn at the top
RESIDUAL_AXIS = (0.0, 7.0)  # y range of the residual views: traces in [0, MARGIN_DISPLAY_MAX], the legend above

# Colours: sensors grey/blue, fault-tolerant estimate green, non-fault-tolerant orange, truth black, faults red.
SENSOR_1, SENSOR_2 = (120, 144, 200), (150, 150, 150)
ESTIMATE, REFERENCE, TRUTH, FAULT = (40, 170, 80), (240, 140, 30), (20, 20, 20), (220, 50, 50)


@dataclass(frozen=True)
class Panel:
    """The live dashboard of one plant kind."""

    plant: Callable[[np.ndarray, np.ndarray | None], Columns]  # (sensor rows, truth rows or None) → every turbine's
    supervisor: Callable[[np.ndarray, np.ndarray, list[dict[str, Any]] | None], Columns]  # (sensors, refs, status)
    colors: dict[str, tuple[int, int, int]]  # series name → colour
    views: Callable[[int], list[Any]]  # turbine → views
    # A plant of several turbines may add rows of the whole plant under ``/farm/…`` and an overview tab:
    farm_plant: Callable[[np.ndarray, np.ndarray | None], Rows] | None = None  # (all sensor rows, all truth rows)
    farm_supervisor: Callable[[np.ndarray, np.ndarray], Rows] | None = None  # (all sensor rows, all refs rows)
    overview: Callable[[list[int]], list[Any]] | None = None  # turbines → views of the overview tab
    site_map: Callable[[Any], FarmGeometry] | None = None  # the scenario's plant section → its map (farm_map)
    uses_status: bool = True  # ``supervisor`` reads the per-turbine status (else it gets None: not built)


def _window() -> list[rrb.VisibleTimeRange]:
    return [
        rrb.VisibleTimeRange(
            "sim_time",
            start=rrb.TimeRangeBoundary.cursor_relative(seconds=-WINDOW_S),
            end=rrb.TimeRangeBoundary.cursor_relative(),
        )
    ]


def display_margin(margin: Any) -> np.ndarray:
    """Statistic / threshold as the residual views draw it: itself up to the trip line at 1, 1 + log₁₀ above
    (monotonic and continuous at 1), at most ``MARGIN_DISPLAY_MAX``; NaN (no statistic) stays NaN."""
    m = np.asarray(margin, dtype=float)
    above = 1.0 + np.log10(np.maximum(m, 1.0), where=~np.isnan(m), out=np.full(m.shape, np.nan))
    return np.minimum(np.where(m > 1.0, above, m), MARGIN_DISPLAY_MAX)


def _margins(names: Any, margins: Any) -> dict[str, Any]:
    """The residual group's columns from margins of shape (n turbines, len(names)): each statistic / threshold as
    drawn, and the trip line at 1."""
    shown = display_margin(np.asarray(margins, dtype=float).reshape(-1, len(names)))
    return {name: shown[:, j] for j, name in enumerate(names)} | {"threshold": 1.0}


def _nan(n: int) -> np.ndarray:
    return np.full(n, np.nan)


def _series_view(origin: str, name: str, window: bool = True) -> rrb.TimeSeriesView:
    """A signal view: its title names the series and their colours; no in-plot legend over the traces."""
    return rrb.TimeSeriesView(
        origin=origin,
        name=name,
        time_ranges=_window() if window else None,
        plot_legend=rrb.PlotLegend(visible=False),
    )


def _residual_view(origin: str, name: str, contents: list[str] | None = None, legend: bool = True) -> Any:
    """A residual view (module docstring): fixed y axis with the legend in the band above the traces."""
    return rrb.TimeSeriesView(
        origin=origin,
        contents=contents if contents is not None else "$origin/**",
        name=name,
        time_ranges=_window(),
        axis_y=rrb.ScalarAxis(range=RESIDUAL_AXIS),
        plot_legend=rrb.PlotLegend(corner=rrb.Corner2D.LeftTop, visible=legend),
    )


def _states_view(turbine: int) -> rrb.StateTimelineView:
    base = f"/turbine/{turbine}"
    return rrb.StateTimelineView(
        origin=base,
        contents=[f"{base}/faults/**", f"{base}/observer"],
        name=f"T{turbine}: faults injected vs detected, selected observer",
    )


# -- benchmark turbine -------------------------------------------------------------------------------------------
def _turbine_plant(sensors: np.ndarray, truth: np.ndarray | None) -> Columns:
    y = np.asarray(sensors["sensors"], dtype=float).reshape(len(sensors), -1)

    def true(name: str, scale: float = 1.0) -> Any:
        return _nan(len(sensors)) if truth is None else np.asarray(truth[name], dtype=float) / scale

    return {
        "speed/omega_g/plant": {
            "sensor 1": y[:, SENSOR_INDEX["omega_g_m1"]],
            "sensor 2": y[:, SENSOR_INDEX["omega_g_m2"]],
            "truth": true("omega_g"),
        },
        "speed/omega_r/plant": {
            "sensor 1": y[:, SENSOR_INDEX["omega_r_m1"]],
            "sensor 2": y[:, SENSOR_INDEX["omega_r_m2"]],
            "truth": true("omega_r"),
        },
        "wind/plant": {"anemometer": y[:, SENSOR_INDEX["v_hub_m"]], "true rotor-effective": true("wind_rotor")},
        "power/plant": {"measured": y[:, SENSOR_INDEX["p_g_m"]] / 1e6, "truth": true("power", 1e6)},
    }


def _turbine_supervisor(sensors: np.ndarray, refs: np.ndarray, status: list[dict[str, Any]] | None) -> Columns:
    first = (status or [{}])[0].get("margins") or {}
    names = list(first)
    margins = [
        [np.nan if m is None else m for m in ((s.get("margins") or {}).get(name) for name in names)]
        for s in (status or [{}] * len(refs))
    ]
    nfte = np.where(np.asarray(refs["nfte_set"], dtype=bool), np.asarray(refs["wind_nfte"], dtype=float), np.nan)
    return {
        "speed/omega_g/supervisor": {"fault-tolerant estimate": refs["omega_g"]},
        "speed/omega_r/supervisor": {"fault-tolerant estimate": refs["omega_r"]},
        "wind/supervisor": {"FTE": refs["wind"], "NFTE": nfte},
        "residuals/supervisor": _margins(names, np.asarray(margins, dtype=float).reshape(len(refs), len(names))),
    }


_RESIDUAL_SCALE = "statistic / threshold, trips above 1 (above 1: 1 + log₁₀, 2 = 10×, 3 = 100×)"


def _turbine_views(turbine: int) -> list[Any]:
    base = f"/turbine/{turbine}"
    return [
        _series_view(
            f"{base}/speed/omega_g",
            f"T{turbine}: generator speed rad/s: sensors (blue, grey), FTE (green), truth (black)",
        ),
        _series_view(
            f"{base}/speed/omega_r", f"T{turbine}: rotor speed rad/s: sensors (blue, grey), FTE (green), truth (black)"
        ),
        _series_view(
            f"{base}/wind",
            f"T{turbine}: wind m/s: FTE (green), NFTE (orange), anemometer (blue), true rotor-effective (black)",
        ),
        _residual_view(  # 11 observers: a legend would cover the traces; hovering a trace names its observer
            f"{base}/residuals",
            f"T{turbine}: {_RESIDUAL_SCALE}: each observer (grey), trip line (red)",
            legend=False,
        ),
        _series_view(f"{base}/power", f"T{turbine}: power MW: measured (blue), truth (black)"),
        _states_view(turbine),
    ]


TURBINE = Panel(
    plant=_turbine_plant,
    supervisor=_turbine_supervisor,
    colors={
        "sensor 1": SENSOR_1,
        "sensor 2": SENSOR_2,
        "anemometer": SENSOR_1,
        "measured": SENSOR_1,
        "fault-tolerant estimate": ESTIMATE,
        "FTE": ESTIMATE,
        "NFTE": REFERENCE,
        "truth": TRUTH,
        "true rotor-effective": TRUTH,
        "threshold": FAULT,
    },
    views=_turbine_views,
)


# -- hydrostatic turbine -----------------------------------------------------------------------------------------
def _hydro_plant(sensors: np.ndarray, truth: np.ndarray | None) -> Columns:
    n = len(sensors)
    y, u = np.asarray(sensors["y"]).reshape(n, -1), np.asarray(sensors["u"]).reshape(n, -1)

    def true(name: str, width: int) -> np.ndarray:
        return np.full((n, width), np.nan) if truth is None else np.asarray(truth[name], dtype=float).reshape(n, -1)

    x, f, u_nom, u_app = true("x", 6), true("f", 2), true("u_nominal", 3), true("u_applied", 3)
    rows: Columns = {
        "speed/omega_r/plant": {"sensor": y[:, 0], "truth": x[:, 0]},
        "speed/omega_g/plant": {"sensor": y[:, 1], "truth": x[:, 1]},
        "hydro/pressure/plant": {"truth": x[:, 2] / 1e6},
        "power/plant": {"truth": true("P_g", 1)[:, 0] / 1e6},
    }
    for j, target in enumerate(FAULT_TARGETS):
        rows[f"hydro/f/{target}/plant"] = {"true offset": f[:, j]}
        rows[f"hydro/commands/{target}/plant"] = {
            "nominal u": u_nom[:, j],
            "corrected u_corr (36)": u[:, j],
            "applied ũ (faults in)": u_app[:, j],
        }
    return rows


def _hydro_supervisor(sensors: np.ndarray, refs: np.ndarray, status: list[dict[str, Any]] | None) -> Columns:
    n = len(refs)
    x_hat = np.asarray(refs["x_hat"], dtype=float).reshape(n, -1)
    f_hat = np.asarray(refs["f_hat"], dtype=float).reshape(n, -1)
    correction = np.asarray(refs["correction"], dtype=float).reshape(n, -1)
    theta = np.array(
        [[(s.get("thresholds") or {}).get(target) or np.nan for target in FAULT_TARGETS] for s in status or [{}] * n],
        dtype=float,
    )
    rows: Columns = {
        "speed/omega_r/supervisor": {"observer": x_hat[:, 0]},
        "speed/omega_g/supervisor": {"observer": x_hat[:, 1]},
        "hydro/pressure/supervisor": {"observer": x_hat[:, 2] / 1e6},
    }
    for j, target in enumerate(FAULT_TARGETS):
        rows[f"hydro/f/{target}/supervisor"] = {"f̂ (35)": f_hat[:, j], "f̂ filtered (37)": correction[:, j]}
    with np.errstate(invalid="ignore", divide="ignore"):
        rows["residuals/supervisor"] = _margins(FAULT_TARGETS, np.abs(correction) / theta)
    return rows


def _hydro_views(turbine: int) -> list[Any]:
    base = f"/turbine/{turbine}"
    return [
        _series_view(
            f"{base}/hydro/f/u_p",
            f"T{turbine}: pump offset f_a1: true (black), reconstruction (35) (orange), filtered (37) (green)",
        ),
        _series_view(
            f"{base}/hydro/f/u_M",
            f"T{turbine}: motor offset f_a2: true (black), reconstruction (35) (orange), filtered (37) (green)",
        ),
        _series_view(
            f"{base}/hydro/commands",
            f"T{turbine}: displacement commands: nominal (grey), corrected (36) (green), applied (red)",
        ),
        _series_view(
            f"{base}/speed",
            f"T{turbine}: rotor and generator speed rad/s: sensor (blue), observer (green), truth (black)",
        ),
        _series_view(f"{base}/hydro/pressure", f"T{turbine}: pressure difference MPa: observer (green), truth (black)"),
        _residual_view(f"{base}/residuals", f"T{turbine}: |f̂_filt| / {_RESIDUAL_SCALE}"),
        _states_view(turbine),
    ]


HYDRO = Panel(
    plant=_hydro_plant,
    supervisor=_hydro_supervisor,
    colors={
        "sensor": SENSOR_1,
        "truth": TRUTH,
        "true offset": TRUTH,
        "observer": ESTIMATE,
        "f̂ (35)": REFERENCE,
        "f̂ filtered (37)": ESTIMATE,
        "nominal u": SENSOR_2,
        "corrected u_corr (36)": ESTIMATE,
        "applied ũ (faults in)": FAULT,
        "u_p": SENSOR_1,
        "u_M": REFERENCE,
        "threshold": FAULT,
    },
    views=_hydro_views,
)

# -- wind farm (seed 001) -----------------------------------------------------------------------------------------
_FARM_TYPES = ("debris", "pitch_misalignment", "drivetrain")


def _farm_turbine_plant(sensors: np.ndarray, truth: np.ndarray | None) -> Columns:
    n = len(sensors)
    y = np.asarray(sensors["sensors"], dtype=float).reshape(n, -1)

    def true(name: str, scale: float = 1.0) -> np.ndarray:
        return _nan(n) if truth is None else np.asarray(truth[name], dtype=float) / scale

    return {
        "power/plant": {"measured": y[:, SENSOR_INDEX["p_g_m"]] / 1e6, "truth": true("power", 1e6)},
        "wind/plant": {
            "anemometer": y[:, SENSOR_INDEX["v_hub_m"]],
            "true rotor-effective": true("wind_rotor"),
            "row mean": true("row_wind"),
        },
    }


def _farm_turbine_supervisor(sensors: np.ndarray, refs: np.ndarray, status: list[dict[str, Any]] | None) -> Columns:
    n = len(refs)
    with np.errstate(invalid="ignore", divide="ignore"):
        margins = np.asarray(refs["statistic"], dtype=float).reshape(n, -1) / np.asarray(
            refs["threshold"], dtype=float
        ).reshape(n, -1)
    return {
        "power/supervisor": {"reference": np.asarray(refs["power_ref"], dtype=float) / 1e6},
        "detector/supervisor": _margins(_FARM_TYPES, margins),
    }


def _farm_turbine_views(turbine: int) -> list[Any]:
    base = f"/turbine/{turbine}"
    return [
        _series_view(f"{base}/power", f"T{turbine}: power MW: measured (blue), truth (black), farm reference (orange)"),
        _residual_view(f"{base}/detector", f"T{turbine}: CUSUM {_RESIDUAL_SCALE} per fault type"),
        _series_view(
            f"{base}/wind", f"T{turbine}: wind m/s: anemometer (blue), rotor-effective (black), row mean (grey)"
        ),
        _states_view(turbine),
    ]


def _farm_plant(sensors: np.ndarray, truth: np.ndarray | None) -> Rows:
    nan = float("nan")
    rows = {
        "power/plant": {
            "farm power": nan if truth is None else float(truth["farm_power"][0]) / 1e6,
            "demand": float(sensors["demand"][0]) / 1e6,
        },
        "wind/plant": {"met mast": float(sensors["mast"][0])},
    }
    if truth is not None:  # one group for the farm (one send a second), not one per turbine
        direction = {"met mast vane": float(sensors["mast_direction"][0])}
        direction |= {f"T{int(t)}": float(d) for t, d in zip(truth["turbine"], truth["wind_direction"], strict=True)}
        rows["direction/plant"] = direction
    return rows


def _farm_supervisor(sensors: np.ndarray, refs: np.ndarray) -> Rows:
    return {"power/supervisor": {"Σ references": float(np.nansum(refs["power_ref"])) / 1e6}}


def _farm_overview(turbines: list[int]) -> list[Any]:
    views: list[Any] = [
        map_view(),
        _series_view("/farm/power", "farm power MW (green) vs demand (black) and the sum of the references (orange)"),
        rrb.TimeSeriesView(
            origin="/farm/direction",
            name="wind direction deg: the mast's vane (blue), the true direction at each turbine (grey)",
            time_ranges=_window(),
            plot_legend=rrb.PlotLegend(visible=False),
        ),
        _residual_view(  # 27 series: no legend; hovering a trace names its turbine
            "/turbine",
            f"CUSUM {_RESIDUAL_SCALE}, all turbines: debris (orange), pitch (purple), drive train (red)",
            contents=[f"/turbine/{t}/detector/**" for t in turbines],
            legend=False,
        ),
        rrb.TimeSeriesView(
            origin="/turbine",
            contents=[f"/turbine/{t}/power/**" for t in turbines],
            name="power per turbine MW: measured (blue), truth (black), its reference (orange)",
            time_ranges=_window(),
            plot_legend=rrb.PlotLegend(visible=False),
        ),
        rrb.StateTimelineView(
            origin="/turbine",
            contents=[f"/turbine/{t}/faults/**" for t in turbines],
            name="faults injected vs detected, all turbines",
        ),
    ]
    return views


FARM = Panel(
    plant=_farm_turbine_plant,
    supervisor=_farm_turbine_supervisor,
    colors={
        "measured": SENSOR_1,
        "truth": TRUTH,
        "reference": REFERENCE,
        "anemometer": SENSOR_1,
        "true rotor-effective": TRUTH,
        "row mean": SENSOR_2,
        "debris": (240, 140, 30),
        "pitch_misalignment": (140, 80, 200),
        "drivetrain": FAULT,
        "threshold": TRUTH,
        "farm power": ESTIMATE,
        "demand": TRUTH,
        "Σ references": REFERENCE,
        "met mast": SENSOR_1,
        "met mast vane": SENSOR_1,
    },
    views=_farm_turbine_views,
    farm_plant=_farm_plant,
    farm_supervisor=_farm_supervisor,
    overview=_farm_overview,
    site_map=geometry_of,
    uses_status=False,  # every series is in the refs rows: the 80 turbines' status is not built for the display
)

PANELS: dict[str, Panel] = {"turbine": TURBINE, "hydro": HYDRO, "farm": FARM}
"""Plant kind → panel. The farm's adds rows of the whole farm and an overview tab."""
