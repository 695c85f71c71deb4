"""Scenario files: every shipped one loads, bad ones are refused naming the field, and TOML round-trips."""

from __future__ import annotations

import tomllib

import pytest

from windwarden.cli import main
from wwcore.scenario import ScenarioError, dump_scenario, load_scenario, parse_scenario, shipped_scenarios

GOOD = {
    "name": "t",
    "duration_s": 100.0,
    "plant": {"kind": "turbine"},
    "faults": [{"target": "omega_r_m1", "kind": "gain", "value": 1.1, "start_s": 10.0, "end_s": 20.0}],
}


def _with(path: str, value) -> dict:
    if path == "faults.0.end_s" and value is _DELETE:
        data = _with("faults.0.start_s", 500.0)
        del data["faults"][0]["end_s"]
        return data
    import copy

    data = copy.deepcopy(GOOD)
    node = data
    keys = path.split(".")
    for key in keys[:-1]:
        node = node[int(key)] if key.isdigit() else node[key]
    last = keys[-1]
    if value is _DELETE:
        del node[last]
    else:
        node[last] = value
    return data


_DELETE = object()


@pytest.mark.parametrize("name", sorted(shipped_scenarios()))
def test_shipped_scenarios_load_and_round_trip(name):
    scenario = load_scenario(name)
    assert scenario.name == name
    again = parse_scenario(tomllib.loads(dump_scenario(scenario)))
    assert again == scenario


@pytest.mark.parametrize(
    ("path", "value", "field", "words"),
    [
        ("colour", "red", "colour", "unknown key"),
        ("plant.rotor", 3, "plant.rotor", "unknown key"),
        ("faults.0.severity", 2, "faults[0].severity", "unknown key"),
        ("faults.0.target", "omega_x", "faults[0].target", "unknown channel"),
        ("faults.0.end_s", 5.0, "faults[0].end_s", "must be after start_s"),
        ("faults.0.value", 50.0, "faults[0].value", "outside the physical range"),
        ("faults.0.kind", "melt", "faults[0].kind", "Input should be"),
        ("faults.0.start_s", "soon", "faults[0].start_s", "valid number"),
        ("faults.0.end_s", _DELETE, "faults[0].start_s", "after the run ends"),
        ("duration_s", -1.0, "duration_s", "greater than 0"),
    ],
)
def test_bad_scenarios_are_refused_naming_the_field(path, value, field, words):
    with pytest.raises(ScenarioError) as caught:
        parse_scenario(_with(path, value))
    fields = [f for f, _ in caught.value.problems]
    messages = " ".join(m for _, m in caught.value.problems)
    assert field in fields, caught.value.problems
    assert words in messages


@pytest.mark.parametrize(
    "fault",
    [
        {"target": "omega_g_m1", "kind": "fixed", "value": 500.0, "start_s": 1.0},  # above the channel's range
        {"target": "omega_g_m1", "kind": "stuck", "value": 1.0, "start_s": 1.0},  # stuck takes no value
        {"target": "converter", "kind": "gain", "value": 1.0, "start_s": 1.0},  # not a component fault kind
        {"target": "pitch_actuator_2", "kind": "pitch_dynamics", "start_s": 1.0},  # needs omega_n and zeta
        {"target": "drivetrain", "kind": "efficiency", "value": 1.5, "start_s": 1.0},  # efficiency above 1
        {"target": "omega_r_m1", "kind": "gain", "value": 1.1, "start_s": 1.0, "turbine": 2},  # one turbine only
    ],
)
def test_physically_impossible_faults_are_refused(fault):
    with pytest.raises(ScenarioError):
        parse_scenario({**GOOD, "faults": [fault]})


def _refused(tmp_path, capsys, tail: str) -> str:
    """What ``windwarden eval`` prints refusing a turbine scenario ending in ``tail`` (exit code 2, nothing
    written)."""
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "bad"\nduration_s = 100.0\n[plant]\nkind = "turbine"\n' + tail)
    out = tmp_path / "out"
    assert main(["eval", str(bad), "--runs", "1", "--out", str(out)]) == 2
    assert not out.exists()
    return capsys.readouterr().err


def test_cli_refuses_bad_scenario_with_exit_code_2_before_running(tmp_path, capsys):
    err = _refused(tmp_path, capsys, '[[faults]]\ntarget = "omega_r_m9"\nkind = "gain"\nvalue = 1.1\nstart_s = 1.0\n')
    assert "faults[0].target" in err and "omega_r_m9" in err


def test_a_folder_named_like_a_shipped_scenario_does_not_hide_it_and_a_folder_is_refused(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "hydro-noise").mkdir()  # e.g. an earlier eval's --out
    assert load_scenario("hydro-noise").name == "hydro-noise"
    (tmp_path / "results").mkdir()
    with pytest.raises(ScenarioError, match="a folder, not a scenario file"):
        load_scenario("results")


def test_cli_refuses_unknown_scenario_and_unknown_algorithm(tmp_path, capsys):
    assert main(["eval", "no-such-scenario", "--runs", "1"]) == 2
    assert "no such file or shipped scenario" in capsys.readouterr().err
    assert main(["eval", "turbine-fault-free", "--runs", "1", "--detector", "nope", "--out", str(tmp_path / "o")]) == 2
    assert "no turbine detector named 'nope'" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_cli_refuses_an_option_the_detector_refuses_before_running(tmp_path, capsys):
    assert "clear_window" in _refused(tmp_path, capsys, "[supervisor]\nparams = {clear_window = 9}\n")


def test_cli_refuses_bad_numbers_with_exit_code_2():
    with pytest.raises(SystemExit) as caught:
        main(["eval", "ftwse-2012", "--runs", "0"])
    assert caught.value.code == 2
