"""Reading and writing scenario files, with errors that name the offending field."""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

import tomli_w
from pydantic import ValidationError

from wwcore.scenario.model import Scenario


class ScenarioError(ValueError):
    """A scenario that cannot run. ``problems`` holds (field path, message) pairs."""

    def __init__(self, source: str, problems: list[tuple[str, str]]):
        self.source = source
        self.problems = problems
        lines = "\n".join(f"  {field}: {message}" for field, message in problems)
        super().__init__(f"scenario {source} is not valid:\n{lines}")


def _field_path(loc: tuple[Any, ...]) -> str:
    path = ""
    for part in loc:
        if isinstance(part, int):
            path += f"[{part}]"
        elif part in {"turbine", "farm", "hydro"} and path == "plant":
            continue  # the discriminator tag pydantic inserts is not a field of the file
        else:
            path += f".{part}" if path else str(part)
    return path or "(root)"


def problems_from_validation_error(error: ValidationError) -> list[tuple[str, str]]:
    """Pydantic's errors as (field path, message) pairs in the file's own terms."""
    out = []
    for err in error.errors():
        message = err["msg"]
        if err["type"] == "extra_forbidden":
            message = "unknown key"
        out.append((_field_path(tuple(err["loc"])), message))
    return out


def parse_scenario(data: dict[str, Any], source: str = "<data>") -> Scenario:
    """Validate a scenario given as a dict; raise ScenarioError naming every bad field."""
    try:
        scenario = Scenario.model_validate(data)
    except ValidationError as error:
        raise ScenarioError(source, problems_from_validation_error(error)) from None
    problems = scenario.problems()
    if problems:
        raise ScenarioError(source, problems)
    return scenario


def shipped_scenarios() -> dict[str, Path]:
    """Scenario name → file for every scenario shipped in the ``scenarios`` package."""
    folder = resources.files("scenarios")
    return {Path(str(p)).stem: Path(str(p)) for p in folder.iterdir() if str(p).endswith(".toml")}


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load a shipped scenario by name or any scenario file by path."""
    path = Path(name_or_path)
    if not path.is_file():  # a folder of the same name (an eval's output, say) does not hide a shipped scenario
        shipped = shipped_scenarios()
        if str(name_or_path) in shipped:
            path = shipped[str(name_or_path)]
        elif path.exists():
            raise ScenarioError(str(name_or_path), [("(file)", "a folder, not a scenario file")])
        else:
            names = ", ".join(sorted(shipped))
            raise ScenarioError(str(name_or_path), [("(file)", f"no such file or shipped scenario; shipped: {names}")])
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as error:
        raise ScenarioError(str(path), [("(file)", f"not valid TOML: {error}")]) from None
    return parse_scenario(data, str(path))


def dump_scenario(scenario: Scenario) -> str:
    """The scenario as TOML; ``parse_scenario(tomllib.loads(dump_scenario(s)))`` gives ``s`` back."""
    return tomli_w.dumps(scenario.model_dump(mode="json", exclude_none=True))
