"""A hostile client for the probes: a Zenoh session on the router, as any program on the network could open one.

It reads the sensor stream (so it learns the tick the plant is at and the run identity, as a real attacker would)
and puts whatever frames it likes on the refs and sensors keys. The probes check the defences at the two ends (plant and
supervisor), so they run on a router without access control (``tests.live.helpers.router``), or with the
supervisor's own credentials where the router enforces it: the question is what the plant and the supervisor do
with what gets through.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import zenoh

from windwarden.live.config import ZenohSettings
from windwarden.live.transport import open_session, query_json
from wwcore.keys import KeyTree
from wwcore.wire import MessageSchema, WireError


class HostileClient:
    def __init__(self, endpoint: str, sensors: MessageSchema, turbine: int = 1, farm: str = "default"):
        self.keys = KeyTree(farm)
        self.turbine = turbine
        self.schema = sensors
        self.session = open_session(ZenohSettings(connect=endpoint, farm=farm))
        self._lock = threading.Lock()
        self.latest: np.void | None = None  # the newest genuine sensor record seen
        self._sub = self.session.declare_subscriber(  # the plant's frames, not its own forgeries
            self.keys.sensors, self._on_sensors, allowed_origin=zenoh.Locality.REMOTE
        )

    def _on_sensors(self, sample) -> None:
        try:
            rows = self.schema.decode_frame(sample.payload.to_bytes())
        except WireError:
            return
        mine = rows[rows["turbine"] == self.turbine]
        if len(mine) != 1:
            return
        record = mine[0]
        with self._lock:
            if self.latest is None or record["tick"] > self.latest["tick"]:
                self.latest = record.copy()

    def sensed(self) -> np.void:
        """The newest sensor record of the plant (waits for one)."""
        deadline = time.monotonic() + 10.0
        while self.latest is None and time.monotonic() < deadline:
            time.sleep(0.01)
        with self._lock:
            assert self.latest is not None, "no sensor frame seen"
            return self.latest.copy()

    def put(self, key: str, schema: MessageSchema, record: np.ndarray) -> None:
        """Put ``record`` (one row or several) as a frame."""
        self.session.put(key, schema.encode_frame(record))

    def flood(self, key: str, schema: MessageSchema, make, seconds: float, every_s: float = 0.005) -> int:
        """Put ``make(latest sensor record)`` every ``every_s`` for ``seconds``; returns how many were put."""
        sent = 0
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.put(key, schema, make(self.sensed()))
            sent += 1
            time.sleep(every_s)
        return sent

    def plant_status(self) -> dict:
        return query_json(self.session, self.keys.plant_status, "plant.status", timeout=2.0)

    def supervisor_status(self) -> dict:
        return query_json(self.session, self.keys.supervisor_status, "supervisor.status", timeout=2.0)

    def close(self) -> None:
        self._sub.undeclare()
        self.session.close()
