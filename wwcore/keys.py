"""The key-expression tree of the wire (``wwcore.wire`` has the table of keys and the messages on them), the
processes that declare liveliness, and the quality of service of each stream. Pure: nothing here opens a session.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from enum import StrEnum

_CHUNK = re.compile(r"^[A-Za-z0-9_\-]+$")


def _check_chunk(name: str, what: str) -> None:
    """``name`` is one key chunk (``*`` and ``<placeholder>`` for patterns and docs); ``ValueError`` otherwise."""
    if name != "*" and not name.startswith("<") and not _CHUNK.match(name):
        raise ValueError(f"{what} {name!r} must be letters, digits, '_' or '-' (one key chunk)")


class Process(StrEnum):
    """The processes that declare liveliness tokens."""

    PLANT = "plant"
    SUPERVISOR = "supervisor"
    API = "api"


@dataclass(frozen=True)
class Qos:
    """Quality of service of a stream, mapped onto Zenoh by the edges."""

    reliable: bool  # reliable transport (retransmitted) rather than best effort
    block: bool  # a full queue blocks the publisher rather than dropping the sample
    priority: str  # Zenoh priority name: REAL_TIME, INTERACTIVE_HIGH, DATA_HIGH, DATA, …
    express: bool = True  # sent at once, not batched


SENSORS_QOS = Qos(reliable=False, block=False, priority="DATA_HIGH")
"""Sensor streams may drop under congestion (realtime). Lockstep sends them with ``COMMAND_QOS``: the plant
waits for every reply anyway, so nothing can queue up, and a lost sample would stall the step."""
COMMAND_QOS = Qos(reliable=True, block=True, priority="REAL_TIME")
"""References, fault commands and events never drop."""
DISPLAY_QOS = Qos(reliable=False, block=False, priority="DATA_LOW", express=False)
"""Truth and status: for display; the newest sample is what matters."""
EVENT_QOS = Qos(reliable=True, block=True, priority="INTERACTIVE_HIGH")


@dataclass(frozen=True)
class KeySpec:
    """One entry of the key-expression registry (for docs and the layering of who publishes what)."""

    pattern: str
    publisher: str
    payload: str
    qos: Qos | None
    doc: str


@dataclass(frozen=True)
class KeyTree:
    """Every key expression of one farm, built from the farm id. ``root`` is fixed by the protocol."""

    farm: str = "default"
    root: str = field(default="windwarden", init=False)

    def __post_init__(self) -> None:
        if not _CHUNK.match(self.farm):
            raise ValueError(f"farm id {self.farm!r} must be letters, digits, '_' or '-' (one key chunk)")

    @classmethod
    def every_farm(cls) -> KeyTree:
        """The tree with ``*`` for the farm chunk: patterns for access-control rules, never keys to publish on."""
        tree = object.__new__(cls)
        object.__setattr__(tree, "farm", "*")
        object.__setattr__(tree, "root", "windwarden")
        return tree

    @property
    def base(self) -> str:
        return f"{self.root}/{self.farm}"

    @property
    def sensors(self) -> str:
        """The plant's sensor frame of tick k: one message per tick, a row per turbine."""
        return f"{self.base}/sensors"

    def refs(self, sender: str) -> str:
        """A supervisor's refs frame of tick k: a row per turbine it owns. ``sender``: ``supervisor`` (one
        supervisor, every turbine) or a shard's name (its turbines); ``*`` for subscribers and access rules."""
        _check_chunk(sender, "refs sender")
        return f"{self.base}/refs/{sender}"

    @property
    def truth(self) -> str:
        """The plant's ground truth, a row per turbine (decimated; display and scoring only)."""
        return f"{self.base}/truth"

    def summary(self, shard: str) -> str:
        """A supervisor shard's 10 Hz summary frame of its turbines, for the farm coordinator."""
        _check_chunk(shard, "shard name")
        return f"{self.base}/summary/{shard}"

    def dispatch(self, shard: str) -> str:
        """The farm coordinator's references frame of a farm sample for one shard, a row per turbine it owns."""
        _check_chunk(shard, "shard name")
        return f"{self.base}/dispatch/{shard}"

    def shard_status(self, name: str) -> str:
        """A supervisor shard's status (``name``: one key chunk, e.g. its turbines ``1-40``)."""
        _check_chunk(name, "shard name")
        return f"{self.base}/shard/{name}/status"

    @property
    def metmast(self) -> str:
        return f"{self.base}/metmast"

    @property
    def plant_status(self) -> str:
        return f"{self.base}/plant/status"

    @property
    def run(self) -> str:
        return f"{self.base}/plant/run"

    @property
    def faults(self) -> str:
        return f"{self.base}/plant/faults"

    @property
    def supervisor_status(self) -> str:
        return f"{self.base}/supervisor/status"

    @property
    def plant_events(self) -> str:
        return f"{self.base}/plant/events"

    @property
    def supervisor_events(self) -> str:
        return f"{self.base}/supervisor/events"

    @property
    def events_all(self) -> str:
        """Both event streams (plant and supervisor), for readers."""
        return f"{self.base}/*/events"

    def alive(self, process: Process | str) -> str:
        return f"{self.base}/alive/{process}"

    @property
    def alive_all(self) -> str:
        return f"{self.base}/alive/*"

    def process_of(self, key: str) -> str:
        """The process named by a liveliness key (``…/alive/<process>``)."""
        return key.rsplit("/", 1)[-1]

    def sender_of(self, key: str) -> str:
        """The sender named by a ``…/refs/<sender>`` or ``…/summary/<shard>`` key (its last chunk)."""
        return key.rsplit("/", 1)[-1]

    def registry(self) -> list[KeySpec]:
        """The whole tree as data: what is published where, how, with which payload."""
        frames = "frame of "
        return [
            KeySpec(
                self.sensors,
                "plant",
                frames + "turbine.sensors | hydro.sensors | farm.sensors",
                SENSORS_QOS,
                "per tick",
            ),
            KeySpec(
                self.refs("<sender>"),
                "supervisor",
                frames + "turbine.refs | hydro.refs | farm.refs",
                COMMAND_QOS,
                "per received tick; <sender>: supervisor, or a shard's name",
            ),
            KeySpec(
                self.truth,
                "plant",
                frames + "turbine.truth | hydro.truth | farm.truth",
                DISPLAY_QOS,
                "decimated; display only",
            ),
            KeySpec(self.metmast, "plant (farm)", "farm.metmast", SENSORS_QOS, "per tick"),
            KeySpec(self.plant_status, "plant", "JSON plant.status", DISPLAY_QOS, "2 Hz; also a queryable"),
            KeySpec(self.run, "plant (queryable)", "JSON plant.run", None, "what the supervisor may know"),
            KeySpec(self.faults, "plant (queryable)", "JSON plant.faults", None, "inject, clear, list"),
            KeySpec(self.supervisor_status, "supervisor", "JSON supervisor.status", DISPLAY_QOS, "2 Hz; queryable"),
            KeySpec(self.plant_events, "plant", "JSON events", EVENT_QOS, "the plant's events, append-only"),
            KeySpec(self.supervisor_events, "supervisor", "JSON events", EVENT_QOS, "the supervisor's events"),
            KeySpec(self.alive("<process>"), "every process", "liveliness token", None, "plant, supervisor, api"),
            KeySpec(
                self.summary("<name>"),
                "supervisor shard",
                frames + "farm.summary",
                COMMAND_QOS,
                "10 Hz; sharded farm only",
            ),
            KeySpec(
                self.dispatch("<name>"),
                "farm coordinator",
                frames + "farm.refs",
                COMMAND_QOS,
                "10 Hz; sharded farm only",
            ),
            KeySpec(self.shard_status("<name>"), "supervisor shard", "JSON shard.status", EVENT_QOS, "2 Hz"),
        ]
