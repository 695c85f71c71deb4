"""Scenario files: schema, validation and loading. See ``docs/scenarios.md`` for the file format."""

from wwcore.scenario.faults import SENSOR_FAULT_KINDS, FaultKind, FaultSpec
from wwcore.scenario.loader import (
    ScenarioError,
    dump_scenario,
    load_scenario,
    parse_scenario,
    problems_from_validation_error,
    shipped_scenarios,
)
from wwcore.scenario.mismatch import Mismatch
from wwcore.scenario.model import Scenario, SupervisorSpec
from wwcore.scenario.wind import WindSpec

__all__ = [
    "SENSOR_FAULT_KINDS",
    "FaultKind",
    "FaultSpec",
    "Mismatch",
    "Scenario",
    "ScenarioError",
    "SupervisorSpec",
    "WindSpec",
    "dump_scenario",
    "load_scenario",
    "parse_scenario",
    "problems_from_validation_error",
    "shipped_scenarios",
]
