"""The UIO bank of seed 000: existence, the equations as written, decoupling, and closed-form residual statistics."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from service.turbine.bank import ObserverBank, design_bank
from service.turbine.design_model import design_model
from service.turbine.fdi import FDISettings, SpeedSensorFDI
from service.turbine.interfaces import DESIGN_Q, DESIGN_Q_UNKNOWN
from service.turbine.uio import UIOExistenceError, design_uio, existence_problem
from wwcore.channels import SPEED_SENSORS
from wwcore.turbine_params import BENCHMARK as P

SIGMA = {"omega_r_m1": 0.0251, "omega_r_m2": 0.0251, "omega_g_m1": 0.05, "omega_g_m2": 0.05}
MODEL = design_model(P)
BANK = design_bank(MODEL, SIGMA, DESIGN_Q, DESIGN_Q_UNKNOWN)


def simulate_design_model(d: np.ndarray, u: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """y[n] of the discrete design model x[n+1] = A x + B u + E d (4 speed sensors), noise (N, 4)."""
    x = np.array([1.2, 1.2 * P.N_g, 1e-3, 2e4])
    ys = []
    C = MODEL.C(SPEED_SENSORS)
    for k in range(len(d)):
        ys.append(C @ x + noise[k])
        x = MODEL.A_d @ x + MODEL.B_d[:, 0] * u[k] + MODEL.E_d[:, 0] * d[k]
    return np.array(ys)


def run_bank(y: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    bank = ObserverBank(BANK, 1)
    bank.initialise(np.array([[1.2, 1.2 * P.N_g, 1e-3, 2e4]]), y[:1])
    chi, xs = [], []
    for k in range(len(y)):
        bank.step(y[k : k + 1], np.array([u[k - 1] if k else u[0]]))
        chi.append(bank.chi2[0].copy())
        xs.append(bank.x_hat[0].copy())
    return np.array(chi), np.array(xs)


def test_existence_conditions_of_every_observer():
    names = dict(zip(BANK.names, BANK.observers, strict=True))
    assert set(names) == {
        "1",
        "2-r1",
        "2-r2",
        "3-g1",
        "3-g2",
        "4",
        "5",
        "6-r1g1",
        "6-r1g2",
        "6-r2g1",
        "6-r2g2",
        "1-nfte",
    }
    for name, obs in names.items():
        if name == "4":  # no UIO: the rigid drive train on the two generator-speed sensors
            assert obs.kind == "rigid" and "not detectable" in obs.note
        elif name == "5":
            assert obs.kind == "kalman" and "not detectable" in obs.note
        else:
            assert obs.kind == "uio"
            # (13): H C E_d = E_d, the decoupling condition; (15) T E_d = 0
            assert np.allclose(obs.H @ obs.C @ MODEL.E_d, MODEL.E_d)
            assert np.allclose(obs.T @ MODEL.E_d, 0.0, atol=1e-12 * np.abs(MODEL.E_d).max())
            assert np.abs(np.linalg.eigvals(obs.F)).max() < 1.0
    # observer 4 (no rotor-speed sensor): the zero-order hold's sampling zero near −3.7 breaks detectability
    problem = existence_problem(MODEL, ("omega_g_m1", "omega_g_m2"))
    assert "not detectable" in problem and "-3.7" in problem
    # observer 5 (no generator-speed sensor): the generator side of the torsion mode decays in ~17 s only
    problem = existence_problem(MODEL, ("omega_r_m1", "omega_r_m2"))
    assert "not detectable" in problem and "0.9624+0.269j" in problem  # |z| = 0.9994
    with pytest.raises(UIOExistenceError, match="not detectable"):
        design_uio(MODEL, ("omega_g_m1", "omega_g_m2"), np.eye(2) * 0.05**2, DESIGN_Q)


def test_residuals_do_not_move_when_only_the_unknown_input_moves():
    rng = np.random.default_rng(0)
    n = 3000
    noise = rng.normal(0.0, [0.0251, 0.0251, 0.05, 0.05], size=(n, 4))
    u = 2e4 + 1e3 * np.sin(np.arange(n) * 0.01)
    calm = np.full(n, 2.0e6)
    gusty = 2.0e6 + 4e5 * np.sin(np.arange(n) * 0.05) + 2e5 * rng.standard_normal(n)
    chi_a, x_a = run_bank(simulate_design_model(calm, u, noise), u)
    chi_b, x_b = run_bank(simulate_design_model(gusty, u, noise), u)
    uio_cols = [j for j, o in enumerate(BANK.observers) if o.kind == "uio"]
    assert np.allclose(chi_a[:, uio_cols], chi_b[:, uio_cols], rtol=1e-6, atol=1e-9)
    # ... while the states themselves of course follow the different torques
    assert not np.allclose(x_a[-1, :2], x_b[-1, :2], rtol=1e-3)


def test_residual_statistics_match_the_closed_form_covariance():
    rng = np.random.default_rng(1)
    n = 40_000
    noise = rng.normal(0.0, [0.0251, 0.0251, 0.05, 0.05], size=(n, 4))
    u = np.full(n, 2e4)
    chi_stat, _ = run_bank(simulate_design_model(np.full(n, 2.0e6), u, noise), u)
    chi_stat = chi_stat[100:]
    for j, obs in enumerate(BANK.observers):
        if obs.kind != "uio":
            continue
        # whitened residual: E[χ²] = rank, and the tail matches χ²(rank)
        assert chi_stat[:, j].mean() == pytest.approx(obs.rank, rel=0.05), BANK.names[j]
        h = chi2.isf(0.01, obs.rank)
        assert (chi_stat[:, j] > h).mean() == pytest.approx(0.01, abs=0.003), BANK.names[j]


def test_bank_block_form_equals_the_paper_equations_observer_by_observer():
    """Two implementations: the stacked bank vs eqs. (11)–(12) written out for one observer."""
    rng = np.random.default_rng(2)
    n = 400
    noise = rng.normal(0.0, [0.0251, 0.0251, 0.05, 0.05], size=(n, 4))
    u = 2e4 + 500 * rng.standard_normal(n)
    y = simulate_design_model(2e6 + 1e5 * rng.standard_normal(n), u, noise)
    _, xs = run_bank(y, u)
    j = BANK.names.index("6-r1g2")
    obs = BANK.observers[j]
    cols = [SPEED_SENSORS.index(s) for s in obs.sensors]
    x0 = np.array([1.2, 1.2 * P.N_g, 1e-3, 2e4])
    z = x0 - obs.H @ y[0, cols]
    for k in range(n):
        if k:
            step = k - 1
            F = obs.F_transient[step] if step < len(obs.F_transient) else obs.F
            K = obs.K_transient[step] if step < len(obs.K_transient) else obs.K
            z = F @ z + obs.TB[:, 0] * u[k - 1] + K @ y[k - 1, cols]  # (11)
        x_hat = z + obs.H @ y[k, cols]  # (12)
        assert np.allclose(x_hat, xs[k, BANK.offsets[j] : BANK.offsets[j] + 4], rtol=1e-9, atol=1e-9)


def test_detection_threshold_follows_the_false_alarm_budget():
    fdi = SpeedSensorFDI(BANK, 1, P.dt, FDISettings(false_alarms_per_1000s=2.0))
    alpha = 2.0 * P.dt / 1000.0  # 2e-5 per sample at 100 Hz, half to each test (PARAMETERS.md d)
    ranks = BANK.ranks[: BANK.n_isolating]
    assert fdi.h_detect == pytest.approx(chi2.isf(alpha / 2, ranks))
    # for a one-dimensional residual this is the two-sided Gaussian test |r| > 4.4 σ of PARAMETERS.md d
    one_dim = list(ranks).index(1)
    assert np.sqrt(fdi.h_detect[one_dim]) == pytest.approx(4.42, abs=0.01)
    # the window test: for a nearly white residual, close to χ² with window·rank degrees of freedom
    w = FDISettings().window
    assert fdi.h_window == pytest.approx(chi2.isf(alpha / 2, w * ranks), rel=0.03)
    # the clearing test sums fewer ticks, at its own α
    settings = FDISettings()
    assert fdi.h_clear == pytest.approx(chi2.isf(settings.clear_alpha, settings.clear_window * ranks), rel=0.03)


def test_a_clearing_window_longer_than_the_detection_window_is_refused():
    with pytest.raises(ValueError, match="clear_window"):
        SpeedSensorFDI(BANK, 1, P.dt, FDISettings(window=4, clear_window=5))


@pytest.mark.parametrize(
    ("faulty", "bias"),
    [
        (("omega_r_m1",), {"omega_r_m1": 0.3}),
        (("omega_g_m2",), {"omega_g_m2": -8.0}),
        (("omega_g_m1", "omega_g_m2"), {"omega_g_m1": -12.0, "omega_g_m2": 9.0}),
        (("omega_r_m2", "omega_g_m1"), {"omega_r_m2": 0.2, "omega_g_m1": -14.0}),
        (("omega_r_m1", "omega_r_m2"), {"omega_r_m1": 0.4, "omega_r_m2": -0.35}),
    ],
)
def test_fdi_isolates_the_faulty_sensors_and_recognises_the_end(faulty, bias):
    rng = np.random.default_rng(3)
    n = 1500
    noise = rng.normal(0.0, [0.0251, 0.0251, 0.05, 0.05], size=(n, 4))
    u = np.full(n, 2e4)
    y = simulate_design_model(2e6 + 1e5 * np.sin(np.arange(n) * 0.02), u, noise)
    start, end = 700, 1100
    for name, b in bias.items():
        y[start:end, SPEED_SENSORS.index(name)] += b
    bank = ObserverBank(BANK, 1)
    bank.initialise(np.array([[1.2, 1.2 * P.N_g, 1e-3, 2e4]]), y[:1])
    fdi = SpeedSensorFDI(BANK, 1, P.dt)
    flags = []
    for k in range(n):
        bank.step(y[k : k + 1], u[k : k + 1])
        fdi.step(y[k : k + 1], bank.chi2, bank.x_hat)
        flags.append(tuple(np.array(SPEED_SENSORS)[fdi.faulty[0]]))
    assert all(f == () for f in flags[:start]), "no false alarm before the fault"
    expected = tuple(s for s in SPEED_SENSORS if s in faulty)
    first = next(k for k in range(start, end) if flags[k])
    assert flags[first] == expected, "the first flag names exactly the faulty set"
    if any(s.startswith("omega_r") for s in faulty):
        assert first <= start + 3
    else:  # the rotor-speed pair's sequential test must first say "healthy": 6 ticks at least, about 10 on average
        assert start + 5 <= first <= start + 20
    assert all(f == expected for f in flags[first:end])
    assert flags[end + 7] == (), "fault end recognised within 0.07 s (on the plant: 0.08 s, docs/turbine.md)"
