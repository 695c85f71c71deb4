"""The built-in farm algorithms, registered by name.

Detectors (``FARM_DETECTORS``): ``paper`` (seed 001 as published, ``service.farm.paper``), ``analytic`` (per-turbine
analytic redundancy with budget-derived thresholds, ``service.farm.analytic``; the default), ``none``.
Controllers (``FARM_CONTROLLERS``): ``dispatch`` (eqs. (18)–(26), the default), ``pi`` (the benchmark's farm PI),
``none`` (every turbine at rated power: no farm control).
"""

from __future__ import annotations

import numpy as np

from service.farm.analytic import AnalyticDetector
from service.farm.dispatch import Dispatch, PIFarmController
from service.farm.interfaces import FarmContext, FarmDiagnosis, FarmSample, empty_diagnosis
from service.farm.paper import PaperDetector
from service.plugins import FARM_CONTROLLERS, FARM_DETECTORS

FARM_DETECTORS.register("paper")(PaperDetector)
FARM_DETECTORS.register("analytic")(AnalyticDetector)
FARM_CONTROLLERS.register("dispatch")(Dispatch)
FARM_CONTROLLERS.register("pi")(PIFarmController)


@FARM_DETECTORS.register("none")
class NoFarmDetector:
    """Flags nothing (the controller then never accommodates)."""

    def __init__(self, *, context: FarmContext, options: dict | None = None):
        self.n = context.n

    def step(self, sample: FarmSample) -> FarmDiagnosis:
        return empty_diagnosis(self.n)


@FARM_CONTROLLERS.register("none")
class NoFarmController:
    """No farm control: every turbine keeps rated power as its reference."""

    def __init__(self, *, context: FarmContext, options: dict | None = None):
        self.rated = context.params.rated_power
        self.n = context.n
        self.mode = np.zeros(self.n, dtype=np.int8)

    def step(self, sample: FarmSample, faulty: np.ndarray) -> np.ndarray:
        return np.full(self.n, self.rated)
