"""Event records: what the run folder's ``events.jsonl``, the wire and the scorecards share.

An event is one discrete thing that happened at a simulation time: a fault injected or cleared in the plant,
a detection or recovery flagged by the supervisor, an observer switch, a liveliness change. Scorecards are
computed from events alone (plus the continuous metrics each plant kind accumulates), so batch, lockstep and
realtime runs are scored by the same code.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from enum import StrEnum
from typing import Any


class EventType(StrEnum):
    FAULT_INJECTED = "fault_injected"  # plant: a fault became active (target, detail.label)
    FAULT_CLEARED = "fault_cleared"  # plant: a fault ended
    DETECTION = "detection"  # supervisor: target newly flagged as faulty
    RECOVERY = "recovery"  # supervisor: target no longer flagged (the fault's end recognised)
    OBSERVER_SWITCH = "observer_switch"  # supervisor: the selected observer changed (detail.from, detail.to)
    DISPATCH = "dispatch"  # farm supervisor: accommodation mode of a turbine changed
    LIVELINESS = "liveliness"  # a process appeared or disappeared (detail.process, detail.alive)
    STREAM = "stream"  # a stream went stale or fresh (detail.stream, detail.fresh)
    RUN = "run"  # run started or ended (detail.phase)


PLANT_EVENTS = frozenset({EventType.FAULT_INJECTED, EventType.FAULT_CLEARED})
SUPERVISOR_EVENTS = frozenset({EventType.DETECTION, EventType.RECOVERY, EventType.OBSERVER_SWITCH, EventType.DISPATCH})


@dataclass(frozen=True)
class Event:
    """One event. ``t`` is simulation time in s; ``wall_time`` (Unix s) is set only in live runs."""

    t: float
    type: EventType
    turbine: int = 1
    target: str | None = None
    run: int = 0
    detail: dict[str, Any] = field(default_factory=dict)
    wall_time: float | None = None

    def to_json(self) -> dict[str, Any]:
        out = asdict(self)
        out["type"] = self.type.value
        return {k: v for k, v in out.items() if v is not None and v != {}}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Event:
        return cls(
            t=float(data["t"]),
            type=EventType(data["type"]),
            turbine=int(data.get("turbine", 1)),
            target=data.get("target"),
            run=int(data.get("run", 0)),
            detail=dict(data.get("detail", {})),
            wall_time=data.get("wall_time"),
        )

    def scoring_key(self) -> tuple[Any, ...]:
        """The fields that must agree between two runs of the same scenario and seed (no wall time)."""
        return (round(self.t, 6), self.type.value, self.turbine, self.target, self.run)
