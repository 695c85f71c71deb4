"""Built-in hydrostatic observers, registered by name in ``service.plugins.HYDRO_OBSERVERS``.

Contract of an entry: ``factory(*, n, params, settings) -> obj`` where ``params`` is the nominal
``wwcore.hydro_params.HydroParams``, ``settings`` a dict from the scenario's ``[supervisor.params]`` and
``obj.step(y, u)`` takes the measurements y (n, 5) of the newest sample and the commands u (n, 3) applied
since the previous one and returns a ``service.hydro.smo.Reconstruction``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from service.hydro.smo import Reconstruction, SMOSettings, TSSlidingModeObserver
from service.plugins import HYDRO_OBSERVERS
from wwcore.hydro_params import HydroParams


@HYDRO_OBSERVERS.register("ts-smo")
def ts_smo(*, n: int, params: HydroParams, settings: dict[str, Any]) -> TSSlidingModeObserver:
    """The paper's TS sliding mode observer (Section 4), settings (39) unless overridden."""
    return TSSlidingModeObserver(params, n, SMOSettings.from_params(settings))


@HYDRO_OBSERVERS.register("none")
class NoObserver:
    """Reconstructs nothing: f̂ = 0, never valid, so compensation is off and nothing is detected.

    ``settings`` are ignored (a scenario's settings for another observer stay valid when this one is chosen).
    """

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
