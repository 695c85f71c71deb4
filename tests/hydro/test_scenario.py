"""Scenario schema of the hydrostatic plant: shipped files load, bad faults are refused naming the field."""

from __future__ import annotations

import pytest

from wwcore.scenario import ScenarioError, load_scenario, parse_scenario

SHIPPED = [
    "hydro-fig5",
    "hydro-fig6",
    "hydro-fig9",
    "hydro-leakage",
    "hydro-aero",
    "hydro-noise",
    "hydro-fault-free",
    "hydro-noise-fault-free",
]


def _scenario(**fault):
    base = {"target": "u_p", "kind": "offset", "value": -0.2, "start_s": 10.0, "end_s": 40.0}
    base.update(fault)
    return {"name": "t", "duration_s": 100.0, "plant": {"kind": "hydro"}, "faults": [base]}


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scenarios_load(name):
    s = load_scenario(name)
    assert s.plant.kind == "hydro" and s.wind.turbulence_intensity == 0.15
    assert all(f.target in ("u_p", "u_M") for f in s.faults)


def test_uncertainty_options():
    assert load_scenario("hydro-leakage").plant.leak_factor == 1.15
    assert load_scenario("hydro-aero").plant.delta_cq == 0.2
    assert load_scenario("hydro-noise").plant.noise_pct == 2.0
    # the noise cases' supervisors are designed for the sensors they read (service.hydro.detector)
    for name in ("hydro-noise", "hydro-noise-fault-free"):
        s = load_scenario(name)
        assert s.supervisor.params["sensor_noise_pct"] == s.plant.noise_pct == 2.0


@pytest.mark.parametrize(
    ("fault", "field"),
    [
        ({"target": "beta_1"}, "faults[0].target"),
        ({"value": 1.5}, "faults[0].value"),
        ({"value": -1.01}, "faults[0].value"),
        ({"value": 0.0}, "faults[0].value"),
        ({"value": None}, "faults[0].value"),
        ({"kind": "gain"}, "faults[0].kind"),
        ({"end_s": 5.0}, "faults[0].end_s"),
    ],
)
def test_bad_fault_names_the_field(fault, field):
    with pytest.raises(ScenarioError) as err:
        parse_scenario(_scenario(**fault))
    assert field in [f for f, _ in err.value.problems]


def test_unknown_plant_option_is_refused():
    data = _scenario()
    data["plant"]["leakage"] = 1.15
    with pytest.raises(ScenarioError) as err:
        parse_scenario(data)
    assert ("plant.leakage", "unknown key") in err.value.problems


def test_noise_out_of_range_is_refused():
    data = _scenario()
    data["plant"]["noise_pct"] = 20.0
    with pytest.raises(ScenarioError) as err:
        parse_scenario(data)
    assert any(f == "plant.noise_pct" for f, _ in err.value.problems)
