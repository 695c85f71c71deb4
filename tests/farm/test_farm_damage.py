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
    assert entry["farm_miner_ratio_window_pooled"] == pytest.approx((26 + 28) / 36)  # the runs' sums, then the ratio
    assert entry["turbines_window"]["wt1"]["miner_ratio_pooled"] == pytest.approx(6 / 4)
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


def _variant(scenario, accommodation: bool, faulty_miner: float, others_miner: float, missing: list[float]):
    from windwarden.evaluation.farm import DAMAGE_BIN_S, Variant

    runs, bins = len(missing), round(scenario.duration_s / DAMAGE_BIN_S)
    twin = np.ones((runs, 9, bins))
    damage = twin.copy()
    window = (np.arange(bins) * DAMAGE_BIN_S >= 3600.0) & (np.arange(bins) * DAMAGE_BIN_S < 4000.0)
    damage[:, :, window] *= others_miner
    damage[:, 3, window] = faulty_miner  # turbine 4's drive-train window
    n_windows = len(scenario.faults)
    return Variant(
        scenario=scenario,
        runs=runs,
        seed=1,
        detector="analytic",
        controller="dispatch",
        accommodation=accommodation,
        events=[],
        twin_events=[],
        over_j=np.zeros(runs),
        missing_j=np.asarray(missing) * 3.6e9,
        demand_j=np.full(runs, 1e12),
        damage=damage,
        twin_damage=twin,
        imbalance=np.zeros((runs, 9, n_windows), dtype=complex),
        twin_imbalance=np.ones((runs, 9, n_windows), dtype=complex),
        trace={},
    )


def test_table_7_gives_the_farm_beside_the_faulty_turbine_and_the_paired_differences():
    from windwarden.evaluation.farm_tables import table7_lines
    from wwcore.scenario import load_scenario

    scenario = load_scenario("farm-case1")
    none = _variant(scenario, False, 16.0, 1.0, [0.10, 0.20])
    moved = _variant(scenario, True, 1.0, 1.5, [0.08, 0.20])  # faulty back to 1, the eight others × 1.5
    text = "\n".join(table7_lines(scenario, moved, {"no_accommodation": none}))
    rows = {line.split(" | ")[1]: line for line in text.splitlines() if line.startswith("| F3 drive train wt4 |")}
    assert set(rows) == {"no accommodation", next(k for k in rows if "3P cancelled" in k)}
    # window: no accommodation farm (16 + 8)/9 = 2.667, faulty excess 15/9; moved (1 + 12)/9 = 1.444, others 4/9
    assert "| 16 | 1 | 2.667 | +1.667 +0.000 |" in rows["no accommodation"]
    moved_row = next(v for k, v in rows.items() if k != "no accommodation")
    assert "| 1 | 1.5 | 1.444 | +0.000 +0.444 |" in moved_row
    none_row = next(line for line in text.splitlines() if line.startswith("| no accommodation | inf |"))
    # over the run (434 bins after the warm-up, nine turbines): farm (3906 + 15 × 40)/3906 = 1.154 in every run;
    # damage 3 is the mean of the two drive-train windows' turbines: ((1034/434)^¼ + 1)/2 = 1.121, window (2 + 1)/2
    assert "| 1.1212 | 1.5 | 1.154; 1.154 | 0.15 |" in none_row
    paired = next(line for line in text.splitlines() if line.startswith("| missing power, MWh |"))
    assert "| 0.15 | 0.14 | -0.01 ± 0.01 | 1 of 2 |" in paired


def test_fig_4_draws_the_faulty_turbines_and_the_farm(tmp_path):
    from windwarden.evaluation.farm_plots import write_plots
    from wwcore.scenario import load_scenario

    scenario = load_scenario("farm-case1")
    none = _variant(scenario, False, 16.0, 1.0, [0.10, 0.20])
    moved = _variant(scenario, True, 1.0, 1.5, [0.08, 0.20])
    (path,) = write_plots(tmp_path, scenario, moved, {"no_accommodation": none})
    assert path.name == "fig4_damage.png" and path.stat().st_size > 10_000
