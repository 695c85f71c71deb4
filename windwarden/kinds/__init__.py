"""The plant kinds, one object each (``PlantKind``), registered once in ``KINDS``.

A kind's object says everything the rest of the program needs of it: its scenario section, plant and supervisor
factories, wire schemas and conversions, status, score accumulator and scorecard, batch evaluator and dashboard
panels. ``windwarden eval``, the plant and supervisor nodes, the API and ``up`` only ever talk to it, so a new kind is
one more module here and one more line in ``KINDS`` (``docs/architecture.md`` lists the files a kind needs).

The kind modules import their plant (``plant_sim``) and supervisor (``service``) code inside the factories, so the
plant process never loads the supervisor's code, nor the supervisor the plant's.
"""

from __future__ import annotations

from windwarden.kinds.base import PlantKind, RunInfo, ScoreAccumulator
from windwarden.kinds.farm import FARM
from windwarden.kinds.hydro import HYDRO
from windwarden.kinds.turbine import TURBINE

KINDS: dict[str, PlantKind] = {kind.kind: kind for kind in (TURBINE, HYDRO, FARM)}
"""Plant kind name → its object."""


class UnsupportedKindError(LookupError):
    """A plant kind no object is registered for."""


def kind_for(name: str) -> PlantKind:
    if name not in KINDS:
        raise UnsupportedKindError(f"no plant kind {name!r}; available: {', '.join(sorted(KINDS))}")
    return KINDS[name]


__all__ = ["KINDS", "PlantKind", "RunInfo", "ScoreAccumulator", "UnsupportedKindError", "kind_for"]
