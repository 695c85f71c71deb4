"""Farm scenario files: the shipped ones load with the paper's rows, and bad farm faults are refused by field."""

from __future__ import annotations

import copy
import itertools
import math

import pytest

from wwcore.scenario import ScenarioError, load_scenario, parse_scenario
from wwcore.scenario.farm import FarmPlant

GOOD = {
    "name": "f",
    "duration_s": 100.0,
    "plant": {"kind": "farm", "wind_case": 2},
    "faults": [{"target": "rotor", "kind": "debris", "value": 0.97, "turbine": 5, "start_s": 10.0, "end_s": 20.0}],
}


def _with_fault(**fields) -> dict:
    data = copy.deepcopy(GOOD)
    data["faults"][0].update(fields)
    return data


@pytest.mark.parametrize("name", ["farm-case1", "farm-case2", "farm-fault-free-case1", "farm-fault-free-case2"])
def test_shipped_farm_scenarios_load(name):
    s = load_scenario(name)
    assert s.plant.kind == "farm" and s.duration_s == 4400.0
    if "fault-free" in name:
        assert s.faults == []
    else:
        kinds = sorted(f.kind.value for f in s.faults)
        assert kinds == ["debris", "debris", "drivetrain_wear", "drivetrain_wear", "offset", "offset"]
        first_pitch = min((f for f in s.faults if f.kind.value == "offset"), key=lambda f: f.start_s)
        assert first_pitch.turbine == 1  # fault 2 in turbine 1, as in the paper
        windows = sorted((f.start_s, f.end_s) for f in s.faults)
        assert all(a[1] <= b[0] for a, b in itertools.pairwise(windows))  # one fault at a time


def test_rows_of_the_two_wind_cases_follow_the_paper():
    assert FarmPlant(wind_case=1).rows() == [(1, 4, 7), (2, 5, 8), (3, 6, 9)]
    assert FarmPlant(wind_case=2).rows() == [(1,), (2, 4), (3, 5, 7), (6, 8), (9,)]
    d = FarmPlant(wind_case=2, spacing_m=805.0).row_distances_m()
    assert d[1] == pytest.approx(805.0 / math.sqrt(2.0)) and d[4] == pytest.approx(2.0 * 805.0 * math.sqrt(2.0))


@pytest.mark.parametrize(
    ("fields", "field", "words"),
    [
        ({"turbine": 12}, "faults[0].turbine", "does not exist"),
        ({"value": 1.2}, "faults[0].value", "outside the range"),
        ({"value": None}, "faults[0].value", "needs a value"),
        ({"target": "drivetrain"}, "faults[0].target", "acts on 'rotor'"),
        ({"kind": "gain"}, "faults[0].kind", "cannot act on the rotor"),
        ({"target": "pitch_actuator_2", "kind": "offset", "value": 7.0}, "faults[0].value", "outside the range"),
        ({"target": "drivetrain", "kind": "drivetrain_wear", "value": 50.0}, "faults[0].value", "mrad"),
        ({"target": "omega_x", "kind": "offset", "value": 1.0}, "faults[0].target", "unknown channel"),
    ],
)
def test_bad_farm_fault_is_refused_naming_the_field(fields, field, words):
    with pytest.raises(ScenarioError) as err:
        parse_scenario(_with_fault(**fields))
    assert any(f == field and words in m for f, m in err.value.problems), err.value.problems


def test_sensor_faults_on_a_farm_turbine_follow_the_turbine_rules():
    ok = _with_fault(target="omega_g_m1", kind="fixed", value=100.0)
    assert parse_scenario(ok).faults[0].turbine == 5
    with pytest.raises(ScenarioError) as err:
        parse_scenario(_with_fault(target="omega_g_m1", kind="fixed", value=1000.0))
    assert err.value.problems[0][0] == "faults[0].value"


def test_demand_profile_needs_points_and_fraction_mode_refuses_them():
    data = copy.deepcopy(GOOD)
    data["plant"]["demand"] = {"mode": "profile"}
    with pytest.raises(ScenarioError) as err:
        parse_scenario(data)
    assert "points" in str(err.value)
    data["plant"]["demand"] = {"mode": "available_fraction", "points": [[0.0, 10.0]]}
    with pytest.raises(ScenarioError):
        parse_scenario(data)
    data["plant"]["demand"] = {"mode": "profile", "points": [[0.0, 10.0], [50.0, 20.0]]}
    assert parse_scenario(data).plant.demand.points[1] == (50.0, 20.0)


def test_the_horns_rev_1_pair_is_80_turbines_with_every_fault_type_on_turbines_drawn_at_random():
    faulty, fault_free = load_scenario("farm-hornsrev1"), load_scenario("farm-hornsrev1-fault-free")
    assert faulty.plant.n_turbines == 80 and faulty.plant.wake_model == "gauss"
    assert faulty.plant.demand.mode == "profile" and fault_free.faults == []
    assert faulty.plant == fault_free.plant and faulty.wind == fault_free.wind
    assert faulty.duration_s == fault_free.duration_s
    kinds = sorted(f.kind.value for f in faulty.faults)
    assert kinds == ["debris", "debris", "drivetrain_wear", "drivetrain_wear", "offset", "offset"]
    assert len({f.turbine for f in faulty.faults}) == 6
    windows = sorted((f.start_s, f.end_s) for f in faulty.faults)
    assert all(a[1] < b[0] for a, b in itertools.pairwise(windows))  # one at a time, quiet time between
    assert faulty.plant.site().turbines == tuple(range(1, 81))
