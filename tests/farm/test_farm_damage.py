"""Table 7's farm damage figures against closed-form answers on synthetic damage sums."""

from __future__ import annotations

import numpy as np
import pytest

from windwarden.evaluation.farm_damage import damage_metrics, span_figures
from windwarden.evaluation.scoring import FaultWindow


def test_the_farm_ratio_is_the_sum_over_turbines_and_its_excess_splits_into_faulty_and_others():
    twin = np.array([[1.0, 2.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0]])  # Σ = 10
    damage = twin.copy()
    damage[0, 3] = 4.0  # the faulty turbine: 4 × its twin's
    damage[0, 1] = 3.0  # a healthy one: + 1
    f = span_figures(damage, twin, faulty=3)
    assert f["miner_ratio"][0] == pytest.approx(4.0)
    assert f["damage_number"][0] == pytest.approx(4.0**0.25)
    assert f["farm_miner_ratio"][0] == pytest.approx(14.0 / 10.0)
    assert f["farm_damage_number"][0] == pytest.approx(1.4**0.25)
    assert f["others_miner_ratio"][0] == pytest.approx(10.0 / 9.0)
    assert f["faulty_excess"][0] == pytest.approx(0.3)
    assert f["others_excess"][0] == pytest.approx(0.1)
    assert f["faulty_excess"][0] + f["others_excess"][0] == pytest.approx(f["farm_miner_ratio"][0] - 1.0)


def test_damage_moved_onto_the_healthy_turbines_shows_in_the_farm_figure():
    twin = np.ones((1, 9))
    without = twin.copy()
    without[0, 0] = 3.0  # the fault alone: farm (3 + 8)/9
    moved = twin * 1.3
    moved[0, 0] = 1.0  # the faulty turbine back at its twin's, the other eight + 30 %: farm (1 + 10.4)/9
    a, b = span_figures(without, twin, 0), span_figures(moved, twin, 0)
    assert b["miner_ratio"][0] < a["miner_ratio"][0]  # the faulty turbine's figure improves...
    assert b["farm_miner_ratio"][0] > a["farm_miner_ratio"][0]  # ...while the farm's total rises
    assert b["others_excess"][0] == pytest.approx(8 * 0.3 / 9)


def test_damage_metrics_per_window_and_run_with_per_run_values():
    runs, bins, bin_s = 2, 10, 10.0  # 100 s; warm-up 20 s leaves bins 2..9
    twin = np.ones((runs, 9, bins))
    damage = twin.copy()
    damage[:, 4, 5:7] = 5.0  # turbine 5, 50–70 s: 5 × in two bins
    damage[1, 0, 5:7] = 2.0  # run 1: turbine 1 doubles in the window too
    window = FaultWindow("F3 drive train wt5", ("drivetrain",), 5, 50.0, 70.0)
    imbalance = np.zeros((runs, 9, 1), dtype=complex)
    metrics, per_run = damage_metrics(damage, twin, bin_s, 20.0, [window], ["wt5:drivetrain"], imbalance, imbalance)
    entry = metrics["per_fault"][0]
    assert entry["miner_ratio_window"] == pytest.approx(5.0)
    assert entry["miner_ratio_run"] == pytest.approx((6 + 10) / 8)  # 6 bins at 1, 2 at 5, over 8
    farm_window = [(10 + 16) / 18, (10 + 4 + 14) / 18]  # run 0: turbine 5 → 10; run 1: turbine 1 → 4 as well
    assert per_run["damage.F3 drive train wt5.farm_miner_ratio_window"] == pytest.approx(farm_window)
    assert entry["farm_miner_ratio_window"] == pytest.approx(np.mean(farm_window))
    assert per_run["damage.F3 drive train wt5.others_miner_ratio_window"] == pytest.approx([1.0, 18 / 16])
    assert entry["faulty_excess_window"] + entry["others_excess_window"] == pytest.approx(
        entry["farm_miner_ratio_window"] - 1.0
    )
    assert entry["turbines_window"]["wt1"]["miner_ratio"] == pytest.approx(1.5)
    farm_run = [(72 + 8) / 72, (72 + 8 + 2) / 72]
    assert per_run["damage.run.farm_miner_ratio"] == pytest.approx(farm_run)
    assert metrics["farm_miner_ratio"] == pytest.approx(np.mean(farm_run))
    assert per_run["damage.run.wt5.damage_number"] == pytest.approx([(16 / 8) ** 0.25] * 2)
    assert per_run["damage.run.wt2.damage_number"] == pytest.approx([1.0, 1.0])
    assert metrics["by_type"]["drivetrain"]["farm_miner_ratio_window"] == pytest.approx(np.mean(farm_window))
    assert all(len(v) == runs for v in per_run.values())


def test_no_twins_no_damage_figures():
    assert damage_metrics(np.ones((1, 9, 3)), None, 10.0, 0.0, [], [], np.zeros((1, 9, 0)), None) == ({}, {})
