"""What a benchmark turbine sends to the supervisor each tick, and what the supervisor sends back.

These are the in-process shapes of the ``sensors`` and ``refs`` messages; ``wwcore.wire`` encodes the same
fields for Zenoh. Arrays are batched: row i is turbine i of the batch (Monte Carlo runs × turbines).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class TurbineFrame:
    """Tick k of n turbines: the sensors y_k and the controller outputs of tick k−1 (the UIO's u[k−1])."""

    k: int  # tick index
    t: float  # s, simulation time of the samples, k·dt
    sensors: np.ndarray  # (n, N_SENSORS) in wwcore.channels.SENSOR_NAMES order, units of each channel
    tau_g_ref: np.ndarray  # (n,) N m, converter torque reference issued at tick k−1
    beta_ref: np.ndarray  # (n,) deg, collective pitch reference issued at tick k−1
    power_ref: np.ndarray  # (n,) W, power reference the controller used at tick k−1
    zone: np.ndarray  # (n,) int, controller zone at tick k−1 (0: region 2, 1: region 3)


@dataclass
class TurbineRefs:
    """The supervisor's references for n turbines, computed from the frame of tick ``tick``.

    The turbine controller uses them at tick ``tick + 1`` onwards while they are fresh, and falls back to its
    own sensors and its last good power reference when they are stale or ``valid`` is false.
    """

    tick: int
    valid: np.ndarray  # (n,) bool, the estimates below may be used
    omega_g: np.ndarray  # (n,) rad/s, fault-tolerant generator speed estimate
    omega_r: np.ndarray  # (n,) rad/s, fault-tolerant rotor speed estimate
    wind: np.ndarray  # (n,) m/s, fault-tolerant rotor-effective wind estimate
    power_ref: np.ndarray | None = None  # (n,) W, per-turbine power reference (farm dispatch); None keeps P_r
