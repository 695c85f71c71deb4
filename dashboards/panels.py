"""What each plant kind shows: which series each process logs, their styles, and the views of its panel.

One ``Panel`` per kind, chosen by name (``PANELS``). A panel maps the wire records a process already holds (sensor,
truth and refs records of ``wwcore.wire``, the supervisor's per-turbine status) to groups of scalar series under
``/turbine/<id>/…``: the plant's ``…/plant`` and the supervisor's ``…/supervisor`` entities side by side in one
view. It also lays out the views of one turbine. The farm kind adds its panel (and a farm overview).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import rerun.blueprint as rrb

from wwcore.channels import SENSOR_INDEX
from wwcore.hydro_params import FAULT_TARGETS

Rows = dict[str, dict[str, float]]
"""One row of every series group: group path under ``/turbine/<id>/`` → series name → value. A group is one entity
holding several scalar series (one ``send_columns`` call for all of them); its names stay the same from row to row."""
WINDOW_S = 120.0  # s of simulation time the time-series views follow behind the cursor

# Colours: sensors grey/blue, fault-tolerant estimate green, non-fault-tolerant orange, truth black, faults red.
SENSOR_1, SENSOR_2 = (120, 144, 200), (150, 150, 150)
ESTIMATE, REFERENCE, TRUTH, FAULT = (40, 170, 80), (240, 140, 30), (20, 20, 20), (220, 50, 50)


@dataclass(frozen=True)
class Panel:
    """The live dashboard of one plant kind."""

    plant: Callable[[np.void, np.void | None], Rows]  # (sensor record, truth record or None) → rows of one turbine
    supervisor: Callable[[np.void, np.void, dict[str, Any]], Rows]  # (sensors, refs, status of that turbine)
    colors: dict[str, tuple[int, int, int]]  # series name → colour
    views: Callable[[int], list[Any]]  # turbine → views
    # A plant of several turbines may add rows of the whole plant under ``/farm/…`` and an overview tab:
    farm_plant: Callable[[np.ndarray, np.ndarray | None], Rows] | None = None  # (all sensor rows, all truth rows)
    farm_supervisor: Callable[[np.ndarray, np.ndarray], Rows] | None = None  # (all sensor rows, all refs rows)
    overview: Callable[[list[int]], list[Any]] | None = None  # turbines → views of the overview tab


def _window() -> list[rrb.VisibleTimeRange]:
    return [
        rrb.VisibleTimeRange(
            "sim_time",
            start=rrb.TimeRangeBoundary.cursor_relative(seconds=-WINDOW_S),
            end=rrb.TimeRangeBoundary.cursor_relative(),
        )
    ]


def _series_view(origin: str, name: str, window: bool = True) -> rrb.TimeSeriesView:
    return rrb.TimeSeriesView(origin=origin, name=name, time_ranges=_window() if window else None)


def _states_view(turbine: int) -> rrb.StateTimelineView:
    base = f"/turbine/{turbine}"
    return rrb.StateTimelineView(
        origin=base,
        contents=[f"{base}/faults/**", f"{base}/observer"],
        name=f"T{turbine}: faults injected vs detected, selected observer",
    )


# -- benchmark turbine -------------------------------------------------------------------------------------------
def _turbine_plant(sensors: np.void, truth: np.void | None) -> Rows:
    y = sensors["sensors"]
    nan = float("nan")

    def true(name: str, scale: float = 1.0) -> float:
        return nan if truth is None else float(truth[name]) / scale

    return {
        "speed/omega_g/plant": {
            "sensor 1": y[SENSOR_INDEX["omega_g_m1"]],
            "sensor 2": y[SENSOR_INDEX["omega_g_m2"]],
            "truth": true("omega_g"),
        },
        "speed/omega_r/plant": {
            "sensor 1": y[SENSOR_INDEX["omega_r_m1"]],
            "sensor 2": y[SENSOR_INDEX["omega_r_m2"]],
            "truth": true("omega_r"),
        },
        "wind/plant": {"anemometer": y[SENSOR_INDEX["v_hub_m"]], "true rotor-effective": true("wind_rotor")},
        "power/plant": {"measured": y[SENSOR_INDEX["p_g_m"]] / 1e6, "truth": true("power", 1e6)},
    }


def _turbine_supervisor(sensors: np.void, refs: np.void, status: dict[str, Any]) -> Rows:
    margins = {name: (float("nan") if m is None else m) for name, m in (status.get("margins") or {}).items()}
    return {
        "speed/omega_g/supervisor": {"fault-tolerant estimate": refs["omega_g"]},
        "speed/omega_r/supervisor": {"fault-tolerant estimate": refs["omega_r"]},
        "wind/supervisor": {"FTE": refs["wind"], "NFTE": refs["wind_nfte"] if refs["nfte_set"] else float("nan")},
        "residuals/supervisor": margins | {"threshold": 1.0},
    }


def _turbine_views(turbine: int) -> list[Any]:
    base = f"/turbine/{turbine}"
    return [
        _series_view(f"{base}/speed/omega_g", f"T{turbine}: generator speed rad/s: sensors vs FTE vs truth"),
        _series_view(f"{base}/speed/omega_r", f"T{turbine}: rotor speed rad/s: sensors vs FTE vs truth"),
        _series_view(f"{base}/wind", f"T{turbine}: wind m/s: FTE vs NFTE vs anemometer vs true rotor-effective"),
        _series_view(f"{base}/residuals", f"T{turbine}: residual / threshold per observer (trips above 1)"),
        _series_view(f"{base}/power", f"T{turbine}: power MW"),
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
def _hydro_plant(sensors: np.void, truth: np.void | None) -> Rows:
    y, u = sensors["y"], sensors["u"]
    nan = float("nan")
    x = truth["x"] if truth is not None else np.full(6, nan)
    f = truth["f"] if truth is not None else np.full(2, nan)
    u_nom = truth["u_nominal"] if truth is not None else np.full(3, nan)
    u_app = truth["u_applied"] if truth is not None else np.full(3, nan)
    rows: Rows = {
        "speed/omega_r/plant": {"sensor": y[0], "truth": x[0]},
        "speed/omega_g/plant": {"sensor": y[1], "truth": x[1]},
        "hydro/pressure/plant": {"truth": x[2] / 1e6},
        "power/plant": {"truth": nan if truth is None else truth["P_g"] / 1e6},
    }
    for j, target in enumerate(FAULT_TARGETS):
        rows[f"hydro/f/{target}/plant"] = {"true offset": f[j]}
        rows[f"hydro/commands/{target}/plant"] = {
            "nominal u": u_nom[j],
            "corrected u_corr (36)": u[j],
            "applied ũ (faults in)": u_app[j],
        }
    return rows


def _hydro_supervisor(sensors: np.void, refs: np.void, status: dict[str, Any]) -> Rows:
    thresholds = status.get("thresholds") or {}
    rows: Rows = {
        "speed/omega_r/supervisor": {"observer": refs["x_hat"][0]},
        "speed/omega_g/supervisor": {"observer": refs["x_hat"][1]},
        "hydro/pressure/supervisor": {"observer": refs["x_hat"][2] / 1e6},
    }
    margins: dict[str, float] = {}
    for j, target in enumerate(FAULT_TARGETS):
        rows[f"hydro/f/{target}/supervisor"] = {"f̂ (35)": refs["f_hat"][j], "f̂ filtered (37)": refs["correction"][j]}
        theta = thresholds.get(target)
        margins[target] = abs(float(refs["correction"][j])) / theta if theta else float("nan")
    rows["residuals/supervisor"] = margins | {"threshold": 1.0}
    return rows


def _hydro_views(turbine: int) -> list[Any]:
    base = f"/turbine/{turbine}"
    return [
        _series_view(f"{base}/hydro/f/u_p", f"T{turbine}: pump offset f_a1: true vs reconstruction (35) vs filtered"),
        _series_view(f"{base}/hydro/f/u_M", f"T{turbine}: motor offset f_a2: true vs reconstruction vs filtered"),
        _series_view(
            f"{base}/hydro/commands", f"T{turbine}: displacement commands: nominal vs corrected (36) vs applied"
        ),
        _series_view(f"{base}/speed", f"T{turbine}: rotor and generator speed rad/s: sensor vs observer vs truth"),
        _series_view(f"{base}/hydro/pressure", f"T{turbine}: pressure difference MPa: observer vs truth"),
        _series_view(f"{base}/residuals", f"T{turbine}: |f̂_filt| / threshold (trips above 1)"),
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


def _farm_turbine_plant(sensors: np.void, truth: np.void | None) -> Rows:
    nan = float("nan")
    return {
        "power/plant": {
            "measured": sensors["sensors"][SENSOR_INDEX["p_g_m"]] / 1e6,
            "truth": nan if truth is None else float(truth["power"]) / 1e6,
        },
        "wind/plant": {
            "anemometer": sensors["sensors"][SENSOR_INDEX["v_hub_m"]],
            "true rotor-effective": nan if truth is None else float(truth["wind_rotor"]),
            "row mean": nan if truth is None else float(truth["row_wind"]),
        },
    }


def _farm_turbine_supervisor(sensors: np.void, refs: np.void, status: dict[str, Any]) -> Rows:
    with np.errstate(invalid="ignore", divide="ignore"):
        margins = np.asarray(refs["statistic"], dtype=float) / np.asarray(refs["threshold"], dtype=float)
    return {
        "power/supervisor": {"reference": float(refs["power_ref"]) / 1e6},
        "detector/supervisor": dict(zip(_FARM_TYPES, map(float, margins), strict=True)) | {"threshold": 1.0},
    }


def _farm_turbine_views(turbine: int) -> list[Any]:
    base = f"/turbine/{turbine}"
    return [
        _series_view(f"{base}/power", f"T{turbine}: power MW: measured vs truth vs farm reference"),
        _series_view(f"{base}/detector", f"T{turbine}: test statistic / threshold per fault type (trips above 1)"),
        _series_view(f"{base}/wind", f"T{turbine}: wind m/s: anemometer vs rotor-effective vs row mean"),
        _states_view(turbine),
    ]


def _farm_plant(sensors: np.ndarray, truth: np.ndarray | None) -> Rows:
    nan = float("nan")
    return {
        "power/plant": {
            "farm power": nan if truth is None else float(truth["farm_power"][0]) / 1e6,
            "demand": float(sensors["demand"][0]) / 1e6,
        },
        "wind/plant": {"met mast": float(sensors["mast"][0])},
    }


def _farm_supervisor(sensors: np.ndarray, refs: np.ndarray) -> Rows:
    return {"power/supervisor": {"Σ references": float(np.nansum(refs["power_ref"])) / 1e6}}


def _farm_overview(turbines: list[int]) -> list[Any]:
    views: list[Any] = [
        _series_view("/farm/power", "farm power vs demand MW (and the sum of the references)"),
        rrb.TimeSeriesView(
            origin="/turbine",
            contents=[f"/turbine/{t}/detector/**" for t in turbines],
            name="CUSUM statistics / thresholds, all turbines (trips above 1)",
            time_ranges=_window(),
        ),
        rrb.TimeSeriesView(
            origin="/turbine",
            contents=[f"/turbine/{t}/power/**" for t in turbines],
            name="power per turbine vs its reference MW",
            time_ranges=_window(),
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
    },
    views=_farm_turbine_views,
    farm_plant=_farm_plant,
    farm_supervisor=_farm_supervisor,
    overview=_farm_overview,
)

PANELS: dict[str, Panel] = {"turbine": TURBINE, "hydro": HYDRO, "farm": FARM}
"""Plant kind → panel. The farm's adds rows of the whole farm and an overview tab."""
