"""Monte Carlo runs of a farm (seed 001's nine turbines, or any layout's N) and its supervisor, and their scorecard
(the evaluator that ``windwarden eval`` calls is ``farm_eval``).

Per run (``FarmBatch``), and when the scenario has faults also its fault-free twin farm (same wind and noise
streams, no faults, same supervisor), in one batch. The scorecard has the schema of the turbine kind:

* ``faults``: one entry per scheduled fault window (``scoring.score_detection``, ``docs/scorecards.md``), target
  ``wt<k>:<type>``: a flag is a (turbine, fault type) pair, so a detection needs the right type on the right
  turbine, and any other flag raised in the farm during the window is a wrong isolation;
* ``false_alarms_per_1000s``: flags raised outside every window, per 1000 turbine-seconds;
* ``metrics.detection``: Table 5 per fault type: detection rate and delay with the right type and turbine,
  false positives of that type (raised where it is not the fault) per 1000 s (farm-seconds, the paper's basis,
  and turbine-seconds), on these runs;
* ``metrics.over_production`` / ``metrics.missing_power``: ∫ pos(P_farm − P_ref,farm) dt and
  ∫ pos(P_ref,farm − P_farm) dt after the warm-up, P_farm the farm's true output (10 Hz block means), per run;
* ``metrics.damage``: drive-train damage (rainflow of the shaft torque, m = 4, against the fault-free twin's;
  ``farm_damage``) of the faulty turbine and of the farm's nine, per fault window and over the run, each run's
  figure kept for paired comparisons; the rotor imbalance of pitch faults.

N comes from the scenario's layout (``FarmPlant.n_turbines``); a process takes at most ``MAX_CHUNK_ROWS`` turbine
rows (``MAX_CHUNK`` runs of nine: 50 runs of the 3 × 3, 5 of Horns Rev 1's 80).

"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from plant_sim.farm import FarmBatch
from plant_sim.farm.damage import imbalance_phasor
from plant_sim.farm.rainflow_stream import StreamingDamage
from service.farm.interfaces import N_TYPES
from service.farm.supervisor import FarmSupervisor
from windwarden.evaluation import farm_damage
from windwarden.evaluation.farm_scoring import (
    MWH_PER_J,
    WARMUP_S,
    PowerBalance,
    detection,
    energy_metrics,
    farm_windows,
    scorecard,
    scorecard_target,
)
from windwarden.evaluation.kinds import EvalOptions
from windwarden.evaluation.paired import runs_digest
from windwarden.evaluation.parallel import run_chunks
from windwarden.evaluation.scoring import FaultWindow, twin_false_alarms
from windwarden.evaluation.scoring_policy import farm_policy
from wwcore.events import Event, EventType
from wwcore.scenario import Scenario
from wwcore.scenario.farm import FARM_DT_S, N_TURBINES

DAMAGE_BIN_S = 10.0  # s, time resolution of the damage sums (Fig. 4)
MAX_CHUNK = 50  # runs of the 3 × 3 per process at most: 100 runs are two chunks of 50 (900 rows and their twins)
MAX_CHUNK_ROWS = MAX_CHUNK * N_TURBINES  # turbine rows per process at most (twins apart), for a farm of any size
PROGRESS_EVERY = 1000  # ticks between progress reports


# ---- one chunk of runs ------------------------------------------------------------------------------------------
@dataclass
class ChunkResult:
    runs: list[int]
    events: list[Event]  # run = Monte Carlo run; twin events have detail["twin"] = True
    over_j: np.ndarray  # (farms,) J
    missing_j: np.ndarray  # (farms,) J
    demand_j: np.ndarray  # (farms,) J
    damage: np.ndarray  # (farms, N, bins) Σ n S^m per DAMAGE_BIN_S bin; no bins without twins
    imbalance: np.ndarray  # (farms, N, windows) complex mean imbalance per fault window; 0 without twins
    twins: bool
    trace: dict[str, np.ndarray] = field(default_factory=dict)  # farm 0 (and its twin), 10 Hz


def simulate_chunk(
    run_ids: list[int],
    progress,
    scenario: Scenario,
    seed: int,
    detector: str,
    controller: str,
    accommodation: bool,
    options: dict,
    twins: bool,
) -> ChunkResult:
    plant = FarmBatch(
        scenario.plant,
        scenario.wind,
        scenario.faults,
        seed=seed,
        duration_s=scenario.duration_s,
        runs=run_ids,
        fault_free_twins=twins,
        mismatch=scenario.mismatch,
    )
    sup = FarmSupervisor(
        scenario.plant.site(plant.dt),
        plant.n,
        detector=detector,
        controller=controller,
        accommodation=accommodation,
        options=options,
    )
    dt, farms, n, per_farm = plant.dt, plant.farms, plant.n, plant.n_turbines
    n_steps = round(scenario.duration_s / dt)
    per_sample = plant.ticks_per_sample
    windows = farm_windows(scenario)
    bins = np.arange(0, n_steps + 1, round(DAMAGE_BIN_S / dt))
    if bins[-1] != n_steps:
        bins = np.append(bins, n_steps)
    # Damage numbers are ratios to the fault-free twin, so without twins nothing would read the shaft torque's
    # reversals (under cProfile they took ≈ 13 % of a detection-only run).
    damage_counter = StreamingDamage(n, bins) if twins else None
    balance = PowerBalance(n, per_sample, per_farm)
    imb_sum = np.zeros((n, len(windows)), dtype=complex)
    imb_count = np.zeros(len(windows))
    trace_on = 0 in run_ids
    r0 = run_ids.index(0) if trace_on else 0
    trace_farms = [r0] + ([r0 + len(run_ids)] if twins else [])
    trace_rows = np.concatenate([np.arange(f * per_farm, (f + 1) * per_farm) for f in trace_farms])
    trace: dict[str, list] = {k: [] for k in ("t", "power", "demand", "power_t", "ref_t", "stat", "thr", "flags")}
    events: list[Event] = []

    def record(k: int, block, refs) -> None:
        """A block's truth (its turbines' power and shaft torque, ticks to k); the farm sample's when it ends one."""
        frame = block.frame if block.frame.sample else None
        p_farm = balance.block(k, block.power, frame is not None, None if frame is None else frame.demand)
        if damage_counter is not None:
            for i, shaft in enumerate(block.shaft_torque):
                damage_counter.step(block.first_tick + i, shaft)
        if p_farm is None:
            return
        t = (k + 1) // per_sample * FARM_DT_S
        if twins:  # the imbalance, like the damage, is read against the twin only
            inside = [i for i, w in enumerate(windows) if w.start_s <= t < w.end_s]
            if inside:
                imb_sum[:, inside] += imbalance_phasor(plant.blade_torque)[:, None]
                imb_count[inside] += 1
        if trace_on:
            diag = sup.diagnosis
            rows = trace_rows
            trace["t"].append(t)
            trace["power"].append(p_farm[trace_farms])
            trace["demand"].append(frame.demand[trace_farms])
            trace["power_t"].append(frame.scada[rows, -1])
            trace["ref_t"].append(refs.power_ref[rows] if refs is not None else np.full(len(rows), np.nan))
            trace["stat"].append(diag.statistics[rows] if diag is not None else np.zeros((len(rows), N_TYPES)))
            trace["thr"].append(diag.thresholds[rows] if diag is not None else np.zeros((len(rows), N_TYPES)))
            trace["flags"].append(diag.faulty[rows] if diag is not None else np.zeros((len(rows), N_TYPES)))

    # A farm sample at a time (``FarmBatch.run_sample``): the supervisor answers samples only and returns the same
    # references in between, so it is given each sample's frame; the ticks' truth comes with the block.
    refs = None
    while plant.k < n_steps:
        block = plant.run_sample(refs, n_steps - plant.k, shaft_torque=damage_counter is not None, states=False)
        refs = sup.step(block.frame)
        first, end = block.first_tick, block.first_tick + len(block.power)
        record(end - 1, block, refs)
        passed = end // PROGRESS_EVERY - first // PROGRESS_EVERY  # progress marks the block's ticks reached
        if passed:
            events.extend(plant.drain_events() + sup.drain_events())
            progress(passed * PROGRESS_EVERY * dt)
    events += plant.drain_events() + sup.drain_events()
    progress((n_steps % PROGRESS_EVERY) * dt)
    if damage_counter is not None:
        damage_counter.finish(n_steps)
        damage = damage_counter.sums.reshape(farms, per_farm, -1)
    else:
        damage = np.zeros((farms, per_farm, 0))
    with np.errstate(invalid="ignore"):
        imbalance = (imb_sum / np.maximum(imb_count, 1)).reshape(farms, per_farm, -1)
    return ChunkResult(
        runs=list(run_ids),
        events=[_relabel(e, plant.run_of_farm, plant.twin_of_farm, run_ids) for e in events],
        over_j=balance.over,
        missing_j=balance.missing,
        demand_j=balance.demand,
        damage=damage,
        imbalance=imbalance,
        twins=twins,
        trace={k: np.asarray(v) for k, v in trace.items()} if trace_on else {},
    )


def _relabel(event: Event, run_of_farm: np.ndarray, twin_of_farm: np.ndarray, run_ids: list[int]) -> Event:
    """Supervisor events carry the farm index as ``run``; plant events the Monte Carlo run already."""
    if event.type in (EventType.FAULT_INJECTED, EventType.FAULT_CLEARED):
        return event
    farm = event.run
    detail = dict(event.detail)
    if twin_of_farm[farm]:
        detail["twin"] = True
    return replace(event, run=int(run_ids[run_of_farm[farm]]), detail=detail)


# ---- merging and scoring ------------------------------------------------------------------------------------------
@dataclass
class Variant:
    """All runs of one configuration, merged in run order (farms: the runs, then their twins if any)."""

    scenario: Scenario
    runs: int
    seed: int
    detector: str
    controller: str
    accommodation: bool
    events: list[Event]  # main farms
    twin_events: list[Event]
    over_j: np.ndarray  # (runs,)
    missing_j: np.ndarray
    demand_j: np.ndarray
    damage: np.ndarray  # (runs, N, bins)
    twin_damage: np.ndarray | None
    imbalance: np.ndarray  # (runs, N, windows) complex
    twin_imbalance: np.ndarray | None
    trace: dict[str, np.ndarray]


def run_variant(
    scenario: Scenario,
    runs: int,
    seed: int,
    options: EvalOptions,
    *,
    detector: str,
    controller: str,
    accommodation: bool,
    twins: bool,
    label: str | None = None,
) -> Variant:
    parts: list[ChunkResult] = run_chunks(
        simulate_chunk,
        runs,
        scenario.duration_s * (2 if twins else 1),
        options,
        args=(scenario, seed, detector, controller, accommodation, dict(scenario.supervisor.params), twins),
        max_chunk=max(1, MAX_CHUNK_ROWS // scenario.plant.n_turbines),
        label=label or scenario.name,
    )
    order = np.argsort(np.concatenate([p.runs for p in parts]))

    def main(name: str) -> np.ndarray:
        return np.concatenate([getattr(p, name)[: len(p.runs)] for p in parts])[order]

    def twin(name: str) -> np.ndarray | None:
        if not twins:
            return None
        return np.concatenate([getattr(p, name)[len(p.runs) :] for p in parts])[order]

    events = sorted((e for p in parts for e in p.events), key=lambda e: (e.run, e.t))
    return Variant(
        scenario=scenario,
        runs=runs,
        seed=seed,
        detector=detector,
        controller=controller,
        accommodation=accommodation,
        events=[e for e in events if not e.detail.get("twin")],
        twin_events=[e for e in events if e.detail.get("twin")],
        over_j=main("over_j"),
        missing_j=main("missing_j"),
        demand_j=main("demand_j"),
        damage=main("damage"),
        twin_damage=twin("damage"),
        imbalance=main("imbalance"),
        twin_imbalance=twin("imbalance"),
        trace=next((p.trace for p in parts if p.trace), {}),
    )


def damage_metrics(v: Variant, windows: list[FaultWindow]) -> tuple[dict[str, Any], dict[str, list[float]]]:
    """Table 7's damage figures of a variant, the faulty turbine's and the farm's (``farm_damage``): the means
    and each run's values."""
    return farm_damage.damage_metrics(
        v.damage,
        v.twin_damage,
        DAMAGE_BIN_S,
        WARMUP_S,
        windows,
        [scorecard_target(w) for w in windows],
        v.imbalance,
        v.twin_imbalance,
    )


def power_per_run(v: Variant) -> dict[str, list[float]]:
    """Each run's over-production and missing power, MWh, in run order (the scorecard's ``per_run``)."""
    return {
        "over_production_mwh": (v.over_j * MWH_PER_J).tolist(),
        "missing_power_mwh": (v.missing_j * MWH_PER_J).tolist(),
    }


def scorecard_of(v: Variant) -> dict[str, Any]:
    scenario = v.scenario
    windows = farm_windows(scenario)
    score, by_type = detection(v.events, windows, v.runs, scenario.duration_s, scenario.plant.n_turbines)
    metrics: dict[str, Any] = energy_metrics(v.over_j, v.missing_j, v.demand_j)
    metrics["damage"], damage_by_run = damage_metrics(v, windows)
    metrics["detection"] = by_type
    card = scorecard(
        scenario,
        runs=v.runs,
        seed=v.seed,
        detector=v.detector,
        controller=v.controller,
        accommodation=v.accommodation,
        score=score,
        metrics=metrics,
        provenance={"options": dict(scenario.supervisor.params), "runs_digest": runs_digest(scenario)},
    )
    card["per_run"] = power_per_run(v) | damage_by_run  # run order; ``windwarden compare`` pairs two scorecards
    if v.twin_events:
        observed = v.runs * (scenario.duration_s - WARMUP_S) * scenario.plant.n_turbines
        whole_run = [(0.0, scenario.duration_s)]
        policy = farm_policy(scenario.plant.n_turbines)
        card["false_alarms_twin"] = twin_false_alarms(v.twin_events, observed, policy, whole_run)
    return card
