"""A short evaluation through the command line: scorecard.json with the hydrostatic metrics and the plots."""

from __future__ import annotations

import json

from windwarden.cli import main

SCENARIO = """
name = "hydro-short"
duration_s = 20.0

[plant]
kind = "hydro"

[wind]
mean = [[0.0, 7.5]]
turbulence_intensity = 0.15
length_scale_m = 340.0

[supervisor]
params = { tau_filter = [0.05, 0.05] }

[[faults]]
name = "pump"
target = "u_p"
kind = "offset"
value = -0.3
start_s = 4.0
end_s = 12.0

[[faults]]
name = "motor"
target = "u_M"
kind = "offset"
value = -0.15
start_s = 9.0
end_s = 16.0
"""


def test_eval_writes_scorecard_and_plots(tmp_path):
    path = tmp_path / "short.toml"
    path.write_text(SCENARIO)
    out = tmp_path / "out"
    assert main(["eval", str(path), "--runs", "2", "--seed", "4", "--out", str(out), "--quiet", "--workers", "1"]) == 0
    card = json.loads((out / "scorecard.json").read_text())
    assert card["scenario"] == "hydro-short" and card["runs"] == 2 and card["compensation"] is True
    assert [f["target"] for f in card["faults"]] == ["u_p", "u_M"]
    assert all(f["detected_pct"] == 100.0 for f in card["faults"])
    m = card["metrics"]
    assert {r["fault"] for r in m["reconstruction"]} == {"pump", "motor"}
    assert all(r["error_pct"] < 3.0 and r["settle_s"] < 1.0 for r in m["reconstruction"])
    for key in ("omega_g_dev_rms", "power_dev_rms"):
        assert set(m[key]) >= {"compensated", "uncompensated"}
        assert m[key]["compensated"] < 0.25 * m[key]["uncompensated"]
    assert m["rotor_overspeed"]["compensated"]["runs_pct"] == 0.0
    assert len(list(out.glob("fig*.png"))) == 4


def test_no_compensation_switches_the_main_figures(tmp_path):
    path = tmp_path / "short.toml"
    path.write_text(SCENARIO.replace("duration_s = 20.0", "duration_s = 14.0"))
    out = tmp_path / "out"
    argv = ["eval", str(path), "--runs", "1", "--out", str(out), "--quiet", "--no-plots", "--no-compensation"]
    assert main(argv) == 0
    card = json.loads((out / "scorecard.json").read_text())
    assert card["compensation"] is False
    assert card["metrics"]["omega_g_dev_rms"]["uncompensated"] > 1.0


def test_bad_fault_is_refused_before_running(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text(SCENARIO.replace('target = "u_p"', 'target = "pitch"'))
    assert main(["eval", str(path), "--runs", "1", "--quiet"]) == 2
    assert "faults[0].target" in capsys.readouterr().err
