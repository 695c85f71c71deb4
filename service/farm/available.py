r"""Each turbine's available power, eqs. (20)–(22) of seed 001.

**Wind** (eq. (20)): in steady state the aerodynamic torque balances the drive train,
τ̂_r = (N_g/η_dt)(τ̄_g + B_g ω̄_g) + B_r ω̂_r, and v solves ½ρπR³ C_q(ω̂_r R/v, β̄) v² = τ̂_r
(``wwcore.aero.wind_from_torque``; ω̂_r = ω̄_g/N_g, β̄ the mean of the six pitch encoders). That is "the wind from
the pitch angle" through the C_q surface rather than the paper's lookup pair h⁻¹, g⁻¹, and with the measured torque
instead of P_ref: equal in steady derated operation, and the measured torque also holds when the turbine cannot
reach its reference.

**Available power** (eqs. (21)–(22)):

.. math::

    \hat P_a = \frac{τ_w}{s + α_w} P_a(w_{est}) \quad (21),\qquad
    P_{avail} = \mathrm{pos}(\hat P_a - P_{ref}) + P_m \quad (22)

with P_a(v) the steady available power (``power_curve``), α_w = τ_w = w_est/D [PROPOSED: the paper gives no
values; one rotor transit time], P_ref the reference sent last and P_m the measured power.

The estimator also keeps w̄, w_est low-passed over ``HOLD_AVERAGING_S``: the wind the drive-train hold chooses its
speed floor and torque cap from (``service.farm.hold``), steadier than w_est.
"""

from __future__ import annotations

import numpy as np

from service.farm.interfaces import BETA, OMEGA_G, P_G, TAU_G, FarmSample
from service.farm.power_curve import WINDS, available_power, available_power_table
from wwcore import aero
from wwcore.aero import _M_T
from wwcore.scenario.farm import FARM_DT_S, ROTOR_DIAMETER_M
from wwcore.turbine_params import TurbineParams

HOLD_AVERAGING_S = 10.0  # s, low-pass of the wind the hold's speed floor and torque cap are chosen from [PROPOSED]


class AvailablePower:
    """Eqs. (20)–(22) for ``n`` turbine rows; the state of eq. (21) and of w̄ between samples. ``fast``:
    ``wwcore.aero_fast`` (``FarmContext.fast_aero``) or None; eq. (20) is solved by its ``wind_from_torque``, the
    compiled twin of ``wwcore.aero``'s, if given. ``kernels``: ``service.farm.fast`` (``FarmContext.fast``) or None;
    given, a sample after the first is three kernels (``available_front``, ``available_back``,
    ``available_filter``) around the aerodynamic fit's product and eq. (21)'s ``exp``, both numpy's: the same
    numbers (``tests/test_fast_backend_farm.py``)."""

    def __init__(self, params: TurbineParams, fast=None, kernels=None):
        self.p = params
        self._fast = fast
        self._kernels = kernels
        if kernels is not None:
            self._front = (
                np.array([OMEGA_G[0], OMEGA_G[1], TAU_G]),
                BETA,
                (params.N_g, params.B_g, params.eta_dt, params.B_r, params.radius),
            )
            consts = (params.aero_torque_gain, 3, FARM_DT_S / HOLD_AVERAGING_S, ROTOR_DIAMETER_M, FARM_DT_S)
            self._back = (WINDS, available_power_table(params), consts)
        self.wind: np.ndarray | None = None  # (n,) m/s, w_est of eq. (20)
        self.p_a_hat: np.ndarray | None = None  # (n,) W, eq. (21) state
        self.slow_wind: np.ndarray | None = None  # (n,) m/s, w̄: w_est low-passed over HOLD_AVERAGING_S

    def step(self, sample: FarmSample, p_ref: np.ndarray) -> np.ndarray:
        """P_avail,t (n,) in W from a sample and the references ``p_ref`` (n,) W sent last."""
        if self._kernels is not None and self.wind is not None:
            return self._compiled_step(sample, p_ref)
        p, y = self.p, sample.scada
        omega_g = y[:, OMEGA_G].mean(axis=1)
        omega_r = omega_g / p.N_g
        pitch = y[:, BETA].mean(axis=(1, 2))
        tau_r = p.N_g * (y[:, TAU_G] + p.B_g * omega_g) / p.eta_dt + p.B_r * omega_r
        solver = aero if self._fast is None else self._fast
        if self.wind is None:
            guess = np.repeat(sample.mast, sample.turbines_per_farm)
            self.wind = solver.wind_from_torque(tau_r, omega_r, pitch, guess, p, iterations=8)
        else:
            self.wind = solver.wind_from_torque(tau_r, omega_r, pitch, self.wind, p, iterations=3)  # eq. (20)
        if self.slow_wind is None:
            self.slow_wind = self.wind.copy()
        else:
            self.slow_wind += (self.wind - self.slow_wind) * (FARM_DT_S / HOLD_AVERAGING_S)
        p_a = available_power(p, self.wind)
        if self.p_a_hat is None:
            self.p_a_hat = p_a.copy()
        a = np.exp(-np.maximum(self.wind, 1.0) / ROTOR_DIAMETER_M * FARM_DT_S)
        self.p_a_hat = a * self.p_a_hat + (1.0 - a) * p_a  # eq. (21), τ_w/(s + α_w) with τ_w = α_w
        return np.maximum(self.p_a_hat - p_ref, 0.0) + y[:, P_G]  # eq. (22)

    def _compiled_step(self, sample: FarmSample, p_ref: np.ndarray) -> np.ndarray:
        """``step`` after the first sample by the kernels (class docstring), the same operations in its order."""
        kernels, y = self._kernels, np.ascontiguousarray(sample.scada, dtype=float)
        features = np.empty((6, len(y)))
        tau_r, rw = kernels.available_front(y, *self._front, features)
        wind = self.wind.copy()
        p_a, exponent = kernels.available_back(tau_r, rw, wind, features, _M_T @ features, self.slow_wind, *self._back)
        self.wind = wind
        return kernels.available_filter(np.exp(exponent), p_a, self.p_a_hat, p_ref, y, P_G)
