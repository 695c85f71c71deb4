r"""Farm controllers: the load-distributing dispatch of seed 001 (``dispatch``) and the benchmark's PI (``pi``).

**Available power** (eqs. (20)–(22)). Each turbine's wind is estimated from its pitch and power: in steady state
the aerodynamic torque balances the drive train, τ̂_r = (N_g/η_dt)(τ̄_g + B_g ω̄_g) + B_r ω̂_r, and v solves
½ρπR³ C_q(ω̂_r R/v, β̄) v² = τ̂_r (``wwcore.aero.wind_from_torque``; ω̂_r = ω̄_g/N_g, β̄ the mean of the six pitch
encoders). That is eq. (20), "the wind from the pitch angle" through the C_q surface rather than the paper's
lookup pair h⁻¹, g⁻¹, and with the measured torque instead of P_ref (equal in steady derated operation; the
measured torque also holds when the turbine cannot reach its reference). Then

.. math::

    \hat P_a = \frac{τ_w}{s + α_w} P_a(w_{est}) \quad (21),\qquad
    P_{avail} = \mathrm{pos}(\hat P_a - P_{ref}) + P_m \quad (22)

with P_a(v) the steady available power (``power_curve``), α_w = τ_w = w_est/D [PROPOSED: the paper gives no
values; one rotor transit time], P_ref the reference sent last and P_m the measured power.

**Dispatch** (eqs. (18)–(19)): P_ref,t = P_avail,t / Σ P_avail · P_ref,farm, active only while
P_ref,farm < Σ P_avail; otherwise every turbine gets rated power (it produces what it can).

**Accommodation** (eqs. (23)–(26)), for turbines the detector flags (when accommodation is on):

* debris: P_avail,f1 = 0.97 P_avail in the sum of (18), then P_ref,f1 = P_ref/0.97 (23)–(24);
* pitch misalignment, drive train: P_over = Σ P_avail − P_ref,farm (25) and
  P_avail,f = max(pos(P_avail − P_over), P_min), P_min = 50 kW (26), then (18) with P_avail,f. *Decision D-26*:
  with several such turbines the headroom is shared out in turbine order, P_over shrinking by what each took.
* drive train, rule ``hold-torque`` (the default) [PROPOSED]: the same (25)–(26) with the floor
  P_min,f = max(P_min, η_gc (S_m − B_g ω_floor) ω_floor), S_m = τ_g,m + B_g ω̄_g: the power the turbine makes at
  its present shaft torque and the lowest speed at which its rotor still delivers that torque. The reference goes
  out with ``hold_torque`` (mode 3), and the turbine derates by speed at held torque
  (``plant_sim.farm.controller``). ω_floor = max(ω_min, N_g λ_f w̄/R), λ_f the tip-speed ratio on the rising
  branch of C_q(λ, 0) (below its peak at λ ≈ 6.5; at the peak when that is not enough) where
  ½ρπR³ C_q(λ_f, 0) w̄² = 1.2 τ̄_r (option ``hold_margin``: torque in hand for the turbulence), and λ_f ≥ 5: below
  that the torque is largest at a pitch above 3 deg, and a controller that goes to fine pitch to speed up stalls
  the rotor instead. w̄, τ̄_r are w_est and τ̂_r low-passed over 10 s, and ω_floor is fixed when the hold begins:
  eq. (20) assumes steady state and reads nonsense while the rotor slows down. The held turbine's reference is
  at least P_min,f; the others share the rest of the demand as in (18). The paper's rule
  (``accommodation_rule = "paper"``) drops the torque to what 50 kW needs, a rainflow cycle as large as the
  working torque that costs more damage than the 3P cycles it saves (docs/farm.md, Table 7); holding the torque
  lowers the 3P swing (∝ ω_r²) without it.

**PI** (the benchmark's reference controller, PARAMETERS.md b): e = (P_ref,farm − Σ P_m)/P_ref,farm,
u = sat(K_p e + I), I = sat(I + K_i e Δt), sat = ±20 %; every turbine gets (1 + u) P_ref,farm / 9.
K_p = 0.3, K_i = 0.05 1/s [PROPOSED].
"""

from __future__ import annotations

import numpy as np

from service.farm.interfaces import BETA, OMEGA_G, P_G, TAU_G, FarmContext, FarmSample
from service.farm.power_curve import available_power
from wwcore import aero
from wwcore.farm_frames import MIN_SPEED_FRACTION
from wwcore.scenario.farm import FARM_DT_S, N_TURBINES, ROTOR_DIAMETER_M

DEBRIS_FACTOR = 0.97  # eqs. (23)–(24)
P_MIN_W = 50e3  # eq. (26)
ACCOMMODATION_RULES = ("hold-torque", "paper")
HOLD_MARGIN = 1.2  # –, rotor torque at fine pitch and the derated speed over the held torque [PROPOSED]
HOLD_MIN_TSR = 5.0  # –, lowest tip-speed ratio of a hold: below it C_q peaks at β > 3 deg and fine pitch stalls
HOLD_AVERAGING_S = 10.0  # s, low-pass of the wind and rotor torque the hold's speed floor is chosen from [PROPOSED]
_TSR = np.linspace(1.5, 12.0, 211)
_CQ_FINE = aero.torque_coefficient(_TSR, np.zeros_like(_TSR))
_RISING = slice(0, int(np.argmax(_CQ_FINE)) + 1)  # C_q(λ, 0) rises with λ up to its peak
PI_KP, PI_KI, PI_LIMIT = 0.3, 0.05, 0.2  # PARAMETERS.md b [PROPOSED]
DEBRIS, PITCH, DRIVETRAIN = 0, 1, 2  # columns of ``faulty``


class Dispatch:
    """Eqs. (18)–(26) for ``farms`` farms of nine turbines (module docstring)."""

    def __init__(self, *, context: FarmContext, options: dict | None = None):
        options = options or {}
        self.context = context
        self.p = context.params
        # [PROPOSED] variant of eq. (26), off by default: never derate a faulty turbine below this share of its
        # own available power (docs/farm.md, "graded accommodation"); 0 is the paper's P_min floor only.
        self.floor = float(options.get("derate_floor", 0.0))
        self.rule = str(options.get("accommodation_rule", ACCOMMODATION_RULES[0]))
        self.hold_margin = float(options.get("hold_margin", HOLD_MARGIN))
        if self.rule not in ACCOMMODATION_RULES:
            raise ValueError(f"accommodation_rule: {self.rule!r} is not one of {', '.join(ACCOMMODATION_RULES)}")
        self.n = context.n
        self.p_ref = np.full(self.n, self.p.rated_power)  # W, the references sent last
        self.wind: np.ndarray | None = None  # m/s, w_est of eq. (20)
        self.p_a_hat: np.ndarray | None = None  # W, eq. (21) state
        self.p_avail = np.zeros(self.n)  # W, eq. (22), before accommodation
        self._slow: np.ndarray | None = None  # (2, n) w_est (m/s) and τ̂_r (N m) over HOLD_AVERAGING_S
        self.speed_floor = np.full(self.n, np.nan)  # rad/s, ω_floor of turbines in the hold (NaN: none)
        self.mode = np.zeros(self.n, dtype=np.int8)  # 0 normal, 1 debris (23)–(24), 2 derated (26), 3 held torque

    def estimate_available(self, sample: FarmSample) -> np.ndarray:
        """Eqs. (20)–(22): P_avail,t (n,) in W."""
        p, y = self.p, sample.scada
        omega_g = y[:, OMEGA_G].mean(axis=1)
        omega_r = omega_g / p.N_g
        pitch = y[:, BETA].mean(axis=(1, 2))
        tau_r = p.N_g * (y[:, TAU_G] + p.B_g * omega_g) / p.eta_dt + p.B_r * omega_r
        if self.wind is None:
            guess = np.repeat(sample.mast, N_TURBINES)
            self.wind = aero.wind_from_torque(tau_r, omega_r, pitch, guess, p, iterations=8)
        else:
            self.wind = aero.wind_from_torque(tau_r, omega_r, pitch, self.wind, p, iterations=3)  # eq. (20)
        if self._slow is None:
            self._slow = np.stack([self.wind, tau_r])
        else:
            self._slow += (np.stack([self.wind, tau_r]) - self._slow) * (FARM_DT_S / HOLD_AVERAGING_S)
        p_a = available_power(p, self.wind)
        if self.p_a_hat is None:
            self.p_a_hat = p_a.copy()
        a = np.exp(-np.maximum(self.wind, 1.0) / ROTOR_DIAMETER_M * FARM_DT_S)
        self.p_a_hat = a * self.p_a_hat + (1.0 - a) * p_a  # eq. (21), τ_w/(s + α_w) with τ_w = α_w
        return np.maximum(self.p_a_hat - self.p_ref, 0.0) + y[:, P_G]  # eq. (22)

    def hold_speed_floor(self) -> np.ndarray:
        """ω_floor (n,) rad/s, generator side: the lowest speed at which each rotor holds its torque (docstring)."""
        p = self.p
        wind, tau_r = self._slow
        need = self.hold_margin * tau_r / (p.aero_torque_gain * wind * wind)
        tsr = np.maximum(np.interp(need, _CQ_FINE[_RISING], _TSR[_RISING]), HOLD_MIN_TSR)
        omega = p.N_g * tsr * wind / p.radius
        return np.minimum(np.maximum(omega, MIN_SPEED_FRACTION * p.omega_nom), p.omega_nom)

    def step(self, sample: FarmSample, faulty: np.ndarray) -> np.ndarray:
        farms = sample.farms
        p_avail = self.estimate_available(sample)
        self.p_avail = p_avail
        avail = p_avail.reshape(farms, N_TURBINES).copy()
        f = faulty.reshape(farms, N_TURBINES, -1)
        demand = sample.demand
        maximum = avail.sum(axis=1)  # the farm's theoretical maximum production, Σ P_avail (19)
        debris = f[:, :, DEBRIS] & ~(f[:, :, PITCH] | f[:, :, DRIVETRAIN])
        derate = f[:, :, PITCH] | f[:, :, DRIVETRAIN]
        avail = np.where(debris, DEBRIS_FACTOR * avail, avail)  # eq. (23)
        over = avail.sum(axis=1) - demand  # eq. (25)
        hold = f[:, :, DRIVETRAIN] & (self.rule == "hold-torque")
        floor = np.full(avail.shape, P_MIN_W)
        if hold.any():
            starting = hold.reshape(-1) & np.isnan(self.speed_floor)
            if starting.any():
                self.speed_floor = np.where(starting, self.hold_speed_floor(), self.speed_floor)
            y, p = sample.scada, self.p
            held_sum = y[:, TAU_G] + p.B_g * y[:, OMEGA_G].mean(axis=1)  # S of plant_sim.farm.controller
            held = p.eta_gc * (held_sum - p.B_g * self.speed_floor) * self.speed_floor
            floor = np.where(hold, np.maximum(held.reshape(farms, N_TURBINES), P_MIN_W), floor)
        for t in range(N_TURBINES):  # eq. (26), headroom shared out in turbine order (D-26)
            hit = derate[:, t]
            if hit.any():
                reduced = np.maximum(np.maximum(avail[:, t] - np.maximum(over, 0.0), 0.0), floor[:, t])
                reduced = np.maximum(reduced, np.minimum(self.floor * avail[:, t], avail[:, t]))
                taken = np.where(hit, avail[:, t] - reduced, 0.0)
                avail[:, t] = np.where(hit, reduced, avail[:, t])
                over = over - taken
        total = avail.sum(axis=1)
        active = demand < maximum  # the dispatch acts only below the farm's maximum production
        share = avail / np.maximum(total, 1.0)[:, None] * demand[:, None]  # eq. (18)
        if hold.any():  # a held turbine gets at least its floor; the others share the rest as in (18)
            fixed = np.where(hold, np.maximum(share, floor), 0.0)
            others = np.where(hold, 0.0, avail)
            rest = np.maximum(demand - fixed.sum(axis=1), 0.0)
            share = np.where(hold, fixed, others / np.maximum(others.sum(axis=1), 1.0)[:, None] * rest[:, None])
        share = np.where(debris, share / DEBRIS_FACTOR, share)  # eq. (24)
        refs = np.where(active[:, None], share, self.p.rated_power)
        refs = np.clip(refs, 0.0, self.p.rated_power).reshape(-1)
        self.speed_floor = np.where(hold.reshape(-1), self.speed_floor, np.nan)
        self.mode = np.where(hold, 3, np.where(derate, 2, np.where(debris, 1, 0))).astype(np.int8).reshape(-1)
        self.p_ref = refs
        return refs


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
        farm_power = sample.per_farm(sample.scada[:, P_G]).sum(axis=1)
        demand = np.maximum(sample.demand, 1.0)
        error = (demand - farm_power) / demand
        self.integral = np.clip(self.integral + self.ki * error * FARM_DT_S, -PI_LIMIT, PI_LIMIT)
        u = np.clip(self.kp * error + self.integral, -PI_LIMIT, PI_LIMIT)
        refs = np.repeat(sample.demand * (1.0 + u) / N_TURBINES, N_TURBINES)
        self.p_ref = np.clip(refs, 0.0, self.p.rated_power)
        return self.p_ref
