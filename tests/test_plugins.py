"""The plug-in registries, and the worked example of docs/plugins.md scored through the command line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from service.plugins import (
    FARM_CONTROLLERS,
    FARM_DETECTORS,
    HYDRO_DETECTORS,
    HYDRO_OBSERVERS,
    TURBINE_DETECTORS,
    TURBINE_ESTIMATORS,
    Registry,
    UnknownAlgorithmError,
)
from windwarden.cli import main

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "median_voter.py"


def test_every_role_has_a_none_entry():
    registries = (TURBINE_DETECTORS, TURBINE_ESTIMATORS, FARM_DETECTORS, FARM_CONTROLLERS, HYDRO_OBSERVERS)
    for registry in (*registries, HYDRO_DETECTORS):
        assert "none" in registry.names(), registry.role
        assert registry.default in registry.names(), registry.role


def test_registry_refuses_unknown_and_duplicate_names():
    registry: Registry[object] = Registry("test role", "for this test", default="a")

    @registry.register("a")
    class A:
        pass

    assert registry.create("a").__class__ is A
    with pytest.raises(UnknownAlgorithmError, match="no test role named 'b'; registered: a"):
        registry.factory("b")
    with pytest.raises(ValueError, match="already registered"):

        @registry.register("a")
        class B:
            pass


def test_the_worked_example_is_scored_like_a_built_in_detector(tmp_path):
    scenario = tmp_path / "short.toml"
    scenario.write_text(
        'name = "short"\nduration_s = 60.0\n[plant]\nkind = "turbine"\n'
        "[wind]\nmean = [[0.0, 10.0]]\n"
        '[[faults]]\ntarget = "omega_g_m1"\nkind = "fixed"\nvalue = 60.0\nstart_s = 30.0\nend_s = 40.0\n'
    )
    out = tmp_path / "out"
    code = main(
        [
            "eval",
            str(scenario),
            "--runs",
            "2",
            "--seed",
            "3",
            "--plugin",
            str(EXAMPLE),
            "--detector",
            "median-voter",
            "--out",
            str(out),
            "--quiet",
            "--no-plots",
            "--workers",
            "1",
        ]
    )
    assert code == 0
    card = json.loads((out / "scorecard.json").read_text())
    assert card["detector"] == "median-voter"
    [fault] = card["faults"]
    assert fault["detected_pct"] == 100.0 and fault["isolated_pct"] == 100.0
    assert fault["delay_s_mean"] <= 0.01


def test_missing_plugin_is_refused_with_exit_code_2(capsys):
    assert main(["eval", "turbine-fault-free", "--runs", "1", "--plugin", "no/such/file.py"]) == 2
    assert "--plugin" in capsys.readouterr().err
