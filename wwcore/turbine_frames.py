"""What a benchmark turbine sends to the supervisor each tick, and what the supervisor sends back.

These are the in-process shapes of the ``sensors`` and ``refs`` messages; ``wwcore.wire`` encodes the same
fields for Zenoh. Arrays are batched: row i is turbine i of the batch (Monte Carlo runs × turbines).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wwcore.turbine_params import BENCHMARK


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


# -- what the plant takes: the physical range of each refs field it acts on (wwcore.wire.WireField.limits) --------
OVERSPEED = 1.2
"""× rated generator speed: the overspeed limit of the benchmark turbine (a multi-MW turbine's overspeed protection
trips at 1.1–1.2 × rated); no speed estimate above it is one the controller may act on."""
OMEGA_G_MAX = OVERSPEED * BENCHMARK.omega_nom  # rad/s, 194.4
OMEGA_R_MAX = OMEGA_G_MAX / BENCHMARK.N_g  # rad/s, 2.05
REFS_WIND_MAX = 70.0  # m/s, the IEC class I extreme 3-s gust (1.4 × 50 m/s): no turbine runs in a stronger wind
POWER_MAX = BENCHMARK.rated_power  # W: no benchmark turbine can be asked for more than P_r
_VALID = ("valid", "==", True)  # the estimates may be used

TURBINE_REFS_LIMITS = {
    "omega_g": (0.0, OMEGA_G_MAX, _VALID),  # rad/s
    "omega_r": (0.0, OMEGA_R_MAX, _VALID),  # rad/s
    "wind": (0.0, REFS_WIND_MAX, _VALID),  # m/s
    "power_ref": (0.0, POWER_MAX, ("power_ref_set", "==", True)),  # W
    "wind_nfte": (0.0, REFS_WIND_MAX, ("nfte_set", "==", True)),  # m/s
}
"""``turbine.refs`` field → (lowest, highest, the rows the range holds on: (field, "==" or ">=", value) or None)."""
