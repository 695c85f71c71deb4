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


def _siegmund_delay(test: RotorBiasTest, mu: float) -> float:
    """Siegmund's approximation of a one-sided Gaussian CUSUM's mean run length: increments X ~ N(δ, σ²), here
    X = m_d (d − m_d/2) with d ~ N(μ/√2, 1), δ = m_d (μ/√2 − m_d/2), σ = m_d; b = h + 1.166 σ (the overshoot)."""
    m = test.parity_shift
    delta, sigma = m * (mu / math.sqrt(2.0) - 0.5 * m), m
    b = test.h + 1.166 * sigma
    x = 2.0 * delta * b / sigma**2
    return (math.exp(-x) + x - 1.0) / (2.0 * delta**2 / sigma**2)


def _old_cusum_raises(e: np.ndarray, h: float, m: float) -> int:
    """The earlier test, kept here as the reference it is compared with: Page's two-sided CUSUM on each sensor's
    exclusion residual e (ticks, rows, 2) as if it were white N(0, 1); a raise resets the row."""
    up, down, raised = np.zeros(e.shape[1:]), np.zeros(e.shape[1:]), 0
    for tick in e:
        up = np.maximum(0.0, up + m * (tick - 0.5 * m))
        down = np.maximum(0.0, down + m * (-tick - 0.5 * m))
        over = ((up >= h) | (down >= h)).any(axis=1)
        raised += int(over.sum())
        up[over], down[over] = 0.0, 0.0
    return raised


def _ar1(rng: np.random.Generator, ticks: int, rows: int, rho: float, variance: float) -> np.ndarray:
    """(ticks, rows) of a stationary AR(1) of coefficient ρ and variance ``variance``."""
    x = np.empty((ticks, rows))
    x[0] = math.sqrt(variance) * rng.standard_normal(rows)
    innovation = math.sqrt(variance * (1.0 - rho**2))
    for k in range(1, ticks):
        x[k] = rho * x[k - 1] + innovation * rng.standard_normal(rows)
    return x


def test_threshold_is_the_false_alarm_budget_shared_by_the_parity_s_two_one_sided_tests():
    assert _test(1, rate=0.01).h == pytest.approx(math.log(2 * 1000.0 / (0.01 * P.dt)))  # ln 2e7 = 16.8


@pytest.mark.parametrize("sensor", [0, 1])
@pytest.mark.parametrize("mu", [0.9, 1.1, 2.0, -2.0, 5.0])
def test_a_noise_free_bias_is_flagged_on_its_sensor_after_2h_over_m_times_mu_minus_half_m_ticks(mu, sensor):
    test = _test(1)
    e = np.zeros((400, 1, 2))
    e[:, 0, sensor] = mu
    first = _feed(test, e)
    m = test.shift
    assert first[0, 1 - sensor] == -1
    assert first[0, sensor] == math.ceil(2.0 * test.h / (m * (abs(mu) - 0.5 * m)) - 1e-9)


def _bank(n: int, rate: float = 0.01, bank: int = 3) -> RotorBiasTest:
    return RotorBiasTest(n, np.array([[0, 1]]), np.ones((1, 2)), P.dt, rate, 1.5, bank=bank)


def test_the_bank_s_threshold_is_the_budget_shared_by_its_2k_one_sided_tests():
    test = _bank(1)
    assert test.shifts.tolist() == [1.5, 3.0, 6.0]  # an octave apart from bias_shift
    assert test.h == pytest.approx(math.log(2 * 3 * 1000.0 / (0.01 * P.dt)))  # ln 6e7 = 17.9


@pytest.mark.parametrize("sensor", [0, 1])
@pytest.mark.parametrize("mu", [1.1, 2.0, 3.0, -5.0, 8.0])
def test_a_noise_free_bias_is_flagged_by_the_bank_s_fastest_cusum(mu, sensor):
    """S_k grows by m_d,k (|μ|/√2 − m_d,k/2) per tick: the bank raises after min_k ⌈h / that⌉ ticks, on the biased
    sensor."""
    test = _bank(1)
    e = np.zeros((400, 1, 2))
    e[:, 0, sensor] = mu
    first = _feed(test, e)
    m = test.parity_shifts
    growth = m * (abs(mu) / math.sqrt(2.0) - 0.5 * m)
    expected = min(math.ceil(test.h / g - 1e-9) for g in growth if g > 0.0)
    assert first[0, 1 - sensor] == -1
    assert first[0, sensor] == expected


def test_the_bank_finds_a_large_bias_in_half_the_single_cusum_s_time_near_lordens_bound():
    """A bias of 5 σ_e (a 7.4 % gain at rated rotor speed): the single CUSUM (m = 1.5) needs ⌈2h₁/(m(μ − m/2))⌉ = 6
    ticks; the bank's 6 σ_e shift ⌈2h/(6(5 − 3))⌉ = 3, and the optimal test for a known bias of 5 (Lorden:
    h₁ / KL, KL = μ²/4 per tick of the parity) 16.8/6.25 = 2.7."""
    e = np.zeros((50, 1, 2))
    e[:, 0, 0] = 5.0
    single, bank = _feed(_test(1), e.copy())[0, 0], _feed(_bank(1), e.copy())[0, 0]
    assert (single, bank) == (6, 3)
    assert bank <= math.ceil(_test(1).h / (5.0**2 / 4.0))


def test_the_bank_s_false_alarms_on_white_noise_stay_within_lordens_bound():
    """Budget 10 per 1000 s: h = ln(2·3·1e4) = 11.0 and the 2K one-sided tests of a row may raise at most
    2K · ticks / e^h times on N(0, 1), the row's budget α = 1e-4 per tick."""
    rng = np.random.default_rng(12)
    rows, ticks = 400, 10_000
    test = _bank(rows, rate=10.0)
    raised = int(_count(test, rng.standard_normal((ticks, rows, 2))).sum())
    assert raised <= 0.5 * rows * ticks * 6 / math.exp(test.h)


def test_the_supervisor_runs_the_bank_by_default():
    test = TurbineSupervisor(1).detector.fdi.bias
    assert FDISettings().bias_bank == 3 and test.shifts.tolist() == [1.5, 3.0, 6.0]
    assert TurbineSupervisor(1, options={"bias_bank": 1}).detector.fdi.bias.shifts.tolist() == [1.5]


def test_a_bias_below_half_the_shift_is_never_flagged():
    test = _test(1)
    e = np.full((5000, 1, 2), 0.0)
    e[:, 0, 0] = 0.74  # just below m/2 = 0.75: the statistic falls by m_d (m_d/2 − μ/√2) per tick
    assert (_feed(test, e) < 0).all()


def test_a_shift_common_to_both_rotor_sensors_is_not_flagged():
    """A generator-speed fault moves the prediction, so both residuals shift alike: no rotor-speed flag."""
    rng = np.random.default_rng(3)
    e = 3.0 + rng.standard_normal((300, 50, 2))
    assert (_feed(_test(50), e) < 0).all()


def test_a_near_limit_bias_is_found_in_siegmunds_mean_delay_on_its_sensor():
    """μ = 0.9 and 1.1 σ_e, just above the limit m/2 = 0.75, in white noise: the mean delay over 400 rows is
    Siegmund's approximation (about 117 and 61 ticks) within 8 %, and the raise names the biased sensor."""
    rng = np.random.default_rng(17)
    rows = 400
    for mu in (0.9, 1.1):
        test = _test(rows)
        first = np.full((rows, 2), -1)
        x_hat, quiet = np.zeros((rows, WIDTH)), np.zeros(rows, dtype=np.int64)
        for k in range(4000):
            y = np.zeros((rows, 4))
            y[:, :2] = rng.standard_normal((rows, 2))
            y[:, 1] -= mu
            over = test.step(y, x_hat, quiet)
            first[(first < 0) & over] = k + 1
            test.reset(over.any(axis=1))
            if (first[:, 1] > 0).all():
                break
        assert (first[:, 1] > 0).all()
        assert (first[:, 0] < 0).mean() >= 0.99  # named right at the first raise
        assert first[:, 1].mean() == pytest.approx(_siegmund_delay(test, mu), rel=0.08)


def test_false_alarms_on_white_noise_stay_within_lordens_bound():
    """With a budget of 10 per 1000 s (h = ln 2e4 = 9.9) each one-sided test's mean run length is at least e^h
    ticks, so 4e6 row-ticks of N(0, 1) may raise at most 4e6 · 2/e^h = 400 flags; the Gaussian CUSUM raises far
    fewer."""
    rng = np.random.default_rng(11)
    rows, ticks = 400, 10_000
    test = _test(rows, rate=10.0)
    e = rng.standard_normal((ticks, rows, 2))
    raised = int((_count(test, e)).sum())
    bound = rows * ticks * 2 / math.exp(test.h)
    assert raised <= 0.5 * bound


def _count(test: RotorBiasTest, e: np.ndarray) -> np.ndarray:
    """Raises per row of residuals e (ticks, n, 2), each raise resetting its row."""
    raised = np.zeros(e.shape[1], dtype=int)
    x_hat, quiet = np.zeros((e.shape[1], WIDTH)), np.zeros(e.shape[1], dtype=np.int64)
    for tick in e:
        y = np.zeros((e.shape[1], 4))
        y[:, :2] = tick
        over = test.step(y, x_hat, quiet).any(axis=1)
        raised += over
        test.reset(over)
    return raised


def test_a_common_ar1_prediction_error_breaks_the_old_bound_and_not_the_parity_s():
    """The healthy residual as measured near rated: each sensor's white noise less a prediction error common to
    both, coloured (here AR(1), ρ = 0.9, variance 2, so e_s has variance 3 and long-run variance 1 + 2·19 = 39).
    At a budget of 10 per 1000 s the old CUSUM on e_s (h = ln 4e4) may raise 4e6 · 4/e^h = 400 flags on 4e6
    row-ticks if e_s were white; it raises more than ten times that. The parity's CUSUM keeps its bound (400):
    the common error cancels in e_1 − e_2."""
    rng = np.random.default_rng(29)
    rows, ticks, rate = 400, 10_000, 10.0
    e = rng.standard_normal((ticks, rows, 2)) - _ar1(rng, ticks, rows, 0.9, 2.0)[:, :, None]
    old_h = math.log(4 * 1000.0 / (rate * P.dt))
    assert _old_cusum_raises(e, old_h, 1.5) > 10 * rows * ticks * 4 / math.exp(old_h)
    test = _test(rows, rate=rate)
    assert int(_count(test, e).sum()) <= 0.5 * rows * ticks * 2 / math.exp(test.h)


def test_noisier_sensors_are_learnt_and_keep_the_bound():
    """Both rotor-speed sensors twice as noisy as designed: the parity's healthy spread ŝ (adaptive, T_a = 10 s)
    converges to 2 (the learnt mean of d² is 4), and the false alarms stay within Lorden's bound."""
    rng = np.random.default_rng(31)
    rows, ticks = 200, 10_000
    test = RotorBiasTest(rows, np.array([[0, 1]]), np.ones((1, 2)), P.dt, 10.0, 1.5, 10.0, 3.0)
    raised = int(_count(test, 2.0 * rng.standard_normal((ticks, rows, 2))).sum())
    assert np.allclose(test.spread.scale, 2.0, rtol=0.1)
    # the first ticks run before ŝ has learnt: count against the bound the whole run
    assert raised <= rows * ticks * 2 / math.exp(test.h)
    assert RotorBiasTest(1, np.array([[0, 1]]), np.ones((1, 2)), P.dt, 10.0, 1.5).spread.enabled is False


def test_rows_that_are_not_quiet_start_from_zero():
    test = _test(2)
    y, x_hat = np.zeros((2, 4)), np.zeros((2, WIDTH))
    y[:, 0] = 2.0
    for _ in range(5):
        test.step(y, x_hat, np.array([0, -1]))
    assert test.up[0] > 0.0 and test.up[1] == 0.0 and (test.down == 0.0).all()


@pytest.mark.parametrize(
    ("shift", "scale", "rate"),
    [(0.0, np.ones((1, 2)), 0.01), (1.5, np.ones((1, 3)), 0.01), (1.5, np.ones((1, 2)), 0.0)],
)
def test_bad_designs_are_refused(shift, scale, rate):
    with pytest.raises(ValueError):
        RotorBiasTest(1, np.array([[0, 1]]), scale, P.dt, rate, shift)


def test_an_empty_bank_is_refused():
    with pytest.raises(ValueError, match="bank"):
        RotorBiasTest(1, np.array([[0, 1]]), np.ones((1, 2)), P.dt, 0.01, 1.5, bank=0)


def test_a_row_whose_predictor_changes_starts_from_zero():
    test = RotorBiasTest(1, np.array([[0, 1], [2, 3]]), np.ones((2, 2)), P.dt, 0.01, 1.5)
    y, x_hat = np.zeros((1, 4)), np.zeros((1, WIDTH))
    y[0, 0] = 1.0
    for _ in range(5):
        test.step(y, x_hat, np.array([0]))
    assert test.up[0] > 0.0
    test.step(y, x_hat, np.array([1]))  # a generator-speed flag: the prediction comes from another observer
    m = test.parity_shift
    assert test.up[0] == pytest.approx(m * (1.0 / math.sqrt(2.0) - 0.5 * m))  # one tick's increment, from zero


def test_bias_shift_must_exceed_the_clear_floor():
    with pytest.raises(AlgorithmOptionError, match="bias_shift"):
        FDISettings(bias_shift=0.8, clear_floor=1.0, rotor_bias_test=True)
    FDISettings(bias_shift=0.8, clear_floor=1.0, rotor_bias_test=False)  # no test, no hysteresis to keep


@pytest.mark.parametrize(
    ("options", "key"),
    [
        ({"bias_shift": 0.1}, "bias_shift"),
        ({"bias_shift": 11.0}, "bias_shift"),
        ({"bias_bank": 0}, "bias_bank"),
        ({"bias_bank": 7}, "bias_bank"),
        ({"rotor_bias_test": "yes"}, "rotor_bias_test"),
        ({"rotor_bias_tset": True}, "rotor_bias_tset"),
        ({"rotor_bias_test": True, "bias_shift": 1.2, "clear_floor": 1.2}, "bias_shift"),
    ],
)
def test_the_supervisor_refuses_bad_bias_test_options_naming_the_key(options, key):
    with pytest.raises(AlgorithmOptionError, match=key):
        TurbineSupervisor(1, options=options)


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
    assert TurbineSupervisor(1).detector.fdi.bias is not None  # on by default (docs/decisions.md)
    assert TurbineSupervisor(1, options={"rotor_bias_test": False}).detector.fdi.bias is None


def test_a_three_percent_rotor_gain_above_rated_is_flagged_once_and_on_its_sensor():
    """Near the limit of the window tests (3 % of ω_r ≈ 1.5 σ_e at 18 m/s), the CUSUM flags ω_r,m2 within 0.3 s
    (the noise-free delay 2h/(m(μ − m/2)) is 29 ticks) and the flag holds to the fault's end; the healthy sensors
    stay unflagged."""
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
    assert (raised_at - 8.0 <= 0.3).all() and (drops == 0).all() and before.all()
