"""CUSUM (6)–(7) against a hand-computed sequence, decision rule (17) with its reset, Page's CUSUM bound."""

from __future__ import annotations

import math

import numpy as np
import pytest

from service.farm.cusum import PageCusum, PaperCusum, llr_increment, threshold_for


def test_increment_is_the_papers_eq_7():
    # μ0 = 0, μ1 = 0.2, σ² = 0.05 (Table 2): s = 4 (r − 0.1)
    assert llr_increment(np.array(0.3), 0.0, 0.2, 0.05) == pytest.approx(0.8)
    assert llr_increment(np.array(0.0), 0.0, 0.2, 0.05) == pytest.approx(-0.4)


def test_g_is_s_minus_its_running_minimum_by_hand():
    r = [0.0, 0.0, 0.3, 0.3, 0.0, 0.3]  # s = −0.4, −0.4, 0.8, 0.8, −0.4, 0.8
    # S = −0.4, −0.8, 0.0, 0.8, 0.4, 1.2; min S = −0.4, −0.8, −0.8, −0.8, −0.8, −0.8
    expect_g = [0.0, 0.0, 0.8, 1.6, 1.2, 2.0]
    c = PaperCusum((1,), h1=100.0, h0=100.0)
    got = []
    for x in r:
        c.step(llr_increment(np.array([x]), 0.0, 0.2, 0.05))
        got.append(float(c.g[0]))
    assert got == pytest.approx(expect_g)


def test_decision_rule_17_rises_at_h1_holds_and_falls_h0_below_the_maximum_then_resets():
    c = PaperCusum((1,), h1=1.5, h0=1.0)
    seq = [1.0, 1.0, -0.5, -0.4, -0.2, 0.1]  # increments
    # g: 0 (first sample), 1.0, 0.5, 0.1, 0 → min-reset…; by hand below
    flags, gs = [], []
    for s in seq:
        flags.append(bool(c.step(np.array([s]))[0]))
        gs.append(float(c.g[0]))
    # S = 1, 2, 1.5, 1.1, 0.9, 1.0; min = 1, 1, 1, 1, 0.9 → g = 0, 1, 0.5, 0.1, 0, …
    assert gs[:5] == pytest.approx([0.0, 1.0, 0.5, 0.1, 0.0])
    assert flags == [False] * 6  # never reached h1 = 1.5
    c = PaperCusum((1,), h1=1.5, h0=1.0)
    seq = [0.0, 1.0, 1.0, -0.5, -0.6, 0.3, 0.3]
    out = [bool(c.step(np.array([s]))[0]) for s in seq]
    # g: 0, 1, 2 (≥ h1: up), 1.5 (max 2, drop 0.5: stays), 0.9 (drop 1.1 ≥ h0: down, reset), then from scratch
    assert out[:5] == [False, False, True, True, False]
    assert c.S[0] == pytest.approx(0.6) and c.g[0] == pytest.approx(0.3)  # S reset at the fall: 0.3 + 0.3


def test_inactive_statistics_never_flag():
    c = PaperCusum((2,), h1=1.0, h0=0.5)
    for _ in range(5):
        f = c.step(np.array([1.0, 1.0]), active=np.array([True, False]))
    assert f.tolist() == [True, False] and c.g[1] == 0.0


def test_page_cusum_threshold_bounds_the_false_alarm_rate():
    """Lorden: with LLR increments, P(g ever reaches h from 0) ≤ e^−h; simulate N(0,1) vs a shift of 1."""
    h = threshold_for(200.0)
    assert h == pytest.approx(math.log(200.0))
    rng = np.random.default_rng(0)
    n, steps = 2000, 4000
    c = PageCusum((n,), h, h)
    alarms = np.zeros(n, dtype=bool)
    for _ in range(steps):
        alarms |= c.step(llr_increment(rng.standard_normal(n), 0.0, 1.0, 1.0))
    rate = alarms.mean() / steps  # first alarms per sample, at most ≈ 1/ARL0
    assert rate < 1.0 / 200.0


def test_page_cusum_detects_and_recovers():
    c = PageCusum((1,), 5.0, 5.0)
    up = [bool(c.step(np.array([2.0]))[0]) for _ in range(3)]
    assert up == [False, False, True]
    down = [bool(c.step(np.array([-2.0]))[0]) for _ in range(3)]
    assert down == [True, True, False] and c.g[0] == 0.0
