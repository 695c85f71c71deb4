"""The speed FDI's compiled tick (``service.turbine.fast_detector.detector_tick``) against ``SpeedSensorFDI.step``'s
numpy lines, tick by tick, on rows that take every branch: the warm-up's last tick, a frozen reading, a row flagged,
a row pending, a rotor-speed bias raised by the kernel on a healthy tick, NaN and −0.0 readings; with the adaptive
thresholds and the bias test on and off. Every array equal to the last bit (zeros' signs and NaNs included)."""

from __future__ import annotations

import numpy as np
import pytest

from service.turbine.fdi import FDISettings, SpeedSensorFDI
from service.turbine.interfaces import TurbineContext
from tests.fast_compare import SEED
from wwcore.backend import fast_module
from wwcore.turbine_params import BENCHMARK as P

DESIGN = TurbineContext(P, 1).bank_design
ROWS = 4
OMEGA_R = 1.5  # rad/s


def _state(fdi: SpeedSensorFDI) -> dict[str, object]:
    """Everything ``step`` changes, by name."""
    arbiter, spread, calibration = fdi.arbiter, fdi.spread, fdi.calibration
    state = {
        "flagged": fdi.flagged, "deadline": fdi.deadline, "provisional": fdi.provisional, "started": fdi.started,
        "confirmed": fdi.confirmed, "ratio": fdi.ratio, "history": fdi._history, "window_sum": fdi._window_sum,
        "count": fdi.readings.count, "frozen": fdi.readings.frozen, "previous": fdi.readings.previous,
        "means": arbiter._means, "parities": arbiter._parities, "jump_covariance": arbiter.jump_covariance,
        "total": arbiter.total, "total_power": arbiter.total_power, "jump": arbiter.jump, "onset": arbiter._onset,
        "parity": arbiter.parity, "clearing": fdi.clearing.statistic, "scalars": np.array(
            [fdi.ticks, arbiter._seen, fdi._maybe_flagged, fdi._pending, fdi.readings.counting], dtype=np.int64
        ),
    }  # fmt: skip
    for name, a in zip(("count", "estimate", "scale2", "scale", "mean", "offset"), spread.state, strict=False):
        state[f"spread.{name}"] = a
    for name, a in zip(("count", "estimate", "scale2", "scale", "mean", "offset"), calibration.state, strict=False):
        state[f"calibration.{name}"] = a
    if fdi.bias is not None:
        b = fdi.bias
        state.update(up=b.up, down=b.down, run_up=b.run_up, run_down=b.run_down, predictor=b.predictor)
        state["bias.scale2"] = b.spread.scale2
    return state


def _bits(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    return a.view(np.int64) if a.dtype == np.float64 else a


def _inputs(rng: np.random.Generator, k: int, n_obs: int, width: int, sigma: np.ndarray, pairs: int | None) -> tuple:
    """One tick's readings, χ² and x̂: healthy noise, with the events of the test's rows at fixed ticks; from tick
    ``pairs`` on (None: never), row 3's ω_g,m1 repeats each reading once (a count running every other tick)."""
    y = np.column_stack([np.full(ROWS, OMEGA_R)] * 2 + [np.full(ROWS, OMEGA_R * P.N_g)] * 2)
    y += rng.standard_normal((ROWS, 4)) * sigma
    x_hat = OMEGA_R + 0.2 * sigma[0] * rng.standard_normal((ROWS, width))
    chi2 = rng.chisquare(2.0, (ROWS, n_obs)) * 0.5
    if k == 70:  # row 3, on healthy ticks: a NaN reading, then −0.0 readings and χ²
        y[3, 1] = np.nan
    if k == 80:
        y[3, :] = -0.0
        chi2[3, :] = -0.0
    if pairs is not None and pairs <= k < 115:
        y[3, 2] = 151.0 + 0.01 * ((k - pairs) // 2)
    if k >= 100:  # row 2: a rotor-speed bias of 4 σ on sensor 1, which the kernel's CUSUM raises on a healthy tick
        y[2, 0] += 4.0 * sigma[0]
    if 120 <= k < 135:  # row 0: a generator-speed reading frozen (flagged at once)
        y[0, 3] = 151.25
    if 200 <= k < 204:  # row 1: the all-sensor observer far beyond its threshold (an isolation pending)
        chi2[1] *= 400.0
    return y, chi2, x_hat


@pytest.mark.parametrize(
    ("settings", "pairs"),
    [
        (FDISettings(warmup_s=0.5), None),
        (FDISettings(warmup_s=0.5), 90),  # the bias raised on a tick after a repeat (Python's healthy lines) …
        (FDISettings(warmup_s=0.5), 91),  # … or on one after none (the kernel's): one of the two
        (FDISettings(warmup_s=0.5, adapt_time_s=0.0), None),
        (FDISettings(warmup_s=0.5, rotor_bias_test=False), None),
    ],
    ids=["adaptive", "repeats-even", "repeats-odd", "fixed-thresholds", "no-bias-test"],
)
def test_the_detector_tick_equals_the_reference(settings, pairs):
    fast = fast_module("service.turbine.fast")
    reference = SpeedSensorFDI(DESIGN, ROWS, P.dt, settings)
    compiled = SpeedSensorFDI(DESIGN, ROWS, P.dt, settings, fast=fast)
    rng = np.random.default_rng(SEED)
    sigma = np.array([0.025, 0.025, 0.05, 0.05])
    n_obs, width = len(DESIGN.names), DESIGN.F_blk.shape[0]
    seen = {"pending": 0, "frozen": 0, "healthy after warm-up": 0}
    bias_raised_on_a_healthy_tick = False
    for k in range(420):
        y, chi2, x_hat = _inputs(rng, k, n_obs, width, sigma, pairs)
        band, channel = np.zeros(ROWS, dtype=np.int64), np.full(ROWS, np.nan)
        healthy = reference.ticks >= reference.warmup_ticks and not (reference.flagged.any() or reference.pending)
        for fdi in (reference, compiled):
            fdi.step(y.copy(), chi2.copy(), x_hat.copy(), band, channel)
        expected, got = _state(reference), _state(compiled)
        for name, value in expected.items():
            assert np.array_equal(_bits(got[name]), _bits(value)), f"tick {k}: {name}"
        seen["pending"] += reference.pending
        seen["frozen"] += bool(reference.readings.frozen.any())
        seen["healthy after warm-up"] += healthy
        bias_raised_on_a_healthy_tick |= healthy and reference.flagged[2] == 1 and not reference.pending
    assert all(seen.values()), seen
    assert bias_raised_on_a_healthy_tick == settings.rotor_bias_test
    assert reference.flagged[0] & 8 and reference.flagged[1] != 0  # the frozen reading's and the isolation's flags
