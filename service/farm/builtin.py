"""The built-in farm algorithms, registered by name.

Detectors (``FARM_DETECTORS``): ``paper`` (seed 001 as published, ``service.farm.paper``), ``analytic`` (per-turbine
analytic redundancy with budget-derived thresholds, ``service.farm.analytic``; the default), ``none``.
Controllers (``FARM_CONTROLLERS``): ``dispatch`` (eqs. (18)–(26), the default), ``pi`` (the benchmark's farm PI),
``none`` (every turbine at rated power: no farm control).

The algorithms read their options from a dict; the dataclasses below declare them (type, default, range) for
``service.plugins.choose``, which refuses what no selected algorithm declares.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np

from service.farm import accommodation, analytic, hold, power_loop
from service.farm.analytic import AnalyticDetector
from service.farm.dispatch import ACCOMMODATION_RULES, PITCH_RULES, Dispatch
from service.farm.interfaces import FarmContext, FarmDiagnosis, FarmSample, empty_diagnosis
from service.farm.paper import DIRECTION_SOURCES, RUNNING_CASE, PaperDetector
from service.farm.power_loop import PIFarmController
from service.plugins import FARM_CONTROLLERS, FARM_DETECTORS
from wwcore.options import Bounds

# The options each farm algorithm reads from ``[supervisor.params]``, with their ranges: what ``service.plugins``
# validates before anything runs. ``tests/test_options.py`` checks that every key an algorithm reads is declared.


@dataclass(frozen=True)
class PaperOptions:
    wind_case: Annotated[int | None, Bounds(ge=1, le=2)] = None  # give the wind case instead of estimating it
    # give the wind direction instead of estimating it (deg from north, where the wind comes from)
    wind_direction_deg: Annotated[float | None, Bounds(ge=0.0, lt=360.0, unit="deg")] = None
    # where the direction comes from: auto (eqs. (1)-(2) on the 3 × 3, the vane elsewhere), power, vane
    direction_source: Literal[DIRECTION_SOURCES] = DIRECTION_SOURCES[0]
    # time constant of the running circular mean of the mast's vane
    direction_averaging_s: Annotated[float, Bounds(gt=0.0, le=3600.0, unit="s")] = 60.0
    # the rows are formed again when the direction estimate has moved this far from theirs
    regroup_deg: Annotated[float, Bounds(ge=0.0, le=45.0, unit="deg")] = 1.0
    # eqs. (1)-(2) taken again on every block of 500 samples (false: the first block's case is kept)
    running_case: bool = RUNNING_CASE


@dataclass(frozen=True)
class AnalyticOptions:
    # design rate of false alarms per fault type, per 1000 s of farm operation
    false_alarms_per_1000s: Annotated[float, Bounds(gt=0.0, le=1000.0, unit="1/1000 s")] = 0.01
    warmup_s: Annotated[float, Bounds(ge=0.0, le=600.0, unit="s")] = analytic.WARMUP_S  # no decisions before this
    # judge each turbine against its own learnt healthy level and spread (False: the design model's, zero and σ)
    learn_levels: bool = True
    # time constant of the learnt levels and of the learnt spreads, after the first samples' running means
    level_time_s: Annotated[float, Bounds(ge=10.0, le=86400.0, unit="s")] = analytic.LEVEL_TIME_S
    spread_time_s: Annotated[float, Bounds(ge=10.0, le=86400.0, unit="s")] = analytic.SPREAD_TIME_S
    # the largest sensor noise, over the design σ, learnt as health (the spreads are bounded to [1, this²])
    max_noise_scale: Annotated[float, Bounds(ge=1.0, le=10.0)] = analytic.MAX_NOISE_SCALE
    # lag between one rotor's pitch actuators left after the learnt rate gain: widens the pitch test by (this · β̇)²
    pitch_lag_tolerance_s: Annotated[float, Bounds(ge=0.0, le=1.0, unit="s")] = analytic.PITCH_LAG_TOLERANCE_S
    # judge the drive train on the 3P lock-in's whitened amplitude (False: the plain amplitude 2|I + jQ|, whose
    # image at 2·3P makes its tail heavier than the Rayleigh threshold assumes; ``service.farm.signals``)
    whiten_lockin: bool = True


@dataclass(frozen=True)
class DispatchOptions:
    derate_floor: Annotated[float, Bounds(ge=0.0, le=1.0)] = 0.0  # share of its own P_avail a derate keeps
    drivetrain_relief: Annotated[float, Bounds(ge=0.0, le=1.0)] = accommodation.DRIVETRAIN_RELIEF  # D-32
    accommodation_rule: Literal[ACCOMMODATION_RULES] = ACCOMMODATION_RULES[0]
    pitch_rule: Literal[PITCH_RULES] = PITCH_RULES[0]
    hold_margin: Annotated[float, Bounds(ge=1.0, le=3.0)] = hold.HOLD_MARGIN
    hold_reserve: Annotated[float, Bounds(ge=0.0, le=1.0)] = hold.HOLD_RESERVE
    release_after_s: Annotated[float, Bounds(ge=0.0, le=600.0, unit="s")] = hold.RELEASE_AFTER_S
    trim_kp: Annotated[float, Bounds(ge=0.0, le=10.0)] = power_loop.TRIM_KP
    trim_ki: Annotated[float, Bounds(ge=0.0, le=10.0, unit="1/s")] = power_loop.TRIM_KI
    trim_limit: Annotated[float, Bounds(ge=0.0, le=1.0)] = power_loop.TRIM_LIMIT
    ripple_compensation: bool = True
    ripple_share: Annotated[float, Bounds(ge=0.0, le=1.0)] = 1.0  # D-29: the part of the ripple the others cancel


@dataclass(frozen=True)
class PIOptions:
    pi_kp: Annotated[float, Bounds(ge=0.0, le=10.0)] = power_loop.PI_KP
    pi_ki: Annotated[float, Bounds(ge=0.0, le=10.0, unit="1/s")] = power_loop.PI_KI


FARM_DETECTORS.register("paper", options=PaperOptions)(PaperDetector)
FARM_DETECTORS.register("analytic", options=AnalyticOptions)(AnalyticDetector)
FARM_CONTROLLERS.register("dispatch", options=DispatchOptions)(Dispatch)
FARM_CONTROLLERS.register("pi", options=PIOptions)(PIFarmController)


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
