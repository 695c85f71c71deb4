r"""The pitch-misalignment accommodation: a per-blade pitch trim that turns the misaligned blade back [PROPOSED].

Fault 2 holds one blade's actuator off the collective command (D-F2), which puts a 1P imbalance on the rotor.
Eq. (26) derates the turbine instead, which leaves the imbalance where it is and costs the farm its reserve
(``docs/farm.md``, D-28). Here the farm controller acts as a virtual actuator: from the flag on, it estimates each
blade's deviation from the blades' mean pitch (deg, from the 10 Hz SCADA means of the two encoders of each blade)

.. math::

    d_i = \bar β_i − \tfrac13 \textstyle\sum_j \bar β_j \;(= \tfrac23 z_{2,i}\ \text{of the analytic detector}),\qquad
    \hat d_i ← \hat d_i + (d_i − \hat d_i)\,Δt/T_d

(starting from the first d_i, T_d = ``AVERAGING_S``) and sends −d̂_i, clipped to ±``LIMIT_DEG``, as the turbine's
per-blade ``pitch_trim``, which its controller adds to each blade's command (``plant_sim.farm.controller``). The
collective part of the trim is zero, so the turbine's power is untouched. The supervisor takes the trim it
commanded off the pitch readings before the detector and the controller see them (``FarmSample.untrimmed``), so
d_i here is the actuator's own misalignment, and the flag stays while the fault lasts and clears when it ends.
"""

from __future__ import annotations

import numpy as np

from service.farm.interfaces import BETA, FarmSample
from wwcore.scenario.farm import FARM_DT_S

AVERAGING_S = 2.0  # s, T_d: low-pass of the blades' misalignment [PROPOSED]
LIMIT_DEG = 1.0  # deg, the largest trim sent to a blade [PROPOSED]


class PitchTrim:
    """Per-blade trims (n, 3) deg for ``n`` turbines; nonzero only on the rows ``step`` is told to trim."""

    def __init__(self, n: int):
        self.trim = np.zeros((n, 3))
        self._estimate = np.full((n, 3), np.nan)  # deg, d̂_i of trimmed rows (NaN: none)

    def step(self, sample: FarmSample, trimmed: np.ndarray) -> None:
        """Update from a sample whose pitch readings are without the trim; ``trimmed`` (n,) bool."""
        if not (trimmed.any() or self.trim.any()):
            return
        blades = sample.scada[:, BETA].mean(axis=2)
        deviation = blades - blades.mean(axis=1, keepdims=True)
        previous = self._estimate
        estimate = np.where(
            np.isnan(previous), deviation, previous + (deviation - previous) * (FARM_DT_S / AVERAGING_S)
        )
        self._estimate = np.where(trimmed[:, None], estimate, np.nan)
        self.trim = np.where(trimmed[:, None], -np.clip(estimate, -LIMIT_DEG, LIMIT_DEG), 0.0)
