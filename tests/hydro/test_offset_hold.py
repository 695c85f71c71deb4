"""The held mean of a flagged offset (``service.hydro.offset_hold``): its noise gain against the closed form of a
telescoping mean, the switch from the filter to the mean, restarts on a change, and the closed loop at ±2 %."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

from service.hydro.noise import noise_response
from service.hydro.offset_hold import OffsetHold, hold_samples, mean_response_l2
from service.hydro.supervisor import HydroSupervisor
from tests.hydro.conftest import offset, run_loop
from wwcore.hydro_params import NOMINAL
from wwcore.scenario import load_scenario

NOISE = {"tau_filter": [0.05, 0.05], "filter_order": 2, "layer_correction": True}  # hydro-noise's observer
LOW_NOISE = {"tau_filter": [0.025, 0.025], "filter_order": 2, "layer_correction": True}


def closed_form(samples: np.ndarray) -> np.ndarray:
    """‖h_a ∗ 1_N/N‖₂ of f̂_a ≈ x̃ + τ_p dx̃/dt − u: mean(x̃) plus the telescoped derivative τ_p (x̃_N − x̃_0)/(N dt)."""
    return np.sqrt(1.0 / samples + 2.0 * (NOMINAL.tau_p / (samples * NOMINAL.dt)) ** 2)


@pytest.mark.parametrize("settings", [NOISE, LOW_NOISE])
def test_the_mean_telescopes_the_differentiated_reading_noise(settings):
    response = noise_response("ts-smo", settings, NOMINAL)
    for samples in (10, 30, 100, 300, 1000):
        gain = mean_response_l2(response.h_a, samples)
        # the observer's boundary layer and first-order hold smooth the kick a little: a little below the closed form
        assert gain == pytest.approx(closed_form(samples) * np.ones(2), rel=0.10)
        assert np.all(gain <= closed_form(samples))
    assert mean_response_l2(response.h_a, 1000) == pytest.approx(closed_form(1000) * np.ones(2), rel=0.02)
    # the switch: the first N whose mean is no noisier than the filter, near the closed form's root
    switch = hold_samples(response)
    root = next(n for n in range(1, 1000) if closed_form(n) <= response.l2[0])
    assert switch[0] == switch[1] and abs(switch[0] - root) <= 0.15 * root
    assert np.all(mean_response_l2(response.h_a, int(switch[0])) <= response.l2)
    assert np.all(mean_response_l2(response.h_a, int(switch[0]) - 1) > response.l2)


def test_the_slower_filter_needs_a_longer_mean_to_beat_it():
    assert hold_samples(noise_response("ts-smo", NOISE, NOMINAL))[0] == 31  # 0.31 s
    assert hold_samples(noise_response("ts-smo", LOW_NOISE, NOMINAL))[0] == 13  # 0.13 s


def test_the_hold_passes_the_filter_until_the_mean_is_better_then_holds_the_mean():
    hold = OffsetHold(1, theta=np.array([0.03, 0.03]), samples=np.array([4, 4]), sigma=np.array([0.02, 0.02]))
    f_hat = np.array([-0.22, -0.18, -0.21, -0.19, -0.25, -0.15])
    f_filt = np.array([-0.05, -0.12, -0.17, -0.19, -0.2, -0.2])
    out = [
        hold.step(np.array([[True, False]]), np.array([[a, 0.5]]), np.array([[b, 0.4]]))
        for a, b in zip(f_hat, f_filt, strict=True)
    ]
    out = np.array(out)[:, 0, :]
    assert out[:3, 0].tolist() == f_filt[:3].tolist()  # 3 samples: the filter
    assert out[3:, 0] == pytest.approx(np.cumsum(f_hat)[3:] / np.arange(4, 7))  # from 4 on: the mean since the flag
    assert out[:, 1].tolist() == [0.4] * 6  # not flagged: f̂_filt, whatever f̂_a
    # within θ of the mean: held; the offset changes and f̂_filt leaves the mean by more than θ: the segment restarts
    held = hold.step(np.array([[True, False]]), np.array([[0.0, 0.0]]), np.array([[-0.15, 0.0]]))[0, 0]
    assert held == pytest.approx(-0.15 - 0.02) and hold.held[0, 0]  # the mean −1.2/7 = −0.171, within σ of f̂_filt
    restart = hold.step(np.array([[True, False]]), np.array([[0.01, 0.0]]), np.array([[-0.1, 0.0]]))[0, 0]
    assert restart == -0.1 and hold.count[0, 0] == 1 and hold.total[0, 0] == 0.01 and not hold.held[0, 0]
    # the flag falls: the filter again, and the segment is gone
    assert hold.step(np.array([[False, False]]), np.array([[0.3, 0.0]]), np.array([[-0.01, 0.0]]))[0, 0] == -0.01
    assert hold.count[0, 0] == 0 and hold.total[0, 0] == 0.0


def test_bad_inputs_are_refused_and_change_nothing():
    with pytest.raises(ValueError, match="two positive values"):
        OffsetHold(2, theta=np.array([0.03, 0.0]), samples=np.array([4, 4]), sigma=np.array([0.01, 0.01]))
    with pytest.raises(ValueError, match="two positive values"):
        OffsetHold(2, theta=np.array([0.03, 0.03]), samples=np.array([0, 4]), sigma=np.array([0.01, 0.01]))
    with pytest.raises(ValueError, match="two positive values"):
        OffsetHold(2, theta=np.array([0.03, 0.03]), samples=np.array([4, 4]), sigma=np.array([0.01]))
    with pytest.raises(ValueError, match="at least one sample"):
        mean_response_l2(np.zeros((10, 5, 2)), 0)
    hold = OffsetHold(2, theta=np.array([0.03, 0.03]), samples=np.array([1, 1]), sigma=np.array([0.01, 0.01]))
    hold.step(np.ones((2, 2), dtype=bool), np.full((2, 2), -0.1), np.full((2, 2), -0.1))
    before = (hold.count.copy(), hold.total.copy(), hold.held.copy())
    with pytest.raises(ValueError, match="f_hat must have the shape"):
        hold.step(np.ones((2, 2), dtype=bool), np.zeros((3, 2)), np.zeros((2, 2)))
    assert all(np.array_equal(a, b) for a, b in zip(before, (hold.count, hold.total, hold.held), strict=True))


def test_the_held_correction_at_2_percent_is_the_telescoped_mean_and_releases_at_the_end(make_plant):
    """hydro-noise's supervisor, a −0.1 motor offset in [2, 22) s at ±2 % sensors: the correction's error over
    [3, 22) s is bounded by the closed forms (the mean's (40') plus what the clamp to f̂_filt ± σ costs, the motor
    reading's noise taken at the rated stroke, an upper bound), a quarter of the filter's, and the correction returns
    to zero after the fault ends."""
    faults = [offset("u_M", -0.1, 2.0, 22.0)]
    options = {**NOISE, "sensor_noise_pct": 2.0}
    held = HydroSupervisor(n=2, options={**options, "hold_offset": True})
    filt = HydroSupervisor(n=2, options=options)
    out = run_loop(make_plant(faults, n=2, seed=21, noise_pct=2.0), held, 26.0)
    ref = run_loop(make_plant(faults, n=2, seed=21, noise_pct=2.0), filt, 26.0)
    window = slice(300, 2200)
    err = np.abs(out["f_filt"][window, :, 1] - out["f"][window, :, 1]).mean()
    err_filt = np.abs(ref["f_filt"][window, :, 1] - ref["f"][window, :, 1]).mean()
    # the mean: E|N(0, σ)| = 0.8 σ with σ = (a/√3) ‖h_a ∗ 1_N/N‖₂, N counted from the flag (about 0.1 s after onset);
    # the clamp: with f̂_filt − f ~ N(0, σ_f), E[(|f̂_filt − f| − σ_f)⁺] = 2 σ_f (φ(1) − Q(1)) = 0.167 σ_f
    n_since = np.arange(300, 2200) - 210
    sigma_f = filt.detector.sigma[1]
    clamp_cost = 2.0 * sigma_f * (norm.pdf(1.0) - norm.sf(1.0))
    bound = 0.8 * 0.02 / np.sqrt(3.0) * closed_form(n_since).mean() + clamp_cost
    assert err < bound and err < 0.25 * err_filt
    assert err_filt == pytest.approx(0.8 * sigma_f * 0.75, rel=0.3)  # the motor sits near 0.75 stroke
    assert np.abs(out["f_filt"][2300:, :, 1]).max() < held.thresholds[1]  # released after the end
    assert sum(e.target == "u_M" for e in held.drain_events()) == 4  # DETECTION and RECOVERY per run


def test_every_shipped_hydro_scenario_holds_its_flagged_offsets():
    for name in ("hydro-fig5", "hydro-fig6", "hydro-fig9", "hydro-leakage", "hydro-aero", "hydro-noise"):
        assert load_scenario(name).supervisor.params["hold_offset"] is True
