"""The 4.8 MW benchmark turbine (seed 000 supervisor) as a plant kind.

Plant and supervisor are built exactly as ``windwarden.evaluation.turbine.simulate_chunk`` builds run 0 of
``windwarden eval SCENARIO --seed S`` (``TurbineBatch(..., seed=S, runs=[0])``, the supervisor with the scenario's
detector, estimator and options), and the wind RMSE figures are accumulated as that function accumulates them:
per tick, the squared error of the FTE, the NFTE and the anemometer against the true rotor-effective wind, summed
in tick order into the window of the tick. So a lockstep run and ``windwarden eval --runs 1`` give the same
scorecard. A tick whose refs never reached the plant (supervisor down) is left out of the RMSE.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from windwarden.evaluation import turbine_scoring
from windwarden.evaluation.kinds import EvalOptions, Evaluation
from windwarden.evaluation.turbine_scoring import WIND_KEYS, window_of_tick
from windwarden.kinds.base import RunInfo, finite_or_none, records_from_batch
from wwcore.channels import DIAGNOSIS_TARGETS, SENSOR_INDEX
from wwcore.events import Event
from wwcore.scenario import FaultSpec, Scenario
from wwcore.scenario.turbine import TurbinePlant
from wwcore.turbine_frames import TurbineFrame, TurbineRefs
from wwcore.wire import TURBINE_REFS, TURBINE_SENSORS, TURBINE_TRUTH

if TYPE_CHECKING:  # the plant process never imports the supervisor's code, nor the supervisor the plant's
    from plant_sim.turbine import TurbineBatch
    from service.turbine.supervisor import TurbineSupervisor

_ANEMOMETER = SENSOR_INDEX["v_hub_m"]


class TurbineKind:
    kind = "turbine"
    section = TurbinePlant
    panels = ("turbine",)
    example_fault: ClassVar[dict[str, Any]] = {
        "target": "omega_g_m2",
        "kind": "fixed",
        "value": 100.0,
        "start_s": 0.0,
        "end_s": 1e5,
        "name": "generator-speed sensor 2 stuck",
    }
    sensors = TURBINE_SENSORS
    refs = TURBINE_REFS
    truth = TURBINE_TRUTH

    def evaluate(self, scenario: Scenario, runs: int, seed: int, options: EvalOptions) -> Evaluation:
        from windwarden.evaluation.turbine import evaluate

        return evaluate(scenario, runs, seed, options)

    def make_plant(self, scenario: Scenario, seed: int) -> TurbineBatch:
        from plant_sim.turbine import TurbineBatch

        return TurbineBatch(
            scenario.plant, scenario.wind, scenario.faults, seed=seed, runs=[0], mismatch=scenario.mismatch
        )

    def make_supervisor(self, info: RunInfo) -> TurbineSupervisor:
        from service.turbine.supervisor import DEFAULT_DETECTOR, DEFAULT_ESTIMATOR, TurbineSupervisor

        sup = info.supervisor
        n = len(info.turbines)
        return TurbineSupervisor(
            n,
            detector=sup.detector or DEFAULT_DETECTOR,
            estimator=sup.estimator or DEFAULT_ESTIMATOR,
            options=dict(sup.params),
            noise_convention=info.site.noise_convention,
            run_of_row=[0] * n,
            turbine_of_row=list(info.turbines),
        )

    def turbines(self, plant: TurbineBatch) -> list[int]:
        return [int(t) for t in plant.turbine_of_row]

    # -- wire -------------------------------------------------------------------------------------------------------
    def frame_records(self, frame: TurbineFrame, turbines: list[int]) -> np.ndarray:
        values = {
            "tick": frame.k,
            "t": frame.t,
            "sensors": frame.sensors,
            "tau_g_ref": frame.tau_g_ref,
            "beta_ref": frame.beta_ref,
            "power_ref": frame.power_ref,
            "zone": frame.zone,
        }
        return records_from_batch(TURBINE_SENSORS, values, turbines)

    def frame_from_records(self, records: np.ndarray) -> TurbineFrame:
        return TurbineFrame(
            k=int(records["tick"][0]),
            t=float(records["t"][0]),
            sensors=np.array(records["sensors"]),
            tau_g_ref=np.array(records["tau_g_ref"]),
            beta_ref=np.array(records["beta_ref"]),
            power_ref=np.array(records["power_ref"]),
            zone=np.array(records["zone"]),
        )

    def refs_records(self, refs: TurbineRefs, supervisor: TurbineSupervisor, turbines: list[int]) -> np.ndarray:
        est = supervisor.estimates
        values: dict[str, Any] = {
            "tick": refs.tick,
            "valid": refs.valid,
            "omega_g": refs.omega_g,
            "omega_r": refs.omega_r,
            "wind": refs.wind,
            "selected": est.selected,
        }
        if refs.power_ref is not None:
            values |= {"power_ref_set": True, "power_ref": refs.power_ref}
        if est.wind_reference is not None:
            values |= {"nfte_set": True, "wind_nfte": est.wind_reference}
        return records_from_batch(TURBINE_REFS, values, turbines)

    def hold_unserved(self, records: np.ndarray, served: np.ndarray, last: np.ndarray | None) -> np.ndarray:
        return records  # one supervisor serves the one turbine: a tick never arrives without it

    def refs_from_records(self, records: np.ndarray) -> TurbineRefs:
        power_set = np.asarray(records["power_ref_set"])
        return TurbineRefs(
            tick=int(records["tick"][0]),
            valid=np.array(records["valid"]),
            omega_g=np.array(records["omega_g"]),
            omega_r=np.array(records["omega_r"]),
            wind=np.array(records["wind"]),
            power_ref=np.array(records["power_ref"]) if power_set.all() else None,
        )

    def truth_records(self, plant: TurbineBatch, frame: TurbineFrame, turbines: list[int]) -> np.ndarray:
        truth = plant.truth()
        values = {
            "tick": plant.k,
            "t": plant.t,
            "omega_r": truth["omega_r"],
            "omega_g": truth["omega_g"],
            "pitch": truth["pitch"],
            "tau_g": truth["tau_g"],
            "power": truth["power"],
            "tau_aero": truth["tau_aero"],
            "wind_rotor": truth["wind_rotor"],
            "wind_hub": truth["wind_hub"],
            "zone": truth["zone"],
        }
        return records_from_batch(TURBINE_TRUTH, values, turbines)

    # -- faults -----------------------------------------------------------------------------------------------------
    def inject(self, plant: TurbineBatch, fault: FaultSpec) -> None:
        plant.inject(fault)

    def clear(self, plant: TurbineBatch, label: str) -> None:
        if not plant.clear(label):
            raise KeyError(label)

    # -- status -----------------------------------------------------------------------------------------------------
    def status(
        self, supervisor: TurbineSupervisor, refs: np.ndarray | None, turbines: list[int]
    ) -> list[dict[str, Any]]:
        diag, est = supervisor.diagnosis, supervisor.estimates
        out = []
        for row, turbine in enumerate(turbines):
            flagged = [DIAGNOSIS_TARGETS[j] for j in np.flatnonzero(supervisor.flags[row])]
            entry: dict[str, Any] = {"turbine": turbine, "flagged": flagged}
            if est is not None:
                sel = int(est.selected[row])
                names = est.observer_names
                entry["observer"] = names[sel] if 0 <= sel < len(names) else sel
                entry["observer_index"] = sel
                entry["estimates"] = {
                    "valid": bool(est.valid[row]),
                    "omega_r": finite_or_none(est.omega_r[row]),
                    "omega_g": finite_or_none(est.omega_g[row]),
                    "wind_fte": finite_or_none(est.wind[row]),
                    "wind_nfte": None if est.wind_reference is None else finite_or_none(est.wind_reference[row]),
                }
            if diag is not None:
                entry["margins"] = {
                    name: finite_or_none(diag.margins[row, j]) for j, name in enumerate(diag.margin_names)
                }
            if refs is not None:
                entry["tick"] = int(refs[row]["tick"])
            out.append(entry)
        return out

    # -- scoring ----------------------------------------------------------------------------------------------------
    def score(self, scenario: Scenario, n_steps: int, dt: float) -> TurbineScore:
        return TurbineScore(scenario, n_steps, dt)

    def scorecard(
        self, scenario: Scenario, seed: int, faults: list[FaultSpec], events: list[Event], metrics: dict[str, Any]
    ) -> dict[str, Any]:
        from service.turbine.supervisor import DEFAULT_DETECTOR, DEFAULT_ESTIMATOR

        sup = scenario.supervisor
        return turbine_scoring.scorecard(
            scenario,
            runs=1,
            seed=seed,
            detector=sup.detector or DEFAULT_DETECTOR,
            estimator=sup.estimator or DEFAULT_ESTIMATOR,
            score=turbine_scoring.detection(events, faults, scenario.duration_s, runs=1),
            wind=metrics.get("wind_rmse", {}),
        )


class TurbineScore:
    """Per-tick squared wind errors; summed per window (in tick order, as the batch loop sums) at the end."""

    def __init__(self, scenario: Scenario, n_steps: int, dt: float):
        self.scenario = scenario
        self.n_steps = n_steps
        self.dt = dt
        self.rows = 0
        self.ticks = 0  # ticks that ran: the counters below count no tick beyond them
        self.err = {key: np.full(n_steps, np.nan) for key in WIND_KEYS}
        self.have = np.zeros(n_steps, dtype=bool)
        self.nfte_set = np.zeros(n_steps, dtype=bool)
        self._pending: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def on_tick(self, k: int, frame: TurbineFrame, plant: TurbineBatch) -> None:
        self.rows = plant.n
        self.ticks = max(self.ticks, k + 1)
        self._pending[k] = (plant.true_rotor_wind().copy(), frame.sensors[:, _ANEMOMETER].copy())
        if len(self._pending) > 4000:  # refs that never came (supervisor down)
            self._pending = {j: v for j, v in self._pending.items() if j >= k - 2000}

    def on_refs(self, k: int, refs: np.ndarray) -> None:
        if k not in self._pending or k >= self.n_steps:
            return
        truth, anemometer = self._pending.pop(k)
        self.err["fte"][k] = np.sum((np.asarray(refs["wind"]) - truth) ** 2)
        if bool(np.all(refs["nfte_set"])):
            self.err["nfte"][k] = np.sum((np.asarray(refs["wind_nfte"]) - truth) ** 2)
            self.nfte_set[k] = True
        self.err["anemometer"][k] = np.sum((anemometer - truth) ** 2)
        self.have[k] = True

    def result(self, faults: list[FaultSpec]) -> dict[str, Any]:
        scenario = self.scenario.model_copy(update={"faults": faults})
        which, labels = window_of_tick(scenario, self.n_steps, self.dt)
        sq = {key: np.zeros(len(labels)) for key in WIND_KEYS}
        counts = np.zeros(len(labels))
        for k in np.flatnonzero(self.have & (which >= 0)):
            w = which[k]
            sq["fte"][w] += self.err["fte"][k]
            if self.nfte_set[k]:
                sq["nfte"][w] += self.err["nfte"][k]
            sq["anemometer"][w] += self.err["anemometer"][k]
            counts[w] += self.rows
        wind_rmse = turbine_scoring.wind_rmse(labels, sq, counts)
        return {"wind_rmse": wind_rmse, "ticks_without_refs": int((~self.have[: self.ticks]).sum())}


TURBINE = TurbineKind()
