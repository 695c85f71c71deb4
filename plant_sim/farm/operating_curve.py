r"""Steady power and thrust of a farm turbine against the wind, at rated or derated reference.

At rated reference the operating point is the benchmark controller's equilibrium (``plant_sim.turbine.trim``).
Asked for P_r below what the wind gives, the farm turbine derates by speed set point (docs/farm.md D-C1): it holds
ω_g = ω_set = clip(Ω_nom (P_r/P_rated)^{1/3}, 0.5 Ω_nom, Ω_nom) with the constant-power torque τ_g = P_r/(η_gc ω_set)
and pitches until the rotor's torque balances it (the steady state of a.2):

.. math::  \tfrac12 ρ π R^3 C_q(λ, β) v^2 = \frac{N_g}{η_{dt}}\bigl(B_g ω_g + τ_g\bigr) + B_r ω_r,
           \qquad λ = ω_r R / v,\ ω_r = ω_g / N_g

A wind that cannot give P_r at the set speed leaves the turbine at its rated-reference point (it makes what it
can). The thrust coefficient is ``wwcore.thrust`` at the point's (λ, β). These curves define the turbine FLORIS
sees (``plant_sim.farm.floris_wakes``) and the steady states of the wake tables.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.optimize import brentq

from plant_sim.farm.controller import speed_setpoint
from plant_sim.turbine.trim import OperatingPoint, _aero_torque, _point, _required_aero_torque, trim
from wwcore import thrust
from wwcore.turbine_params import TurbineParams

PITCH_SEARCH_MAX_DEG = 45.0  # deg, upper end of the pitch search of a derated point
CURVE_WINDS = np.concatenate([[0.0, 2.9], np.arange(3.0, 25.001, 0.25), [25.01, 50.0]])  # m/s, tabulated curve
CUT_IN_MPS, CUT_OUT_MPS = 3.0, 25.0  # m/s, the tabulated curve's operating range (no power, C_T ~ 0 outside)
IDLE_THRUST = 1e-4  # –, C_T outside the operating range (FLORIS needs a positive value)


def derated_point(p: TurbineParams, wind: float, power_reference: float) -> OperatingPoint:
    """The farm turbine's equilibrium at ``wind`` m/s asked for ``power_reference`` W (module docstring)."""
    rated = trim(p, wind)
    if power_reference >= rated.power:
        return rated
    omega_g = float(speed_setpoint(p, np.array(power_reference)))
    omega_r = omega_g / p.N_g
    tau_g = power_reference / (p.eta_gc * omega_g)
    need = _required_aero_torque(p, omega_r, tau_g)

    def residual(pitch: float) -> float:
        return _aero_torque(p, wind, omega_r, pitch) - need

    lo, hi = p.pitch_min_deg, PITCH_SEARCH_MAX_DEG
    if residual(lo) < 0.0:
        return rated  # the rotor cannot hold the set speed with this torque: it makes what the wind gives
    pitch = brentq(residual, lo, hi) if residual(hi) < 0.0 else hi
    return _point(p, None, wind, omega_r, tau_g, pitch, 1)


def operating_thrust(p: TurbineParams, op: OperatingPoint) -> float:
    """C_T of an operating point from its tip-speed ratio and pitch (``wwcore.thrust``)."""
    if op.wind <= 0.0:
        return 0.0
    return float(thrust.thrust_coefficient(np.array(op.omega_r * p.radius / op.wind), np.array(op.pitch)))


def steady_operating_curve(
    p: TurbineParams, winds: np.ndarray, power_reference: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(electrical power W, C_T) at each wind speed (m/s) for a reference (W, default rated)."""
    p_ref = p.rated_power if power_reference is None else float(power_reference)
    points = [derated_point(p, float(v), p_ref) for v in np.asarray(winds, dtype=float)]
    return np.array([op.power for op in points]), np.array([operating_thrust(p, op) for op in points])


@functools.lru_cache(maxsize=4)
def rated_curve(p: TurbineParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(wind m/s, electrical power W, C_T) at rated reference on ``CURVE_WINDS``: the curve FLORIS's turbine is
    defined by (``floris_wakes.benchmark_turbine``) and the farm's steady states follow; linear in between."""
    keep = (CURVE_WINDS >= CUT_IN_MPS) & (CURVE_WINDS <= CUT_OUT_MPS)
    power = np.zeros_like(CURVE_WINDS)
    ct = np.full_like(CURVE_WINDS, IDLE_THRUST)
    power[keep], ct[keep] = steady_operating_curve(p, CURVE_WINDS[keep])
    for a in (power, ct):
        a.flags.writeable = False
    return CURVE_WINDS, power, np.maximum(ct, IDLE_THRUST)
