"""Steady operating points of the benchmark turbine under its own controller, for a uniform steady wind.

Used to start simulations in equilibrium (the benchmark starts from ω_r = 1, ω_g = 100 rad/s, θ_Δ = 0, which
excites the 4.5 Hz torsion mode) and as the closed-form reference of the power-curve test.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from plant_sim.turbine.dynamics import plant_torque_coefficient
from wwcore import aero
from wwcore.turbine_params import TurbineParams


@dataclass(frozen=True)
class PlantAero:
    """A plant's aerodynamics where they differ from the design model: τ_r × ``factor`` (s ρ/ρ_0) and the C_p
    surface moved by ``tsr_shift`` Δλ (``plant_sim.turbine.mismatch``). The controller stays the design's."""

    factor: float = 1.0
    tsr_shift: float = 0.0


@dataclass(frozen=True)
class OperatingPoint:
    wind: float  # m/s
    omega_r: float  # rad/s
    omega_g: float  # rad/s
    theta: float  # rad, drive-train torsion
    tau_g: float  # N m
    pitch: float  # deg
    zone: int  # 0: region 2, 1: region 3
    power: float  # W, electrical P_g = η_gc ω_g τ_g
    tau_aero: float  # N m


def _aero_torque(p: TurbineParams, v: float, omega_r: float, pitch: float, plant: PlantAero | None = None) -> float:
    tsr = omega_r * p.radius / v
    if plant is None:
        return float(p.aero_torque_gain * aero.torque_coefficient(tsr, pitch) * v * v)
    cq = plant_torque_coefficient(tsr, pitch, plant.tsr_shift)
    return float(plant.factor * p.aero_torque_gain * cq * v * v)


def _required_aero_torque(p: TurbineParams, omega_r: float, tau_g: float) -> float:
    """Aerodynamic torque that holds ω_r = ω_g/N_g steady against the generator torque τ_g (a.2 at rest)."""
    omega_g = p.N_g * omega_r
    shaft = p.N_g * (p.B_g * omega_g + tau_g) / p.eta_dt
    return shaft + p.B_r * omega_r


def trim(
    p: TurbineParams, wind: float, power_reference: float | None = None, plant: PlantAero | None = None
) -> OperatingPoint:
    """The equilibrium the benchmark controller settles to in a steady uniform wind.

    ``plant`` gives the rotor's aerodynamics where they differ from the design model (the controller, its K_opt
    and set points are the design's in any case). θ_Δ is for the design stiffness K_dt: divide it by the plant's
    stiffness factor.
    """
    p_ref = p.rated_power if power_reference is None else power_reference

    def region2_residual(omega_r: float) -> float:
        tau_g = p.k_opt * (p.N_g * omega_r) ** 2
        return _aero_torque(p, wind, omega_r, 0.0, plant) - _required_aero_torque(p, omega_r, tau_g)

    omega_lo, omega_hi = 0.05, 3.0 * p.omega_nom / p.N_g
    omega_r = brentq(region2_residual, omega_lo, omega_hi) if region2_residual(omega_lo) > 0 else omega_lo
    omega_g = p.N_g * omega_r
    tau_g = p.k_opt * omega_g**2
    if omega_g < p.omega_nom and p.eta_gc * omega_g * tau_g < p_ref:
        return _point(p, plant, wind, omega_r, tau_g, 0.0, 0)
    region2 = _point(p, plant, wind, omega_r, tau_g, 0.0, 0)
    # Region 3: speed held at Ω_nom by pitch, constant-power torque.
    omega_r = p.omega_nom / p.N_g
    tau_g = p_ref / (p.eta_gc * p.omega_nom)
    need = _required_aero_torque(p, omega_r, tau_g)

    def region3_residual(pitch: float) -> float:
        return _aero_torque(p, wind, omega_r, pitch, plant) - need

    lo, hi = p.pitch_min_deg, 45.0
    if region3_residual(lo) >= 0:
        pitch = brentq(region3_residual, lo, hi) if region3_residual(hi) < 0 else hi
        return _point(p, plant, wind, omega_r, tau_g, pitch, 1)

    # Between the regions: constant-power torque with the pitch at its stop holds ω_g below Ω_nom, and the zone
    # logic keeps region 3 while ω_g ≥ Ω_nom − Ω_Δ.
    def saturated_residual(omega_r: float) -> float:
        torque = p_ref / (p.eta_gc * p.N_g * omega_r)
        return _aero_torque(p, wind, omega_r, lo, plant) - _required_aero_torque(p, omega_r, torque)

    omega_lo = max((p.omega_nom - p.omega_delta) / p.N_g, region2.omega_r)
    if saturated_residual(omega_lo) < 0:
        return region2
    omega_r = brentq(saturated_residual, omega_lo, p.omega_nom / p.N_g)
    return _point(p, plant, wind, omega_r, p_ref / (p.eta_gc * p.N_g * omega_r), lo, 1)


def _point(
    p: TurbineParams, plant: PlantAero | None, wind: float, omega_r: float, tau_g: float, pitch: float, zone: int
) -> OperatingPoint:
    omega_g = p.N_g * omega_r
    tau_aero = _aero_torque(p, wind, omega_r, pitch, plant)
    shaft = tau_aero - p.B_r * omega_r
    return OperatingPoint(
        wind=wind,
        omega_r=omega_r,
        omega_g=omega_g,
        theta=shaft / p.K_dt,
        tau_g=tau_g,
        pitch=pitch,
        zone=zone,
        power=p.eta_gc * omega_g * tau_g,
        tau_aero=tau_aero,
    )


def power_curve(p: TurbineParams, winds: np.ndarray) -> np.ndarray:
    """Steady electrical power (W) at each wind speed (m/s)."""
    return np.array([trim(p, float(v)).power for v in winds])
