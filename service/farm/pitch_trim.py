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

**The trim as the readings carry it** (``TrimInReadings``). A blade follows its trim through its actuator,
ω_n²/(s² + 2ζω_n s + ω_n²) (PARAMETERS.md a.2, 0.2–0.3 s to settle), and a farm sample is the mean of the ten
readings since the last one. So what is taken off sample j is not the trim last commanded but its response:

.. math::  x_{m+1} = A_d x_m + B_d u_m,\qquad \hat T_j = \tfrac1{10}\textstyle\sum_{m=1}^{10} C x_m,

(A_d, B_d the actuator's zero-order-hold model at the turbine's Δt; u the trim the blade's command carried in
tick m: the one sent with sample j−2 in the block's first tick, the plant taking new references from the tick
after the sample, then the one sent with sample j−1; ``wwcore.stepping``). Why not the commanded trim: it would
show every step of the trim as a misalignment of the step's size, of the other sign, for the 0.2–0.3 s the blade
takes to follow; when the flag of a fault of δ falls and its trim of ≈ ⅔δ (at most ``LIMIT_DEG``) goes, the
misalignment test would read ⅔δ on the blade and raise a new flag at once, whose trim's removal would do the same
the other way: flaps after every large fault's end (``docs/farm.md`` D-28).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import cont2discrete

from service.farm.interfaces import BETA, FarmSample
from wwcore.scenario.farm import FARM_DT_S
from wwcore.turbine_params import TurbineParams

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


def actuator_model(params: TurbineParams) -> tuple[np.ndarray, np.ndarray]:
    """(A_d, B_d) of the pitch actuator ω_n²/(s² + 2ζω_n s + ω_n²), zero-order hold at ``params.dt``; state
    (position deg, rate deg/s)."""
    wn, zeta = params.pitch.omega_n, params.pitch.zeta
    a = np.array([[0.0, 1.0], [-(wn**2), -2.0 * zeta * wn]])
    b = np.array([[0.0], [wn**2]])
    ad, bd, *_ = cont2discrete((a, b, np.eye(2), np.zeros((2, 1))), params.dt, method="zoh")
    return ad, bd[:, 0]


class TrimInReadings:
    """The trim (n, 3) deg in a farm sample's pitch readings, from the trims commanded (module docstring)."""

    def __init__(self, n: int, params: TurbineParams):
        self.ad, self.bd = actuator_model(params)
        self.ticks = round(FARM_DT_S / params.dt)
        self.state = np.zeros((n, 3, 2))  # the trim's part of each blade's (position, rate)
        self.applied = np.zeros((n, 3))  # deg, the trim the blades' commands carry at the end of the last sample
        self.read = np.zeros((n, 3))  # deg, the trim in the last sample's readings
        self._idle = True  # no trim applied or dying out, ``read`` zeros: a sample without a command reads none

    def step(self, commanded: np.ndarray | None) -> np.ndarray:
        """The trim in this sample's readings; ``commanded`` (n, 3) deg the trim sent with the last sample (None:
        none)."""
        if commanded is None and self._idle:
            return self.read
        commanded = np.zeros_like(self.applied) if commanded is None else np.asarray(commanded, dtype=float)
        if not (commanded.any() or self.applied.any() or self.state.any()):
            self.read = np.zeros_like(self.applied)
            self._idle = True
            return self.read
        self._idle = False
        total = np.zeros_like(self.applied)
        trim = self.applied
        for _ in range(self.ticks):
            self.state = self.state @ self.ad.T + trim[..., None] * self.bd
            total += self.state[..., 0]
            trim = commanded  # the plant takes the new references from the tick after the sample
        self.applied = commanded
        gone = (commanded == 0.0) & (np.abs(self.state).max(axis=-1) < 1e-9)  # deg, deg/s: a removed trim has died out
        self.state = np.where(gone[..., None], 0.0, self.state)
        self.read = total / self.ticks
        return self.read
