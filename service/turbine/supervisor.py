"""The turbine supervisor: a detector and an estimator chosen by name, composed into the step contract."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from service.plugins import TURBINE_DETECTORS, TURBINE_ESTIMATORS
from service.turbine.interfaces import Diagnosis, Estimates, TurbineContext
from wwcore.channels import DIAGNOSIS_TARGETS
from wwcore.events import Event, EventType
from wwcore.turbine_frames import TurbineFrame, TurbineRefs
from wwcore.turbine_params import BENCHMARK, TurbineParams

DEFAULT_DETECTOR = "benchmark"
DEFAULT_ESTIMATOR = "uio-bank"


class TurbineSupervisor:
    """Supervises n turbines (rows); emits DETECTION/RECOVERY/OBSERVER_SWITCH events as flags change."""

    def __init__(
        self,
        n: int,
        *,
        detector: str | None = None,
        estimator: str | None = None,
        options: dict | None = None,
        noise_convention: str = "sigma",
        params: TurbineParams = BENCHMARK,
        run_of_row: Sequence[int] | None = None,
        turbine_of_row: Sequence[int] | None = None,
    ):
        options = options or {}
        self.context = TurbineContext(params, n, noise_convention)
        self.detector = TURBINE_DETECTORS.create(detector or DEFAULT_DETECTOR, context=self.context, options=options)
        self.estimator = TURBINE_ESTIMATORS.create(
            estimator or DEFAULT_ESTIMATOR, context=self.context, options=options
        )
        self.n = n
        self.run_of_row = np.zeros(n, dtype=int) if run_of_row is None else np.asarray(run_of_row)
        self.turbine_of_row = np.ones(n, dtype=int) if turbine_of_row is None else np.asarray(turbine_of_row)
        self.flags = np.zeros((n, len(DIAGNOSIS_TARGETS)), dtype=bool)
        self.selected = np.zeros(n, dtype=int)
        self.diagnosis: Diagnosis | None = None
        self.estimates: Estimates | None = None
        self._events: list[Event] = []

    def step(self, frame: TurbineFrame) -> TurbineRefs:
        diagnosis = self.detector.step(frame)
        # the estimator stops using a sensor as soon as the detector suspects it, before it is flagged
        distrusted = diagnosis.faulty if diagnosis.suspect is None else diagnosis.suspect
        estimates = self.estimator.step(frame, distrusted)
        self._record(frame.t, diagnosis, estimates)
        self.diagnosis, self.estimates = diagnosis, estimates
        return TurbineRefs(
            tick=frame.k,
            valid=estimates.valid,
            omega_g=estimates.omega_g,
            omega_r=estimates.omega_r,
            wind=estimates.wind,
        )

    def drain_events(self) -> list[Event]:
        events, self._events = self._events, []
        return events

    def _record(self, t: float, diagnosis: Diagnosis, estimates: Estimates) -> None:
        changed = diagnosis.faulty != self.flags
        if changed.any():
            for row, col in zip(*np.nonzero(changed), strict=True):
                kind = EventType.DETECTION if diagnosis.faulty[row, col] else EventType.RECOVERY
                self._events.append(self._event(t, kind, row, DIAGNOSIS_TARGETS[col]))
            self.flags = diagnosis.faulty.copy()
        switched = estimates.selected != self.selected
        if switched.any():
            names = estimates.observer_names
            for row in np.flatnonzero(switched):
                old, new = int(self.selected[row]), int(estimates.selected[row])
                detail = {
                    "from": names[old] if old >= 0 and names else old,
                    "to": names[new] if new >= 0 and names else new,
                }
                self._events.append(self._event(t, EventType.OBSERVER_SWITCH, row, None, detail))
            self.selected = estimates.selected.copy()

    def _event(self, t: float, kind: EventType, row: int, target: str | None, detail: dict | None = None) -> Event:
        return Event(
            t=t,
            type=kind,
            turbine=int(self.turbine_of_row[row]),
            target=target,
            run=int(self.run_of_row[row]),
            detail=detail or {},
        )
