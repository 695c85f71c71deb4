"""The parameter set and the nonlinear model (4)–(5): rated point, aero map, equilibrium."""

from __future__ import annotations

import numpy as np
import pytest

from wwcore.hydro_model import aero_torque, derivative, equilibrium, power_coefficient
from wwcore.hydro_params import NOMINAL as P


def test_rated_point_is_self_consistent():
    # torques: the pump holds the rated rotor torque at Δp_N and full stroke (PARAMETERS.md c: 4.18e6 N m)
    assert P.V_p * P.dp_rated == pytest.approx(4.18e6, rel=0.01)
    # flows: x̃_p = x̃_M = 1 at the rated rotor speed gives ω_g,N (Ṽ_p ω_r = Ṽ_M ω_g)
    assert P.V_p * P.omega_r_rated == pytest.approx(P.V_M * P.omega_g_N, rel=0.005)
    # leakage: 3 % of the pump flow at rated pressure
    assert P.k_leak * P.dp_rated / (P.V_p * P.omega_r_rated) == pytest.approx(0.03, rel=0.05)
    # hydraulic capacitance of 0.4 m³ of oil at 1.2e9 Pa
    assert pytest.approx(0.4 / 1.2e9, rel=0.01) == P.C_H
    # rated generator torque times ω_g,N equals rated hydraulic power at the motor
    assert P.rated_generator_torque * P.omega_g_N == pytest.approx(P.dp_rated * P.V_M * P.omega_g_N)
    assert P.k_opt == pytest.approx(2.14e6, rel=0.01)


def test_aero_map_peaks_at_the_stated_point():
    lam = np.linspace(2.0, 14.0, 2401)
    cp = power_coefficient(lam, P)
    assert lam[np.argmax(cp)] == pytest.approx(P.lambda_opt, abs=0.01)
    assert cp.max() == pytest.approx(P.cp_max, rel=1e-4)
    # the optimal-torque law (18) is the aero torque at λ_opt: T_r = k_opt ω_r²
    w = np.array([0.8, 1.0, 1.2])
    assert aero_torque(w, w * P.radius / P.lambda_opt, P) == pytest.approx(P.k_opt * w**2, rel=1e-9)


@pytest.mark.parametrize("delta_cq", [0.0, 0.2])
def test_equilibrium_is_steady(delta_cq):
    v = np.array([5.5, 7.0, 8.5, 10.0])
    eq = equilibrium(v, P, delta_cq)
    dx = derivative(eq.x, eq.u, aero_torque(eq.x[:, 0], v, P, delta_cq), P)
    scale = np.array([1.0, P.omega_g_N, P.dp_rated, P.rated_generator_torque, 1.0, 1.0])
    assert np.abs(dx / scale).max() < 1e-9
    assert np.allclose(eq.x[:, 1], P.omega_g_N)
    # partial load: full pump stroke, the motor carries the ratio (PARAMETERS.md c)
    assert np.allclose(eq.x[:, 4], 1.0) and np.all(eq.x[:, 5] < 1.0)
    # power balance: rotor power = generator power + leakage loss k_leak Δp²
    P_r = aero_torque(eq.x[:, 0], v, P, delta_cq) * eq.x[:, 0]
    P_g = eq.x[:, 3] * eq.x[:, 1]
    assert P_r == pytest.approx(P_g + P.k_leak * eq.x[:, 2] ** 2, rel=1e-9)


def test_hydraulic_mode_is_not_stiff():
    wn, zeta = P.hydraulic_mode(1.0)
    assert 1.0 < wn < 5.0 and 0.0 < zeta < 0.2
