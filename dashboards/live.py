"""Logging a live run into Rerun: both processes into one recording, stamped with simulation time.

Plant and supervisor each open a ``RecordingStream`` with the same application id and the run's recording id,
and push to one Rerun gRPC proxy (``windwarden up`` starts one that also saves ``recording.rrd``); the proxy and
every viewer merge the two streams into one recording. Rows arrive already down-sampled by the nodes
(``display_every``, 10 Hz by default); they are buffered per group of series (one entity holds several scalar
series) and sent with ``send_columns`` once a second of simulation time, one group per tick, so a one-hour run
stays light in the viewer and logging never lands on one tick. Events become state timelines (faults injected vs
detected, selected observer) and a text log. A farm's overview adds a map (``dashboards.farm_map``): the plant
logs the layout and the wind once, the supervisor the turbines' states when they change.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import rerun as rr

from dashboards.blueprints import blueprint
from dashboards.farm_map import MapColours, WindArrow, log_geometry
from dashboards.panels import PANELS
from wwcore.events import Event, EventType

APPLICATION_ID = "windwarden"
TIMELINE = "sim_time"
_UNSAFE = re.compile(r"[^A-Za-z0-9_\-/.]")  # entity path parts: letters, digits, _ - . only
FLUSH_ROWS = 10  # rows per series group buffered before a send_columns call (1 s of simulation time at 10 Hz)


@dataclass
class _Group:
    """Buffered rows of one entity holding several scalar series."""

    path: str
    names: list[str]
    times: list[float] = field(default_factory=list)
    values: list[list[float]] = field(default_factory=list)


def open_stream(recording_id: str, url: str | None = None, path: str | None = None) -> rr.RecordingStream:
    """A recording stream of the run, sinking to a gRPC proxy (``url``) and/or a file (``path``)."""
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id, send_properties=False)
    sinks: list[Any] = []
    if url:
        sinks.append(rr.GrpcSink(url))
    if path:
        sinks.append(rr.FileSink(path))
    rec.set_sinks(*sinks)
    return rec


class LiveRecording:
    """One process's share of the run's recording. ``role`` is "plant" or "supervisor".

    Rows are buffered per series group; ``pump()`` (called once per tick by the node) sends at most one full group,
    so the cost of logging is spread over ticks instead of landing on one tick as a deadline overrun.
    """

    def __init__(
        self,
        kind: str,
        role: str,
        recording_id: str,
        url: str | None = None,
        *,
        path: str | None = None,
        n_turbines: int = 1,
        turbines: list[int] | None = None,
        plant_section: Any = None,
    ):
        self.kind = kind
        self.role = role
        self.panel = PANELS[kind]
        self.turbines = turbines or list(range(1, n_turbines + 1))
        self.rec = open_stream(recording_id, url, path)
        self._groups: dict[str, _Group] = {}
        self._order: list[str] = []
        self._next = 0
        self.map_colours: MapColours | None = None
        self.wind_arrow: WindArrow | None = None
        if role == "plant":
            self.rec.send_blueprint(blueprint(kind, self.turbines), make_active=True, make_default=True)
            if self.panel.site_map is not None and plant_section is not None:
                geometry = self.panel.site_map(plant_section)
                log_geometry(self.rec, geometry)
                if geometry.wind_moves:
                    self.wind_arrow = WindArrow(geometry)
        elif self.panel.site_map is not None:
            self.map_colours = MapColours(max(self.turbines))

    # -- series -------------------------------------------------------------------------------------------------
    def _add(self, path: str, t: float, row: dict[str, float]) -> None:
        group = self._groups.get(path)
        if group is None or list(row) != group.names:
            if group is not None:
                self._send(group)
            group = self._groups[path] = _Group(path, list(row))
            if path not in self._order:
                self._order.append(path)
            colors = [self.panel.colors.get(name, (90, 90, 90)) for name in group.names]
            self.rec.log(path, rr.SeriesLines(names=group.names, colors=colors), static=True)
        group.times.append(t)
        group.values.append([float(v) for v in row.values()])
        if len(group.times) >= 5 * FLUSH_ROWS:  # nobody pumps: do not let it grow
            self._send(group)

    def _send(self, group: _Group) -> None:
        if not group.times:
            return
        times, values = np.asarray(group.times), np.asarray(group.values)
        group.times, group.values = [], []
        self.rec.send_columns(
            group.path,
            indexes=[rr.TimeColumn(TIMELINE, duration=times)],
            columns=rr.Scalars.columns(scalars=values if values.shape[1] > 1 else values[:, 0]),
        )

    def pump(self) -> None:
        """Send the next group that has a second's worth of rows (round robin); cheap when there is none."""
        n = len(self._order)
        for i in range(n):
            group = self._groups[self._order[(self._next + i) % n]]
            if len(group.times) >= FLUSH_ROWS:
                self._send(group)
                self._next = (self._next + i + 1) % n
                return

    def flush_series(self) -> None:
        for group in self._groups.values():
            self._send(group)

    def _rows(self, turbine: int, t: float, rows: dict[str, dict[str, float]]) -> None:
        for suffix, row in rows.items():
            self._add(f"/turbine/{turbine}/{_UNSAFE.sub('_', suffix)}", t, row)

    def plant_rows(self, sensors: np.ndarray, truth: np.ndarray | None) -> None:
        for i in range(len(sensors)):
            row = sensors[i]
            self._rows(int(row["turbine"]), float(row["t"]), self.panel.plant(row, None if truth is None else truth[i]))
        if self.panel.farm_plant is not None and len(sensors):
            self._farm_rows(float(sensors[0]["t"]), self.panel.farm_plant(sensors, truth))
        if self.wind_arrow is not None and len(sensors) and "mast_direction" in (sensors.dtype.names or ()):
            self.wind_arrow.update(self.rec, TIMELINE, float(sensors[0]["t"]), float(sensors[0]["mast_direction"]))

    def supervisor_rows(self, sensors: np.ndarray, refs: np.ndarray, status: list[dict[str, Any]]) -> None:
        for i in range(len(refs)):
            row = sensors[i]
            self._rows(int(row["turbine"]), float(row["t"]), self.panel.supervisor(row, refs[i], status[i]))
        if self.panel.farm_supervisor is not None and len(refs):
            self._farm_rows(float(sensors[0]["t"]), self.panel.farm_supervisor(sensors, refs))
        if self.map_colours is not None and len(refs):
            self.map_colours.update(self.rec, TIMELINE, float(sensors[0]["t"]), refs)

    def _farm_rows(self, t: float, rows: dict[str, dict[str, float]]) -> None:
        for suffix, row in rows.items():
            self._add(f"/farm/{_UNSAFE.sub('_', suffix)}", t, row)

    def timing(self, t: float, status: dict[str, Any]) -> None:
        """The plant's loop figures (at the status rate): latency over the last 1000 ticks, overruns so far."""
        latency = status.get("latency_recent") or {}
        nan = float("nan")
        row = {
            "latency p50 ms": latency.get("p50_ms") or nan,
            "latency p99 ms": latency.get("p99_ms") or nan,
            "overruns": status.get("overruns") or 0.0,
        }
        self._add("/run/timing", t, row)

    # -- events -------------------------------------------------------------------------------------------------
    def event(self, event: Event) -> None:
        """State timelines and the text log. Called for the events this process writes."""
        states: list[tuple[str, str | None]] = []
        base = f"/turbine/{event.turbine}"
        label = event.detail.get("label", event.target)
        match event.type:
            case EventType.FAULT_INJECTED:
                states.append((f"{base}/faults/injected/{event.target}", f"injected {label}"))
            case EventType.FAULT_CLEARED:
                states.append((f"{base}/faults/injected/{event.target}", None))
            case EventType.DETECTION:
                states.append((f"{base}/faults/detected/{event.target}", "flagged"))
            case EventType.RECOVERY:
                states.append((f"{base}/faults/detected/{event.target}", None))
            case EventType.OBSERVER_SWITCH:
                states.append((f"{base}/observer", str(event.detail.get("to"))))
        time_index = [rr.TimeColumn(TIMELINE, duration=[event.t])]
        for path, state in states:
            self.rec.send_columns(path, indexes=time_index, columns=rr.StateChange.columns(state=[state]))
        text = f"{event.type.value} turbine {event.turbine}" + (f" {event.target}" if event.target else "")
        if event.detail:
            text += " " + ", ".join(f"{k}={v}" for k, v in event.detail.items())
        level = "WARN" if event.type in (EventType.DETECTION, EventType.LIVELINESS, EventType.STREAM) else "INFO"
        self.rec.send_columns("/events", indexes=time_index, columns=rr.TextLog.columns(text=[text], level=[level]))

    def flush(self) -> None:
        self.flush_series()
        self.rec.flush(timeout_sec=10.0)

    def close(self) -> None:
        """Send what is buffered and let go of the proxy (nothing left to flush at exit)."""
        self.flush()
        self.rec.disconnect()
