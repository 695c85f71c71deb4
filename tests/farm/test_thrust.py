"""The thrust rule (wwcore.thrust) and the farm turbine's steady operating curve (plant_sim.farm.operating_curve)."""

from __future__ import annotations

from pathlib import Path

import floris
import numpy as np
import pytest
import yaml
from scipy.optimize import minimize_scalar

from plant_sim.farm.operating_curve import derated_point, operating_thrust, steady_operating_curve
from plant_sim.turbine.trim import trim
from wwcore import aero, thrust
from wwcore.turbine_params import BENCHMARK

LIBRARY = Path(floris.__file__).parent / "turbine_library"


def test_closed_form_inverse():
    """h(C_T) = 4a(1 − a)² = K C_p/C_p,max: for a = 0.2, C_T = 0.64 and h = 0.512."""
    a = np.array([0.0, 0.05, 0.2, 0.3])
    ct = 4 * a * (1 - a)
    h = 4 * a * (1 - a) ** 2
    cp = h * 0.45 / 0.6
    assert thrust.thrust_from_power_coefficient(cp, cp_max=0.45, loading=0.6) == pytest.approx(ct, abs=1e-6)
    assert thrust.loading_function(ct) == pytest.approx(h, abs=1e-12)
    assert thrust.axial_induction(ct) == pytest.approx(a, abs=1e-12)


def test_bounds_and_monotone():
    cp = np.linspace(-0.2, 0.7, 400)
    ct = thrust.thrust_from_power_coefficient(cp)
    assert np.all(np.diff(ct) >= 0.0)
    assert ct[cp <= 0].max() == 0.0
    assert ct.max() <= 8.0 / 9.0 + 1e-12


def test_model_cp_max_is_the_aero_models():
    assert thrust.model_cp_max() == pytest.approx(0.4584, abs=2e-4)
    assert thrust.thrust_coefficient(np.array(7.92), np.array(-0.33)) == pytest.approx(0.788, abs=0.003)


def test_the_constant_is_the_least_squares_fit_to_the_reference_turbines():
    """K is the least-squares fit on the FLORIS library's four reference turbines (the V80 adds 17 points, checked
    in tools/fit_thrust.py); their C_T is reproduced with an RMS below 0.025 from C_p max to cut-out."""
    c_all, ct_all = [], []
    for name in ("nrel_5MW", "iea_10MW", "iea_15MW", "iea_22MW"):
        table = yaml.safe_load((LIBRARY / f"{name}.yaml").read_text())
        d = table["rotor_diameter"]
        t = table["power_thrust_table"]
        v, p, ct = (np.array(t[k], float) for k in ("wind_speed", "power", "thrust_coefficient"))
        keep = (v >= 3.5) & (v <= 25.01) & (p > 0)
        cp = p[keep] * 1e3 / (0.5 * 1.225 * np.pi * d * d / 4 * v[keep] ** 3)
        top = int(np.argmax(cp))
        c_all.append(cp[top:] / cp.max())
        ct_all.append(ct[keep][top:])
    c, ct = np.concatenate(c_all), np.concatenate(ct_all)

    def rms(k):
        return float(np.sqrt(np.mean((thrust.thrust_from_power_coefficient(c, 1.0, k) - ct) ** 2)))

    best = minimize_scalar(rms, bounds=(0.3, thrust.H_MAX), method="bounded").x
    assert best == pytest.approx(thrust.THRUST_LOADING_K, abs=0.003)
    assert rms(thrust.THRUST_LOADING_K) < 0.025


def test_benchmark_runs_near_ct_08_below_rated_and_sheds_thrust_above():
    winds = np.array([7.0, 9.0, 11.0, 15.0, 19.0, 25.0])
    power, ct = steady_operating_curve(BENCHMARK, winds)
    assert ct[:3] == pytest.approx([0.711, 0.739, 0.754], abs=0.005)
    assert ct[3:] == pytest.approx([0.416, 0.190, 0.081], abs=0.005)
    # the momentum-theory thrust on the same C_p (the ideal disc, K = C_p,max) is far lower below rated
    ideal = thrust.thrust_from_power_coefficient(0.441, loading=thrust.model_cp_max())
    assert ideal < 0.55 < ct[0]
    assert power == pytest.approx([trim(BENCHMARK, float(v)).power for v in winds], rel=1e-12)


@pytest.mark.parametrize("wind", [8.0, 11.0, 14.0])
def test_derated_turbine_makes_its_reference_with_less_thrust(wind):
    available = trim(BENCHMARK, wind).power
    cts = []
    for fraction in (1.0, 0.8, 0.5):
        op = derated_point(BENCHMARK, wind, fraction * available)
        assert op.power == pytest.approx(fraction * available, rel=1e-6)
        # the point is a steady state: aerodynamic torque balances the drive train (PARAMETERS.md a.2 at rest)
        lam = op.omega_r * BENCHMARK.radius / wind
        tau_aero = BENCHMARK.aero_torque_gain * aero.torque_coefficient(np.array(lam), np.array(op.pitch)) * wind**2
        need = BENCHMARK.N_g * (BENCHMARK.B_g * op.omega_g + op.tau_g) / BENCHMARK.eta_dt + BENCHMARK.B_r * op.omega_r
        assert float(tau_aero) == pytest.approx(need, rel=1e-6)
        cts.append(operating_thrust(BENCHMARK, op))
    assert cts[0] > cts[1] > cts[2]
    assert cts[2] < 0.6 * cts[0]


def test_reference_above_available_changes_nothing():
    op = derated_point(BENCHMARK, 9.0, BENCHMARK.rated_power)
    assert op == trim(BENCHMARK, 9.0)
