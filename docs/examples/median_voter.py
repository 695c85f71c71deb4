"""A worked example of a user's own turbine detector: a median voter over the four speed sensors.

Run it on the same scenarios as the built-in detectors and compare the scorecards::

    windwarden eval ftwse-2012 --runs 10 --plugin docs/examples/median_voter.py --detector median-voter

The four speed sensors measure almost the same thing once the generator speeds are divided by the gear ratio
(the shaft twists by milliradians), so a sensor is suspect when it is far from the median of the four. The
threshold comes from the false-alarm budget like the built-in detectors' do.

Its one option is declared with it (``VoterOptions``): a scenario may set ``false_alarms_per_1000s`` in
``[supervisor.params]``, a value outside (0, 1000] or any key neither this detector nor the estimator declares is
refused before anything runs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

import numpy as np
from scipy.stats import norm

from service.plugins import TURBINE_DETECTORS
from service.turbine.interfaces import Diagnosis, TurbineContext
from wwcore.channels import DIAGNOSIS_TARGETS, SENSOR_INDEX, SPEED_SENSORS, TARGET_INDEX
from wwcore.options import Bounds
from wwcore.turbine_frames import TurbineFrame

COLUMNS = np.array([SENSOR_INDEX[s] for s in SPEED_SENSORS])
TARGETS = np.array([TARGET_INDEX[s] for s in SPEED_SENSORS])


@dataclass(frozen=True)
class VoterOptions:
    # design rate of false alarms, all four sensors together
    false_alarms_per_1000s: Annotated[float, Bounds(gt=0.0, le=1000.0, unit="1/1000 s")] = 0.1


@TURBINE_DETECTORS.register("median-voter", options=VoterOptions)
class MedianVoter:
    """Flags a speed sensor whose reading, on the rotor side, is far from the median of the four."""

    def __init__(self, *, context: TurbineContext, options: dict | None = None):
        p = context.params
        self.n = context.n
        self.scale = np.array([1.0, 1.0, 1.0 / p.N_g, 1.0 / p.N_g])  # to rotor-side rad/s
        sigma = np.array([context.sensor_sigma[s] for s in SPEED_SENSORS]) * self.scale
        settings = VoterOptions(**(options or {}))  # the declared keys the scenario gave, already checked
        alpha = settings.false_alarms_per_1000s * p.dt / 1000.0 / len(SPEED_SENSORS)
        # a healthy sensor minus the median of four is roughly N(0, σ² + σ_median²), and the median is as noisy as
        # the rotor-speed sensors (rough on purpose: this is an example, and the scorecard says how rough)
        self.threshold = norm.isf(alpha / 2.0) * np.sqrt(sigma**2 + sigma.max() ** 2)

    def step(self, frame: TurbineFrame) -> Diagnosis:
        speeds = frame.sensors[:, COLUMNS] * self.scale
        deviation = np.abs(speeds - np.median(speeds, axis=1, keepdims=True))
        faulty = np.zeros((self.n, len(DIAGNOSIS_TARGETS)), dtype=bool)
        faulty[:, TARGETS] = deviation > self.threshold
        return Diagnosis(faulty=faulty, margins=deviation / self.threshold, margin_names=SPEED_SENSORS)
