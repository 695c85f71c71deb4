"""The learnt levels and spreads of the ``analytic`` detector (``service.farm.baseline``): closed-form cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from service.farm.baseline import LearntLevel, LearntRateGain, LearntRayleighScale
from service.farm.cusum import PageCusum, llr_increment, threshold_for
from service.farm.signals import LockIn3P, lockin_iq_std

LEARNT = {"level_time_s": 600.0, "spread_time_s": 600.0, "max_ratio": 9.0}


def test_the_spread_of_white_noise_converges_to_its_variance_over_the_design():
    rng = np.random.default_rng(1)
    level = LearntLevel((200,), **LEARNT)
    design, true = 2.0, 2.6  # σ_d and σ (noise 1.3 × the data sheet)
    for _ in range(3000):
        level.update(5.0 + true * rng.standard_normal(200), design)
    # batch means of 1-s blocks: 300 blocks per statistic, relative standard error √(2/300) ≈ 8 %
    assert level.ratio.mean() == pytest.approx((true / design) ** 2, rel=0.02)
    assert np.std(level.ratio) / (true / design) ** 2 == pytest.approx(math.sqrt(2 / 300), rel=0.25)
    np.testing.assert_allclose(level.level, 5.0, atol=4 * true / math.sqrt(3000))


def test_the_spread_is_the_long_run_variance_of_correlated_noise():
    """AR(1) noise e_k = a e_{k−1} + w_k has long-run variance σ_w²/(1 − a)², not its one-sample σ_w²/(1 − a²)."""
    rng = np.random.default_rng(2)
    a, n, steps = 0.5, 200, 6000
    level = LearntLevel((n,), level_time_s=6000.0, spread_time_s=6000.0, max_ratio=100.0, block=40)
    e = np.zeros(n)
    for _ in range(steps):
        e = a * e + rng.standard_normal(n)
        level.update(e, 1.0)
    long_run, one_sample = 1.0 / (1.0 - a) ** 2, 1.0 / (1.0 - a * a)
    # batch means of B samples underestimate by ≈ 2a/((1 − a²) B) relative: 3 % at B = 40
    assert level.ratio.mean() == pytest.approx(long_run, rel=0.06)
    assert level.ratio.mean() > 2.5 * one_sample


def test_a_spread_below_the_design_and_one_beyond_the_largest_are_bounded():
    rng = np.random.default_rng(3)
    level = LearntLevel((50,), **LEARNT)
    for _ in range(2000):
        level.update(np.concatenate([0.5 * rng.standard_normal(25), 5.0 * rng.standard_normal(25)]), 1.0)
    np.testing.assert_array_equal(level.ratio[:25], 1.0)  # quieter than designed: the design's σ stays
    np.testing.assert_array_equal(level.ratio[25:], 9.0)  # noisier than 3 σ: not health
    assert np.all(level.raw_ratio[:25] < 0.5) and np.all(level.raw_ratio[25:] > 15.0)


def test_nothing_is_learnt_while_frozen():
    rng = np.random.default_rng(4)
    level = LearntLevel((3,), **LEARNT)
    for _ in range(500):
        level.update(1.0 + rng.standard_normal(3), 1.0)
    before = (level.level.copy(), level.raw_ratio.copy(), level.samples.copy())
    frozen = np.array([True, True, False])
    for _ in range(500):
        level.update(50.0 + 20.0 * rng.standard_normal(3), 1.0, frozen)
    np.testing.assert_array_equal(level.level[:2], before[0][:2])
    np.testing.assert_array_equal(level.raw_ratio[:2], before[1][:2])
    np.testing.assert_array_equal(level.samples[:2], before[2][:2])
    assert level.level[2] > 20.0 and level.raw_ratio[2] > 4.0  # the live one learnt the change


def test_the_level_tracks_with_its_time_constant_after_the_learning_samples():
    level = LearntLevel((1,), level_time_s=100.0, spread_time_s=100.0, max_ratio=9.0)
    for _ in range(2000):  # running mean: exact after any number of samples while 1/k > Δt/T
        level.update(np.array([2.0]), 1.0)
    assert level.level[0] == pytest.approx(2.0)
    for _ in range(1000):  # a step of 1, then w = Δt/T = 0.001 per sample: 1 − (1 − 0.001)^1000 ≈ 1 − e^{−1}
        level.update(np.array([3.0]), 1.0)
    assert level.level[0] == pytest.approx(2.0 + 1.0 - (1.0 - 0.001) ** 1000, rel=1e-9)


def _cusum_run(offset: float, step_at: int | None, steps: int, rng, learn: bool) -> tuple[bool, np.ndarray]:
    """64 pitch-like residuals (σ 0.11 deg, design) with a steady ``offset`` from the start and, from ``step_at``, a
    step of the paper's 0.3 deg; returns (any false alarm before the step, each one's first alarm after it in
    samples, −1 where none)."""
    sigma, delta, h = 0.11, 0.3, threshold_for(1e7)
    level = LearntLevel((64,), **LEARNT)
    cusum = PageCusum((64,), h, h)
    false_alarm, first = False, np.full(64, -1)
    for k in range(steps):
        z = offset + sigma * rng.standard_normal(64) + (delta if step_at is not None and k >= step_at else 0.0)
        if learn:
            level.update(z, sigma, cusum.flag | (cusum.g >= 0.5 * h))
            z = z - level.level
        if k < 300:  # warm-up: learnt, not judged
            continue
        flags = cusum.step(llr_increment(z, 0.0, delta, sigma * sigma * (level.ratio if learn else 1.0)))
        if step_at is None or k < step_at:
            false_alarm |= bool(flags.any())
        else:
            first = np.where((first < 0) & flags, k - step_at, first)
    return false_alarm, first


def test_a_learnt_constant_offset_is_not_flagged_and_a_step_of_the_fault_size_is():
    rng = np.random.default_rng(5)
    # an offset of 0.25 deg (a bias within tolerance) flags at once on the design level...
    assert _cusum_run(0.25, None, 1500, rng, learn=False)[0]
    # ...is learnt as health, and the paper's 0.3 deg onset on top of it is found within a second
    false_alarm, first = _cusum_run(0.25, 1000, 1500, rng, learn=True)
    assert not false_alarm
    assert np.all(first >= 0) and first.max() <= 20
    # Page's CUSUM: delay ≈ h / (δ²/2σ²) = 16.1 / 3.72 ≈ 4.3 samples, plus the overshoot of less than one sample
    assert 3.0 <= first.mean() <= 6.0


def test_the_rayleigh_scale_of_a_noise_only_lockin_converges_and_is_bounded():
    rng = np.random.default_rng(6)
    n, tau, sigma = 100, 1.5, 0.02
    lockin = LockIn3P(n, tau)
    design = float(lockin_iq_std(sigma, tau))
    scale = LearntRayleighScale(n, design, spread_time_s=600.0, max_ratio=9.0)
    for k in range(6000):
        amplitude = lockin.step(1.5 * sigma * rng.standard_normal(n), np.full(n, 1.2))
        scale.update(amplitude, frozen=k < 100)
    assert scale.scale.mean() / design == pytest.approx(1.5, rel=0.05)  # E[A²] = 8 s² with s ∝ σ
    quiet = LearntRayleighScale(n, design, spread_time_s=600.0, max_ratio=9.0)
    quiet.update(np.zeros(n))
    np.testing.assert_array_equal(quiet.scale, design)  # bounded below by the design


def test_the_rate_gain_is_the_lag_difference_and_leaves_a_constant_offset_alone():
    """r = k x + offset + noise with x a zero-mean rate: k̂ → k; the offset is uncorrelated with x and stays in
    r − k̂ x; where x has not moved, the prior holds k̂ at 0."""
    rng = np.random.default_rng(7)
    gain = LearntRateGain((100,), time_s=600.0, prior=100.0)
    still = LearntRateGain((100,), time_s=600.0, prior=100.0)
    k = 0.012  # s: lags differing by 8 ms, in z_2's combination
    for _ in range(3000):
        x = 3.0 * rng.standard_normal(100)  # deg/s
        gain.update(0.25 + k * x + 0.1 * rng.standard_normal(100), x)
        still.update(0.25 + 0.1 * rng.standard_normal(100), np.zeros(100))
    # least squares: standard error σ/√(Σx²) with Σx² ≈ 9 · 3000 (the forgetting spans 6000 samples)
    assert gain.gain.mean() == pytest.approx(k, abs=3 * 0.1 / math.sqrt(9 * 3000 * 100))
    assert np.std(gain.gain) < 3 * 0.1 / math.sqrt(9 * 3000)
    np.testing.assert_array_equal(still.gain, 0.0)
    frozen = gain.gain.copy()
    gain.update(np.full(100, 5.0), np.full(100, 50.0), frozen=True)
    np.testing.assert_array_equal(gain.gain, frozen)


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="max_ratio"):
        LearntLevel((1,), level_time_s=10.0, spread_time_s=10.0, max_ratio=0.5)
    with pytest.raises(ValueError, match="time constants"):
        LearntLevel((1,), level_time_s=0.0, spread_time_s=10.0, max_ratio=4.0)
    with pytest.raises(ValueError, match="prior"):
        LearntRateGain((1,), time_s=10.0, prior=0.0)
