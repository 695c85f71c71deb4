"""Registries of algorithms by name: how a user plugs in their own detector, estimator or controller.

Each role has one registry. An entry is a factory (usually the class itself) called with keyword arguments
that the role documents, returning an object with ``step(...)``. Every role has a ``"none"`` entry so a stage
can be switched off from a scenario file without flags.

A user's own algorithm registers the same way as the built-in ones::

    from service.plugins import TURBINE_DETECTORS
    from wwcore.options import Bounds

    @dataclass(frozen=True)
    class MyOptions:
        false_alarms_per_1000s: Annotated[float, Bounds(gt=0.0, le=1000.0, unit="1/1000 s")] = 0.1

    @TURBINE_DETECTORS.register("my-detector", options=MyOptions)
    class MyDetector:
        def __init__(self, *, context, options): ...  # options: the declared keys the scenario gave
        def step(self, frame): ...  # -> service.turbine.interfaces.Diagnosis

Its options (the scenario's ``[supervisor.params]``) are declared with it and checked by ``choose`` before
anything runs, the same way in every plant kind. It is then scored with
``windwarden eval ftwse-2012 --plugin my_module --detector my-detector``. See ``docs/plugins.md`` for each
role's contract and a worked example.
"""

from __future__ import annotations

import difflib
import importlib
import importlib.util
import sys
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any, Generic, TypeVar

from wwcore.options import OptionSchema

T = TypeVar("T")
DeclaredOptions = OptionSchema | type | Mapping[str, type] | None
F = TypeVar("F", bound=Callable[..., Any])


class UnknownAlgorithmError(LookupError):
    """A scenario or command named an algorithm no registry has."""


class AlgorithmOptionError(ValueError):
    """The supervisor's algorithms or options were refused: an unknown key, a value out of range, a role the plant
    kind does not have. ``problems`` holds (key, message) pairs; the message names every key."""

    def __init__(self, message: str | list[tuple[str, str]]):
        self.problems = [("", message)] if isinstance(message, str) else list(message)
        if isinstance(message, str):
            super().__init__(message)
        else:
            lines = "\n".join(f"  {key}: {text}" for key, text in self.problems)
            super().__init__(f"supervisor options refused:\n{lines}")


class Registry(Generic[T]):
    """Name → factory for one role (for example turbine fault detectors), with each entry's declared options."""

    def __init__(self, role: str, description: str, default: str):
        self.role = role
        self.description = description
        self.default = default  # the entry a scenario gets when it names none
        self._factories: dict[str, Callable[..., T]] = {}
        self._schemas: dict[str, OptionSchema] = {}

    def register(
        self, name: str, *, options: OptionSchema | type | Mapping[str, type] | None = None
    ) -> Callable[[F], F]:
        """Decorator: register ``factory`` under ``name``. Names are unique within a role.

        ``options`` declares the options the factory reads from the scenario's ``[supervisor.params]``: a
        dataclass whose fields carry their types, defaults and ``wwcore.options.Bounds`` (or a mapping
        prefix → dataclass, or a pydantic model). Whatever is not declared by one of the selected algorithms
        is refused before anything runs; a factory that declares nothing gets no options.
        """
        schema = OptionSchema.of(options)

        def decorate(factory: F) -> F:
            if name in self._factories and self._factories[name] is not factory:
                raise ValueError(f"{self.role}: {name!r} is already registered")
            self._factories[name] = factory
            self._schemas[name] = schema
            return factory

        return decorate

    def names(self) -> list[str]:
        load_plugins()
        return sorted(self._factories)

    def factory(self, name: str) -> Callable[..., T]:
        load_plugins()
        try:
            return self._factories[name]
        except KeyError:
            raise UnknownAlgorithmError(
                f"no {self.role} named {name!r}; registered: {', '.join(self.names())}"
            ) from None

    def options(self, name: str) -> OptionSchema:
        """The options ``name`` declared (``factory`` refuses an unknown name first)."""
        self.factory(name)
        return self._schemas[name]

    def create(self, name: str, **kwargs: Any) -> T:
        return self.factory(name)(**kwargs)

    def __contains__(self, name: str) -> bool:
        load_plugins()
        return name in self._factories


TURBINE_DETECTORS: Registry[Any] = Registry(
    "turbine detector", "sensor/actuator fault detection and isolation", default="benchmark"
)
TURBINE_ESTIMATORS: Registry[Any] = Registry(
    "turbine estimator", "fault-tolerant wind and speed estimation", default="uio-bank"
)
FARM_DETECTORS: Registry[Any] = Registry("farm detector", "farm-level fault detection", default="analytic")
FARM_CONTROLLERS: Registry[Any] = Registry("farm controller", "farm power dispatch", default="dispatch")
HYDRO_OBSERVERS: Registry[Any] = Registry("hydro observer", "actuator fault reconstruction", default="ts-smo")
HYDRO_DETECTORS: Registry[Any] = Registry(
    "hydro detector", "actuator fault detection from the reconstruction", default="threshold"
)

ROLES: dict[str, dict[str, Registry[Any]]] = {
    "turbine": {"detector": TURBINE_DETECTORS, "estimator": TURBINE_ESTIMATORS},
    "farm": {"detector": FARM_DETECTORS, "controller": FARM_CONTROLLERS},
    "hydro": {"detector": HYDRO_DETECTORS, "estimator": HYDRO_OBSERVERS},
}
"""Per plant kind, the supervisor's roles (the ``[supervisor]`` keys, ``wwcore.scenario.model.SUPERVISOR_ROLES``)."""


@dataclass(frozen=True)
class SupervisorChoice:
    """The algorithms a supervisor runs (role → name) and the options each one declared, validated."""

    kind: str
    names: dict[str, str]
    options: dict[str, dict[str, Any]]


def choose(kind: str, params: Mapping[str, Any] | None = None, **names: str | None) -> SupervisorChoice:
    """Resolve and check the supervisor of a ``kind`` plant: the algorithm of each role (``names``, None picks
    the registry's default) and the options ``params`` (a scenario's ``[supervisor.params]``).

    Refused, with every offending key named (``AlgorithmOptionError``): a role the kind does not have, a key no
    selected algorithm declares, a value of the wrong type or out of its declared range. An unknown algorithm
    name raises ``UnknownAlgorithmError``.
    """
    params = dict(params or {})
    roles = ROLES[kind]
    problems: list[tuple[str, str]] = []
    for role, name in names.items():
        if role not in roles and name is not None:
            problems.append(
                (f"supervisor.{role}", f"the {kind} supervisor has no {role}; its roles are {', '.join(roles)}")
            )
    chosen = {role: names.get(role) or registry.default for role, registry in roles.items()}
    schemas = {role: roles[role].options(name) for role, name in chosen.items()}
    declared = {key for schema in schemas.values() for key in schema.options}
    running = " + ".join(f"{role} {name!r}" for role, name in chosen.items())
    for key in params:
        if key not in declared:
            hint = difflib.get_close_matches(key, sorted(declared), n=1)
            known = f"did you mean {hint[0]!r}? " if hint else ""
            problems.append(
                (
                    f"supervisor.params.{key}",
                    f"unknown option for {running}; {known}known: {', '.join(sorted(declared)) or 'none'}",
                )
            )
    options: dict[str, dict[str, Any]] = {}
    for role, schema in schemas.items():
        values, refused = schema.validate(params)
        options[role] = values
        problems.extend(
            (f"supervisor.params.{key}", f"{message} ({role} {chosen[role]!r})") for key, message in refused
        )
    if problems:
        raise AlgorithmOptionError(list(dict.fromkeys(problems)))
    return SupervisorChoice(kind, chosen, options)


_BUILTIN_MODULES = ("service.turbine.builtin", "service.farm.builtin", "service.hydro.builtin")
_loaded = False
_loading = threading.RLock()


def load_plugins(extra_modules: tuple[str, ...] = ()) -> None:
    """Import the built-in algorithms, installed ``windwarden.plugins`` entry points and ``extra_modules``
    (module names, or paths of ``.py`` files)."""
    global _loaded
    with _loading:  # a second thread waits until the registries are full instead of seeing them half-filled
        if not _loaded:
            for module in _BUILTIN_MODULES:
                try:
                    importlib.import_module(module)
                except ModuleNotFoundError as error:
                    missing = error.name or ""
                    if not module.startswith(missing):  # a plant kind not installed is fine; a broken import is not
                        raise
            for entry in entry_points(group="windwarden.plugins"):
                entry.load()
            _loaded = True
        for module in extra_modules:
            if module.endswith(".py"):
                _import_file(Path(module))
            else:
                importlib.import_module(module)


def _import_file(path: Path) -> None:
    if not path.is_file():
        raise ModuleNotFoundError(f"no plug-in file {path}", name=str(path))
    name = f"windwarden_plugin_{path.stem}"
    if name in sys.modules:
        return
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
