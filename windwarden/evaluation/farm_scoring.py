"""The farm's scorecard, one set of functions for ``windwarden eval`` (``evaluation.farm``) and the live run folder
(``windwarden.kinds.farm``): the fault windows and their targets, the detection figures with Table 5 per fault
type, the farm's power balance against the demand, and the scorecard's fields in their order."""

from __future__ import annotations

from typing import Any

import numpy as np

from windwarden.evaluation.scoring import DetectionScore, FaultWindow, score_detection
from windwarden.evaluation.scoring_policy import FARM as SCORING
from windwarden.evaluation.scoring_policy import farm_policy
from wwcore.events import Event
from wwcore.scenario import Scenario
from wwcore.scenario.farm import FARM_DT_S, FARM_FAULT_TYPES, farm_fault_name

WARMUP_S = SCORING.warmup_s  # s, not scored (scoring_policy says why)
GRACE_S = SCORING.grace_s  # s after a fault ends during which its flags may still be up (scoring_policy)
MWH_PER_J = 1.0 / 3.6e9
MAX_SHOWN = 12  # turbines a plot or a table shows one by one at most


def shown_turbines(scenario: Scenario) -> list[int]:
    """0-based turbines a plot or table shows one by one: all of a farm of at most ``MAX_SHOWN``; else the faulty
    ones, then the first."""
    n = scenario.plant.n_turbines
    if n <= MAX_SHOWN:
        return list(range(n))
    faulty = sorted({f.turbine - 1 for f in scenario.faults})[:MAX_SHOWN]
    rest = [t for t in range(n) if t not in faulty][: MAX_SHOWN - len(faulty)]
    return sorted(faulty + rest)


def farm_windows(scenario: Scenario) -> list[FaultWindow]:
    """One window per fault, its target the flagged name (debris, pitch_misalignment, drivetrain, or a sensor)."""
    out = []
    for f in sorted(scenario.faults, key=lambda f: (f.start_s, f.turbine)):
        end = scenario.duration_s if f.end_s is None else min(f.end_s, scenario.duration_s)
        out.append(FaultWindow(f.label, (farm_fault_name(f),), f.turbine, f.start_s, end))
    return out


def scorecard_target(w: FaultWindow) -> str:
    return f"wt{w.turbine}:{w.target}"


def score_farm(
    events: list[Event], windows: list[FaultWindow], runs: int, duration_s: float, turbines: int
) -> DetectionScore:
    """The detection figures of farm runs (``scoring.score_detection``, every turbine in the time base)."""
    return score_detection(
        events,
        windows,
        runs=runs,
        duration_s=duration_s,
        policy=farm_policy(turbines),
        turbines=tuple(range(1, turbines + 1)),
    )


def detection_by_type(
    events: list[Event], windows: list[FaultWindow], runs: int, duration_s: float, turbines: int
) -> dict:
    """Table 5 per fault type: detected % and mean/max delay with the right type and turbine, isolated % (first
    flag), false positives of that type (``DetectionScore.by_target``) per 1000 farm-s and turbine-s."""
    return detection(events, windows, runs, duration_s, turbines)[1]


def detection(
    events: list[Event], windows: list[FaultWindow], runs: int, duration_s: float, turbines: int
) -> tuple[DetectionScore, dict[str, Any]]:
    """The scorecard's detection figures (each window's target ``wt<k>:<type>``) and Table 5 per fault type, for
    farms of ``turbines`` turbines."""
    score = score_farm(events, windows, runs, duration_s, turbines)
    for entry, w in zip(score.faults, windows, strict=True):
        entry["target"] = scorecard_target(w)
    farm_seconds = runs * max(duration_s - WARMUP_S, 0.0)
    return score, {name: score.by_target(name, farm_seconds) for name in FARM_FAULT_TYPES}


class PowerBalance:
    """The farm's true output (10 Hz block means of the turbines' power) against the demand, after the warm-up:
    ∫ pos(P_farm − P_ref,farm) dt, ∫ pos(P_ref,farm − P_farm) dt and ∫ P_ref,farm dt in J, per farm of the batch
    (``rows`` turbine rows, farm-major, ``turbines`` per farm)."""

    def __init__(self, rows: int, ticks_per_sample: int, turbines: int):
        self.turbines = turbines
        self.farms = rows // turbines
        self.per_sample = ticks_per_sample
        self.warm_sample = round(WARMUP_S / FARM_DT_S)
        self.power_sum = np.zeros(rows)
        self.over = np.zeros(self.farms)
        self.missing = np.zeros(self.farms)
        self.demand = np.zeros(self.farms)

    def tick(self, k: int, power: np.ndarray, sample: bool, demand: np.ndarray) -> np.ndarray | None:
        """Tick k's turbine powers (W, one per row); on a farm sample tick the block's mean farm power (W, one per
        farm), counted against ``demand`` once past the warm-up; None between samples."""
        self.power_sum += power
        return self._sample(k, demand) if sample else None

    def block(self, k: int, power: np.ndarray, sample: bool, demand: np.ndarray) -> np.ndarray | None:
        """``tick`` for the ticks of a block ending at tick k, ``power`` (ticks, rows) W: the rows added in their
        order, as tick by tick."""
        for row in power:
            self.power_sum += row
        return self._sample(k, demand) if sample else None

    def _sample(self, k: int, demand: np.ndarray) -> np.ndarray:
        """The farm sample ending at tick k: its mean farm power (W, one per farm), counted once past the warm-up."""
        p_farm = (self.power_sum * (1.0 / self.per_sample)).reshape(self.farms, self.turbines).sum(axis=1)
        self.power_sum[:] = 0.0
        if (k + 1) // self.per_sample > self.warm_sample:
            gap = p_farm - demand
            self.over += np.maximum(gap, 0.0) * FARM_DT_S
            self.missing += np.maximum(-gap, 0.0) * FARM_DT_S
            self.demand += demand * FARM_DT_S
        return p_farm


def farm_geometry(scenario: Scenario) -> dict[str, Any]:
    """The farm the scorecard is of: the paper's wind case on its 3 × 3; for a layout or a direction, the number of
    turbines, the layout's source and the wind direction instead (the wind case says nothing there)."""
    plant = scenario.plant
    if plant.layout is None and plant.wind_direction_deg is None and plant.wind_direction_profile is None:
        return {"wind_case": plant.wind_case}
    layout = plant.resolved_layout()
    out = {"turbines": layout.n_turbines, "layout": layout.source, "wind_direction_deg": plant.direction_deg}
    if plant.direction_varies:  # the direction at t = 0, and how it moves
        lo, hi = plant.direction_sector_deg()
        out |= {"wind_direction_range_deg": [lo, hi], "veer_sigma_deg": plant.veer_sigma_deg}
    return out


def energy_metrics(over_j: np.ndarray, missing_j: np.ndarray, demand_j: np.ndarray) -> dict[str, Any]:
    """Over-production and missing power of the runs (J each): MWh per run, and as a fraction of the demand."""
    demand = float(np.sum(demand_j))

    def energy(joules: np.ndarray) -> dict[str, Any]:
        return {
            "mwh_per_run": float(np.mean(joules) * MWH_PER_J),
            "fraction_of_demand": float(np.sum(joules) / demand) if demand > 0 else None,
        }

    return {"over_production": energy(over_j), "missing_power": energy(missing_j)}


def scorecard(
    scenario: Scenario,
    *,
    runs: int,
    seed: int,
    detector: str,
    controller: str,
    accommodation: bool,
    score: DetectionScore,
    metrics: dict[str, Any],
    provenance: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The farm scorecard (``docs/scorecards.md``); ``provenance``: the batch's options and runs digest."""
    return {
        "scenario": scenario.name,
        "runs": runs,
        "seed": seed,
        "duration_s": scenario.duration_s,
        **farm_geometry(scenario),
        "detector": detector,
        "controller": controller,
        "accommodation": accommodation,
        **(provenance or {}),
        **score.card_fields(),
        "metrics": metrics,
    }
