"""The baseline controller of Section 3 (Fig. 2), vectorised over the batch, and the virtual actuator (36).

Per tick, from the measured rotor and generator speeds:

* demanded ratio, eq. (20) plus the PI feedback: r_cv,d = ω_g,N/ω_r + K_p e + K_i ∫e dt,  e = ω_g,N − ω_g;
* displacements, eq. (19): (u_p, u_M) = (x̃_p,d, x̃_M,d)(r_cv,d);
* torque demand, eq. (18): T_g,d = k_opt ω_r²/r_cv,d;
* virtual actuator, eq. (36): u_corr = u − f̂_a,filt when the supervisor's correction is valid.

Decision (the paper leaves Fig. 2's wiring open): the PI adds to the ratio, so (18) uses the same r_cv,d as
(19). In steady state the rotor then sees exactly k_opt ω_r² (Equilibrium in ``wwcore.hydro_model``); under an
uncompensated displacement fault the PI restores ω_g,N with an r_cv,d that no longer matches the true ratio,
so the rotor leaves the optimal tip-speed ratio: a pump fault (less flow per rotor turn) unloads the rotor,
which overspeeds and loses power, as the paper describes in Section 4.3.
"""

from __future__ import annotations

import numpy as np

from wwcore.hydro_model import displacement_feedforward
from wwcore.hydro_params import HydroParams


class BaselineController:
    """Commands u = [u_p, u_M, T_g,d] for n turbines. State: the PI integral and the held correction."""

    def __init__(self, p: HydroParams, n: int, pi_integral: np.ndarray):
        self.p = p
        self.n = n
        self.integral = np.array(pi_integral, dtype=float).reshape(n)  # rad, ∫(ω_g,N − ω_g) dt
        self.correction = np.zeros((n, 2))  # last valid f̂_a,filt, held while the supervisor is silent
        self.apply = np.zeros(n, dtype=bool)

    def set_correction(self, correction: np.ndarray, apply: np.ndarray) -> None:
        """Take the supervisor's newest correction; ``apply`` False drops it (u_corr = u)."""
        self.correction = np.where(apply[:, None], correction, 0.0)
        self.apply = apply.copy()

    def step(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(commands sent u_corr (n, 3), nominal commands u (n, 3)) from measurements y (n, 5)."""
        p, c = self.p, self.p.controller
        w_r = np.maximum(y[:, 0], p.omega_r_cut_in)
        # e = ω_g,N − ω_g, integrated with anti-windup on K_i ∫e
        e = p.omega_g_N - y[:, 1]
        self.integral = np.clip(self.integral + p.dt * e, -c.integral_limit / c.K_i, c.integral_limit / c.K_i)
        # (20) and the PI: r_cv,d = ω_g,N/ω_r + K_p e + K_i ∫e
        r_cv_d = np.clip(p.omega_g_N / w_r + c.K_p * e + c.K_i * self.integral, c.r_cv_min, c.r_cv_max)
        # (19)
        x_p_d, x_M_d = displacement_feedforward(r_cv_d, p)
        # (18) T_g,d = k_opt ω_r² / r_cv,d
        T_g_d = p.k_opt * w_r**2 / r_cv_d
        u = np.column_stack([x_p_d, x_M_d, T_g_d])
        # (36) u_corr = u − f̂_a,filt on the displacement commands, within the stroke range
        u_corr = u.copy()
        u_corr[:, :2] = np.clip(u[:, :2] - self.correction, p.stroke_min, p.stroke_max)
        return u_corr, u
