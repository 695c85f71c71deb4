"""The hydrostatic turbine's supervisor, following ``wwcore.stepping.Supervisor``.

Per frame: the registered observer reconstructs the displacement offsets (eqs. (23)–(37)), the registered
detector flags the actuators from the reconstruction, every change of a flag becomes a DETECTION or RECOVERY
event, and the refs carry f̂_a,filt as the correction of eq. (36) with a validity flag. The supervisor sees only
the frame (measurements and commands), never truth.

``options`` (a scenario's ``[supervisor.params]``) are checked by ``service.plugins.choose`` against what the
observer and the detector declare; each receives the keys it declared.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from service.flag_events import flag_events
from service.hydro.builtin import HydroContext
from service.hydro.offset_hold import OffsetHold, hold_samples
from service.plugins import HYDRO_DETECTORS, HYDRO_OBSERVERS, choose
from wwcore.events import Event
from wwcore.hydro_frames import HydroFrame, HydroRefs
from wwcore.hydro_params import FAULT_TARGETS, NOMINAL, HydroParams

DEFAULT_OBSERVER = HYDRO_OBSERVERS.default
DEFAULT_DETECTOR = HYDRO_DETECTORS.default
CONVERGENCE_S = 1.0  # s, no correction is applied before the observer has converged from its first sample


class HydroSupervisor:
    """Observer + detector + virtual-actuator output for n turbines (one per Monte Carlo run).

    ``compensation`` False (per turbine, or for all) still reconstructs and detects but marks the correction
    as not to be applied.
    The correction is valid once the observer has converged (``CONVERGENCE_S``) and is in its sliding mode
    (‖P_2 e_y‖ < δ); otherwise (35) does not hold and the controller gets no correction.
    """

    def __init__(
        self,
        *,
        n: int,
        run_ids: list[int] | None = None,
        params: HydroParams = NOMINAL,
        observer: str | None = None,
        detector: str | None = None,
        options: dict[str, Any] | None = None,
        compensation: bool | np.ndarray = True,
    ):
        self.choice = choose("hydro", options, estimator=observer, detector=detector)  # refuses bad options
        self.n = n
        self.run_ids = list(range(n)) if run_ids is None else list(run_ids)
        self._turbine_of_row = [1] * n  # one turbine per run
        self.observer_name = self.choice.names["estimator"]
        self.detector_name = self.choice.names["detector"]
        settings = self.choice.options["estimator"]
        self.observer = HYDRO_OBSERVERS.create(self.observer_name, n=n, params=params, settings=settings)
        self.context = HydroContext(n, params, self.observer_name, settings)
        self.detector = HYDRO_DETECTORS.create(
            self.detector_name, context=self.context, options=self.choice.options["detector"]
        )
        self.hold = self._offset_hold(self.choice.options["detector"])
        self.compensation = np.broadcast_to(np.asarray(compensation, dtype=bool), (n,)).copy()
        self.flags = np.zeros((n, len(FAULT_TARGETS)), dtype=bool)
        self.last: Any = None
        self._events: list[Event] = []

    @property
    def thresholds(self) -> np.ndarray | None:
        """θ (2,) of the detector, if it has thresholds."""
        theta = getattr(self.detector, "theta", None)
        return None if theta is None else np.asarray(theta, dtype=float)

    def _offset_hold(self, detection: dict[str, Any]) -> OffsetHold | None:
        """The held mean of a flagged offset (option ``hold_offset``), designed from the observer's noise response
        and the detector's θ and predicted σ of f̂_filt; None when off or when the detector has neither."""
        theta, sigma = self.thresholds, getattr(self.detector, "sigma", None)
        if not detection.get("hold_offset", False) or theta is None or sigma is None:
            return None
        return OffsetHold(self.n, theta, hold_samples(self.context.noise_response()), np.asarray(sigma, dtype=float))

    def step(self, frame: HydroFrame) -> HydroRefs:
        rec = self.observer.step(frame.y, frame.u)
        self.last = rec
        flags = np.asarray(self.detector.step(frame.t, rec), dtype=bool)
        self._record(frame.t, flags, rec.f_filt)
        correction = rec.f_filt if self.hold is None else self.hold.step(flags, rec.f_hat, rec.f_filt)
        valid = rec.sliding & (frame.t >= CONVERGENCE_S) & np.all(np.isfinite(correction), axis=1)
        return HydroRefs(
            t=frame.t,
            k=frame.k,
            correction=correction,
            apply=valid & self.compensation,
            f_hat=rec.f_hat,
            x_hat=rec.x_hat,
            flagged=flags.copy(),
        )

    def bridge(self, frame: HydroFrame) -> None:
        """Advance through tick ``frame.k``, whose frame was lost (``frame`` interpolated, ``wwcore.stepping``): the
        observer steps (its states and f̂_filt move on); the detector does not, so its sample counters only count
        measured samples and no decision changes."""
        self.observer.step(frame.y, frame.u)

    def drain_events(self) -> list[Event]:
        events, self._events = self._events, []
        return events

    def _record(self, t: float, flags: np.ndarray, f_filt: np.ndarray) -> None:
        theta = self.thresholds

        def detail(i: int, j: int) -> dict[str, Any]:
            out: dict[str, Any] = {"f_hat_filt": float(f_filt[i, j])}
            if theta is not None:
                out["threshold"] = float(theta[j])
            return out

        raised = flag_events(t, self.flags, flags, FAULT_TARGETS, self._turbine_of_row, self.run_ids, detail)
        if raised:
            self._events += raised
            self.flags = flags.copy()
