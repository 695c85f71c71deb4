"""What the supervisor may learn of the site (``wwcore.site.SiteInfo`` inside ``windwarden.kinds.RunInfo``): the
published parameters only, typed and frozen, and a ``plant.run`` body carrying anything else is refused."""

from __future__ import annotations

import pydantic
import pytest

from windwarden.kinds import KINDS, RunInfo, kind_for
from wwcore.scenario import load_scenario
from wwcore.site import SiteInfo
from wwcore.wire import WireError, decode_json, encode_json

SHIPPED = ("demo", "farm-case1", "hydro-fig5")


@pytest.mark.parametrize("name", SHIPPED)
def test_run_info_round_trips_through_the_wire(name):
    scenario = load_scenario(name)
    info = RunInfo.of(scenario, [1], 0.01, run_id="r1", mode="lockstep", run_key=42)
    body = decode_json("plant.run", encode_json("plant.run", info.to_json()))
    again = RunInfo.from_json(body)
    assert again == info
    assert isinstance(again.site, SiteInfo) and again.site.kind == scenario.plant.kind


@pytest.mark.parametrize(
    ("where", "field", "value"),
    [
        ("run", "mismatch", {"sensor_scale": {"omega_g_m1": 1.02}}),
        ("run", "faults", [{"target": "omega_g_m2", "kind": "fixed", "value": 100.0, "start_s": 1.0}]),
        ("run", "plant", {"kind": "farm", "wind_case": 2}),
        ("site", "mismatch", {"k_leak": 1.15}),
        ("site", "wind_case", 2),
        ("site", "fault_schedule", []),
    ],
)
def test_a_run_description_with_truth_in_it_is_refused(where, field, value):
    body = RunInfo.of(load_scenario("farm-case1"), list(range(1, 10)), 0.01).to_json()
    (body if where == "run" else body["site"])[field] = value
    with pytest.raises(pydantic.ValidationError) as error:
        RunInfo.from_json(body)
    assert field in str(error.value) and "Extra inputs are not permitted" in str(error.value)


def test_an_old_run_description_is_refused_by_its_version():
    payload = b'{"schema": "plant.run", "v": 1, "body": {}}'
    with pytest.raises(WireError, match="version 1 is not 2"):
        decode_json("plant.run", payload)


def test_the_site_is_frozen():
    site = load_scenario("demo").plant.site()
    with pytest.raises(pydantic.ValidationError):
        site.dt = 0.02  # type: ignore[misc]


def test_the_farm_site_does_not_tell_the_wind_case():
    """Cases 1 and 2 differ in the wind direction only: the supervisor gets the same site for both (its detector
    estimates the case, or its own ``wind_case`` option gives it)."""
    case1, case2 = load_scenario("farm-case1"), load_scenario("farm-case2")
    assert case1.plant.wind_case != case2.plant.wind_case
    assert case1.plant.site() == case2.plant.site()
    assert "wind_case" not in SiteInfo.model_fields


def test_the_site_holds_the_published_parameters():
    farm = load_scenario("farm-case1").plant.site()
    assert farm.turbines == tuple(range(1, 10)) and farm.rated_power_w == 4.8e6
    assert farm.positions_m[1] == (farm.spacing_m, 0.0) and farm.mast_distance_m is not None
    assert farm.positions_m[3] == (0.0, -farm.spacing_m)  # east, north: the second grid row stands south
    assert farm.sensor_sigma["omega_g_m1"] == pytest.approx(0.05)  # PARAMETERS.md a.3, read as σ
    hydro = load_scenario("hydro-fig5").plant.site()
    assert hydro.stroke_max == load_scenario("hydro-fig5").plant.stroke_max
    assert not hydro.sensor_sigma  # the hydrostatic supervisor designs from its own sensor-accuracy option


@pytest.mark.parametrize("name", SHIPPED)
def test_every_kind_builds_its_supervisor_from_the_run_description_alone(name):
    scenario = load_scenario(name)
    kind = kind_for(scenario.plant.kind)
    assert KINDS[kind.kind] is kind and isinstance(scenario.plant, kind.section)
    plant = kind.make_plant(scenario, 1)
    info = RunInfo.from_json(RunInfo.of(scenario, kind.turbines(plant), plant.dt).to_json())
    supervisor = kind.make_supervisor(info)
    refs = supervisor.step(plant.measure())
    assert len(kind.refs_records(refs, supervisor, list(info.turbines))) == plant.n
