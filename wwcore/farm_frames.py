"""What the wind-farm plant sends to the farm supervisor each tick, and what the supervisor sends back.

Rows are turbines of farms: row ``f·N + (t − 1)`` is turbine t of farm f (a Monte Carlo run, or its fault-free
twin), N the farm's turbines (9 on the paper's 3 × 3). The plant ticks at the turbines' 100 Hz; the farm level works
at 10 Hz (``wwcore.scenario.farm.FARM_DT_S``): every tenth tick is a *farm sample*, carrying the turbines' SCADA
values (the means of their last ten sensor samples, an anti-aliasing average), a new met-mast reading (speed and
vane) and the demand. The supervisor computes on farm samples and holds its references in between.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wwcore.turbine_frames import OMEGA_G_MAX, OMEGA_R_MAX, POWER_MAX, TurbineFrame
from wwcore.turbine_params import BENCHMARK

MIN_SPEED_FRACTION = 0.5  # –, ω_min = 0.5 Ω_nom: the lowest speed set point a farm turbine derates to [PROPOSED]
DEBRIS_MODE = 1  # accommodation mode (wire ``mode``): eqs. (23)–(24), the reference raised by 1/0.97
DERATED_MODE = 2  # accommodation mode (wire ``mode``): derated by eq. (26)
HOLD_TORQUE_MODE = 3  # accommodation mode (wire ``mode``) in which a turbine derates by speed at held torque
PITCH_TRIM_MODE = 4  # accommodation mode (wire ``mode``) in which a turbine's blades get a per-blade pitch trim
CANCEL_3P_MODE = 5  # accommodation mode (wire ``mode``): normal laws, the drive-train fault's 3P torque cancelled
DISPATCH_MODES = ("normal", "debris", "derated", "held torque", "pitch trim", "3P cancelled")  # wire ``mode`` names


@dataclass
class FarmFrame:
    """Tick k of the farm plant: every turbine's sensors, and on farm samples the 10 Hz farm-level signals."""

    k: int  # tick index (100 Hz)
    t: float  # s, k·dt
    turbines: TurbineFrame  # (n, …) the turbines' own frames of this tick
    sample: bool  # this tick closes a 10 Hz farm sample: the fields below are new
    scada: np.ndarray  # (n, N_SENSORS) means of the last ten sensor readings, channel units
    power_ref_used: np.ndarray  # (n,) W, the power reference each turbine's controller used
    mast: np.ndarray  # (farms,) m/s, met-mast wind reading (10 Hz, held in between)
    demand: np.ndarray  # (farms,) W, the farm power demand P_ref,farm
    mast_direction: np.ndarray | None = None  # (farms,) deg from north, the mast vane's reading (None: no vane)

    @property
    def farms(self) -> int:
        return len(self.mast)


@dataclass
class FarmRefs:
    """Per-turbine power references P_ref,t (W), the supervisor's answer to the frame of tick ``tick``.

    They were computed from the farm sample of tick ``computed_tick`` (≤ tick; the supervisor answers every tick
    and computes every tenth). Each turbine's controller takes a reference when ``computed_tick`` is new and keeps
    the last one it received while none arrives (a set point, not an estimate: it does not go stale).
    """

    tick: int
    power_ref: np.ndarray  # (n,) W
    computed_tick: int | None = None  # None: the same as ``tick``
    hold_torque: np.ndarray | None = None  # (n,) bool: derate at held torque (drive-train accommodation)
    cancel_3p: np.ndarray | None = None  # (n,) bool: cancel the drive-train fault's 3P torque without derating
    held_torque: np.ndarray | None = None  # (n,) N m, generator side: most torque sum S a hold keeps (NaN: its own)
    pitch_trim: np.ndarray | None = None  # (n, 3) deg added to each blade's pitch command (pitch accommodation)
    # (n,) complex W and (n,) rad/s: each turbine adds Re{C e^{jω(t − t_c)}} to its power, t_c the time of the farm
    # sample the refs were computed from ((computed_tick + 1)·Δt): the held turbine's 3P ripple cancelled
    ripple_power: np.ndarray | None = None
    ripple_rate: np.ndarray | None = None

    @property
    def source_tick(self) -> int:
        return self.tick if self.computed_tick is None else self.computed_tick


# -- what the plant takes: the physical range of each farm.refs field it acts on (wwcore.wire.WireField.limits) ----
TORQUE_MAX = 1.2 * BENCHMARK.rated_torque + BENCHMARK.B_g * OMEGA_G_MAX  # N m: converter limit + friction at overspeed
RIPPLE_RATE_MAX = 3.0 * OMEGA_R_MAX  # rad/s, the 3P frequency at the overspeed limit
PITCH_TRIM_MAX = 5.0  # deg, the largest blade misalignment of the farm's fault model (wwcore.scenario.farm)

FARM_REFS_LIMITS = {
    "power_ref": (0.0, POWER_MAX, ("computed_tick", ">=", 0)),  # W, on the rows that carry a reference
    "mode": (0, len(DISPATCH_MODES) - 1, None),
    "held_torque": (0.0, TORQUE_MAX, ("mode", "==", HOLD_TORQUE_MODE)),  # N m
    "pitch_trim": (-PITCH_TRIM_MAX, PITCH_TRIM_MAX, None),  # deg
    "ripple_power": (-POWER_MAX, POWER_MAX, None),  # W
    "ripple_rate": (0.0, RIPPLE_RATE_MAX, None),  # rad/s
}
"""``farm.refs`` field → (lowest, highest, the rows the range holds on), as ``turbine_frames.TURBINE_REFS_LIMITS``."""
