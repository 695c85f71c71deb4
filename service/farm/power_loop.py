r"""PI loops on the farm's measured power: the dispatch's farm-power trim and the benchmark's farm PI.

Both act on each farm's relative power error

.. math::

    e = (P_{ref,farm} − Σ P_m)/P_{ref,farm},\quad I ← \operatorname{sat}(I + K_i e Δt),\quad
    u = \operatorname{sat}(K_p e + I)

(sat = ±limit, Δt the 10 Hz farm sample). With turbines no shard commands (``FarmSample.held``) the loop is on the
served ones: P_ref,farm less the held turbines' references P_H and Σ P_m over the served turbines,
e = (P_ref,farm − P_H − Σ_S P_m)/(P_ref,farm − P_H) (a held turbine's power in the sample is its last summary's).

**Farm-power trim** (D-27, ``docs/farm.md`` §2.3) [PROPOSED; not in the paper]: eq. (18) shares the demand in
proportion to P_avail, which eq. (21) low-passes over a rotor transit, so a turbine in a lull cannot make its
share while one in a gust is held to its own, and the farm falls short although it has the power. The trim closes
that loop: P_ref,t ← (1 + u) P_ref,t on every turbine the accommodation leaves free (not derated by (26), not
held), only while the dispatch acts (P_ref,farm < Σ P_avail); I restarts from 0 otherwise. K_p = 0.5,
K_i = 0.5 1/s, ±10 % (options ``trim_kp``, ``trim_ki``, ``trim_limit``; K_p = K_i = 0 is the paper's open-loop
dispatch). It does not follow a held turbine's 0.6–0.8 Hz power ripple (D-C4): the references move at most 10 % of
rated per second.

**PI** (the benchmark's reference farm controller, PARAMETERS.md b): u as above with sat = ±20 %; every turbine gets
(1 + u) P_ref,farm / N (the served ones (1 + u)(P_ref,farm − P_H)/N_S while some are held). K_p = 0.3, K_i = 0.05 1/s
[PROPOSED].
"""

from __future__ import annotations

import numpy as np

from service.farm.interfaces import P_G, FarmContext, FarmSample
from wwcore.scenario.farm import FARM_DT_S

PI_KP, PI_KI, PI_LIMIT = 0.3, 0.05, 0.2  # PARAMETERS.md b [PROPOSED]
TRIM_KP, TRIM_KI, TRIM_LIMIT = 0.5, 0.5, 0.1  # –, 1/s, –: the dispatch's farm-power trim [PROPOSED]


def farm_power_pi(
    sample: FarmSample, integral: np.ndarray, kp: float, ki: float, limit: float, held_power: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """One step of a PI on each farm's relative power error e = (P_ref,farm − Σ P_m)/P_ref,farm: the new integral
    I = sat(I + K_i e Δt) and the output u = sat(K_p e + I), sat = ±``limit`` (the PI and the dispatch's trim).
    ``held_power`` (farms,) W, the held turbines' references P_H: the error of the served turbines (module
    docstring)."""
    power = sample.scada[:, P_G]
    target = sample.demand
    if held_power is not None and sample.held is not None:
        power = np.where(sample.held, 0.0, power)
        target = np.maximum(target - held_power, 0.0)
    farm_power = sample.per_farm(power).sum(axis=1)
    demand = np.maximum(target, 1.0)
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

    def apply(
        self,
        sample: FarmSample,
        refs: np.ndarray,
        active: np.ndarray,
        free: np.ndarray,
        held_power: np.ndarray | None = None,
    ) -> np.ndarray:
        """(1 + u) on the references ``refs`` (farms, N) of the turbines in ``free`` of the farms where the
        dispatch is ``active`` (farms,); I restarts from 0 where it is not. ``held_power`` (farms,) W: the held
        turbines' references, the error then the served turbines' (``farm_power_pi``)."""
        integral, u = farm_power_pi(sample, self.integral, self.kp, self.ki, self.limit, held_power)
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
        """Equal shares (1 + u) P_ref,farm/N; with held turbines (``FarmSample.held``), the served ones share
        (1 + u)(P_ref,farm − P_H) equally and the held ones keep their last reference."""
        per_farm = sample.turbines_per_farm
        if sample.held is None or not sample.held.any():
            self.integral, u = farm_power_pi(sample, self.integral, self.kp, self.ki, PI_LIMIT)
            refs = np.repeat(sample.demand * (1.0 + u) / per_farm, per_farm)
            self.p_ref = np.clip(refs, 0.0, self.p.rated_power)
            return self.p_ref
        held = sample.per_farm(sample.held)
        held_power = np.where(held, sample.per_farm(self.p_ref), 0.0).sum(axis=1)
        self.integral, u = farm_power_pi(sample, self.integral, self.kp, self.ki, PI_LIMIT, held_power)
        served = np.maximum((~held).sum(axis=1), 1)
        share = np.maximum(sample.demand - held_power, 0.0) * (1.0 + u) / served
        refs = np.clip(np.repeat(share, per_farm), 0.0, self.p.rated_power)
        self.p_ref = np.where(sample.held, self.p_ref, refs)
        return self.p_ref
