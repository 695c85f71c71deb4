"""The paper detector's direction estimate runs: it follows a moving wind (the vane's running circular mean, the
running eqs. (1)–(2) on the 3 × 3) and its rows follow; and a short sweep end to end, plant and supervisor."""

from __future__ import annotations

import math

import numpy as np
import pytest

from service.farm.interfaces import P_G, FarmContext, FarmSample
from service.farm.paper import CASE_SAMPLES, PaperDetector
from tests.farm.conftest import detections, simulate, wind
from wwcore.channels import N_SENSORS
from wwcore.scenario.farm import FarmDemand, FarmPlant
from wwcore.scenario.faults import FaultSpec


def sample(j: int, direction: np.ndarray, n: int, p1_minus_p4: float = 0.0) -> FarmSample:
    farms = len(direction)
    scada = np.zeros((n, N_SENSORS))
    scada[:, -1] = 2e6
    scada[::9, P_G] += p1_minus_p4  # turbine 1 of every farm of nine
    return FarmSample(
        j, j * 0.1, scada, np.zeros(n, dtype=np.int8), np.zeros(n), np.full(farms, 10.0), np.full(farms, 1e7), direction
    )


def three_by_three(**kw) -> FarmPlant:
    return FarmPlant(wake_model="gauss", demand=FarmDemand(mode="profile", points=[(0.0, 25.0)]), **kw)


def test_the_vane_estimate_lags_a_steady_veer_by_the_averaging_time():
    """A first-order mean of a ramp of rate r lags it by τ r (closed form): at 0.1°/s and τ = 20 s, 2°; the rows are
    formed again as it moves (never more than ``regroup_deg`` behind the estimate)."""
    site = three_by_three(wind_direction_profile=[(0.0, 270.0), (1000.0, 300.0)]).site()
    context = FarmContext(site, 9)
    det = PaperDetector(context=context, options={"direction_source": "vane", "direction_averaging_s": 20.0})
    rate, regrouped = 0.1, set()
    for j in range(4000):  # 400 s: the filter's transient (e^{-20}) is gone
        det.step(sample(j, np.array([270.0 + rate * j * 0.1]), 9))
        if j >= CASE_SAMPLES:
            assert abs(det.direction[0] - det.grouped[0]) <= 1.0 + 1e-9
            regrouped.add(round(float(det.grouped[0]), 6))
    truth = 270.0 + rate * 3999 * 0.1
    assert det.direction[0] == pytest.approx(truth - 20.0 * rate, abs=0.01)
    assert len(regrouped) > 25  # about one regroup per degree of the 35° swept after the first 500 samples
    assert det.rows[0] == context.rows(float(det.grouped[0]))


def test_the_running_wind_case_follows_a_change_after_two_quiet_blocks():
    """Eqs. (1)–(2) on every block of 500 samples: p = 0 (case 1) for three blocks, then p = 50 kW (case 2): the case
    changes at the end of the second block that shows it, not the first; with ``running_case`` false it stays."""
    context = FarmContext(three_by_three().site(), 9)
    running = PaperDetector(context=context, options={"direction_source": "power"})
    once = PaperDetector(context=context, options={"direction_source": "power", "running_case": False})
    cases = []
    for j in range(6 * CASE_SAMPLES):
        p = 0.0 if j < 3 * CASE_SAMPLES else 50e3
        for det in (running, once):
            det.step(sample(j, np.array([np.nan]), 9, p))
        if (j + 1) % CASE_SAMPLES == 0:
            cases.append(int(running.case[0]))
    assert cases == [1, 1, 1, 1, 2, 2]
    assert once.case[0] == 1 and running.direction[0] == 315.0


def test_a_block_with_a_fault_reported_does_not_move_the_wind_case():
    context = FarmContext(three_by_three().site(), 9)
    det = PaperDetector(context=context, options={"direction_source": "power"})
    for j in range(4 * CASE_SAMPLES):
        if j >= CASE_SAMPLES:
            det.reported[0] = 0  # a fault is reported on the farm: its power says nothing of the wind
        det.step(sample(j, np.array([np.nan]), 9, 0.0 if j < CASE_SAMPLES else 80e3))
    assert det.case[0] == 1


SWEEP = [(0.0, 270.0), (20.0, 270.0), (60.0, 282.0)]  # 0.3°/s: quicker than a real veer, to keep the test short


def test_a_short_sweep_end_to_end_the_paper_rows_follow_the_direction():
    """The 3 × 3 with FLORIS wakes, the wind from 270° veering to 282° between 20 and 60 s: at 75 s the paper
    detector's vane estimate (τ = 5 s, through the plant's noisy vane) is within 1.5° of the true direction, with
    its rows formed for it (no longer case 1's)."""
    options = {"direction_source": "vane", "direction_averaging_s": 5.0}
    plant, sup, _ = simulate(three_by_three(wind_direction_profile=SWEEP), wind(10.0), [], 75.0, seed=19,
                             detector="paper", options=options)  # fmt: skip
    truth = float(plant.direction.at(np.array([0]), 750)[0])
    assert math.isclose(truth, 282.0)
    assert abs(sup.detector.direction[0] - truth) < 1.5
    assert sup.detector.rows[0] == sup.context.rows(float(sup.detector.grouped[0]))
    assert sup.detector.rows[0] != sup.context.rows(270.0)


def test_debris_during_a_sweep_is_flagged_on_the_right_turbine():
    fault = FaultSpec(target="rotor", kind="debris", value=0.97, turbine=5, start_s=40.0)
    _, _, events = simulate(three_by_three(wind_direction_profile=SWEEP), wind(10.0), [fault], 60.0, seed=19)
    hits = detections(events)
    assert {(e.turbine, e.target) for e in hits} == {(5, "debris")}
    assert min(e.t for e in hits) - fault.start_s < 3.0
