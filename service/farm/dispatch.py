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
* pitch misalignment, option ``pitch_rule``: ``trim`` (the default) [PROPOSED], D-28: a per-blade pitch trim turns
  the misaligned blade back to the others (``pitch_trim``); the turbine keeps its power. ``paper``: (26). Why not
  (26): on farm-case1 (4 runs, development seed 4243) derating the pitch-faulty turbine to the farm's headroom left
  the rotor imbalance where it was (15.9 → 17.0 × the twin's), raised the turbine's shaft damage number over the
  window from 1.00 to 3.8 (the drop to the floor and back is one large torque cycle) and took the farm's reserve,
  doubling the window's missing power.
* drive train, rule ``cancel`` (the default) [PROPOSED]: from the flag on the turbine runs its normal laws and its
  converter cancels the fault's 3P shaft torque (mode 5, ``cancel_3p``; ``plant_sim.farm.controller``, D-C4); the
  farm cancels the power ripple that leaves (D-29 below). Nothing is derated below (1 − r) P_avail (D-32), so the
  farm keeps its reserve.
  Why not the hold below: once the cancellation stopped ringing the pitch loop above rated (D-C4b), 20 development
  runs per case (seeds 4281, 4282, with twins) gave the cancel rule 89 % / 87 % of the run's drive-train
  damage-number excess removed at −0.1 / +0.6 kWh per run of missing power, and the hold 87 % / 84 % at +3.6 / +0.6:
  a held rotor has to speed up again whenever a lull needs its power (docs/farm.md §4).
* **D-32, relief** of a drive train whose 3P is cancelled (rule ``cancel``; option ``drivetrain_relief`` = r,
  default 0.1) [PROPOSED]: eq. (26) with the floor (1 − r) P_avail instead of P_min: while the farm has headroom,
  the flagged turbine takes up to r P_avail of it, the others share the rest as in (18), and the farm-power trim
  still acts on it, so in a lull it gives that power back first. Beyond the farm's maximum it runs at rated as
  every turbine does. Why: a turbine asked for less than its share casts a weaker wake, which the rows behind it
  turn into power when the farm later has none to spare; unrelieved, the accommodated turbine carried its full
  share and the farm missed more power than with the fault unaccommodated (docs/farm.md §4, Table 7). r = 0.1
  from three values on 20 development runs per case (seeds 4311, 4312): r = 0.05, 0.1, 0.2 moved case 2's missing
  power −2.1, −4.1, −7.4 kWh per run against r = 0 and case 1's −0.1, +0.4, +1.1 (without the trim on the
  relieved turbine; with it, r = 0.1 gave −3.9 and +0.15).
* drive train, rule ``hold-torque`` [PROPOSED]: the turbine is derated by speed, not by torque.
  When the hold begins the dispatch fixes its speed floor ω_floor = clip(N_g λ w̄/R, ω_min, Ω_nom) and a cap S_max(λ)
  = η_dt (½ρπR³ C_q(λ, 0) w̄²/1.2 − B_r ω_r)/N_g on the held generator-side sum S = τ_g + B_g ω_g: what the rotor
  makes at λ at fine pitch with 20 % in hand for the turbulence (option ``hold_margin``). λ is the smallest tip-speed
  ratio on a 0.05 grid from λ_f = 5 to λ_q ≈ 6.55 with S_max(λ) ≥ S_m, the sum the turbine makes when the hold begins:
  the slowest speed at which the rotor keeps its torque, so the hold moves the mean shaft torque by nothing (a cap
  below S_m costs one rainflow cycle as large as the step, on entry and again on release). λ_f is the lowest λ at
  which fine pitch still gives the rotor's largest torque (below it that takes a pitch above 3 deg, and a controller
  that goes to fine pitch to speed up stalls the rotor instead); λ_q gives the most torque at fine pitch, so where no
  λ keeps S_m the hold runs there with S capped at S_max(λ_q). w̄ is w_est low-passed over 10 s; ω_floor and S_max
  stay fixed while the hold lasts, since eq. (20) assumes steady state and reads nonsense while the rotor slows down.
  The reference is the floor P_min,f = max(P_min, η_gc (min(S_m, S_max) − B_g ω_floor) ω_floor), S_m = τ_g,m + B_g
  ω̄_g, sent with ``hold_torque`` (mode 3) and ``held_torque`` = S_max (``plant_sim.farm.controller``); the other
  turbines share the rest of the demand as in (18). The held turbine keeps its floor when the farm cannot meet the
  demand too (the others then run at rated): a hold released by a lull would swing the torque through the cycles it
  exists to avoid. Why: the fault's 3P torque swing grows with ω_r² and its rainflow damage with about ω_r⁹ at m = 4,
  while lowering the mean torque costs one cycle of the torque change. In the hold the turbine also cancels the
  fault's 3P shaft torque with its converter (``plant_sim.farm.controller``, D-C4).
  **D-30, release**: when the farm needs the held turbine's power, the others being asked for more than
  1 − ``HOLD_RESERVE`` of their available power (or the demand beyond the farm's maximum) for ``RELEASE_AFTER_S``,
  the hold is released until the flag clears: the turbine runs its normal laws with its 3P torque still cancelled
  (mode 5, ``cancel_3p``). A derated rotor gives its power back only as fast as it can speed up, so the first
  seconds of a lull cost what they cost; without the release, a hold begun in a lull kept its low torque while the
  wind rose and the farm fell short for minutes (``docs/farm.md`` §4).
  The paper's rule (``accommodation_rule = "paper"``)
  drops the torque to what 50 kW needs at unchanged speed: a cycle as large as the working torque, and a 3P swing as
  large as before (docs/farm.md, Table 7).
* **D-29, the ripple of a cancelled 3P torque**: a turbine whose 3P torque its converter cancels (modes 3 and 5)
  makes a 3P power ripple instead; the dispatch estimates it and asks the free turbines of the farm for its
  opposite (``service.farm.ripple``), and reads the turbines' power without it (eq. (22), the trim): the ripple is
  not its power loop's to answer. Option ``ripple_compensation = false`` turns it off (estimate and all: the
  power loop then answers the ripple); ``ripple_share`` = s ∈ [0, 1] (default 1) asks the free turbines for s of
  the ripple's opposite only, the estimate still taken off the readings.

**Farm-power trim** [PROPOSED; not in the paper]. Eq. (18) shares the demand in proportion to P_avail, which
eq. (21) low-passes over a rotor transit: a turbine in a lull cannot make its share while one in a gust is held
to its own, and the farm falls short although it has the power. A PI on the farm's measured power closes the loop:

.. math::

    e = (P_{ref,farm} − Σ P_m)/P_{ref,farm},\quad I ← \operatorname{sat}(I + K_i e Δt),\quad
    u = \operatorname{sat}(K_p e + I),\qquad P_{ref,t} ← (1 + u)\,P_{ref,t}

(sat = ±``trim_limit``) on every turbine the accommodation leaves alone (not derated by (26), not held); it acts
only while the dispatch does (P_ref,farm < Σ P_avail), and I restarts from 0 otherwise. K_p = 0.5, K_i = 0.5 1/s,
±10 % (options ``trim_kp``, ``trim_ki``, ``trim_limit``; K_p = K_i = 0 is the paper's open-loop dispatch).
It does not follow the held turbine's 0.6–0.8 Hz power ripple (D-C4): the references move at most 10 % of rated
per second.

**PI** (the benchmark's reference controller, PARAMETERS.md b): e = (P_ref,farm − Σ P_m)/P_ref,farm,
u = sat(K_p e + I), I = sat(I + K_i e Δt), sat = ±20 %; every turbine gets (1 + u) P_ref,farm / 9.
K_p = 0.3, K_i = 0.05 1/s [PROPOSED].
"""

from __future__ import annotations

import numpy as np

from service.farm.interfaces import BETA, OMEGA_G, P_G, TAU_G, FarmContext, FarmSample
from service.farm.pitch_trim import PitchTrim
from service.farm.power_curve import available_power
from service.farm.ripple import RippleCompensation
from service.plugins import AlgorithmOptionError
from wwcore import aero
from wwcore.farm_frames import (
    CANCEL_3P_MODE,
    DEBRIS_MODE,
    DERATED_MODE,
    HOLD_TORQUE_MODE,
    MIN_SPEED_FRACTION,
    PITCH_TRIM_MODE,
)
from wwcore.scenario.farm import FARM_DT_S, N_TURBINES, ROTOR_DIAMETER_M

DEBRIS_FACTOR = 0.97  # eqs. (23)–(24)
P_MIN_W = 50e3  # eq. (26)
ACCOMMODATION_RULES = ("cancel", "hold-torque", "paper")  # the first is the default
PITCH_RULES = ("trim", "paper")
HOLD_MARGIN = 1.2  # –, rotor torque at fine pitch and the hold's speed over the held torque cap [PROPOSED]
HOLD_MIN_TSR = 5.0  # –, tip-speed ratio of a hold: the lowest at which fine pitch gives the most torque (below, stall)
HOLD_RESERVE = 0.05  # –, share of their available power the others keep in hand before a hold is released [PROPOSED]
RELEASE_AFTER_S = 5.0  # s the farm must need a held turbine's power before its hold is released [PROPOSED]
HOLD_AVERAGING_S = 10.0  # s, low-pass of the wind the hold's speed floor and torque cap are chosen from [PROPOSED]
_TSR_GRID = np.arange(HOLD_MIN_TSR, 9.0 + 1e-9, 0.05)
HOLD_MAX_TORQUE_TSR = float(_TSR_GRID[np.argmax(aero.torque_coefficient(_TSR_GRID, np.zeros_like(_TSR_GRID)))])
"""λ_q, –: the tip-speed ratio of the most rotor torque at fine pitch for a given wind (≈ 6.5)"""
HOLD_TSRS = _TSR_GRID[_TSR_GRID <= HOLD_MAX_TORQUE_TSR + 1e-9]  # the λ a hold may choose, slowest first
PI_KP, PI_KI, PI_LIMIT = 0.3, 0.05, 0.2  # PARAMETERS.md b [PROPOSED]
TRIM_KP, TRIM_KI, TRIM_LIMIT = 0.5, 0.5, 0.1  # –, 1/s, –: the dispatch's farm-power trim [PROPOSED]
DRIVETRAIN_RELIEF = 0.1  # –, share of its available power a flagged, cancelled drive train gives up, D-32 [PROPOSED]
DEBRIS, PITCH, DRIVETRAIN = 0, 1, 2  # columns of ``faulty``


def _share_option(options: dict, name: str, default: float) -> float:
    """``options[name]`` (else ``default``) as a share in [0, 1]; an AlgorithmOptionError naming it otherwise."""
    value = options.get(name, default)
    try:
        share = float(value)
    except (TypeError, ValueError):
        share = float("nan")
    if not 0.0 <= share <= 1.0:
        raise AlgorithmOptionError(f"{name}: {value!r} is not a share in [0, 1]")
    return share


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


class Dispatch:
    """Eqs. (18)–(26) for ``farms`` farms of nine turbines (module docstring)."""

    def __init__(self, *, context: FarmContext, options: dict | None = None):
        options = options or {}
        self.context = context
        self.p = context.params
        # [PROPOSED] variant of eq. (26), off by default: never derate a faulty turbine below this share of its
        # own available power (docs/farm.md §2.3, ``derate_floor``); 0 is the paper's P_min floor only.
        self.floor = float(options.get("derate_floor", 0.0))
        self.relief = _share_option(options, "drivetrain_relief", DRIVETRAIN_RELIEF)  # D-32
        self.rule = str(options.get("accommodation_rule", ACCOMMODATION_RULES[0]))
        self.hold_margin = float(options.get("hold_margin", HOLD_MARGIN))
        if self.rule not in ACCOMMODATION_RULES:
            raise AlgorithmOptionError(
                f"accommodation_rule: {self.rule!r} is not one of {', '.join(ACCOMMODATION_RULES)}"
            )
        self.pitch_rule = str(options.get("pitch_rule", PITCH_RULES[0]))
        if self.pitch_rule not in PITCH_RULES:
            raise AlgorithmOptionError(f"pitch_rule: {self.pitch_rule!r} is not one of {', '.join(PITCH_RULES)}")
        self.n = context.n
        self.p_ref = np.full(self.n, self.p.rated_power)  # W, the references sent last
        self.wind: np.ndarray | None = None  # m/s, w_est of eq. (20)
        self.p_a_hat: np.ndarray | None = None  # W, eq. (21) state
        self.p_avail = np.zeros(self.n)  # W, eq. (22), before accommodation
        self._slow_wind: np.ndarray | None = None  # (n,) m/s, w_est low-passed over HOLD_AVERAGING_S
        self.speed_floor = np.full(self.n, np.nan)  # rad/s, ω_floor of turbines in the hold (NaN: none)
        self.held_torque = np.full(self.n, np.nan)  # N m, S_max of turbines in the hold (NaN: none)
        self.hold_reserve = float(options.get("hold_reserve", HOLD_RESERVE))
        self.release_after_s = float(options.get("release_after_s", RELEASE_AFTER_S))
        # flagged drive trains on their normal laws with the 3P cancelled (mode 5): under rule ``cancel`` every one
        # from its flag on, under ``hold-torque`` the holds D-30 released
        self.released = np.zeros(self.n, dtype=bool)
        self._needed_s = np.zeros(self.n)  # s, how long the farm has needed a held turbine's power
        self.held_sum = np.full(self.n, np.nan)  # N m, min(S_m, S_max) latched when the hold began (NaN: none)
        # wwcore.farm_frames.DISPATCH_MODES: normal, debris, derated (26), held torque, pitch trim, 3P cancelled
        self.mode = np.zeros(self.n, dtype=np.int8)
        self.pitch = PitchTrim(self.n)  # the pitch rule ``trim``
        self.trim_kp = float(options.get("trim_kp", TRIM_KP))
        self.trim_ki = float(options.get("trim_ki", TRIM_KI))
        self.trim_limit = float(options.get("trim_limit", TRIM_LIMIT))
        self.trim = np.zeros(context.farms)  # –, the trim's integral I per farm
        ripple_share = _share_option(options, "ripple_share", 1.0)  # D-29: the part of the ripple the others cancel
        compensate = bool(options.get("ripple_compensation", True))
        self.ripple = RippleCompensation(self.p, self.n, ripple_share) if compensate else None

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
        if self._slow_wind is None:
            self._slow_wind = self.wind.copy()
        else:
            self._slow_wind += (self.wind - self._slow_wind) * (FARM_DT_S / HOLD_AVERAGING_S)
        p_a = available_power(p, self.wind)
        if self.p_a_hat is None:
            self.p_a_hat = p_a.copy()
        a = np.exp(-np.maximum(self.wind, 1.0) / ROTOR_DIAMETER_M * FARM_DT_S)
        self.p_a_hat = a * self.p_a_hat + (1.0 - a) * p_a  # eq. (21), τ_w/(s + α_w) with τ_w = α_w
        return np.maximum(self.p_a_hat - self.p_ref, 0.0) + y[:, P_G]  # eq. (22)

    def hold_point(self, held_sum: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(ω_floor, S_max) (n,) of a hold begun now with the generator-side torque sum ``held_sum`` (N m): the
        slowest speed (rad/s) at a tip-speed ratio in [λ_f, λ_q] where the rotor makes that sum at fine pitch with
        ``hold_margin`` in hand, and the sum it makes there (at λ_q, the most it can, if none keeps ``held_sum``)."""
        p = self.p
        wind = np.maximum(self._slow_wind, 1.0)[:, None]
        omega = np.clip(p.N_g * HOLD_TSRS * wind / p.radius, MIN_SPEED_FRACTION * p.omega_nom, p.omega_nom)
        omega_r = omega / p.N_g
        tsr = omega_r * p.radius / wind
        rotor = p.aero_torque_gain * aero.torque_coefficient(tsr, np.zeros_like(tsr)) * wind * wind / self.hold_margin
        most = p.eta_dt * (rotor - p.B_r * omega_r) / p.N_g  # (n, grid): S the rotor holds at each λ
        keeps = most >= held_sum[:, None]
        pick = np.where(keeps.any(axis=1), keeps.argmax(axis=1), len(HOLD_TSRS) - 1)
        rows = np.arange(len(pick))
        return omega[rows, pick], most[rows, pick]

    def step(self, sample: FarmSample, faulty: np.ndarray) -> np.ndarray:
        measured, farms = sample, sample.farms
        if self.ripple is not None:
            sample = self.ripple.without_ripple(sample)
        p_avail = self.estimate_available(sample)
        self.p_avail = p_avail
        avail = p_avail.reshape(farms, N_TURBINES).copy()
        f = faulty.reshape(farms, N_TURBINES, -1)
        demand = sample.demand
        maximum = avail.sum(axis=1)  # the farm's theoretical maximum production, Σ P_avail (19)
        debris = f[:, :, DEBRIS] & ~(f[:, :, PITCH] | f[:, :, DRIVETRAIN])
        trimmed = f[:, :, PITCH] & (self.pitch_rule == "trim")
        self.released &= f[:, :, DRIVETRAIN].reshape(-1)
        if self.rule == "cancel":  # no hold at all: the normal laws with the fault's 3P torque cancelled
            self.released |= f[:, :, DRIVETRAIN].reshape(-1)
        released = self.released.reshape(farms, N_TURBINES)
        derate = (f[:, :, PITCH] & ~trimmed) | (f[:, :, DRIVETRAIN] & ~released)
        relieved = f[:, :, DRIVETRAIN] & released & (self.rule == "cancel") & (self.relief > 0.0)
        self.pitch.step(sample, trimmed.reshape(-1))
        avail = np.where(debris, DEBRIS_FACTOR * avail, avail)  # eq. (23)
        over = avail.sum(axis=1) - demand  # eq. (25)
        hold = f[:, :, DRIVETRAIN] & (self.rule == "hold-torque") & ~released
        floor = np.full(avail.shape, P_MIN_W)
        if hold.any():
            y, p = sample.scada, self.p
            starting = hold.reshape(-1) & np.isnan(self.speed_floor)
            if starting.any():
                now = y[:, TAU_G] + p.B_g * y[:, OMEGA_G].mean(axis=1)  # S of plant_sim.farm.controller
                omega, most = self.hold_point(now)
                self.speed_floor = np.where(starting, omega, self.speed_floor)
                self.held_torque = np.where(starting, most, self.held_torque)
                self.held_sum = np.where(starting, np.minimum(now, most), self.held_sum)
            # S_m as latched, not as measured now: in a lull the turbine's torque falls below its set point's
            # (the controller's zone-0 taper), and a floor that followed it would lower the set point and with
            # it the taper's knee, step by step, until the rotor stalled (docs/farm.md, D-26b)
            held = p.eta_gc * (self.held_sum - p.B_g * self.speed_floor) * self.speed_floor
            floor = np.where(hold, np.maximum(held.reshape(farms, N_TURBINES), P_MIN_W), floor)
        # the share of its own available power a turbine keeps: ``derate_floor`` for (26), 1 − r for D-32
        kept = np.where(relieved, 1.0 - self.relief, self.floor)
        for t in range(N_TURBINES):  # eq. (26), headroom shared out in turbine order (D-26)
            hit = derate[:, t] | relieved[:, t]
            if hit.any():
                reduced = np.maximum(np.maximum(avail[:, t] - np.maximum(over, 0.0), 0.0), floor[:, t])
                reduced = np.maximum(reduced, np.minimum(kept[:, t] * avail[:, t], avail[:, t]))
                taken = np.where(hit, avail[:, t] - reduced, 0.0)
                avail[:, t] = np.where(hit, reduced, avail[:, t])
                over = over - taken
        total = avail.sum(axis=1)
        active = demand < maximum  # the dispatch acts only below the farm's maximum production
        share = avail / np.maximum(total, 1.0)[:, None] * demand[:, None]  # eq. (18)
        if hold.any():  # a held turbine gets its floor; the others share the rest as in (18)
            fixed = np.where(hold, floor, 0.0)
            others = np.where(hold, 0.0, avail)
            rest = np.maximum(demand - fixed.sum(axis=1), 0.0)
            self._release_when_needed(hold, ~active | (rest > (1.0 - self.hold_reserve) * others.sum(axis=1)))
            share = np.where(hold, fixed, others / np.maximum(others.sum(axis=1), 1.0)[:, None] * rest[:, None])
        share = np.where(debris, share / DEBRIS_FACTOR, share)  # eq. (24)
        # beyond the farm's maximum every turbine runs at rated, but a held one stays at its floor (until released)
        refs = np.where(active[:, None], share, np.where(hold, floor, self.p.rated_power))
        if self.trim_kp > 0.0 or self.trim_ki > 0.0:
            refs = self._trimmed(sample, refs, active, ~(derate | hold))  # a relieved turbine too (D-32)
        refs = np.clip(refs, 0.0, self.p.rated_power).reshape(-1)
        self.speed_floor = np.where(hold.reshape(-1), self.speed_floor, np.nan)
        self.held_torque = np.where(hold.reshape(-1), self.held_torque, np.nan)
        self.held_sum = np.where(hold.reshape(-1), self.held_sum, np.nan)
        # ``released`` views self.released, so it holds the holds released at this sample too: they go out as
        # mode 5 at once (with this sample's references, computed as held)
        cancelled = f[:, :, DRIVETRAIN] & released
        mode = np.where(debris, DEBRIS_MODE, 0)
        mode = np.where(trimmed, PITCH_TRIM_MODE, mode)
        mode = np.where(derate, DERATED_MODE, mode)
        mode = np.where(cancelled, CANCEL_3P_MODE, np.where(hold, HOLD_TORQUE_MODE, mode))
        self.mode = mode.astype(np.int8).reshape(-1)
        if self.ripple is not None:  # D-29: the cancelling turbines' 3P power ripple, cancelled by the free ones
            sources = (hold | cancelled).reshape(-1)
            self.ripple.step(measured, sources, ~(hold | derate | cancelled).reshape(-1))
        self.p_ref = refs
        return refs

    def _release_when_needed(self, hold: np.ndarray, needed: np.ndarray) -> None:
        """Release the holds (``hold`` (farms, 9)) of farms whose demand has ``needed`` (farms,) them for
        ``RELEASE_AFTER_S``: such a turbine runs its normal laws, its 3P still cancelled, until its flag clears."""
        asked = (hold & needed[:, None]).reshape(-1)
        self._needed_s = np.where(asked, self._needed_s + FARM_DT_S, 0.0)
        self.released |= self._needed_s >= self.release_after_s - 1e-9

    @property
    def ripple_power(self) -> np.ndarray:
        """(n,) complex W, the power phasor each turbine is asked to add (D-29); zeros without compensation."""
        return np.zeros(self.n, dtype=complex) if self.ripple is None else self.ripple.power

    @property
    def ripple_rate(self) -> np.ndarray:
        """(n,) rad/s, the frequency of ``ripple_power``."""
        return np.zeros(self.n) if self.ripple is None else self.ripple.rate

    @property
    def pitch_trim(self) -> np.ndarray:
        """(n, 3) deg, the per-blade pitch trims asked of the turbines (D-28)."""
        return self.pitch.trim

    def _trimmed(self, sample: FarmSample, refs: np.ndarray, active: np.ndarray, free: np.ndarray) -> np.ndarray:
        """The farm-power trim (module docstring): (1 + u) on the references of the turbines in ``free``."""
        integral, u = farm_power_pi(sample, self.trim, self.trim_kp, self.trim_ki, self.trim_limit)
        self.trim = np.where(active, integral, 0.0)
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
        refs = np.repeat(sample.demand * (1.0 + u) / N_TURBINES, N_TURBINES)
        self.p_ref = np.clip(refs, 0.0, self.p.rated_power)
        return self.p_ref
