"""The plant-kind registry (``windwarden.kinds.KINDS``): one object per scenario kind, each complete and consistent
with the scenario schema, the wire contract and the dashboard panels it names."""

from __future__ import annotations

import typing

import pytest

from dashboards.panels import PANELS
from windwarden.kinds import KINDS, UnsupportedKindError, kind_for
from wwcore.scenario.model import FAULT_CHECKS, PlantSpec
from wwcore.wire import SCHEMAS

SECTIONS = typing.get_args(typing.get_args(PlantSpec)[0])  # the [plant] section models of the scenario union


def test_every_scenario_kind_has_one_object_and_no_object_lacks_a_kind():
    declared = {section.model_fields["kind"].default: section for section in SECTIONS}
    assert set(KINDS) == set(declared) == set(FAULT_CHECKS)
    for name, kind in KINDS.items():
        assert kind.kind == name and kind.section is declared[name]


@pytest.mark.parametrize("name", sorted(KINDS))
def test_each_kind_says_everything_the_program_asks_of_it(name):
    kind = KINDS[name]
    for method in (
        "evaluate",
        "make_plant",
        "make_supervisor",
        "turbines",
        "frame_records",
        "frame_from_records",
        "refs_records",
        "refs_from_records",
        "hold_unserved",
        "truth_records",
        "inject",
        "clear",
        "status",
        "score",
        "scorecard",
    ):
        assert callable(getattr(kind, method)), method
    for schema in (kind.sensors, kind.refs, kind.truth):
        assert SCHEMAS[schema.name] is schema  # declared once, in the wire contract
    assert kind.panels and all(panel in PANELS for panel in kind.panels)
    assert kind.section.model_validate({"kind": name}).site().kind == name


def test_an_unknown_kind_is_refused_by_name():
    with pytest.raises(UnsupportedKindError, match="no plant kind 'tidal'; available: farm, hydro, turbine"):
        kind_for("tidal")
