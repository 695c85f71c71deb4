"""The nonlinear model of the hydrostatic wind turbine, eqs. (4)–(5): aero map, derivative, equilibrium.

Pure, vectorised functions shared by the plant (``plant_sim.hydro``) and the observer design
(``service.hydro``: the TS premise bounds need the aero map). Arrays are shaped (n, …) over a batch of turbines.

States x = [ω_r, ω_g, Δp, T_g, x̃_p, x̃_M] (rad/s, rad/s, Pa, N m, –, –); inputs u = [u_p, u_M, T_g,d].
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from wwcore.hydro_params import HydroParams

# Analytic C_p(λ, β) (Heier / Slootweg form), rescaled to an NREL-5-MW-like rotor [PROPOSED]:
#   C_p = c1 (c2/λ_i − c3 β − c4) exp(−c5/λ_i) + c6 λ,   1/λ_i = 1/(λ + 0.08 β) − 0.035/(β³ + 1)
_C = (0.5176, 116.0, 0.4, 5.0, 21.0, 0.0068)


def _cp_base(lam: np.ndarray, beta_deg: np.ndarray | float = 0.0) -> np.ndarray:
    c1, c2, c3, c4, c5, c6 = _C
    lam = np.maximum(lam, 1e-3)
    inv_li = 1.0 / (lam + 0.08 * beta_deg) - 0.035 / (np.asarray(beta_deg) ** 3 + 1.0)
    return c1 * (c2 * inv_li - c3 * beta_deg - c4) * np.exp(-c5 * inv_li) + c6 * lam


@cache
def _base_peak() -> tuple[float, float]:
    """(λ*, C_p*) of the unscaled map at β = 0."""
    res = minimize_scalar(lambda x: -float(_cp_base(np.array(x))), bounds=(4.0, 12.0), method="bounded")
    return float(res.x), float(-res.fun)


def power_coefficient(lam: np.ndarray, p: HydroParams, beta_deg: float = 0.0) -> np.ndarray:
    """C_p(λ, β): the base map stretched in λ so its peak sits at (λ_opt, C_p,max) [PROPOSED]."""
    lam_star, cp_star = _base_peak()
    return (p.cp_max / cp_star) * _cp_base(np.asarray(lam) * lam_star / p.lambda_opt, beta_deg)


def torque_coefficient(lam: np.ndarray, p: HydroParams, beta_deg: float = 0.0) -> np.ndarray:
    """C_Q(λ, β) = C_p/λ, the aero map of eq. (5)."""
    lam = np.maximum(np.asarray(lam, dtype=float), 1e-3)
    return power_coefficient(lam, p, beta_deg) / lam


def aero_torque(omega_r: np.ndarray, v: np.ndarray, p: HydroParams, delta_cq: float = 0.0) -> np.ndarray:
    """Rotor torque, eq. (5): T_r = ½ρπR³ v² C_Q(λ, β), λ = ω_r R/v, with eq. (17)'s C_Q = C_Q,n (1 + δ_CQ)."""
    v = np.maximum(v, 0.1)
    lam = omega_r * p.radius / v
    return p.aero_gain * v**2 * torque_coefficient(lam, p) * (1.0 + delta_cq)


def derivative(x: np.ndarray, u: np.ndarray, T_r: np.ndarray, p: HydroParams) -> np.ndarray:
    """ẋ of eq. (4) for states x (n, 6), actuator inputs u (n, 3) = [u_p, u_M, T_g,d] and rotor torque T_r (n,).

    ``u`` is what reaches the actuators (commands plus faults, after the stroke clamp); ``p.k_leak`` is the
    plant's (possibly uncertain) leakage.
    """
    w_r, w_g, dp, T_g, x_p, x_M = x.T
    dx = np.empty_like(x)
    # ω̇_r = (T_r − Ṽ_p x̃_p Δp)/J_r
    dx[:, 0] = (T_r - p.V_p * x_p * dp) / p.J_r
    # ω̇_g = (Ṽ_M x̃_M Δp − T_g)/J_g
    dx[:, 1] = (p.V_M * x_M * dp - T_g) / p.J_g
    # Δṗ = (Ṽ_p x̃_p ω_r − Ṽ_M x̃_M ω_g − k_leak Δp)/C_H
    dx[:, 2] = (p.V_p * x_p * w_r - p.V_M * x_M * w_g - p.k_leak * dp) / p.C_H
    # Ṫ_g = (T_g,d − T_g)/τ_g
    dx[:, 3] = (u[:, 2] - T_g) / p.tau_g
    # dx̃_p/dt = (u_p − x̃_p)/τ_p,  dx̃_M/dt = (u_M − x̃_M)/τ_M
    dx[:, 4] = (u[:, 0] - x_p) / p.tau_p
    dx[:, 5] = (u[:, 1] - x_M) / p.tau_M
    return dx


def displacement_feedforward(r_cv_d: np.ndarray, p: HydroParams) -> tuple[np.ndarray, np.ndarray]:
    """Eq. (19): (x̃_p,d, x̃_M,d) for a demanded transmission ratio r_cv,d.

    x̃_p,d = (Ṽ_M/Ṽ_p) r_cv,d and x̃_M,d = 1 if r_cv,d ≤ Ṽ_p/Ṽ_M, else x̃_p,d = 1 and x̃_M,d = (Ṽ_p/Ṽ_M)/r_cv,d.
    """
    r0 = p.ratio_max_displacement
    low = r_cv_d <= r0
    x_p = np.where(low, r_cv_d / r0, 1.0)
    x_M = np.where(low, 1.0, r0 / np.maximum(r_cv_d, 1e-9))
    return x_p, x_M


@dataclass(frozen=True)
class Equilibrium:
    """A steady operating point of the closed loop (baseline controller, no fault)."""

    x: np.ndarray  # (n, 6) states
    u: np.ndarray  # (n, 3) commands
    pi_integral: np.ndarray  # (n,) the PI integral that holds ω_g = ω_g,N against leakage
    lam: float  # tip speed ratio


def equilibrium(v: np.ndarray, p: HydroParams, delta_cq: float = 0.0) -> Equilibrium:
    """Closed-loop steady state at wind speeds ``v`` (n,) for the baseline controller of Section 3.

    The rotor settles where T_r = Ṽ_p x̃_p Δp = k_opt ω_r² (the PI holds ω_g = ω_g,N, so (18) with r_cv,d gives
    exactly k_opt ω_r² on the rotor), i.e. C_p(λ)(1 + δ_CQ) = C_p,max (λ/λ_opt)³, λ = λ_opt when δ_CQ = 0.
    Then Δp = k_opt ω_r²/Ṽ_p and the flow balance Ṽ_p x̃_p ω_r = Ṽ_M x̃_M ω_g,N + k_leak Δp fixes r_cv,d.
    """
    v = np.atleast_1d(np.asarray(v, dtype=float))

    def balance(lam: float) -> float:
        return float(power_coefficient(np.array(lam), p)) * (1.0 + delta_cq) - p.cp_max * (lam / p.lambda_opt) ** 3

    lam = p.lambda_opt if delta_cq == 0.0 else brentq(balance, 0.5 * p.lambda_opt, 2.0 * p.lambda_opt)
    w_r = lam * v / p.radius
    dp = p.k_opt * w_r**2 / p.V_p
    # the ratio at which the pump flow minus leakage drives the motor at ω_g,N: with x̃_p = 1 (partial load)
    # Ṽ_p ω_r = Ṽ_M x̃_M ω_g,N + k_leak Δp and x̃_M = (Ṽ_p/Ṽ_M)/r_cv,d give r_cv,d = ω_g,N/(ω_r − k_leak Δp/Ṽ_p)
    r_d = p.omega_g_N / (w_r - p.k_leak * dp / p.V_p)
    high = r_d <= p.ratio_max_displacement  # above rated speed x̃_M = 1 and x̃_p carries the ratio
    if np.any(high):
        dp_h = p.k_opt * w_r**2 * p.ratio_max_displacement / (p.V_p * r_d)  # Ṽ_p x̃_p Δp = k_opt ω_r²
        r_h = (p.omega_g_N + p.k_leak * dp_h / p.V_M) / w_r
        dp = np.where(high, p.k_opt * w_r**2 * p.ratio_max_displacement / (p.V_p * r_h), dp)
        r_d = np.where(high, r_h, r_d)
    x_p, x_M = displacement_feedforward(r_d, p)
    T_g = p.k_opt * w_r**2 / r_d
    x = np.column_stack([w_r, np.full_like(v, p.omega_g_N), dp, T_g, x_p, x_M])
    u = np.column_stack([x_p, x_M, T_g])
    r_ff = p.omega_g_N / np.maximum(w_r, p.omega_r_cut_in)
    return Equilibrium(x=x, u=u, pi_integral=(r_d - r_ff) / p.controller.K_i, lam=float(lam))
