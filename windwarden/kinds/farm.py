"""The wind farm (seed 001's 3 × 3, or any layout: N turbines per farm, from the plant) as a plant kind.

Plant and supervisor are built as ``windwarden.evaluation.farm.simulate_chunk`` builds run 0 of
``windwarden eval SCENARIO --seed S`` (``FarmBatch(..., seed=S, runs=[0])``; the supervisor with the scenario's
detector and controller and accommodation on). The plant ticks at 100 Hz and publishes every turbine's frame each
tick; every tenth tick carries the 10 Hz farm sample (SCADA means, met mast, demand) the supervisor computes on.
The supervisor answers every tick (its references change on farm samples only).

Scorecard of a live run: the batch schema (``evaluation.farm_scoring``), with detection figures from the event log
and the farm's over-production and missing power summed by ``farm_scoring.PowerBalance`` from the truth the plant
node feeds ``FarmScore``, as the batch sums them. Damage numbers need the fault-free twin farm and are batch-only.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from windwarden.evaluation import farm_scoring
from windwarden.evaluation.farm_scoring import PowerBalance
from windwarden.evaluation.kinds import EvalOptions, Evaluation
from windwarden.kinds.base import RunInfo, records_from_batch
from wwcore.events import Event
from wwcore.farm_frames import CANCEL_3P_MODE, DISPATCH_MODES, HOLD_TORQUE_MODE, FarmFrame, FarmRefs
from wwcore.scenario import FaultSpec, Scenario
from wwcore.scenario.farm import FARM_DT_S, FARM_FAULT_TYPES, FarmPlant
from wwcore.turbine_frames import TurbineFrame
from wwcore.wire import FARM_REFS, FARM_SENSORS, FARM_TRUTH

if TYPE_CHECKING:  # the plant process never imports the supervisor's code, nor the supervisor the plant's
    from plant_sim.farm import FarmBatch
    from service.farm.supervisor import FarmSupervisor


class FarmKind:
    kind = "farm"
    section = FarmPlant
    panels = ("farm",)
    example_fault: ClassVar[dict[str, Any]] = {
        "target": "drivetrain",
        "kind": "drivetrain_wear",
        "value": 5.0,
        "turbine": 9,
        "start_s": 0.0,
        "end_s": 1e5,
        "name": "drive-train wear on turbine 9",
    }
    sensors = FARM_SENSORS
    refs = FARM_REFS
    truth = FARM_TRUTH

    def evaluate(self, scenario: Scenario, runs: int, seed: int, options: EvalOptions) -> Evaluation:
        from windwarden.evaluation.farm_eval import evaluate

        return evaluate(scenario, runs, seed, options)

    def make_plant(self, scenario: Scenario, seed: int) -> FarmBatch:
        from plant_sim.farm import FarmBatch

        return FarmBatch(
            scenario.plant,
            scenario.wind,
            scenario.faults,
            seed=seed,
            duration_s=scenario.duration_s,
            runs=[0],
            mismatch=scenario.mismatch,
        )

    def make_supervisor(self, info: RunInfo) -> FarmSupervisor:
        from service.farm.supervisor import FarmSupervisor

        sup = info.supervisor
        return FarmSupervisor(
            info.site,
            len(info.turbines),
            detector=sup.detector,
            controller=sup.controller,
            options=dict(sup.params),
        )

    def turbines(self, plant: FarmBatch) -> list[int]:
        return [int(t) for t in plant.turbine_of_row]

    # -- wire -------------------------------------------------------------------------------------------------------
    def frame_records(self, frame: FarmFrame, turbines: list[int]) -> np.ndarray:
        f = frame.turbines
        values = {
            "tick": frame.k,
            "t": frame.t,
            "sensors": f.sensors,
            "tau_g_ref": f.tau_g_ref,
            "beta_ref": f.beta_ref,
            "power_ref": f.power_ref,
            "zone": f.zone,
            "sample": frame.sample,
            "scada": frame.scada,
            "power_ref_used": frame.power_ref_used,
        }
        per_farm = len(turbines) // frame.farms
        values["mast"] = _per_turbine(frame.mast, per_farm)
        values["demand"] = _per_turbine(frame.demand, per_farm)
        if frame.mast_direction is not None:
            values["mast_direction"] = _per_turbine(frame.mast_direction, per_farm)
        return records_from_batch(FARM_SENSORS, values, turbines)

    def frame_from_records(self, records: np.ndarray) -> FarmFrame:
        k, t = int(records["tick"][0]), float(records["t"][0])
        first = np.flatnonzero(records["turbine"] == records["turbine"][0])  # each farm's first row
        return FarmFrame(
            k=k,
            t=t,
            turbines=TurbineFrame(
                k,
                t,
                np.array(records["sensors"]),
                np.array(records["tau_g_ref"]),
                np.array(records["beta_ref"]),
                np.array(records["power_ref"]),
                np.array(records["zone"]),
            ),
            sample=bool(records["sample"][0]),
            scada=np.array(records["scada"]),
            power_ref_used=np.array(records["power_ref_used"]),
            mast=np.array(records["mast"][first]),
            demand=np.array(records["demand"][first]),
            mast_direction=np.array(records["mast_direction"][first]),
        )

    def refs_records(self, refs: FarmRefs | None, supervisor: FarmSupervisor, turbines: list[int]) -> np.ndarray:
        n = len(turbines)
        diag = supervisor.diagnosis
        values: dict[str, Any] = {
            "tick": supervisor.last_tick,
            "computed_tick": -1 if refs is None else refs.source_tick,
            "power_ref": np.full(n, np.nan) if refs is None else refs.power_ref,
            "mode": supervisor.mode,
            "held_torque": np.nan if refs is None or refs.held_torque is None else refs.held_torque,
            "pitch_trim": 0.0 if refs is None or refs.pitch_trim is None else refs.pitch_trim,
        }
        if refs is not None and refs.ripple_power is not None:
            values["ripple_power"] = np.column_stack([refs.ripple_power.real, refs.ripple_power.imag])
            values["ripple_rate"] = refs.ripple_rate
        if diag is not None:
            values |= {"flags": supervisor.flags, "statistic": diag.statistics, "threshold": diag.thresholds}
        return records_from_batch(FARM_REFS, values, turbines)

    def refs_from_records(self, records: np.ndarray) -> FarmRefs | None:
        computed_ticks = records["computed_tick"]
        computed = int(computed_ticks[0])
        if computed < 0 or (computed_ticks != computed).any():
            # No farm sample yet, or (a sharded supervisor in real time) rows of two farm samples in one tick, one
            # shard having answered before the coordinator's new rows reached it: every turbine keeps the
            # reference it has until the rows agree (a tick or so later), so no turbine takes another sample's
            # phasor time or a row that has no reference (NaN power, computed_tick −1).
            return None
        mode = np.array(records["mode"])
        ripple = records["ripple_power"]
        return FarmRefs(
            tick=int(records["tick"][0]),
            power_ref=np.array(records["power_ref"]),
            computed_tick=computed,
            hold_torque=mode == HOLD_TORQUE_MODE,
            held_torque=np.array(records["held_torque"]),
            cancel_3p=mode == CANCEL_3P_MODE,
            pitch_trim=np.array(records["pitch_trim"]),
            ripple_power=ripple[:, 0] + 1j * ripple[:, 1],
            ripple_rate=np.array(records["ripple_rate"]),
        )

    def hold_unserved(self, records: np.ndarray, served: np.ndarray, last: np.ndarray | None) -> np.ndarray:
        """A tick's refs in which the rows not ``served`` (turbines of a sharded supervisor's lost shard: no sender
        of the plan owns them) keep the turbine's last reference: its row of ``last`` (the refs the plant took
        last) with this tick's ``tick`` and ``computed_tick``, so the tick's rows agree (``refs_from_records``) and
        the controller sees the same power reference, mode, held torque and pitch trim again (no change). The 3P
        ripple a held row asked for is dropped: its phasor needs the coordinator's closed loop, and run open it
        would drift out of phase. Without a reference to keep (none taken yet, or the served rows carry none),
        the rows say "no reference" (computed_tick −1) and the whole tick keeps what it has."""
        out = records.copy()
        held = ~served
        computed = int(records["computed_tick"][served][0]) if served.any() else -1
        keep = held & (last["computed_tick"] >= 0) if last is not None and computed >= 0 else np.zeros_like(held)
        if keep.any():
            for name in ("power_ref", "flags", "statistic", "threshold", "mode", "held_torque", "pitch_trim"):
                out[name][keep] = last[name][keep]
            out["computed_tick"][keep] = computed
            out["ripple_power"][keep], out["ripple_rate"][keep] = 0.0, 0.0
        empty = held & ~keep
        out["computed_tick"][empty], out["power_ref"][empty], out["held_torque"][empty] = -1, np.nan, np.nan
        return out

    def truth_records(self, plant: FarmBatch, frame: FarmFrame, turbines: list[int]) -> np.ndarray:
        truth = plant.truth()
        per_farm = len(turbines) // frame.farms
        farm_power = truth["power"].reshape(-1, per_farm).sum(axis=1)
        values = {
            "tick": plant.k,
            "t": plant.t,
            "omega_r": truth["omega_r"],
            "omega_g": truth["omega_g"],
            "pitch": truth["pitch"],
            "power": truth["power"],
            "power_ref": truth["power_ref"],
            "shaft_torque": truth["shaft_torque"],
            "wind_rotor": truth["wind_rotor"],
            "row_wind": truth["row_wind"],
            "zone": truth["zone"],
            "farm_power": np.repeat(farm_power, per_farm),
            "wind_direction": truth["wind_direction"],
        }
        return records_from_batch(FARM_TRUTH, values, turbines)

    # -- faults -----------------------------------------------------------------------------------------------------
    def inject(self, plant: FarmBatch, fault: FaultSpec) -> None:
        plant.inject(fault)

    def clear(self, plant: FarmBatch, label: str) -> None:
        if not plant.clear(label):
            raise KeyError(label)

    # -- status -----------------------------------------------------------------------------------------------------
    def status(self, supervisor: FarmSupervisor, refs: np.ndarray | None, turbines: list[int]) -> list[dict[str, Any]]:
        """Every turbine's status. The columns are taken out of numpy once (``tolist``), not value by value: the
        supervisor builds this for 80 turbines twice a second on its loop's thread."""
        diag = supervisor.diagnosis
        controller = supervisor.controller
        avail = getattr(controller, "p_avail", None)
        n = len(turbines)
        flags = np.asarray(supervisor.flags, dtype=bool).reshape(n, -1).tolist()
        modes = [DISPATCH_MODES[m] for m in np.asarray(supervisor.mode, dtype=int).tolist()]
        detector = type(supervisor.detector).__name__
        margins = None if diag is None else _finite_rows(diag.margins)
        power_ref = None if supervisor.refs is None else _finite_rows(supervisor.refs.power_ref)
        available = _finite_rows(avail) if avail is not None and len(avail) == n else None
        ticks = None if refs is None else np.asarray(refs["tick"]).tolist()
        out = []
        for row, turbine in enumerate(turbines):
            entry: dict[str, Any] = {
                "turbine": turbine,
                "flagged": [name for name, up in zip(FARM_FAULT_TYPES, flags[row], strict=False) if up],
                "dispatch_mode": modes[row],
                "detector": detector,
            }
            if margins is not None:
                entry["margins"] = dict(zip(FARM_FAULT_TYPES, margins[row], strict=False))
            if power_ref is not None:
                entry["power_ref_w"] = power_ref[row]
            if available is not None:
                entry["available_power_w"] = available[row]
            if ticks is not None:
                entry["tick"] = int(ticks[row])
            out.append(entry)
        return out

    # -- scoring ----------------------------------------------------------------------------------------------------
    def score(self, scenario: Scenario, n_steps: int, dt: float) -> FarmScore:
        return FarmScore(scenario, n_steps, dt)

    def scorecard(
        self, scenario: Scenario, seed: int, faults: list[FaultSpec], events: list[Event], metrics: dict[str, Any]
    ) -> dict[str, Any]:
        from service.farm.supervisor import DEFAULT_CONTROLLER, DEFAULT_DETECTOR

        live = scenario.model_copy(update={"faults": faults})
        windows = farm_scoring.farm_windows(live)
        score, by_type = farm_scoring.detection(events, windows, 1, scenario.duration_s, scenario.plant.n_turbines)
        sup = scenario.supervisor
        return farm_scoring.scorecard(
            scenario,
            runs=1,
            seed=seed,
            detector=sup.detector or DEFAULT_DETECTOR,
            controller=sup.controller or DEFAULT_CONTROLLER,
            accommodation=True,
            score=score,
            metrics={
                "over_production": metrics.get("over_production", {}),
                "missing_power": metrics.get("missing_power", {}),
                "damage": {"note": "damage numbers need the fault-free twin farm: windwarden eval (batch) only"},
                "detection": by_type,
            },
        )


class FarmScore:
    """The farm's power against the demand (``farm_scoring.PowerBalance``, as the batch evaluator sums it)."""

    def __init__(self, scenario: Scenario, n_steps: int, dt: float):
        self.n_steps = n_steps
        self.balance = PowerBalance(scenario.plant.n_turbines, round(FARM_DT_S / dt), scenario.plant.n_turbines)
        self.have = np.zeros(n_steps, dtype=bool)  # ticks whose references reached the plant
        self.ticks = 0  # ticks that ran

    def on_tick(self, k: int, frame: FarmFrame, plant: FarmBatch) -> None:
        self.ticks = max(self.ticks, k + 1)
        self.balance.tick(k, plant.power_output(), frame.sample, frame.demand)

    def on_refs(self, k: int, refs: np.ndarray) -> None:
        """The references reach the plant through ``control``; here only counted, per tick."""
        if 0 <= k < self.n_steps:
            self.have[k] = True

    def result(self, faults: list[FaultSpec]) -> dict[str, Any]:
        b = self.balance
        return {
            **farm_scoring.energy_metrics(b.over, b.missing, b.demand),
            "ticks_without_refs": int((~self.have[: self.ticks]).sum()),
        }


FARM = FarmKind()


def _per_turbine(per_farm_values: np.ndarray, per_farm: int) -> np.ndarray:
    """Each farm's value on each of its turbines' rows: one farm's (a live run) broadcasts as it is."""
    return per_farm_values if len(per_farm_values) == 1 else np.repeat(per_farm_values, per_farm)


def _finite_rows(values: Any) -> list[Any]:
    """``values`` as nested Python lists with NaN and ±inf as None (``finite_or_none`` of every element)."""
    array = np.asarray(values, dtype=float)
    return np.where(np.isfinite(array), array, None).tolist()
