"""What differs between plant kinds in the live system, as one adapter per kind behind one small table.

An adapter builds the kind's plant and supervisor with the same constructors ``windwarden eval`` uses, turns
their frames and refs into wire records (``wwcore.wire``) and back, reports a supervisor's status per turbine,
accumulates what the kind's scorecard needs, and computes that scorecard from the run's events. The nodes, the
API and ``up`` only ever talk to this interface, so a new kind (the 9-turbine farm) is one more module and one
more line in ``ADAPTERS``.
"""

from __future__ import annotations

import importlib

from windwarden.live.adapters.base import KindAdapter, RunInfo, ScoreAccumulator

ADAPTERS: dict[str, str] = {
    "turbine": "windwarden.live.adapters.turbine",
    "hydro": "windwarden.live.adapters.hydro",
    "farm": "windwarden.live.adapters.farm",
}
"""Plant kind → module with an ``ADAPTER`` object. The farm kind adds its line here."""


class UnsupportedKindError(LookupError):
    """A plant kind the live system has no adapter for (yet)."""


def adapter_for(kind: str) -> KindAdapter:
    if kind not in ADAPTERS:
        raise UnsupportedKindError(f"no live adapter for plant kind {kind!r}; available: {', '.join(sorted(ADAPTERS))}")
    return importlib.import_module(ADAPTERS[kind]).ADAPTER


def load_adapters() -> None:
    """Import every kind's adapter (and with it its plant and supervisor code: about a second of imports)."""
    for module in ADAPTERS.values():
        importlib.import_module(module)


__all__ = [
    "ADAPTERS",
    "KindAdapter",
    "RunInfo",
    "ScoreAccumulator",
    "UnsupportedKindError",
    "adapter_for",
    "load_adapters",
]
