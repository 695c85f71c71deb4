"""Built-in hydrostatic algorithms, registered by name in ``service.plugins``.

Observers (``HYDRO_OBSERVERS``): ``factory(*, n, params, settings) -> obj`` where ``params`` is the nominal
``wwcore.hydro_params.HydroParams``, ``settings`` the declared keys of the scenario's ``[supervisor.params]``,
and ``obj.step(y, u)`` takes the measurements y (n, 5) of the newest sample and the commands u (n, 3) applied
since the previous one and returns a ``service.hydro.smo.Reconstruction``. ``ts-smo`` (the default) declares
the fields of ``SMOSettings``.

Detectors (``HYDRO_DETECTORS``): ``factory(*, context: HydroContext, options) -> obj`` with
``obj.step(t, reconstruction) -> flags`` (n, 2) bool for [u_p, u_M]; the supervisor turns every change of a
flag into a DETECTION or RECOVERY event. ``threshold`` (the default) declares the fields of
``DetectionSettings``; its θ is designed from ``context.noise_response()`` (``service.hydro.detector``).

The ``none`` entries declare the options of their role's default, and ignore them, so a scenario written for
the default can switch a stage off by name.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from service.hydro.detector import DetectionSettings, NoDetector, ThresholdDetector
from service.hydro.noise import NoiseResponse, noise_response
from service.hydro.smo import Reconstruction, SMOSettings, TSSlidingModeObserver
from service.plugins import HYDRO_DETECTORS, HYDRO_OBSERVERS
from wwcore.hydro_params import HydroParams


@dataclass(frozen=True)
class HydroContext:
    """What a hydro detector may know: batch size, sample time, the nominal model and the observer it reads."""

    n: int
    params: HydroParams
    observer: str  # registered name
    observer_settings: dict[str, Any] = field(default_factory=dict)

    @property
    def dt(self) -> float:
        return self.params.dt

    def noise_response(self) -> NoiseResponse:
        """The observer's linear response to measurement noise (``service.hydro.noise``), computed once."""
        return noise_response(self.observer, self.observer_settings, self.params)


@HYDRO_OBSERVERS.register("ts-smo", options=SMOSettings)
def ts_smo(*, n: int, params: HydroParams, settings: dict[str, Any]) -> TSSlidingModeObserver:
    """The paper's TS sliding mode observer (Section 4), settings (39) unless overridden."""
    return TSSlidingModeObserver(params, n, SMOSettings(**settings))


@HYDRO_OBSERVERS.register("none", options=SMOSettings)
class NoObserver:
    """Reconstructs nothing: f̂ = 0, never valid, so compensation is off and nothing is detected."""

    def __init__(self, *, n: int, params: HydroParams, settings: dict[str, Any]):
        self.n = n

    def step(self, y: np.ndarray, u: np.ndarray) -> Reconstruction:
        zeros = np.zeros((self.n, 2))
        return Reconstruction(
            f_hat=zeros,
            f_filt=zeros.copy(),
            x_hat=np.full((self.n, 6), np.nan),
            sliding=np.zeros(self.n, dtype=bool),
            e_y_norm=np.full(self.n, np.nan),
        )


HYDRO_DETECTORS.register("threshold", options=DetectionSettings)(ThresholdDetector)
HYDRO_DETECTORS.register("none", options=DetectionSettings)(NoDetector)
