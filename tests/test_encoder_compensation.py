"""Fault estimation and compensation of a flagged generator-speed encoder (``service.turbine.encoder_compensation``):
the fault (offset, drift) against the healthy encoder by recursive least squares, the corrected reading, its
residual test, when it makes the quieter torque, and the wind estimate through a flagged offset (docs/turbine.md,
"Estimates")."""

from __future__ import annotations

import numpy as np
import pytest

from plant_sim.turbine import TurbineBatch
from service.turbine.builtin import UIOBankEstimator
from service.turbine.encoder_compensation import EncoderFaultEstimate, ticks_until_better, torque_noise_variances
from service.turbine.interfaces import TurbineContext
from service.turbine.supervisor import TurbineSupervisor
from wwcore.channels import SENSOR_INDEX, SENSORS, noise_std
from wwcore.scenario.faults import FaultKind, FaultSpec
from wwcore.scenario.turbine import TurbinePlant
from wwcore.scenario.wind import WindSpec
from wwcore.stepping import run_ticks
from wwcore.turbine_params import BENCHMARK as P

SIGMA_G = noise_std(SENSORS[SENSOR_INDEX["omega_g_m1"]], "sigma")
SIGMA_D = float(np.hypot(SIGMA_G, SIGMA_G))


def _readings(rng, rows: int, ticks: int, dt: float):
    """A shaft swinging by ±0.5 rad/s around 13 rad/s (4 m/s's generator speed) at 0.01–0.05 Hz, and two encoders'
    white noise (σ_g each): (ticks, rows) true speed, healthy and faulty-before-the-fault readings."""
    t = np.arange(ticks)[:, None] * dt
    phase = rng.uniform(0, 2 * np.pi, (1, rows))
    omega = 13.0 + 0.5 * np.sin(2 * np.pi * 0.02 * t + phase) + 0.2 * np.sin(2 * np.pi * 0.05 * t + 2 * phase)
    return (
        omega,
        omega + SIGMA_G * rng.standard_normal((ticks, rows)),
        omega + SIGMA_G * rng.standard_normal((ticks, rows)),
    )


def _estimate(faulty: np.ndarray, healthy: np.ndarray, forget_s: float, min_ticks: int = 0):
    rows = faulty.shape[1]
    estimate = EncoderFaultEstimate(rows, P.dt, SIGMA_D, min_ticks, forget_s=forget_s)
    encoder = np.zeros(rows, dtype=np.int64)
    predictions = np.empty_like(faulty)
    for k in range(len(faulty)):
        estimate.step(encoder, faulty[k], healthy[k])
        predictions[k] = estimate.prediction
    return estimate, predictions


def test_offset_and_drift_are_recovered_within_their_standard_errors():
    """Synthetic readings, 400 rows × 20 s with an offset of −7σ_g and a drift of +0.3σ_g/s on the faulty encoder:
    with a forgetting time of 1 000 s (λ = 1 − 10⁻⁵, the weights within 2 % of 1) the least squares' b̂ and ŝ are
    off by their standard errors σ_d √P in distribution (the z-scores' spread within 10 % of 1, none beyond 4.5),
    and with the estimator's 10-s forgetting every row is within 4.5 of its (approximate) standard errors."""
    rng = np.random.default_rng(84204)
    rows, ticks = 400, 2_000
    _, healthy, faulty = _readings(rng, rows, ticks, P.dt)
    offset, drift = -7.0 * SIGMA_G, 0.3 * SIGMA_G
    t = np.arange(ticks)[:, None] * P.dt
    faulty = faulty + offset + drift * t
    for forget_s, spread in ((1e3, True), (10.0, False)):
        estimate, _ = _estimate(faulty, healthy, forget_s)
        b, s, se_b, se_s = estimate.fault()
        z_b = (b - (offset + drift * t[-1, 0])) / se_b
        z_s = (s - drift) / se_s
        assert np.abs(z_b).max() < 4.5 and np.abs(z_s).max() < 4.5
        if spread:
            assert z_b.std() == pytest.approx(1.0, abs=0.1) and z_s.std() == pytest.approx(1.0, abs=0.1)
            assert abs(z_b.mean()) < 0.2 and abs(z_s.mean()) < 0.2
            assert se_b.mean() == pytest.approx(2.0 * SIGMA_D / np.sqrt(ticks), rel=0.02)  # a line's end point


def test_a_gain_is_followed_as_a_moving_offset():
    """A gain of 0.98 (a 2 % error, −0.26 rad/s at 13 rad/s): the corrected reading ỹ_f = y_f − d̂ follows the shaft
    to within the faulty encoder's own noise (its error's σ within 5 % of σ_g, its mean within 0.1 σ_g) once the
    forgetting's 10 s have passed, though the fault moves with ω by ±0.014 rad/s."""
    rng = np.random.default_rng(84205)
    rows, ticks = 50, 3_000
    omega, healthy, faulty = _readings(rng, rows, ticks, P.dt)
    faulty = omega * 0.98 + (faulty - omega)
    _, predictions = _estimate(faulty, healthy, 10.0)
    error = (faulty - predictions - omega)[1_000:]
    assert error.std() == pytest.approx(SIGMA_G, rel=0.05)
    assert abs(error.mean()) < 0.1 * SIGMA_G


def test_the_residual_test_restarts_where_the_fault_changed_and_rarely_elsewhere():
    """Blocks of 20 ticks (the wind's inversions): on a fault that fits (1) the test restarts a share ≈ α = 10⁻³ of
    the blocks; a further 2σ_g step of the offset restarts every settled row's estimate within two blocks."""
    rng = np.random.default_rng(84206)
    rows, ticks = 200, 2_040
    _, healthy, faulty = _readings(rng, rows, ticks, P.dt)
    faulty = faulty - 5.0 * SIGMA_G
    step_at = 2_000
    faulty[step_at:] += 2.0 * SIGMA_G
    estimate = EncoderFaultEstimate(rows, P.dt, SIGMA_D, 0)
    encoder = np.zeros(rows, dtype=np.int64)
    false, restarted = 0, np.full(rows, -1)
    for k in range(step_at + 40):
        estimate.step(encoder, faulty[k], healthy[k])
        if (k + 1) % 20 == 0:
            misfit = estimate.test()
            false += int(misfit.sum()) if k < step_at else 0
            restarted = np.where(misfit, k, restarted)
            if k == step_at - 1:
                settled = restarted < step_at - 100  # fits a second old or more when the step comes
    assert 5 <= false <= 40  # 200 rows × 100 blocks at α = 10⁻³: 20 expected (Poisson: outside [5, 40] < 10⁻⁴)
    # every row whose fit was a second old or more restarted with the step's first two blocks (a fit restarted by
    # chance just before rests on a few ticks and absorbs much of the step into its offset)
    assert settled.sum() >= 0.95 * rows
    assert (restarted[settled] >= step_at).all()


def test_a_frozen_reading_is_never_corrected():
    rows = 2
    estimate = EncoderFaultEstimate(rows, P.dt, SIGMA_D, 0)
    rng = np.random.default_rng(84207)
    encoder = np.zeros(rows, dtype=np.int64)
    for _ in range(50):
        healthy = 13.0 + SIGMA_G * rng.standard_normal(rows)
        faulty = np.array([12.0, 12.0 + SIGMA_G * rng.standard_normal()])  # row 0 stuck
        use = estimate.step(encoder, faulty, healthy)
    assert use.tolist() == [False, True]


def test_the_corrected_pair_is_quieter_once_the_estimate_has_settled():
    """The wind filter's torque noise on the corrected pair against the healthy encoder's alone, both at the
    one-encoder cutoff (0.252 Hz): early on the prediction's own motion makes the pair noisier; from
    ``ticks_until_better`` ticks (235, 2.35 s) it is quieter for good, and at the forgetting's stationarity within
    5 % of half (the pair of healthy encoders': the estimate takes back little of what the second one brings)."""
    context = TurbineContext(P, 1)
    estimator = UIOBankEstimator(context=context)
    own, healthy = estimator._own[0], estimator._pair[0]  # ω_g,m1 flagged: 4-g2 runs on it, 4-g1 on ω_g,m2
    c_now, c_prev = estimator.recovery.rigid_speed_coefficients(context.bank_design, int(own))
    cutoffs = estimator.recovery.torque_cutoffs_hz
    assert cutoffs[own] == cutoffs[healthy] < 0.3
    args = (c_now, c_prev, 0.5, SIGMA_G, SIGMA_G, float(cutoffs[own]), float(cutoffs[healthy]), P.dt)
    variance, single = torque_noise_variances(*args)
    start = ticks_until_better(*args)
    assert start == estimator._fault_estimate.min_ticks == 235
    assert (variance[start:] <= single).all() and variance[start - 1] > single
    assert variance[-1] / single == pytest.approx(0.5, rel=0.05)


def _offset_run(compensation: bool, backend: str = "numpy") -> tuple[np.ndarray, np.ndarray]:
    rows, start, end = 4, 20.0, 60.0
    faults = [
        FaultSpec(
            target="omega_g_m1", kind=FaultKind.OFFSET, value=-10.0 * SIGMA_G, start_s=start, end_s=end,
            turbine=t, name=f"g1 offset -10σ #{t}",
        )
        for t in range(1, rows + 1)
    ]  # fmt: skip
    plant = TurbineBatch(
        TurbinePlant(), WindSpec(mean=[(0.0, 4.0)]), faults, seed=84208, runs=(0,),
        turbines=list(range(1, rows + 1)), fault_free_twins=True,
    )  # fmt: skip
    supervisor = TurbineSupervisor(plant.n, options={"encoder_compensation": compensation}, backend=backend)
    squared = np.zeros(plant.n)
    winds = []

    def record(k: int, frame, refs) -> None:
        winds.append(supervisor.estimates.wind.copy())
        if k * P.dt >= start + 10.0:  # after the estimate has settled (2.35 s after the flag)
            error = supervisor.estimates.wind - plant.true_rotor_wind()
            squared[:] += error * error

    run_ticks(plant, supervisor, range(round(end / P.dt)), stepped=record)
    return squared[:rows] / squared[rows:], np.array(winds)


def test_the_wind_estimate_through_a_flagged_offset_is_better_compensated():
    """A −10σ_g offset on ω_g,m1 at 4 m/s, flagged within 0.1 s: without compensation the estimate runs on the one
    healthy encoder (the one-encoder floor); with it, on both encoders through the one-encoder filter, the flagged
    one's reading corrected: the wind's squared error over 30 s is below the uncompensated one's on every row (0.68–
    0.78 × the twins' against 1.00–1.39 × on this seed: at 4 m/s the pair at the one-encoder cutoff beats the twin's
    0.3 Hz, which is noise-bound there). The compiled backend gives the same winds."""
    without, _ = _offset_run(False)
    with_, winds = _offset_run(True)
    assert (with_ < without).all(), (with_, without)
    assert with_.mean() < 0.85 < 1.1 < without.mean()
    _, compiled = _offset_run(True, backend="numba")
    np.testing.assert_allclose(compiled, winds, rtol=1e-9, atol=1e-9)
