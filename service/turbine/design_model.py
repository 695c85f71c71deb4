"""The design model the observers of seed 000 are built on, derived from the benchmark turbine.

State, input and unknown input (continuous time, eqs. (21)–(23) of seed 000 plus the converter of a.2)::

    x = [ω_r, ω_g, θ_Δ, τ_g]ᵀ      rotor speed (rad/s), generator speed (rad/s), torsion (rad), converter torque (N m)
    u = τ_g,r                      converter torque reference (N m), known: the controller's output
    d = τ_r                        aerodynamic torque (N m), the unknown input

    ẋ = A x + B u + E d,   A = [[−(B_dt+B_r)/J_r,  B_dt/(N_g J_r),            −K_dt/J_r,        0     ],
                                [η B_dt/(N_g J_g), −(η B_dt/N_g² + B_g)/J_g,  η K_dt/(N_g J_g), −1/J_g],
                                [1,                −1/N_g,                    0,                0     ],
                                [0,                0,                         0,                −α_gc ]]
                           B = [0, 0, 0, α_gc]ᵀ,   E = [1/J_r, 0, 0, 0]ᵀ

Why the whole aerodynamic torque is the unknown input: the paper linearises τ_r around an operating point (25)
and calls the C_p and wind deviations unknown. Taking all of τ_r as unknown makes the observers' error dynamics
independent of wind, pitch and operating point (the drive train is exactly linear), so one design holds in both
regions and the residuals are exactly decoupled from the wind. The wind speed is recovered afterwards from the
estimated aerodynamic torque (``wind_recovery``). The pitch reference, the paper's second input, then enters
only that recovery.

The sensors measure ω_r (``omega_r_m1``, ``omega_r_m2``) and ω_g (``omega_g_m1``, ``omega_g_m2``). The hub
anemometer does not measure any state of this model, so the paper's observers 1 and 7 coincide here; the
anemometer only seeds the wind inversion at start-up (the paper's own finding, Fig. 3: "the wind speed
measurement is not required for the estimator anyway").

Discretised with a zero-order hold on u and d (``wwcore.lti.zoh``, the matrix exponential) at the controller's Ts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wwcore.lti import zoh
from wwcore.turbine_params import TurbineParams

STATE_NAMES = ("omega_r", "omega_g", "theta", "tau_g")
SPEED_SENSOR_STATE = {"omega_r_m1": 0, "omega_r_m2": 0, "omega_g_m1": 1, "omega_g_m2": 1, "omega_g_pe": 1}


@dataclass(frozen=True)
class DesignModel:
    """Discrete design model x[n+1] = A_d x[n] + B_d u[n] + E_d d[n] (eq. (1) of seed 000)."""

    A: np.ndarray  # (4, 4) continuous
    B: np.ndarray  # (4, 1)
    E: np.ndarray  # (4, 1)
    A_d: np.ndarray
    B_d: np.ndarray
    E_d: np.ndarray
    dt: float

    def C(self, sensors: tuple[str, ...]) -> np.ndarray:
        """Output matrix C_j of a sensor subset (rows in the subset's order)."""
        C = np.zeros((len(sensors), 4))
        for row, name in enumerate(sensors):
            C[row, SPEED_SENSOR_STATE[name]] = 1.0
        return C


def design_model(p: TurbineParams, eta_dt: float | None = None) -> DesignModel:
    """The benchmark's drive train and converter as a discrete-time state-space model."""
    eta = p.eta_dt if eta_dt is None else eta_dt
    N = p.N_g
    A = np.array(
        [
            [-(p.B_dt + p.B_r) / p.J_r, p.B_dt / (N * p.J_r), -p.K_dt / p.J_r, 0.0],
            [
                eta * p.B_dt / (N * p.J_g),
                -(eta * p.B_dt / N**2 + p.B_g) / p.J_g,
                eta * p.K_dt / (N * p.J_g),
                -1.0 / p.J_g,
            ],
            [1.0, -1.0 / N, 0.0, 0.0],
            [0.0, 0.0, 0.0, -p.alpha_gc],
        ]
    )
    B = np.array([[0.0], [0.0], [0.0], [p.alpha_gc]])
    E = np.array([[1.0 / p.J_r], [0.0], [0.0], [0.0]])
    A_d, BE_d = zoh(A, np.hstack([B, E]), p.dt)
    return DesignModel(A=A, B=B, E=E, A_d=A_d, B_d=BE_d[:, :1], E_d=BE_d[:, 1:], dt=p.dt)
