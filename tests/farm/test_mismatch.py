"""Farm turbines that differ from the design model: per-turbine values and draws, the design plant bit for bit
without a mismatch, and the farm supervisor built from exactly what it is built from without one."""

from __future__ import annotations

import copy
import hashlib
import json
import math

import numpy as np
import pytest

from plant_sim.farm import FarmBatch
from plant_sim.turbine.dynamics import OMEGA_R, THETA
from service.farm.analytic import AnalyticDetector
from service.farm.interfaces import FarmContext
from service.farm.supervisor import FarmSupervisor
from tests.farm.conftest import farm_spec, wind
from windwarden.evaluation import farm as farm_runs
from windwarden.evaluation import farm_eval
from windwarden.evaluation.kinds import EvalOptions
from windwarden.evaluation.scoring_policy import FARM as FARM_POLICY
from wwcore.scenario import Mismatch, ScenarioError, load_scenario, parse_scenario
from wwcore.scenario.farm import N_TURBINES
from wwcore.stepping import run_ticks
from wwcore.turbine_params import BENCHMARK as P


def _farm(mismatch: dict | None, speed: float = 10.0, ti: float = 0.1, runs=(0,), twins=False, **spec) -> FarmBatch:
    m = None if mismatch is None else Mismatch.model_validate(mismatch)
    spec_, wind_ = farm_spec(1, **spec), wind(speed, ti)
    return FarmBatch(spec_, wind_, [], seed=4, duration_s=20.0, runs=runs, fault_free_twins=twins, mismatch=m)


def _run(plant: FarmBatch, ticks: int) -> None:
    for _ in range(ticks):
        plant.measure()
        plant.control(None)
        plant.advance()


def test_turbines_take_their_own_entry_or_a_draw_of_their_own():
    spec = {
        "cp_scale": 0.96,
        "air_density_kgm3": 1.2,
        "spread": {"cp_scale": 0.02, "air_density_kgm3": 0.05},
        "turbines": [{"turbine": 4, "cp_scale": 0.85, "sensor_bias": {"p_g_m": 10e3}}],
    }
    plant = _farm(spec, runs=(0, 1, 2), twins=True)
    m, turbine = plant.turbines.mismatch, plant.turbine_of_row
    four = turbine == 4
    assert np.all(np.abs(m.cp_scale[four] - 0.85) <= 0.02) and np.all(np.abs(m.cp_scale[~four] - 0.96) <= 0.02)
    assert np.all(m.bias[four, -1] == 10e3) and np.all(m.bias[~four, -1] == 0.0)
    assert np.all(np.abs(m.density_ratio * P.rho - 1.2) <= 0.05 + 1e-12)
    real = ~plant.twin_of_row
    assert len(np.unique(m.cp_scale[real])) == 3 * N_TURBINES  # one draw per turbine and run
    np.testing.assert_array_equal(m.cp_scale[real], m.cp_scale[~real])  # a twin is the same plant
    # each turbine's wakes are read with its own air density
    np.testing.assert_allclose(plant.field._area_power, 0.5 * m.density_ratio * P.rho * math.pi * P.radius**2)
    with pytest.raises(ScenarioError, match=r"mismatch.turbines\[0\].turbine"):
        data = load_scenario("farm-case1").model_dump(mode="json", exclude_none=True)
        parse_scenario({**data, "mismatch": {"turbines": [{"turbine": 10, "cp_scale": 0.9}]}})


def test_a_zero_mismatch_reproduces_the_design_farm_bit_for_bit():
    design, plant = _farm(None, twins=True), _farm({}, twins=True)
    _run(design, 300)
    _run(plant, 300)
    np.testing.assert_array_equal(design.turbines.x, plant.turbines.x)
    np.testing.assert_array_equal(design.scada, plant.scada)


def test_farm_turbines_start_at_their_own_equilibrium():
    """With the row model. FLORIS's wakes start from the design turbine's steady C_T (``wakes.steady_winds``), so a
    mismatched farm's waked turbines settle a few hundredths of a m/s away from their start (docs/farm.md §1.7)."""
    spec = {"cp_scale": 0.85, "tsr_shift": -0.5, "drivetrain_stiffness_factor": 0.8, "spread": {"cp_scale": 0.05}}
    for speed in (8.0, 16.0):
        plant = _farm(spec, speed, ti=0.0, coherent_ti=0.0, wake_model="rows")
        start = plant.turbines.x.copy()
        _run(plant, 300)
        x = plant.turbines.x
        np.testing.assert_allclose(x[:, OMEGA_R], start[:, OMEGA_R], rtol=3e-3)
        np.testing.assert_allclose(x[:, THETA], start[:, THETA], rtol=1e-2)


SHORT = {
    "name": "short-farm",
    "duration_s": 70.0,
    "plant": {"kind": "farm", "wind_case": 1},
    "wind": {"mean": [[0.0, 10.0]], "turbulence_intensity": 0.1},
    # the window after the farm's 60-s warm-up, so that the scorecards compared hold a scored detection
    "faults": [{"target": "rotor", "kind": "debris", "value": 0.97, "turbine": 5, "start_s": 62.0, "end_s": 68.0}],
}


def _scorecard_hash(data: dict) -> str:
    options = EvalOptions(workers=1, progress=False, twins=False)
    card = farm_eval.evaluate(parse_scenario(data), 2, 11, options).scorecard
    return hashlib.sha256(json.dumps(card, sort_keys=True).encode()).hexdigest()


def test_an_empty_mismatch_section_gives_the_same_farm_scorecard():
    assert _scorecard_hash({**SHORT, "mismatch": {}}) == _scorecard_hash(SHORT)


class _SeenError(Exception):
    pass


def test_no_mismatch_value_reaches_the_batch_farm_supervisor(monkeypatch):
    """``windwarden eval`` builds the farm supervisor from exactly what it builds it from without the mismatch."""
    seen = []

    def spy(*args, **kwargs):
        seen.append(copy.deepcopy((args, kwargs)))
        raise _SeenError

    monkeypatch.setattr(farm_runs, "FarmSupervisor", spy)
    nominal = load_scenario("farm-case1")
    data = nominal.model_dump(mode="json", exclude_none=True)
    mismatched = parse_scenario({**data, "mismatch": {"cp_scale": 0.913, "spread": {"air_density_kgm3": 0.05}}})
    for scenario in (nominal, mismatched):
        with pytest.raises(_SeenError):
            farm_runs.simulate_chunk([0], lambda s: None, scenario, 3, "analytic", "dispatch", True, {}, False)
    assert seen[0] == seen[1]
    assert "0.913" not in repr(seen[1])


@pytest.mark.parametrize("duration", [200.0, pytest.param(400.0, marks=pytest.mark.slow)])
def test_the_analytic_detector_keeps_quiet_on_a_plant_that_differs_from_its_model(duration):
    """The first 200 s (``make test-slow``: 400 s) of farm-case1-mismatch (its first fault starts at 400 s), one
    run: calibration biases, actuators that differ per blade, noisy sensors and the demand's steps (every 30 s).
    The supervisor's ``analytic`` detector, judging each turbine on its learnt levels and spreads, raises no flag
    after the farm's 60 s warm-up; the same detector on the design model's levels and spreads, fed the same
    samples, raises several (the test can fail; seed 2611: 90 flags by 200 s, 291 by 400 s)."""
    scenario = load_scenario("farm-case1-mismatch")
    plant = FarmBatch(
        scenario.plant, scenario.wind, [], seed=2611, duration_s=duration, runs=[0], mismatch=scenario.mismatch
    )
    site = scenario.plant.site(plant.dt)
    sup = FarmSupervisor(site, plant.n, detector="analytic", controller="dispatch", accommodation=True, options={})
    design = AnalyticDetector(context=FarmContext(site, plant.n), options={"learn_levels": False})
    raised = {"learnt": 0, "design": 0}
    last = {"learnt": np.zeros((plant.n, 3), bool), "design": np.zeros((plant.n, 3), bool)}

    def count(k, frame, refs) -> None:
        if sup.diagnosis is None or (k + 1) % plant.ticks_per_sample:  # a farm sample closes every tenth tick
            return
        for name, flags in (("learnt", sup.diagnosis.faulty), ("design", design.step(sup.sample).faulty)):
            if sup.sample.t >= FARM_POLICY.warmup_s:
                raised[name] += int((flags & ~last[name]).sum())
            last[name] = flags.copy()

    run_ticks(plant, sup, range(round(duration / plant.dt)), stepped=count)
    assert raised["design"] >= 3, raised
    assert raised["learnt"] == 0, raised
