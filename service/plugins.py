"""Registries of algorithms by name: how a user plugs in their own detector, estimator or controller.

Each role has one registry. An entry is a factory (usually the class itself) called with keyword arguments
that the role documents, returning an object with ``step(...)``. Every role has a ``"none"`` entry so a stage
can be switched off from a scenario file without flags.

A user's own algorithm registers the same way as the built-in ones::

    from service.plugins import TURBINE_DETECTORS

    @TURBINE_DETECTORS.register("my-detector")
    class MyDetector:
        def __init__(self, *, n, params, options): ...
        def step(self, frame): ...  # -> service.turbine.interfaces.Diagnosis

and is then scored with ``windwarden eval ftwse-2012 --plugin my_module --detector my-detector``. See
``docs/plugins.md`` for each role's contract and a worked example.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from collections.abc import Callable
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any, Generic, TypeVar

T = TypeVar("T")
F = TypeVar("F", bound=Callable[..., Any])


class UnknownAlgorithmError(LookupError):
    """A scenario or command named an algorithm no registry has."""


class AlgorithmOptionError(ValueError):
    """An algorithm refused one of its options (the scenario's ``[supervisor] params``): the message names it."""


class Registry(Generic[T]):
    """Name → factory for one role (for example turbine fault detectors)."""

    def __init__(self, role: str, description: str):
        self.role = role
        self.description = description
        self._factories: dict[str, Callable[..., T]] = {}

    def register(self, name: str) -> Callable[[F], F]:
        """Decorator: register ``factory`` under ``name``. Names are unique within a role."""

        def decorate(factory: F) -> F:
            if name in self._factories and self._factories[name] is not factory:
                raise ValueError(f"{self.role}: {name!r} is already registered")
            self._factories[name] = factory
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

    def create(self, name: str, **kwargs: Any) -> T:
        return self.factory(name)(**kwargs)

    def __contains__(self, name: str) -> bool:
        load_plugins()
        return name in self._factories


TURBINE_DETECTORS: Registry[Any] = Registry("turbine detector", "sensor/actuator fault detection and isolation")
TURBINE_ESTIMATORS: Registry[Any] = Registry("turbine estimator", "fault-tolerant wind and speed estimation")
FARM_DETECTORS: Registry[Any] = Registry("farm detector", "farm-level fault detection")
FARM_CONTROLLERS: Registry[Any] = Registry("farm controller", "farm power dispatch")
HYDRO_OBSERVERS: Registry[Any] = Registry("hydro observer", "actuator fault reconstruction")

_BUILTIN_MODULES = ("service.turbine.builtin", "service.farm.builtin", "service.hydro.builtin")
_loaded = False


def load_plugins(extra_modules: tuple[str, ...] = ()) -> None:
    """Import the built-in algorithms, installed ``windwarden.plugins`` entry points and ``extra_modules``
    (module names, or paths of ``.py`` files)."""
    global _loaded
    if not _loaded:
        _loaded = True
        for module in _BUILTIN_MODULES:
            try:
                importlib.import_module(module)
            except ModuleNotFoundError as error:
                missing = error.name or ""
                if not module.startswith(missing):  # a plant kind not installed is fine; a broken import is not
                    raise
        for entry in entry_points(group="windwarden.plugins"):
            entry.load()
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
