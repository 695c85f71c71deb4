r"""The supervisor's own steady-state model of a benchmark turbine: available power and the power–speed relation.

The supervisor knows the turbine's published parameters (``wwcore.turbine_params``) and the project's analytic
aerodynamics (``wwcore.aero``), never the simulator's code. In region 2 the benchmark controller holds
τ_g = K_opt ω_g², so a steady wind v gives the rotor speed where the aerodynamic torque balances the drive train,

.. math::  ½ρπR^3 C_q(ω_r R/v, 0)\, v^2 = \frac{N_g}{η_{dt}}\bigl(B_g N_g ω_r + K_{opt} N_g^2 ω_r^2\bigr) + B_r ω_r

and the electrical power P = η_gc K_opt (N_g ω_r)³, capped at rated power: that is P_a(v), the power available at
wind v (the paper's P_a in eqs. (12) and (21)). It is solved once on a grid by bisection.

The power–speed relation f_ω of eq. (4) is the one the farm turbine's controller enforces in steady state
(``plant_sim.farm.controller`` documents the controller; the relation is a published property of it): in zone 0
P = η_gc K_opt ω_g³, in zone 1 (derated or rated) the speed sits at ω_set(P_r) = Ω_nom (P_r/P_rated)^{1/3}, so
P = P_rated (ω_g/Ω_nom)³.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from wwcore import aero
from wwcore.turbine_params import TurbineParams

WINDS = np.arange(2.0, 40.01, 0.05)  # m/s, grid of the tabulated curve


@lru_cache(maxsize=4)
def available_power_table(p: TurbineParams) -> np.ndarray:
    """P_a (W) on ``WINDS``: region-2 steady state of the benchmark controller, capped at rated power."""
    v = WINDS

    def residual(omega_r: np.ndarray) -> np.ndarray:
        omega_g = p.N_g * omega_r
        need = p.N_g * (p.B_g * omega_g + p.k_opt * omega_g**2) / p.eta_dt + p.B_r * omega_r
        return aero.rotor_torque(v, omega_r, 0.0, p) - need

    lo = np.full_like(v, 0.05)
    hi = np.full_like(v, 3.0 * p.omega_nom / p.N_g)
    for _ in range(60):  # bisection on the operating branch (residual > 0 below the root)
        mid = 0.5 * (lo + hi)
        up = residual(mid) > 0.0
        lo, hi = np.where(up, mid, lo), np.where(up, hi, mid)
    omega_g = p.N_g * 0.5 * (lo + hi)
    power = p.eta_gc * p.k_opt * omega_g**3
    return np.where(residual(np.full_like(v, 0.05)) > 0.0, np.minimum(power, p.rated_power), 0.0)


def available_power(p: TurbineParams, wind: np.ndarray) -> np.ndarray:
    """P_a(v) in W for winds in m/s (interpolated on the table, held at its ends)."""
    return np.interp(wind, WINDS, available_power_table(p))


def power_from_speed(p: TurbineParams, omega_g: np.ndarray, zone: np.ndarray) -> np.ndarray:
    """f_ω⁻¹ of eq. (4): the steady power (W) of a turbine at generator speed ω_g (rad/s) in its zone."""
    region2 = p.eta_gc * p.k_opt * omega_g**3
    derated = p.rated_power * (omega_g / p.omega_nom) ** 3
    return np.where(zone == 1, derated, region2)


def speed_from_power(p: TurbineParams, power: np.ndarray) -> np.ndarray:
    """f_ω of eq. (11): the steady generator speed (rad/s) at power P (W), on the region-2 curve up to Ω_nom."""
    return np.minimum(np.cbrt(np.maximum(power, 0.0) / (p.eta_gc * p.k_opt)), p.omega_nom)
