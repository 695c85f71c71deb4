"""The turbine supervisor: a detector and an estimator chosen by name, composed into the step contract.

``options`` (a scenario's ``[supervisor.params]``) are checked by ``service.plugins.choose`` against what the two
algorithms declare; each algorithm receives the keys it declared.
"""

from __future__ import annotations

import inspect
from collections.abc import Sequence

import numpy as np

from service.flag_events import flag_events, row_event
from service.plugins import TURBINE_DETECTORS, TURBINE_ESTIMATORS, choose
from service.turbine.interfaces import Diagnosis, Estimates, TurbineContext
from wwcore.channels import DIAGNOSIS_TARGETS
from wwcore.events import Event, EventType
from wwcore.turbine_frames import TurbineFrame, TurbineRefs
from wwcore.turbine_params import BENCHMARK, TurbineParams

DEFAULT_DETECTOR = TURBINE_DETECTORS.default
DEFAULT_ESTIMATOR = TURBINE_ESTIMATORS.default


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
        backend: str | None = None,
    ):
        self.choice = choose("turbine", options, detector=detector, estimator=estimator)  # refuses bad options
        self.context = TurbineContext(params, n, noise_convention, backend=backend)
        names, chosen = self.choice.names, self.choice.options
        self.detector = TURBINE_DETECTORS.create(names["detector"], context=self.context, options=chosen["detector"])
        self.estimator = TURBINE_ESTIMATORS.create(
            names["estimator"], context=self.context, options=chosen["estimator"]
        )
        # an estimator whose ``step`` takes ``flagged`` is told which distrusted targets are flagged, not suspected
        self._estimator_takes_flags = "flagged" in inspect.signature(self.estimator.step).parameters
        self.n = n
        self.run_of_row = np.zeros(n, dtype=int) if run_of_row is None else np.asarray(run_of_row)
        self.turbine_of_row = np.ones(n, dtype=int) if turbine_of_row is None else np.asarray(turbine_of_row)
        self.flags = np.zeros((n, len(DIAGNOSIS_TARGETS)), dtype=bool)
        self.selected = np.zeros(n, dtype=int)
        self.diagnosis: Diagnosis | None = None
        self.estimates: Estimates | None = None
        self._events: list[Event] = []
        # a detector that folds its common compiled tick with the estimator's (``BenchmarkDetector.folded``)
        folded = getattr(self.detector, "folded", None)
        self._folded = None if folded is None else folded(self.estimator)

    def step(self, frame: TurbineFrame) -> TurbineRefs:
        folded = self._folded
        if folded is not None:  # unless a test replaced the detector or the estimator
            mine = folded.detector is self.detector and folded.estimator is self.estimator
            folded = folded.step(frame, self.flags, self.selected) if mine else None
        if folded is not None:  # the compiled common tick in one call (``fast_supervisor``), the estimator's after it
            diagnosis, healthy, unchanged = folded
            distrusted = diagnosis.faulty if diagnosis.suspect is None else diagnosis.suspect
            estimates = self.estimator.step(frame, distrusted, flagged=diagnosis.faulty, healthy=healthy)
        else:
            unchanged = None
            diagnosis = self.detector.step(frame)
            # the estimator stops using a sensor as soon as the detector suspects it, before it is flagged
            distrusted = diagnosis.faulty if diagnosis.suspect is None else diagnosis.suspect
            if self._estimator_takes_flags:  # which of them are flagged rather than suspected
                estimates = self.estimator.step(frame, distrusted, flagged=diagnosis.faulty)
            else:
                estimates = self.estimator.step(frame, distrusted)
        if not unchanged:  # else the kernel found no flag changed and no row switched observer
            self._record(frame.t, diagnosis, estimates)
        self.diagnosis, self.estimates = diagnosis, estimates
        return TurbineRefs(
            tick=frame.k,
            valid=estimates.valid,
            omega_g=estimates.omega_g,
            omega_r=estimates.omega_r,
            wind=estimates.wind,
        )

    def bridge(self, frame: TurbineFrame) -> None:
        """Advance through tick ``frame.k``, whose frame was lost (``frame`` interpolated, ``wwcore.stepping``): the
        observer bank and the estimator step (flags held, outputs dropped); the detector does not, so its window
        tests never take a made-up sample and no decision changes. A detector with state of its own may have a
        ``bridge(frame)`` of its own: it is called."""
        self.context.bank(frame)
        self.estimator.step(frame, self.flags)
        detector_bridge = getattr(self.detector, "bridge", None)
        if detector_bridge is not None:
            detector_bridge(frame)

    def drain_events(self) -> list[Event]:
        events, self._events = self._events, []
        return events

    def _record(self, t: float, diagnosis: Diagnosis, estimates: Estimates) -> None:
        fast = self.context.fast
        arrays = isinstance(diagnosis.faulty, np.ndarray) and isinstance(estimates.selected, np.ndarray)
        selection = self.selected, estimates.selected
        # the common tick: no flag changed, no row switched observer
        if arrays and fast is not None and fast.record_unchanged(self.flags, diagnosis.faulty, *selection):
            return
        rows = self.turbine_of_row, self.run_of_row
        raised = flag_events(t, self.flags, diagnosis.faulty, DIAGNOSIS_TARGETS, *rows)
        if raised:
            self._events += raised
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
                self._events.append(row_event(t, EventType.OBSERVER_SWITCH, row, *rows, None, detail))
            self.selected = estimates.selected.copy()
