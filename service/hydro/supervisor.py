"""The hydrostatic turbine's supervisor, following ``wwcore.stepping.Supervisor``.

Per frame: the registered observer reconstructs the displacement offsets (eqs. (23)–(37)), the detector turns
the filtered reconstruction into DETECTION/RECOVERY events, and the refs carry f̂_a,filt as the correction of
eq. (36) with a validity flag. The supervisor sees only the frame (measurements and commands), never truth.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from service.hydro.detector import DetectionSettings, OffsetDetector
from service.plugins import HYDRO_OBSERVERS
from wwcore.events import Event
from wwcore.hydro_frames import HydroFrame, HydroRefs
from wwcore.hydro_params import NOMINAL, HydroParams


class HydroSupervisor:
    """Observer + detector + virtual-actuator output for n turbines (one per Monte Carlo run).

    ``compensation`` False (per turbine, or for all) still reconstructs and detects but marks the correction
    as not to be applied.
    The correction is valid once the warm-up is over and the observer is in its sliding mode
    (‖P_2 e_y‖ < δ); otherwise (35) does not hold and the controller gets no correction.
    """

    def __init__(
        self,
        *,
        n: int,
        run_ids: list[int] | None = None,
        params: HydroParams = NOMINAL,
        observer: str = "ts-smo",
        observer_params: dict[str, Any] | None = None,
        detection: DetectionSettings | None = None,
        compensation: bool | np.ndarray = True,
    ):
        self.n = n
        self.run_ids = list(range(n)) if run_ids is None else list(run_ids)
        self.observer_name = observer
        self.observer = HYDRO_OBSERVERS.create(observer, n=n, params=params, settings=dict(observer_params or {}))
        self.detection = DetectionSettings() if detection is None else detection
        self.detector = OffsetDetector(n, self.run_ids, self.detection)
        self.compensation = np.broadcast_to(np.asarray(compensation, dtype=bool), (n,)).copy()
        self.last: Any = None

    def step(self, frame: HydroFrame) -> HydroRefs:
        rec = self.observer.step(frame.y, frame.u)
        self.last = rec
        flagged = self.detector.step(frame.t, rec.f_filt)
        valid = rec.sliding & (frame.t >= self.detection.warmup_s) & np.all(np.isfinite(rec.f_filt), axis=1)
        return HydroRefs(
            t=frame.t,
            k=frame.k,
            correction=rec.f_filt,
            apply=valid & self.compensation,
            f_hat=rec.f_hat,
            x_hat=rec.x_hat,
            flagged=flagged.copy(),
        )

    def bridge(self, frame: HydroFrame) -> None:
        """Advance through tick ``frame.k``, whose frame was lost (``frame`` interpolated, ``wwcore.stepping``): the
        observer steps (its states and f̂_filt move on); the detector does not, so its sample counters only count
        measured samples and no decision changes."""
        self.observer.step(frame.y, frame.u)

    def drain_events(self) -> list[Event]:
        return self.detector.drain()
