"""The generator-speed arbitration (``service.turbine.arbitration``, docs/turbine.md "Which generator-speed
sensor"): which of the two encoders moved, the rotor-speed sensors it leaves out, and the onset's jump."""

from __future__ import annotations

import math

import numpy as np
import pytest

from service.turbine.arbitration import JUMP_GUARD, JUMP_HISTORY, JUMP_LOOKBACK, JUMP_TICKS, GeneratorArbiter
from service.turbine.interfaces import TurbineContext
from wwcore.turbine_params import BENCHMARK as P

DESIGN = TurbineContext(P, 1).bank_design


def test_arbitration_names_the_sensor_that_moved_and_is_silent_without_a_fault():
    rng = np.random.default_rng(11)
    n, omega = 200, 100.0
    arbiter = GeneratorArbiter(DESIGN, n, 1e-3)
    faulty_g1 = np.arange(n) < n // 2  # half the rows: ω_g,m1 reads 0.3 rad/s (6σ) high, the others ω_g,m2
    band = np.full(n, 1)  # 35 % torque: σ of the power-speed channel ≈ 0.8 rad/s
    for _ in range(300):
        y = omega + rng.standard_normal((n, 4)) * [0.0251 * P.N_g, 0.0251 * P.N_g, 0.05, 0.05]
        y[:, :2] /= P.N_g
        y[faulty_g1, 2] += 0.3
        y[~faulty_g1, 3] += 0.3
        pe = omega + rng.standard_normal(n) * np.sqrt(arbiter.power_variance[1])
        arbiter.step(y, pe, band, np.ones((n, 2), bool), np.ones(n, bool))
    assert arbiter.decided().mean() > 0.95
    assert ((arbiter.total > 0) == faulty_g1)[arbiter.decided()].all()
    quiet = GeneratorArbiter(DESIGN, n, 1e-3)
    for _ in range(300):
        y = omega + rng.standard_normal((n, 4)) * [0.0251 * P.N_g, 0.0251 * P.N_g, 0.05, 0.05]
        y[:, :2] /= P.N_g
        quiet.step(y, omega + rng.standard_normal(n), band, np.ones((n, 2), bool), np.ones(n, bool))
    assert quiet.decided().mean() < 0.01


def test_arbitration_leaves_out_rotor_speed_sensors_that_disagree():
    """A 4 % gain on ω_r,m1 beside a 0.4 rad/s offset on ω_g,m2 (a double fault): the rotor-speed opinion, 2 % of
    ω_g high, names the healthy ω_g,m1 (``total`` > 0); the two rotor-speed sensors disagree by 1.2 σ_d per tick,
    so the sum with the power-speed channel alone decides, and names ω_g,m2 (``log_ratio`` < 0)."""
    rng = np.random.default_rng(12)
    n, omega = 200, 100.0
    arbiter = GeneratorArbiter(DESIGN, n, 1e-3)
    band = np.full(n, 1)
    for _ in range(300):
        y = omega + rng.standard_normal((n, 4)) * [0.0251 * P.N_g, 0.0251 * P.N_g, 0.05, 0.05]
        y[:, :2] /= P.N_g
        y[:, 0] *= 1.04
        y[:, 3] += 0.4
        pe = omega + rng.standard_normal(n) * np.sqrt(arbiter.power_variance[1])
        arbiter.step(y, pe, band, np.ones((n, 2), bool), np.ones(n, bool))
    assert arbiter.rotor_disagree.all()
    assert (arbiter.total > 0).mean() > 0.95  # the rotor-speed opinion alone would blame the healthy sensor
    assert arbiter.decided().mean() > 0.95 and (arbiter.log_ratio[arbiter.decided()] < 0).all()
    # healthy rotor-speed sensors agree: the parity fires at the isolation level only (α = 1e-3 per row)
    quiet = GeneratorArbiter(DESIGN, 2000, 1e-3)
    for _ in range(300):
        y = omega + rng.standard_normal((2000, 4)) * [0.0251 * P.N_g, 0.0251 * P.N_g, 0.05, 0.05]
        y[:, :2] /= P.N_g
        quiet.step(y, np.full(2000, omega), np.full(2000, 1), np.ones((2000, 2), bool), np.ones(2000, bool))
    assert quiet.rotor_disagree.mean() < 0.01


def _onset_run(arbiter: GeneratorArbiter, rng, b: float, faulty_g1: np.ndarray, ticks: int = 3000, late: int = 1):
    """A smooth generator speed (a quadratic in time, which the onset prediction extrapolates exactly) read by two
    sensors of σ_g = 0.05 rad/s; from tick ``ticks − late`` on, ω_g,m1 (rows of ``faulty_g1``) or ω_g,m2 reads
    b high. The isolation starts on the last tick (``late`` ticks after the onset)."""
    n = len(faulty_g1)
    for k in range(ticks):
        omega = 100.0 + 0.02 * k + 1e-6 * k * k
        y = omega + rng.standard_normal((n, 4)) * 0.05
        if k >= ticks - late:
            y[faulty_g1, 2] += b
            y[~faulty_g1, 3] += b
        arbiter.observe(y, np.full(n, k < ticks - late))
    arbiter.reset(np.ones(n, dtype=bool), np.ones(n, dtype=bool))


def _expected_jump(arbiter: GeneratorArbiter, b: float, fault_ticks: list[int], k: int) -> np.ndarray:
    """E[ℓ_J] per row over k compared ticks of which ``fault_ticks`` carry the offset b: δ = b + (η1 − η2) and
    m − p = b/2 + noise there, δ's noise uncorrelated with m's, so E[δᵀC⁻¹e] = (b²/2) 1_Fᵀ C⁻¹ 1_F."""
    C = arbiter.jump_covariance[:, :k, :k] + 0.5 * 0.05**2 * np.eye(k)
    ones = np.zeros((k, 1))
    ones[fault_ticks] = 1.0
    return 0.5 * b**2 * (ones.T @ np.linalg.solve(C, np.broadcast_to(ones, (len(C), k, 1))))[:, 0, 0]


def test_the_onset_jump_names_the_generator_sensor_at_once():
    """An offset b on one generator-speed sensor, detected on its first tick: the onset is placed a guard tick
    before the parity's change point, so ℓ_J = δᵀC⁻¹(m − p) spans a healthy tick and the fault's first, with mean
    (b²/2)(C⁻¹)₂₂ (δ's noise η1 − η2 is uncorrelated with m's η1 + η2). The learnt Cov(e) of a speed the quadratic
    predicts exactly is the white-noise (σ_g²/2)(I + w wᵀ). At b = 0.4 rad/s (8 σ_g) E[ℓ_J] ≈ 15, twice
    h = ln 1000: decided on the isolation's first tick in 94 % of the rows, naming the sensor that jumped. Before,
    only the sum with the power-speed channel decided it, ≈ 0.15 per tick."""
    rng = np.random.default_rng(21)
    n, b = 2000, 0.4
    arbiter = GeneratorArbiter(DESIGN, n, 1e-3, P.dt)
    faulty_g1 = np.arange(n) < n // 2
    _onset_run(arbiter, rng, b, faulty_g1, late=1)
    white = 0.5 * 0.05**2 * (np.eye(4) + arbiter.weights @ arbiter.weights.T)
    assert arbiter.jump_floor == pytest.approx(white, rel=1e-9)
    assert arbiter.jump_covariance.mean(axis=0) == pytest.approx(white, rel=0.05, abs=2e-5)
    expected = _expected_jump(arbiter, b, [1], 2)
    assert np.abs(arbiter.jump).mean() == pytest.approx(expected.mean(), rel=0.05)
    assert expected.mean() > 2.0 * math.log(1e3)
    decided = arbiter.decided()
    assert decided.mean() > 0.9
    assert ((arbiter.total > 0) == faulty_g1)[decided].all()


def test_the_onset_jump_grows_over_the_ticks_after_the_onset():
    """A 6 σ_g offset (0.3 rad/s) detected 4 ticks late: ℓ_J over the L = 4 ticks from the placed onset (a healthy
    tick and the fault's first three) has mean (b²/2) 1_Fᵀ C⁻¹ 1_F ≈ 10, against one tick's b²/(2 C₁₁) = 9.1
    (h = 6.9); decided on the isolation's first tick in about two thirds of the rows (the rest wait for the sums),
    naming the wrong sensor in at most α_iso = 1e-3 of them."""
    rng = np.random.default_rng(23)
    n, b = 4000, 0.3
    arbiter = GeneratorArbiter(DESIGN, n, 1e-3, P.dt)
    faulty_g1 = np.arange(n) < n // 2
    _onset_run(arbiter, rng, b, faulty_g1, late=4)
    expected = _expected_jump(arbiter, b, [1, 2, 3], 4)
    assert np.abs(arbiter.jump).mean() == pytest.approx(expected.mean(), rel=0.07)
    decided = arbiter.decided()
    assert decided.mean() > 0.6
    assert (((arbiter.total > 0) != faulty_g1) & decided).mean() <= 1e-3


def test_the_onset_jump_is_silent_without_a_fault_and_absent_when_not_asked():
    """No fault: ℓ_J = δᵀC⁻¹e with δ ~ N(0, 2σ_g² I) and e = m − p ~ N(0, Σ_e) independent, so E ℓ_J = 0 and
    Var(ℓ_J | δ) = δᵀC⁻¹Σ_eC⁻¹δ. It passes h = 6.9 in a few rows in 1000 (a product of normals has
    exponential tails): the chance that the jump alone decides an arbitration where no generator-speed sensor
    jumped (a drift), against a sum that then keeps growing. Rows not given a jump (a generator-speed sensor
    flagged) start from 0."""
    rng = np.random.default_rng(22)
    n = 4000
    arbiter = GeneratorArbiter(DESIGN, n, 1e-3, P.dt)
    _onset_run(arbiter, rng, 0.0, np.zeros(n, dtype=bool))
    assert arbiter.decided().mean() < 5e-3
    # each row's ℓ_J spans k = min(L, J − onset) ticks from its placed onset (anywhere, without a fault), and the
    # change point is where δ happens to move most, so the variance is taken given the δ it chose:
    # Var(ℓ_J | δ) = δᵀ C⁻¹ Σ_e C⁻¹ δ, e independent of δ
    onset = np.maximum(arbiter._change_point(np.arange(n)) - JUMP_GUARD, 0)
    variance = np.empty(n)
    for row in range(n):
        k = min(JUMP_TICKS, JUMP_LOOKBACK - onset[row])
        delta = arbiter._parities[row, JUMP_HISTORY + onset[row] :][:k]
        sigma_e = arbiter.jump_covariance[row, :k, :k]
        inverse = np.linalg.inv(sigma_e + 0.5 * 0.05**2 * np.eye(k))
        variance[row] = delta @ inverse @ sigma_e @ inverse @ delta
    assert arbiter.jump.mean() == pytest.approx(0.0, abs=4.0 * math.sqrt(variance.mean() / n))
    assert arbiter.jump.var() == pytest.approx(variance.mean(), rel=0.1)
    quiet = GeneratorArbiter(DESIGN, 10, 1e-3, P.dt)
    for k in range(100):
        y = 100.0 + rng.standard_normal((10, 4)) * 0.05
        y[:, 3] += 0.4 * (k == 99)
        quiet.observe(y, np.ones(10, dtype=bool))
    quiet.reset(np.ones(10, dtype=bool), np.zeros(10, dtype=bool))
    assert (quiet.total == 0.0).all() and (quiet.jump == 0.0).all()
