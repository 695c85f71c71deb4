"""A short farm evaluation through the command line: scorecard.json with the farm metrics, options refused."""

from __future__ import annotations

import json

import pytest

from windwarden.cli import main

SCENARIO = """
name = "farm-short"
duration_s = 80.0

[plant]
kind = "farm"
wind_case = 2

[plant.demand]
mode = "profile"
points = [[0.0, 8.0]]

[wind]
mean = [[0.0, 10.0]]
turbulence_intensity = 0.10

[[faults]]
name = "debris"
target = "rotor"
kind = "debris"
value = 0.97
turbine = 9
start_s = 65.0
end_s = 75.0
"""


def test_eval_writes_the_farm_scorecard(tmp_path):
    path = tmp_path / "farm.toml"
    path.write_text(SCENARIO)
    out = tmp_path / "out"
    args = ["eval", str(path), "--runs", "1", "--seed", "2", "--out", str(out), "--quiet", "--workers", "1"]
    assert main([*args, "--no-plots"]) == 0
    card = json.loads((out / "scorecard.json").read_text())
    assert card["detector"] == "analytic" and card["controller"] == "dispatch" and card["accommodation"] is True
    assert [f["target"] for f in card["faults"]] == ["wt9:debris"]
    assert card["faults"][0]["detected_pct"] == 100.0
    metrics = card["metrics"]
    assert {"over_production", "missing_power", "damage"} <= set(metrics)
    assert metrics["damage"]["per_fault"][0]["target"] == "wt9:debris"
    assert set(metrics["detection"]) == {"debris", "pitch_misalignment", "drivetrain"}


def test_the_scorecard_keeps_each_runs_energy_for_paired_comparisons(tmp_path):
    path = tmp_path / "farm.toml"
    path.write_text(SCENARIO.replace("duration_s = 80.0", "duration_s = 70.0"))
    out = tmp_path / "out"
    assert main(["eval", str(path), "--runs", "2", "--out", str(out), "--quiet", "--workers", "1", "--no-plots"]) == 0
    card = json.loads((out / "scorecard.json").read_text())
    metrics, per_run = card["metrics"], card["per_run"]
    for name in ("over_production", "missing_power"):
        by_run = per_run[f"{name}_mwh"]
        assert len(by_run) == 2 and min(by_run) >= 0.0
        assert sum(by_run) / 2 == pytest.approx(metrics[name]["mwh_per_run"])
    assert max(per_run["missing_power_mwh"]) > 0.0
    for key in ("damage.run.farm_miner_ratio", "damage.run.wt9.damage_number", "damage.debris.miner_ratio_window"):
        assert len(per_run[key]) == 2
    assert card["runs_digest"] and card["options"] == {}


def test_eval_takes_the_paper_detector_the_pi_and_no_accommodation(tmp_path):
    path = tmp_path / "farm.toml"
    path.write_text(
        SCENARIO.replace("duration_s = 80.0", "duration_s = 20.0").replace("65.0", "10.0").replace("75.0", "15.0")
    )
    out = tmp_path / "out"
    args = ["eval", str(path), "--runs", "1", "--out", str(out), "--quiet", "--workers", "1", "--no-plots"]
    assert main([*args, "--detector", "paper", "--controller", "pi", "--no-accommodation"]) == 0
    card = json.loads((out / "scorecard.json").read_text())
    assert (card["detector"], card["controller"], card["accommodation"]) == ("paper", "pi", False)


def test_unknown_farm_detector_is_refused_before_running(tmp_path):
    path = tmp_path / "farm.toml"
    path.write_text(SCENARIO)
    assert main(["eval", str(path), "--runs", "1", "--quiet", "--detector", "magic"]) == 2


@pytest.mark.parametrize(
    "params, named",
    [
        ('pitch_rule = "bend"', "pitch_rule"),
        ('accommodation_rule = "stop"', "accommodation_rule"),
        ("drivetrain_relief = 2.0", "drivetrain_relief"),
    ],
)
def test_an_accommodation_rule_no_controller_knows_is_refused_before_running(tmp_path, capsys, params, named):
    path = tmp_path / "farm.toml"
    path.write_text(SCENARIO.replace("[plant]\n", f"[supervisor]\nparams = {{{params}}}\n\n[plant]\n", 1))
    out = tmp_path / "out"
    assert main(["eval", str(path), "--runs", "1", "--quiet", "--out", str(out)]) == 2
    assert named in capsys.readouterr().err
    assert not out.exists()
