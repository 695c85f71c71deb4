"""The hydrostatic turbine (seed 003) as a plant kind.

Plant and supervisor are built as ``windwarden.evaluation.hydro`` builds its *compensated* twin of run 0 (random
streams ``SeedSequence(seed, spawn_key=(0, 0))``, the nominal parameters with the scenario's stroke limit, the
correction applied). A one-row batch gives bit for bit the numbers of that twin, so the live reconstruction
figures equal ``windwarden eval``'s.

Scorecard of a live run: detection figures from the event log (``scoring.score_detection`` on the supervisor's own
events, as ``windwarden eval`` scores them: both run the same supervisor with the same design thresholds) and the
reconstruction figures of ``evaluation.hydro_scoring.reconstruction_metrics`` from the corrections the plant received.
The deviation-from-fault-free figures need the fault-free twin and are batch-only.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from windwarden.evaluation import hydro_scoring
from windwarden.evaluation.kinds import EvalOptions, Evaluation
from windwarden.kinds.base import RunInfo, finite_or_none, records_from_batch
from wwcore.events import Event
from wwcore.hydro_frames import HydroFrame, HydroRefs
from wwcore.hydro_params import FAULT_TARGETS, NOMINAL, X_NAMES
from wwcore.scenario import FaultSpec, Scenario
from wwcore.scenario.hydro import HydroPlant
from wwcore.wire import HYDRO_REFS, HYDRO_SENSORS, HYDRO_TRUTH

if TYPE_CHECKING:  # the plant process never imports the supervisor's code, nor the supervisor the plant's
    from plant_sim.hydro import HydroTurbineBatch
    from service.hydro.supervisor import HydroSupervisor

DEFAULT_OBSERVER = "ts-smo"  # service.plugins.HYDRO_OBSERVERS.default (the plant process does not import it)
DEFAULT_DETECTOR = "threshold"  # service.plugins.HYDRO_DETECTORS.default


class HydroKind:
    kind = "hydro"
    section = HydroPlant
    panels = ("hydro",)
    example_fault: ClassVar[dict[str, Any]] = {
        "target": "u_p",
        "kind": "offset",
        "value": -0.2,
        "start_s": 0.0,
        "end_s": 1e5,
        "name": "pump displacement offset",
    }
    sensors = HYDRO_SENSORS
    refs = HYDRO_REFS
    truth = HYDRO_TRUTH

    def evaluate(self, scenario: Scenario, runs: int, seed: int, options: EvalOptions) -> Evaluation:
        from windwarden.evaluation.hydro import evaluate

        return evaluate(scenario, runs, seed, options)

    def make_plant(self, scenario: Scenario, seed: int) -> HydroTurbineBatch:
        from plant_sim.hydro import HydroTurbineBatch

        seeds = [np.random.SeedSequence(seed, spawn_key=(0, 0))]  # evaluation.hydro._seeds(seed, 0, [0])
        return HydroTurbineBatch(scenario.plant, scenario.wind, list(scenario.faults), seeds, [0], NOMINAL)

    def make_supervisor(self, info: RunInfo) -> HydroSupervisor:
        from service.hydro.supervisor import HydroSupervisor

        return HydroSupervisor(
            n=len(info.turbines),
            run_ids=[0] * len(info.turbines),
            params=replace(NOMINAL, stroke_max=info.site.stroke_max),  # the nominal model the plant publishes
            observer=info.supervisor.estimator,
            detector=info.supervisor.detector,
            options=info.supervisor.params,
            compensation=True,
        )

    def turbines(self, plant: HydroTurbineBatch) -> list[int]:
        return [1] * plant.n

    # -- wire -------------------------------------------------------------------------------------------------------
    def frame_records(self, frame: HydroFrame, turbines: list[int]) -> np.ndarray:
        return records_from_batch(HYDRO_SENSORS, {"tick": frame.k, "t": frame.t, "y": frame.y, "u": frame.u}, turbines)

    def frame_from_records(self, records: np.ndarray) -> HydroFrame:
        return HydroFrame(
            t=float(records["t"][0]), k=int(records["tick"][0]), y=np.array(records["y"]), u=np.array(records["u"])
        )

    def refs_records(self, refs: HydroRefs, supervisor: HydroSupervisor, turbines: list[int]) -> np.ndarray:
        values = {
            "tick": refs.k,
            "t": refs.t,
            "correction": refs.correction,
            "apply": refs.apply,
            "f_hat": refs.f_hat,
            "x_hat": refs.x_hat,
            "flagged": refs.flagged,
        }
        return records_from_batch(HYDRO_REFS, values, turbines)

    def hold_unserved(self, records: np.ndarray, served: np.ndarray, last: np.ndarray | None) -> np.ndarray:
        return records  # one supervisor serves the one turbine: a tick never arrives without it

    def refs_from_records(self, records: np.ndarray) -> HydroRefs:
        return HydroRefs(
            t=float(records["t"][0]),
            k=int(records["tick"][0]),
            correction=np.array(records["correction"]),
            apply=np.array(records["apply"]),
            f_hat=np.array(records["f_hat"]),
            x_hat=np.array(records["x_hat"]),
            flagged=np.array(records["flagged"]),
        )

    def truth_records(self, plant: HydroTurbineBatch, frame: HydroFrame, turbines: list[int]) -> np.ndarray:
        truth = plant.truth()
        values = {
            "tick": plant.k,
            "t": plant.t,
            "x": truth["x"],
            "f": truth["f"],
            "v": truth["v"],
            "P_g": truth["P_g"],
            "u_nominal": truth["u_nominal"],
            "u_applied": truth["u_applied"],
        }
        return records_from_batch(HYDRO_TRUTH, values, turbines)

    # -- faults -----------------------------------------------------------------------------------------------------
    def inject(self, plant: HydroTurbineBatch, fault: FaultSpec) -> None:
        plant.inject(fault)

    def clear(self, plant: HydroTurbineBatch, label: str) -> None:
        plant.clear(label)

    # -- status -----------------------------------------------------------------------------------------------------
    def status(self, supervisor: HydroSupervisor, refs: np.ndarray | None, turbines: list[int]) -> list[dict[str, Any]]:
        theta = supervisor.thresholds
        out = []
        for row, turbine in enumerate(turbines):
            entry: dict[str, Any] = {
                "turbine": turbine,
                "flagged": [FAULT_TARGETS[j] for j in np.flatnonzero(supervisor.flags[row])],
                "observer": supervisor.observer_name,
                "detector": supervisor.detector_name,
            }
            if theta is not None:
                entry["thresholds"] = dict(zip(FAULT_TARGETS, map(float, theta), strict=True))
            if refs is not None:
                r = refs[row]
                corr = np.asarray(r["correction"], dtype=float)
                entry["estimates"] = {
                    "f_hat_filt": dict(zip(FAULT_TARGETS, map(finite_or_none, corr), strict=True)),
                    "f_hat": dict(zip(FAULT_TARGETS, map(finite_or_none, r["f_hat"]), strict=True)),
                    "x_hat": dict(zip(X_NAMES, map(finite_or_none, r["x_hat"]), strict=True)),
                    "correction_applied": bool(r["apply"]),
                }
                if theta is not None:
                    entry["margins"] = {
                        f"|f_hat_filt[{name}]|/threshold": finite_or_none(abs(c) / th)
                        for name, c, th in zip(FAULT_TARGETS, corr, theta, strict=True)
                    }
                entry["tick"] = int(r["tick"])
            out.append(entry)
        return out

    # -- scoring ----------------------------------------------------------------------------------------------------
    def score(self, scenario: Scenario, n_steps: int, dt: float) -> HydroScore:
        return HydroScore(scenario, n_steps, dt)

    def scorecard(
        self, scenario: Scenario, seed: int, faults: list[FaultSpec], events: list[Event], metrics: dict[str, Any]
    ) -> dict[str, Any]:
        score = hydro_scoring.detection(scenario.model_copy(update={"faults": faults}), events, runs=1)
        return hydro_scoring.scorecard(
            scenario,
            runs=1,
            seed=seed,
            observer=scenario.supervisor.estimator or DEFAULT_OBSERVER,
            detector=scenario.supervisor.detector or DEFAULT_DETECTOR,
            compensation=True,
            score=score,
            metrics={
                "reconstruction": metrics.get("reconstruction", []),
                "detection": {"false_alarms": score.false_alarms},
            },
        )


class HydroScore:
    """f̂_a,filt as the plant received it and the true offsets, per tick (float32, as the batch evaluator keeps
    them). A tick whose refs never arrived keeps the last correction the plant had."""

    def __init__(self, scenario: Scenario, n_steps: int, dt: float):
        self.scenario = scenario
        self.dt = dt
        self.f_true = np.zeros((n_steps, 1, 2), dtype=np.float32)
        self.f_filt = np.full((n_steps, 1, 2), np.nan, dtype=np.float32)
        self.n_steps = n_steps
        self.ticks = 0  # ticks that ran: the figures cover no tick beyond them

    def on_tick(self, k: int, frame: HydroFrame, plant: HydroTurbineBatch) -> None:
        self.ticks = max(self.ticks, min(k + 1, self.n_steps))
        if k < self.n_steps:
            self.f_true[k] = (plant.fault_offsets(plant.t) * plant.fault_mask[:, None])[:1]

    def on_refs(self, k: int, refs: np.ndarray) -> None:
        if k < self.n_steps:
            self.f_filt[k] = refs["correction"][:1]

    def result(self, faults: list[FaultSpec]) -> dict[str, Any]:
        ticks = self.ticks
        f_filt = self.f_filt[:ticks].copy()
        last = np.zeros((1, 2), dtype=np.float32)
        for k in np.flatnonzero(np.isnan(f_filt[:, 0, 0])):  # carry the last received correction forward
            f_filt[k] = f_filt[k - 1] if k > 0 else last
        ran = ticks * self.dt
        update = {"faults": [f for f in faults if f.start_s < ran]}
        if ticks < self.n_steps:
            update["duration_s"] = ran
        scenario = self.scenario.model_copy(update=update)
        traces = {"f_filt": f_filt, "f_true": self.f_true[:ticks]}
        missing = int(np.isnan(self.f_filt[:ticks, 0, 0]).sum())
        reconstruction = hydro_scoring.reconstruction_metrics(traces, scenario, self.dt)
        return {"reconstruction": reconstruction, "ticks_without_refs": missing}


HYDRO = HydroKind()
