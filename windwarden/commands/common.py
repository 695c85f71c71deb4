"""What every subcommand shares: the bad-input error (exit code 2), the consoles, argument types, and the check
that a scenario's supervisor can be built before anything runs."""

from __future__ import annotations

import argparse

from rich.console import Console

from service.plugins import AlgorithmOptionError, UnknownAlgorithmError, choose
from wwcore.scenario import Scenario, ScenarioError, parse_scenario

EXIT_BAD_INPUT = 2
console = Console()
err_console = Console(stderr=True)


class BadInputError(Exception):
    """Input refused before anything ran (exit code 2)."""


def positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be ≥ 1, got {value}")
    return value


def with_wake_model(scenario: Scenario, model: str) -> Scenario:
    """The scenario with its farm's wakes from ``model`` (``--wake-model``), validated again as a whole: a
    combination the plant refuses (the row model with a layout or a moving direction) is bad input (exit 2)."""
    if scenario.plant.kind != "farm":
        raise BadInputError(f"--wake-model: scenario {scenario.name} is a {scenario.plant.kind}; only a farm has wakes")
    data = scenario.model_dump(mode="json", exclude_none=True)
    data["plant"]["wake_model"] = model
    try:
        return parse_scenario(data, f"{scenario.name} with --wake-model {model}")
    except ScenarioError as error:
        raise BadInputError(f"--wake-model: {error}") from None


def check_supervisor(scenario: Scenario, **flags: str | None) -> None:
    """Refuse (exit 2), before anything runs, a scenario whose supervisor the registries would not build: a role
    its plant kind does not have, an unknown algorithm, an option no selected algorithm declares or out of its
    range (``service.plugins.choose``). ``flags``: role → name given on the command line (wins over the file)."""
    spec = scenario.supervisor
    names = {role: flags.get(role) or getattr(spec, role) for role in ("detector", "estimator", "controller")}
    try:
        choose(scenario.plant.kind, spec.params, **names)
    except UnknownAlgorithmError as error:
        raise BadInputError(f"scenario {scenario.name}: {error}") from None
    except AlgorithmOptionError as error:
        # a role refused because of a flag names the flag; everything else the scenario file's key
        lines = []
        for key, text in error.problems:
            role = key.removeprefix("supervisor.")
            lines.append(f"  {'--' + role if flags.get(role) else key}: {text}")
        raise BadInputError(f"scenario {scenario.name}: supervisor options refused:\n" + "\n".join(lines)) from None
