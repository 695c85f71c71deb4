"""The detection threshold is a design value: the observer's noise response (closed form on a pass-through
observer, structure of the TS-SMO's), the predicted fault-free σ of f̂_filt against the simulated plant at both
noise levels, and θ from the design rate."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

from service.hydro.builtin import HydroContext
from service.hydro.detector import DetectionSettings, ThresholdDetector, design_thresholds
from service.hydro.noise import DESIGN_WIND, _response, noise_response
from service.hydro.smo import Reconstruction
from service.hydro.supervisor import HydroSupervisor
from service.plugins import HYDRO_OBSERVERS
from tests.hydro.conftest import run_loop
from wwcore.hydro_params import NOMINAL
from wwcore.scenario import load_scenario


@HYDRO_OBSERVERS.register("test-pass-through")
class PassThrough:
    """f̂_filt = x̃_measured − u: the reconstruction of an observer that trusts the stroke readings blindly."""

    def __init__(self, *, n, params, settings):
        self.n = n

    def step(self, y: np.ndarray, u: np.ndarray) -> Reconstruction:
        f = y[:, 3:5] - u[:, :2]
        return Reconstruction(f, f.copy(), np.zeros((self.n, 6)), np.ones(self.n, dtype=bool), np.zeros(self.n))


def test_the_noise_response_of_a_pass_through_observer_is_one_tap():
    response = noise_response("test-pass-through", {}, NOMINAL)
    assert response.l2 == pytest.approx([1.0, 1.0], abs=1e-6) and response.l1 == pytest.approx([1.0, 1.0], abs=1e-6)
    assert response.sigma(2.0) == pytest.approx(np.full(2, 0.02 / np.sqrt(3.0)), rel=1e-6)
    assert response.worst(2.0) == pytest.approx([0.02, 0.02], rel=1e-6)
    # θ = σ Q⁻¹(R dt / (4 · 1000 s)), floored at min_offset
    settings = DetectionSettings(false_alarms_per_1000s=0.1, sensor_noise_pct=2.0, min_offset=0.0)
    z = norm.isf(0.1 * 0.01 / 4000.0)
    assert design_thresholds(response, settings, 0.01) == pytest.approx(z * 0.02 / np.sqrt(3.0), rel=1e-6)
    floored = DetectionSettings(sensor_noise_pct=0.01, min_offset=0.01)
    assert design_thresholds(response, floored, 0.01).tolist() == [0.01, 0.01]
    by_hand = DetectionSettings(threshold=(0.2, 0.3))
    assert design_thresholds(response, by_hand, 0.01).tolist() == [0.2, 0.3]


def test_the_ts_smo_reconstruction_sees_only_its_own_stroke_reading_at_any_wind():
    settings = (("tau_filter", (0.05, 0.05)),)
    design = _response("ts-smo", settings, NOMINAL, DESIGN_WIND)
    others = np.delete(design.h, [3, 4], axis=1)
    assert np.abs(others).max() < 1e-6 * np.abs(design.h).max()
    assert np.abs(design.h[:, 4, 0]).max() == pytest.approx(0.0, abs=1e-6)  # x̃_M noise does not reach f̂_p
    for wind in (5.0, 11.0):
        assert _response("ts-smo", settings, NOMINAL, wind).l2 == pytest.approx(design.l2, rel=1e-4)


SHIPPED_LOW_NOISE = {"tau_filter": [0.025, 0.025], "filter_order": 2, "layer_correction": True}
SHIPPED_NOISE = {"tau_filter": [0.05, 0.05], "filter_order": 2, "layer_correction": True}  # hydro-noise's


@pytest.mark.parametrize(
    ("noise_pct", "observer"),
    [
        (0.1, {"tau_filter": [0.05, 0.05]}),
        (0.1, SHIPPED_LOW_NOISE),
        (2.0, {"tau_filter": [0.1, 0.1]}),
        (2.0, SHIPPED_NOISE),
    ],
)
def test_the_predicted_sigma_is_what_the_simulated_plant_shows(make_plant, noise_pct, observer):
    """Fault-free f̂_filt of the plant in closed loop against the prediction from the sensors' accuracy alone."""
    options = {**observer, "sensor_noise_pct": noise_pct}
    sup = HydroSupervisor(n=2, options=options, compensation=False)
    out = run_loop(make_plant([], n=2, seed=11, noise_pct=noise_pct), sup, 30.0)
    f = out["f_filt"][100:]  # after the first second
    sigma, worst = sup.detector.sigma, sup.detector.noise.worst(noise_pct)
    # u_p: the pump reading sits at its rated stroke (1) all through partial load, as the design assumes
    assert f[:, :, 0].std() == pytest.approx(sigma[0], rel=0.05)
    # u_M: the motor stroke is below 1 in partial load, so its relative noise (and f̂_filt's) is smaller
    assert 0.4 * sigma[1] < f[:, :, 1].std() < sigma[1]
    assert np.abs(f).max() <= 1.01 * worst.max()
    assert sup.drain_events() == []  # and no alarm: θ is well above all of it
    assert np.all(sup.thresholds >= 5.4 * sigma)


def test_the_detector_uses_the_design_of_its_own_context():
    context = HydroContext(1, NOMINAL, "ts-smo", {"tau_filter": (0.1, 0.1)})
    noisy = ThresholdDetector(context=context, options={"sensor_noise_pct": 2.0})
    assert noisy.theta == pytest.approx([0.0573, 0.0573], abs=2e-4)
    assert ThresholdDetector(context=context, options={}).theta.tolist() == [0.01, 0.01]  # the floor at 0.1 %


def test_the_noise_case_filter_halves_the_reconstruction_noise_at_the_papers_lag():
    """(37') of two 0.05-s stages lags like (37) at 0.1 s (the stages' time constants add up to the same mean delay)
    but rolls off the differentiated reading noise (37) passes at its flat gain: its predicted σ of f̂_filt and so
    its threshold are about half; the shipped scenarios use it."""
    paper = HydroSupervisor(n=2, options={"tau_filter": [0.1, 0.1], "sensor_noise_pct": 2.0}, compensation=False)
    split = HydroSupervisor(n=2, options={**SHIPPED_NOISE, "sensor_noise_pct": 2.0}, compensation=False)
    assert sum(SHIPPED_NOISE["tau_filter"]) == pytest.approx(0.1)
    assert np.all(split.detector.sigma < 0.6 * paper.detector.sigma)
    assert np.all(split.detector.theta < 0.6 * paper.detector.theta)
    for name in ("hydro-noise", "hydro-noise-fault-free"):
        params = load_scenario(name).supervisor.params
        assert {k: params[k] for k in SHIPPED_NOISE} == SHIPPED_NOISE
