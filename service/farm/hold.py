r"""The drive-train hold: a flagged drive train derated by speed, not by torque, and released when the farm needs it.

Option ``accommodation_rule = "hold-torque"`` (D-26b and D-30, ``docs/farm.md`` §2.3) [PROPOSED].

**Hold** (D-26b). When the hold begins the dispatch fixes the turbine's speed floor ω_floor = clip(N_g λ w̄/R, ω_min,
Ω_nom) and a cap S_max(λ) = η_dt (½ρπR³ C_q(λ, 0) w̄²/m − B_r ω_r)/N_g on the held generator-side sum
S = τ_g + B_g ω_g: what the rotor makes at λ at fine pitch with m = ``hold_margin`` (1.2) in hand for the
turbulence. λ is the smallest tip-speed ratio on a 0.05 grid from λ_f = 5 to λ_q ≈ 6.55 with S_max(λ) ≥ S_m, the
sum the turbine makes when the hold begins: the slowest speed at which the rotor keeps its torque, so the hold
moves the mean shaft torque by nothing (a cap below S_m costs one rainflow cycle as large as the step, on entry and
again on release). λ_f is the lowest λ at which fine pitch still gives the rotor's largest torque (below it, stall);
λ_q gives the most torque at fine pitch, so where no λ keeps S_m the hold runs there with S capped at S_max(λ_q).
w̄ is w_est low-passed over 10 s (``service.farm.available``); ω_floor, S_max and S_m stay latched while the hold
lasts, since eq. (20) assumes steady state and reads nonsense while the rotor slows down, and a floor that followed
the measured torque down a lull would lower the set point step by step until the rotor stalled.

The held turbine's reference is its floor P_min,f = max(P_min, η_gc (min(S_m, S_max) − B_g ω_floor) ω_floor), sent
with ``hold_torque`` (mode 3) and ``held_torque`` = S_max (``plant_sim.farm.controller``, which also cancels the
fault's 3P shaft torque, D-C4); the other turbines share the rest of the demand as in (18). It keeps its floor when
the farm cannot meet the demand too: a hold released by every lull would swing the torque through the cycles it
exists to avoid. Why hold by speed: the fault's 3P torque swing grows with ω_r² and its rainflow damage with about
ω_r⁹ at m = 4, while lowering the mean torque costs one cycle of the torque change.

**Release** (D-30). When the farm needs the held turbine's power, the others being asked for more than
1 − ``hold_reserve`` of their available power (or the demand being beyond the farm's maximum) for
``release_after_s``, the hold is released until the flag clears: the turbine runs its normal laws with its 3P still
cancelled (mode 5). A derated rotor gives its power back only as fast as it can speed up; without the release, a
hold begun in a lull kept its low torque while the wind rose and the farm fell short for minutes.
"""

from __future__ import annotations

import numpy as np

from service.farm.accommodation import P_MIN_W, AccommodationPlan, DrivetrainRule
from service.farm.available import AvailablePower
from service.farm.interfaces import OMEGA_G, TAU_G, FarmSample
from wwcore import aero
from wwcore.farm_frames import MIN_SPEED_FRACTION
from wwcore.scenario.farm import FARM_DT_S
from wwcore.turbine_params import TurbineParams

HOLD_MARGIN = 1.2  # –, rotor torque at fine pitch and the hold's speed over the held torque cap [PROPOSED]
HOLD_MIN_TSR = 5.0  # –, tip-speed ratio of a hold: the lowest at which fine pitch gives the most torque (below, stall)
HOLD_RESERVE = 0.05  # –, share of their available power the others keep in hand before a hold is released [PROPOSED]
RELEASE_AFTER_S = 5.0  # s the farm must need a held turbine's power before its hold is released [PROPOSED]
_TSR_GRID = np.arange(HOLD_MIN_TSR, 9.0 + 1e-9, 0.05)
HOLD_MAX_TORQUE_TSR = float(_TSR_GRID[np.argmax(aero.torque_coefficient(_TSR_GRID, np.zeros_like(_TSR_GRID)))])
"""λ_q, –: the tip-speed ratio of the most rotor torque at fine pitch for a given wind (≈ 6.5)"""
HOLD_TSRS = _TSR_GRID[_TSR_GRID <= HOLD_MAX_TORQUE_TSR + 1e-9]  # the λ a hold may choose, slowest first


class HoldRelease:
    """D-30 (module docstring) for ``n`` turbine rows: which flagged drive trains' holds are released."""

    def __init__(self, n: int, reserve: float = HOLD_RESERVE, after_s: float = RELEASE_AFTER_S):
        self.reserve, self.after_s = reserve, after_s
        self.released = np.zeros(n, dtype=bool)  # released holds, until their flag clears
        self._needed_s = np.zeros(n)  # s, how long the farm has needed a held turbine's power

    def keep_flagged(self, flagged: np.ndarray) -> None:
        """A release lasts while the flag does: a new flag is a new hold."""
        self.released &= flagged.reshape(-1)

    def update(self, hold: np.ndarray, others_asked: np.ndarray, others_avail: np.ndarray, active: np.ndarray) -> None:
        """Release the holds (``hold`` (farms, N)) of farms whose other turbines have been asked for more than
        1 − ``reserve`` of their available power (``others_asked``, ``others_avail`` (farms,) W), or whose demand
        is beyond the farm's maximum (not ``active``), for ``after_s``."""
        needed = ~active | (others_asked > (1.0 - self.reserve) * others_avail)
        asked = (hold & needed[:, None]).reshape(-1)
        self._needed_s = np.where(asked, self._needed_s + FARM_DT_S, 0.0)
        self.released |= self._needed_s >= self.after_s - 1e-9


class HoldTorqueRule(DrivetrainRule):
    """The hold (module docstring) for ``n`` turbine rows, with its ``release``; reads w̄ from ``available``."""

    def __init__(
        self,
        params: TurbineParams,
        n: int,
        available: AvailablePower,
        *,
        margin: float = HOLD_MARGIN,
        reserve: float = HOLD_RESERVE,
        release_after_s: float = RELEASE_AFTER_S,
    ):
        super().__init__(n)
        self.p = params
        self.available = available
        self.margin = margin
        self.release = HoldRelease(n, reserve, release_after_s)
        self.speed_floor = np.full(n, np.nan)  # rad/s, ω_floor of turbines in the hold (NaN: none)
        self.held_sum = np.full(n, np.nan)  # N m, min(S_m, S_max) latched when the hold began (NaN: none)

    def hold_point(self, held_sum: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(ω_floor, S_max) (n,) of a hold begun now with the generator-side torque sum ``held_sum`` (N m): the
        slowest speed (rad/s) at a tip-speed ratio in [λ_f, λ_q] where the rotor makes that sum at fine pitch with
        ``margin`` in hand, and the sum it makes there (at λ_q, the most it can, if none keeps ``held_sum``)."""
        p = self.p
        wind = np.maximum(self.available.slow_wind, 1.0)[:, None]
        omega = np.clip(p.N_g * HOLD_TSRS * wind / p.radius, MIN_SPEED_FRACTION * p.omega_nom, p.omega_nom)
        omega_r = omega / p.N_g
        tsr = omega_r * p.radius / wind
        rotor = p.aero_torque_gain * aero.torque_coefficient(tsr, np.zeros_like(tsr)) * wind * wind / self.margin
        most = p.eta_dt * (rotor - p.B_r * omega_r) / p.N_g  # (n, grid): S the rotor holds at each λ
        keeps = most >= held_sum[:, None]
        pick = np.where(keeps.any(axis=1), keeps.argmax(axis=1), len(HOLD_TSRS) - 1)
        rows = np.arange(len(pick))
        return omega[rows, pick], most[rows, pick]

    def mark(self, plan: AccommodationPlan, flagged: np.ndarray, sample: FarmSample) -> None:
        """Hold the flagged turbines not released, at their latched floor; a hold begins on a new flag."""
        self.release.keep_flagged(flagged)
        hold = flagged & ~self.release.released.reshape(flagged.shape)
        plan.derate |= hold
        plan.hold = hold
        if hold.any():
            y, p = sample.scada, self.p
            starting = hold.reshape(-1) & np.isnan(self.speed_floor)
            if starting.any():
                now = y[:, TAU_G] + p.B_g * y[:, OMEGA_G].mean(axis=1)  # S of plant_sim.farm.controller
                omega, most = self.hold_point(now)
                self.speed_floor = np.where(starting, omega, self.speed_floor)
                self.held_torque = np.where(starting, most, self.held_torque)
                self.held_sum = np.where(starting, np.minimum(now, most), self.held_sum)
            held = p.eta_gc * (self.held_sum - p.B_g * self.speed_floor) * self.speed_floor
            plan.floor = np.where(hold, np.maximum(held.reshape(hold.shape), P_MIN_W), plan.floor)

    def shares(
        self, plan: AccommodationPlan, avail: np.ndarray, demand: np.ndarray, active: np.ndarray, share: np.ndarray
    ) -> np.ndarray:
        """A held turbine gets its floor, the others share the rest as in (18); holds the farm has needed long
        enough are released (they go out as mode 5 at once, with these references); a hold that ended is
        forgotten. A turbine no shard commands (``plan.held``) keeps its latched hold but takes no part here."""
        hold = plan.hold & ~plan.held
        if hold.any():
            fixed = np.where(hold, plan.floor, 0.0)
            others = np.where(hold, 0.0, avail)
            rest = np.maximum(demand - fixed.sum(axis=1), 0.0)
            self.release.update(hold, rest, others.sum(axis=1), active)
            share = np.where(hold, fixed, others / np.maximum(others.sum(axis=1), 1.0)[:, None] * rest[:, None])
        held = plan.hold.reshape(-1)
        self.speed_floor = np.where(held, self.speed_floor, np.nan)
        self.held_torque = np.where(held, self.held_torque, np.nan)
        self.held_sum = np.where(held, self.held_sum, np.nan)
        return share

    def cancelled(self, flagged: np.ndarray) -> np.ndarray:
        return flagged & self.release.released.reshape(flagged.shape)
