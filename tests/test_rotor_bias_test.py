"""The rotor-speed bias CUSUM (``service.turbine.bias_test``): its threshold, its delay against the closed form,
its false-alarm rate against Lorden's bound, and the shifts it must not flag (common to both sensors)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from plant_sim.turbine import TurbineBatch
from service.plugins import AlgorithmOptionError
from service.turbine.bias_test import RotorBiasTest
from service.turbine.fdi import FDISettings
from service.turbine.interfaces import TurbineContext
from service.turbine.supervisor import TurbineSupervisor
from wwcore.scenario.faults import FaultSpec
from wwcore.scenario.turbine import TurbinePlant
from wwcore.scenario.wind import WindSpec
from wwcore.turbine_params import BENCHMARK as P

WIDTH = 4  # a stand-in x̂ whose columns 0 and 1 hold the predicted rotor speed


def _test(n: int, rate: float = 0.01, shift: float = 1.5) -> RotorBiasTest:
    return RotorBiasTest(n, np.array([[0, 1]]), np.ones((1, 2)), P.dt, rate, shift)


def _feed(test: RotorBiasTest, e: np.ndarray) -> np.ndarray:
    """Feed residuals e (ticks, n, 2) in σ_e with the prediction at 0; (n, 2) tick of the first raise, −1 none."""
    ticks, n, _ = e.shape
    first = np.full((n, 2), -1)
    x_hat, quiet = np.zeros((n, WIDTH)), np.zeros(n, dtype=np.int64)
    for k in range(ticks):
        y = np.zeros((n, 4))
        y[:, :2] = e[k]
        over = test.step(y, x_hat, quiet)
        first[(first < 0) & over] = k + 1
        test.reset(over.any(axis=1))
    return first


def test_threshold_is_the_false_alarm_budget_shared_by_four_one_sided_tests():
    assert _test(1, rate=0.01).h == pytest.approx(math.log(4 * 1000.0 / (0.01 * P.dt)))  # ln 4e7 = 17.5


@pytest.mark.parametrize("mu", [0.9, 1.1, 2.0, -2.0, 5.0])
def test_a_noise_free_bias_is_flagged_after_h_over_m_times_mu_minus_half_m_ticks(mu):
    test = _test(1)
    e = np.zeros((200, 1, 2))
    e[:, 0, 1] = mu
    first = _feed(test, e)
    m = test.shift
    assert first[0, 0] == -1
    assert first[0, 1] == math.ceil(test.h / (m * (abs(mu) - 0.5 * m)))


def test_a_bias_below_half_the_shift_is_never_flagged():
    test = _test(1)
    e = np.full((5000, 1, 2), 0.0)
    e[:, 0, 0] = 0.74  # just below m/2 = 0.75: the statistic falls by m (m/2 − μ) per tick
    assert (_feed(test, e) < 0).all()


def test_a_shift_common_to_both_rotor_sensors_is_not_flagged():
    """A generator-speed fault moves the prediction, so both residuals shift alike: no rotor-speed flag."""
    rng = np.random.default_rng(3)
    e = 3.0 + rng.standard_normal((300, 50, 2))
    assert (_feed(_test(50), e) < 0).all()


def test_false_alarms_on_white_noise_stay_within_lordens_bound():
    """With a budget of 10 per 1000 s (h = ln 4e4 = 10.6) each one-sided test's mean run length is at least e^h
    ticks, so 4e6 row-ticks of N(0, 1) may raise at most 4e6 · 4/e^h = 400 flags; the Gaussian CUSUM raises far
    fewer (Siegmund's approximation: ≈ 1e6 ticks each)."""
    rng = np.random.default_rng(11)
    rows, ticks = 400, 10_000
    test = _test(rows, rate=10.0)
    x_hat, quiet, raised = np.zeros((rows, WIDTH)), np.zeros(rows, dtype=np.int64), 0
    for _ in range(ticks):
        y = np.zeros((rows, 4))
        y[:, :2] = rng.standard_normal((rows, 2))
        over = test.step(y, x_hat, quiet)
        raised += int(over.sum())
        test.reset(over.any(axis=1))
    bound = rows * ticks * 4 / math.exp(test.h)
    assert raised <= bound
    assert raised <= 0.25 * bound


def test_rows_that_are_not_quiet_start_from_zero():
    test = _test(2)
    y, x_hat = np.zeros((2, 4)), np.zeros((2, WIDTH))
    y[:, 0] = 2.0
    for _ in range(5):
        test.step(y, x_hat, np.array([0, -1]))
    assert test.up[0, 0] > 0.0 and test.up[1, 0] == 0.0 and (test.down == 0.0).all()


def test_noise_scale_divides_the_residual():
    """A row whose healthy noise is twice the design's sees a 2σ_design bias as 1σ: slower by the closed form."""
    test = _test(1)
    y, x_hat = np.zeros((1, 4)), np.zeros((1, WIDTH))
    y[0, 0] = 2.0
    ticks = next(k for k in range(1, 500) if test.step(y, x_hat, np.zeros(1, np.int64), np.array([2.0]))[0, 0])
    assert ticks == math.ceil(test.h / (test.shift * (1.0 - 0.5 * test.shift)))


@pytest.mark.parametrize(("shift", "scale"), [(0.0, np.ones((1, 2))), (1.5, np.ones((1, 3)))])
def test_bad_designs_are_refused(shift, scale):
    with pytest.raises(ValueError):
        RotorBiasTest(1, np.array([[0, 1]]), scale, P.dt, 0.01, shift)


def test_a_row_whose_predictor_changes_starts_from_zero():
    test = RotorBiasTest(1, np.array([[0, 1], [2, 3]]), np.ones((2, 2)), P.dt, 0.01, 1.5)
    y, x_hat = np.zeros((1, 4)), np.zeros((1, WIDTH))
    y[0, 0] = 1.0
    for _ in range(5):
        test.step(y, x_hat, np.array([0]))
    assert test.up[0, 0] > 0.0
    test.step(y, x_hat, np.array([1]))  # a generator-speed flag: the prediction comes from another observer
    assert test.up[0, 0] == pytest.approx(1.5 * (1.0 - 0.75))  # one tick's increment, from zero


def test_bias_shift_must_exceed_the_clear_floor():
    with pytest.raises(AlgorithmOptionError, match="bias_shift"):
        FDISettings(bias_shift=0.8, clear_floor=1.0, rotor_bias_test=True)
    FDISettings(bias_shift=0.8, clear_floor=1.0, rotor_bias_test=False)  # no test, no hysteresis to keep


def test_the_fdi_reads_the_generator_only_kalman_filter_which_never_uses_a_rotor_speed_sensor():
    fdi = TurbineContext(P, 1)
    supervisor = TurbineSupervisor(1, options={"rotor_bias_test": True})
    detector = supervisor.detector.fdi
    assert detector.bias is not None
    design = fdi.bank_design
    # nothing flagged, ω_g,m1 flagged, ω_g,m2 flagged: a generator-speed Kalman filter; both flagged: untested
    predictors = detector._bias_predictor[[0b0000, 0b0100, 0b1000, 0b1100, 0b0001]]
    assert (predictors[:3] >= 0).all() and (predictors[3:] < 0).all()
    for j, left_out in zip(predictors[:3], ({"omega_g_m1"}, {"omega_g_m1"}, {"omega_g_m2"}), strict=True):
        o = design.observers[j]
        assert "omega_r_m1" not in o.sensors and "omega_r_m2" not in o.sensors
        assert not (left_out & set(o.sensors)) or j == predictors[0]
        # σ_e ≈ σ_r: the generator side predicts the rotor speed far better than a rotor-speed sensor reads it
        assert np.allclose(1.0 / detector.bias.scale[j], 0.0251, rtol=0.05)
    assert TurbineSupervisor(1).detector.fdi.bias is None  # off by default (docs/decisions.md)


def test_a_three_percent_rotor_gain_above_rated_is_flagged_once_and_on_its_sensor():
    """Near the limit of the window tests (3 % of ω_r ≈ 2 σ at 18 m/s), the CUSUM flags ω_r,m2 within 0.2 s and
    the flag holds to the fault's end; the healthy sensors stay unflagged."""
    fault = FaultSpec(target="omega_r_m2", kind="gain", value=0.97, start_s=8.0, end_s=14.0)
    plant = TurbineBatch(TurbinePlant(), WindSpec(mean=[(0.0, 18.0)]), [fault], seed=4, runs=[0, 1, 2, 3])
    supervisor = TurbineSupervisor(plant.n, options={"rotor_bias_test": True})
    refs, raised_at, drops, before = None, np.full(plant.n, np.nan), np.zeros(plant.n, int), np.zeros(plant.n, bool)
    for _ in range(round(14.0 / plant.dt)):
        frame = plant.measure()
        plant.control(refs)
        refs = supervisor.step(frame)
        fdi = supervisor.detector.fdi
        flagged = fdi.faulty[:, 1]
        assert not fdi.faulty[:, [0, 2, 3]].any()
        raised_at[np.isnan(raised_at) & flagged] = frame.t
        drops += before & ~flagged
        before = flagged
        plant.advance()
    assert (raised_at - 8.0 <= 0.2).all() and (drops == 0).all() and before.all()
