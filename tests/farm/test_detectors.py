"""Farm detectors: budget-derived thresholds, the noise model behind them, detection of faults in turbines and at
times the shipped scenarios do not use, no false alarms fault-free, and the paper's eqs. (1)–(2) and one-at-a-time."""

from __future__ import annotations

import math

import numpy as np
import pytest

from service.farm.analytic import AnalyticDetector, pitch_residual_variance
from service.farm.interfaces import BETA, FarmContext, FarmSample
from service.farm.paper import CASE_SAMPLES, PaperDetector, row_matrices
from tests.farm.conftest import detections, farm_spec, simulate, wind
from wwcore.channels import N_SENSORS
from wwcore.scenario.farm import FarmPlant
from wwcore.scenario.faults import FaultSpec
from wwcore.turbine_params import BENCHMARK as P


def test_analytic_thresholds_follow_from_the_false_alarm_budget():
    det = AnalyticDetector(context=FarmContext(FarmPlant().site(), 9), options={"false_alarms_per_1000s": 0.01})
    # ARL0 = 10⁴ samples/1000 s × 9 turbines × m tests / budget; h = ln ARL0 (Lorden)
    assert det.h1 == pytest.approx(math.log(1e4 * 9 * 1 / 0.01))
    assert det.h2 == pytest.approx(math.log(1e4 * 9 * 6 / 0.01))
    p3 = 0.01 / (1e4 * 9)
    assert math.exp(-(det.h3**2) / (8.0 * det.s3**2)) == pytest.approx(p3, rel=1e-9)  # Rayleigh tail
    looser = AnalyticDetector(context=FarmContext(FarmPlant().site(), 9), options={"false_alarms_per_1000s": 1.0})
    assert looser.h1 < det.h1 and looser.h3 < det.h3


def test_pitch_residual_noise_model_matches_the_plant():
    from plant_sim.farm import FarmBatch

    plant = FarmBatch(farm_spec(1), wind(9.0), [], seed=8, duration_s=120.0)
    z = []
    for _ in range(12000):
        frame = plant.measure()
        plant.control(None)
        if frame.sample:
            b = frame.scada[:, BETA].mean(axis=2)
            z.append(1.5 * b - 0.5 * b.sum(axis=1, keepdims=True))
        plant.advance()
    z = np.array(z)[20:]
    short = z.var()
    block = z.reshape(-1, 20, 9, 3).mean(axis=1).var() * 20  # variance of 2-s sums / 20: the long-run variance
    model = pitch_residual_variance(P, 0.2)
    assert block == pytest.approx(model, rel=0.3)
    assert short < model  # one sample varies less than the sums the CUSUM adds up


@pytest.mark.parametrize(
    ("case", "speed", "fault", "name"),
    [
        (2, 8.0, FaultSpec(target="rotor", kind="debris", value=0.97, turbine=8, start_s=30.0), "debris"),
        (
            2,
            8.0,
            FaultSpec(target="pitch_actuator_1", kind="offset", value=-0.3, turbine=6, start_s=30.0),
            "pitch_misalignment",
        ),
        (
            2,
            8.0,
            FaultSpec(target="drivetrain", kind="drivetrain_wear", value=5.0, turbine=9, start_s=30.0),
            "drivetrain",
        ),
        (
            1,
            15.0,
            FaultSpec(target="drivetrain", kind="drivetrain_wear", value=5.0, turbine=2, start_s=30.0),
            "drivetrain",
        ),
    ],
)
def test_analytic_detector_finds_faults_where_the_shipped_scenarios_have_none(case, speed, fault, name):
    _, _, events = simulate(farm_spec(case), wind(speed), [fault], 40.0, seed=11)
    hits = [e for e in detections(events) if e.t >= fault.start_s]
    assert hits, "not detected"
    first = min(hits, key=lambda e: e.t)
    assert (first.turbine, first.target) == (fault.turbine, name)
    assert first.t - fault.start_s < 3.0
    assert not [e for e in detections(events) if e.t < fault.start_s]


def test_analytic_detector_is_quiet_without_faults():
    _, _, events = simulate(farm_spec(2), wind(11.0), [], 90.0, seed=12, runs=(0, 1))
    assert detections(events) == []


def _sample(power_w: np.ndarray, j: int) -> FarmSample:
    scada = np.zeros((9, N_SENSORS))
    scada[:, -1] = power_w
    return FarmSample(j, j * 0.1, scada, np.zeros(9, dtype=np.int8), np.zeros(9), np.array([10.0]), np.array([1e7]))


@pytest.mark.parametrize(("gap_w", "case"), [(9e3, 1), (-9e3, 1), (11e3, 2), (2e5, 2)])
def test_paper_wind_case_from_the_first_500_samples(gap_w, case):
    det = PaperDetector(context=FarmContext(FarmPlant().site(), 9))
    power = np.full(9, 2e6)
    power[0] += gap_w  # P_1 − P_4 = gap
    for j in range(CASE_SAMPLES):
        det.step(_sample(power, j))
    assert det.case[0] == case


def test_paper_rows_leave_turbines_1_and_9_alone_in_case_2():
    _, alone = row_matrices(FarmPlant(wind_case=2).rows())
    assert alone.tolist() == [True] + [False] * 7 + [True]
    m, alone = row_matrices(FarmPlant(wind_case=1).rows())
    assert not alone.any() and m[0, 3] == m[0, 6] == 0.5 and m[0, 1] == 0.0


def test_paper_reports_one_fault_at_a_time():
    det = PaperDetector(context=FarmContext(FarmPlant().site(), 18))
    flags = np.zeros((18, 3), dtype=bool)
    flags[4, 2] = True  # farm 0: fault 3 on turbine 5
    assert det._one_at_a_time(flags)[4, 2]
    flags[1, 0] = True  # fault 1 on turbine 2 rises later: not reported while turbine 5's is
    out = det._one_at_a_time(flags)
    assert out[4, 2] and not out[1, 0]
    flags[4, 2] = False  # turbine 5 clears: turbine 2's is reported now
    out = det._one_at_a_time(flags)
    assert out[1, 0] and out.sum() == 1
    flags[10, 1] = flags[12, 0] = True  # farm 1: two flags together → the lower fault number
    out = det._one_at_a_time(flags)
    assert out[12, 0] and not out[10, 1]
