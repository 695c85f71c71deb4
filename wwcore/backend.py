"""Which implementation runs the batch step: the numpy reference or its compiled twin.

``numpy`` is the readable, vectorised formulation with units and equation numbers: the reference. ``numba`` runs
the same operations, in the same order, as compiled loops over the rows (the modules named ``fast`` next to the
numpy code they mirror); tests compare the two (``tests/test_fast_backend.py``). The compiled twin matters where
a tick is a few hundred small numpy calls on a handful of rows: one Monte Carlo run, one farm.

An object that steps (``TurbineBatch``, ``TurbineSupervisor``, ``FarmBatch``) takes ``backend=`` when it is built;
``None`` means ``$WINDWARDEN_STEP_BACKEND``, else ``numpy``. ``windwarden eval`` chooses ``numba`` (its
``--step-backend``) by setting the variable for its own process and the worker processes it starts
(``process_backend``); the live plant and supervisor keep ``numpy`` (their tick is paced by the clock, and they
start without importing the compiler).

This module imports no compiler: ``numba`` is imported only when a ``fast`` module is loaded (``fast_module``),
so commands that never step a batch start as quickly without it.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType

BACKENDS = ("numpy", "numba")
ENV_VAR = "WINDWARDEN_STEP_BACKEND"


class BackendError(ValueError):
    """An unknown backend name, or ``numba`` asked for where it is not installed."""


def resolve_backend(backend: str | None = None) -> str:
    """The backend to use: ``backend`` if given, else ``$WINDWARDEN_STEP_BACKEND``, else ``numpy``; checked."""
    name = backend if backend is not None else (os.environ.get(ENV_VAR) or "numpy")
    if name not in BACKENDS:
        source = "backend" if backend is not None else ENV_VAR
        raise BackendError(f"{source} = {name!r}: choose one of {', '.join(BACKENDS)}")
    return name


def available(backend: str) -> str:
    """``backend``, checked: a known name, and for ``numba`` the package installed (not imported)."""
    name = resolve_backend(backend)
    if name == "numba" and importlib.util.find_spec("numba") is None:
        raise BackendError("the numba step backend needs numba installed (pip install numba), or use numpy")
    return name


@contextmanager
def process_backend(backend: str) -> Iterator[str]:
    """Within the block, ``backend`` is the default of this process and of the processes it starts
    (``$WINDWARDEN_STEP_BACKEND``); the variable is restored after it."""
    name = available(backend)
    before = os.environ.get(ENV_VAR)
    os.environ[ENV_VAR] = name
    try:
        yield name
    finally:
        if before is None:
            os.environ.pop(ENV_VAR, None)
        else:
            os.environ[ENV_VAR] = before


class Kernels:
    """A compiled twin's public names (``kernels.name``), which copies and pickles as the module's name: the objects
    that hold one can be deep-copied (a fault-free twin run in the same process) or sent to another process."""

    def __init__(self, module: ModuleType):
        self.__dict__.update({k: v for k, v in vars(module).items() if not k.startswith("__")})
        self.module_name = module.__name__

    def __reduce__(self):
        return fast_module, (self.module_name,)

    def __deepcopy__(self, memo: dict) -> Kernels:
        return self  # stateless: the kernels and constants of a module


def fast_module(name: str) -> Kernels:
    """The compiled twin ``name`` (e.g. ``plant_sim.turbine.fast``), imported on first use.

    Imported here rather than at the top of the numpy modules so that importing the simulator or the supervisor
    (the live nodes, ``windwarden --help``) does not import the compiler; there is no import cycle to avoid.
    """
    if name not in _LOADED:
        try:
            module = importlib.import_module(name)
        except ImportError as exc:  # numba missing or broken: say so instead of a traceback from deep inside
            raise BackendError(f"backend 'numba' needs numba installed ({exc})") from exc
        _LOADED[name] = Kernels(module)
    return _LOADED[name]


_LOADED: dict[str, Kernels] = {}
