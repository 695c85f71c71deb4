r"""PI loops on the farm's measured power: the dispatch's farm-power trim and the benchmark's farm PI.

Both act on each farm's relative power error

.. math::

    e = (P_{ref,farm} − Σ P_m)/P_{ref,farm},\quad I ← \operatorname{sat}(I + K_i e Δt),\quad
    u = \operatorname{sat}(K_p e + I)

(sat = ±limit, Δt the 10 Hz farm sample).

**Farm-power trim** (D-27, ``docs/farm.md`` §2.3) [PROPOSED; not in the paper]: eq. (18) shares the demand in
proportion to P_avail, which eq. (21) low-passes over a rotor transit, so a turbine in a lull cannot make its
share while one in a gust is held to its own, and the farm falls short although it has the power. The trim closes
that loop: P_ref,t ← (1 + u) P_ref,t on every turbine the accommodation leaves free (not derated by (26), not
held), only while the dispatch acts (P_ref,farm < Σ P_avail); I restarts from 0 otherwise. K_p = 0.5,
K_i = 0.5 1/s, ±10 % (options ``trim_kp``, ``trim_ki``, ``trim_limit``; K_p = K_i = 0 is the paper's open-loop
dispatch). It does not follow a held turbine's 0.6–0.8 Hz power ripple (D-C4): the references move at most 10 % of
rated per second.

**PI** (the benchmark's reference farm controller, PARAMETERS.md b): u as above with sat = ±20 %; every turbine gets
(1 + u) P_ref,farm / 9. K_p = 0.3, K_i = 0.05 1/s [PROPOSED].
"""

from __future__ import annotations

import numpy as np

from service.farm.interfaces import P_G, FarmContext, FarmSample
from wwcore.scenario.farm import FARM_DT_S

PI_KP, PI_KI, PI_LIMIT = 0.3, 0.05, 0.2  # PARAMETERS.md b [PROPOSED]
TRIM_KP, TRIM_KI, TRIM_LIMIT = 0.5, 0.5, 0.1  # –, 1/s, –: the dispatch's farm-power trim [PROPOSED]


def farm_power_pi(
    sample: FarmSample, integral: np.ndarray, kp: float, ki: float, limit: float
) -> tuple[np.ndarray, np.ndarray]:
    """One step of a PI on each farm's relative power error e = (P_ref,farm − Σ P_m)/P_ref,farm: the new integral
    I = sat(I + K_i e Δt) and the output u = sat(K_p e + I), sat = ±``limit`` (the PI and the dispatch's trim)."""
    farm_power = sample.per_farm(sample.scada[:, P_G]).sum(axis=1)
    demand = np.maximum(sample.demand, 1.0)
    error = (demand - farm_power) / demand
    integral = np.clip(integral + ki * error * FARM_DT_S, -limit, limit)
    return integral, np.clip(kp * error + integral, -limit, limit)


class FarmPowerTrim:
    """The dispatch's farm-power trim (D-27, module docstring) for ``farms`` farms."""

    def __init__(self, farms: int, kp: float = TRIM_KP, ki: float = TRIM_KI, limit: float = TRIM_LIMIT):
        self.kp, self.ki, self.limit = kp, ki, limit
        self.integral = np.zeros(farms)  # –, I per farm

    @property
    def enabled(self) -> bool:
        """False with K_p = K_i = 0: the paper's open-loop dispatch."""
        return self.kp > 0.0 or self.ki > 0.0

    def apply(self, sample: FarmSample, refs: np.ndarray, active: np.ndarray, free: np.ndarray) -> np.ndarray:
        """(1 + u) on the references ``refs`` (farms, N) of the turbines in ``free`` of the farms where the
        dispatch is ``active`` (farms,); I restarts from 0 where it is not."""
        integral, u = farm_power_pi(sample, self.integral, self.kp, self.ki, self.limit)
        self.integral = np.where(active, integral, 0.0)
        return np.where(free & active[:, None], refs * (1.0 + u[:, None]), refs)


class PIFarmController:
    """The benchmark's farm PI: equal shares of the demand, corrected by a PI on the farm power error."""

    def __init__(self, *, context: FarmContext, options: dict | None = None):
        options = options or {}
        self.p = context.params
        self.n = context.n
        self.kp = float(options.get("pi_kp", PI_KP))
        self.ki = float(options.get("pi_ki", PI_KI))
        self.integral = np.zeros(context.farms)
        self.mode = np.zeros(self.n, dtype=np.int8)
        self.p_ref = np.full(self.n, self.p.rated_power)

    def step(self, sample: FarmSample, faulty: np.ndarray) -> np.ndarray:
        self.integral, u = farm_power_pi(sample, self.integral, self.kp, self.ki, PI_LIMIT)
        per_farm = sample.turbines_per_farm
        refs = np.repeat(sample.demand * (1.0 + u) / per_farm, per_farm)
        self.p_ref = np.clip(refs, 0.0, self.p.rated_power)
        return self.p_ref
