"""Logging a live run into Rerun: both processes into one recording, stamped with simulation time.

Plant and supervisor each open a ``RecordingStream`` with the same application id and the run's recording id,
and push to one Rerun gRPC proxy (``windwarden up`` starts one that also saves ``recording.rrd``); the proxy and
every viewer merge the two streams into one recording. Events become state timelines (faults injected vs detected,
selected observer) and a text log. A farm's overview adds a map (``dashboards.farm_map``): the plant logs the
layout and the wind once, the supervisor the turbines' states when they change.

**What a tick pays.** Rows arrive already down-sampled by the nodes (``display_every``, 10 Hz by default), one call
per display tick for every turbine of the frame: the panel (``dashboards.panels``) builds each series group's
columns for all turbines at once with numpy, and they are copied into one buffer per group (rows × turbines ×
series), with their sample times. Nothing is sent then. Sending is spread over ticks: each group's turbines are cut
into *units* of a few entities, and ``pump()`` (once per tick, by the node, after the tick's own work) sends the
next unit that holds ``FLUSH_ROWS`` unsent rows, as one ``rerun.send_record_batch`` of its entities (one Rerun call
for several entities, their rows since the unit's last send, stamped with their own sample times). Units are sized
so that a flush period (``FLUSH_ROWS`` display rows, ``display_every × FLUSH_ROWS`` ticks) needs at most half its
ticks to send every unit once: each turbine's series reach the recording once a simulated second, and no tick
sends more than one unit. A node may skip ``pump()`` when it is behind (it is then counted, ``deferred``); if a
unit falls ``BUFFER_ROWS`` rows behind, it is sent at once when the next row comes (``forced``), so no row is
ever dropped. ``counters()`` reports rows, sends and both counts for the nodes' status.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np
import pyarrow as pa
import rerun as rr
from rerun.chunk import Chunk

from dashboards.blueprints import blueprint
from dashboards.farm_map import MapColours, WindArrow, log_geometry
from dashboards.panels import PANELS, Columns, Rows
from wwcore.events import Event, EventType

APPLICATION_ID = "windwarden"
TIMELINE = "sim_time"
_UNSAFE = re.compile(r"[^A-Za-z0-9_\-/.]")  # entity path parts: letters, digits, _ - . only
FLUSH_ROWS = 10  # rows a unit holds before it is due to be sent (1 s of simulation time at 10 Hz)
BUFFER_ROWS = 5 * FLUSH_ROWS  # a unit this far behind is sent at once: nobody pumps, do not let it grow
DISPLAY_EVERY = 10  # ticks between two display rows, when the node does not say (``display_every``)
MIN_UNIT = 16  # entities per send where a group has them: a send's fixed cost is about that of a few entities

_TIME_FIELD = pa.field(TIMELINE, pa.duration("ns"), metadata={"rerun:kind": "index", "rerun:index_name": TIMELINE})
_SCALARS = {  # what ``rr.Scalars.columns`` declares for its one component, as Arrow field metadata
    "rerun:kind": "data",
    "rerun:archetype": "rerun.archetypes.Scalars",
    "rerun:component": "Scalars:scalars",
    "rerun:component_type": "rerun.components.Scalar",
}


@dataclass(eq=False)
class _Unit:
    """Entities ``start:stop`` of a group, sent together; ``sent`` rows of the group's buffer are out."""

    group: _Group
    start: int
    stop: int
    sent: int = 0
    declared: bool = False  # the entities' series names and colours (static) went out with the first send


@dataclass(eq=False)
class _Group:
    """Buffered rows of one series group for several entities (a turbine each, or one of the whole plant)."""

    paths: list[str]
    names: list[str]
    key: Any  # what the entities are (the turbine numbers): rows of other entities start a new group
    fields: list[pa.Field] = field(init=False)
    times: np.ndarray = field(init=False)
    values: np.ndarray = field(init=False)  # rows × entities × series
    filled: int = 0
    units: list[_Unit] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.fields = [
            pa.field(path, pa.list_(pa.float64()), metadata={**_SCALARS, "rerun:entity_path": path})
            for path in self.paths
        ]
        self.times = np.empty(BUFFER_ROWS + 1)
        self.values = np.empty((BUFFER_ROWS + 1, len(self.paths), len(self.names)))


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


def _record_batch(unit: _Unit) -> pa.RecordBatch:
    """The unit's unsent rows: a ``sim_time`` column and, per entity, a column of ``Scalars`` (its series' values
    of each row), the entity named by the column's metadata, as ``rr.send_columns`` would send each of them."""
    group = unit.group
    lo, hi = unit.sent, group.filled
    n, width = hi - lo, len(group.names)
    entities = unit.stop - unit.start
    block = np.ascontiguousarray(group.values[lo:hi, unit.start : unit.stop, :].transpose(1, 0, 2))
    nanoseconds = np.rint(group.times[lo:hi] * 1e9).astype("timedelta64[ns]")  # the sample time, to the nearest ns
    arrays: list[pa.Array] = [pa.array(nanoseconds, pa.duration("ns"))]
    # one list array of every entity's rows (entity-major), each entity's column a zero-copy slice of it: one Arrow
    # construction per send instead of one per entity
    offsets = pa.array(np.arange(0, entities * n * width + 1, width, dtype=np.int32))
    rows = pa.ListArray.from_arrays(offsets, pa.array(block.ravel()))
    arrays += [rows.slice(e * n, n) for e in range(entities)]
    return pa.RecordBatch.from_arrays(arrays, schema=pa.schema([_TIME_FIELD, *group.fields[unit.start : unit.stop]]))


def _turbine_paths(turbines: np.ndarray, suffix: str) -> list[str]:
    return [f"/turbine/{int(k)}/{suffix}" for k in turbines]


def unit_size(n_entities: int, display_every: int) -> int:
    """Entities per send: at least ``MIN_UNIT`` (fewer Rerun calls), and enough that every one of ``n_entities``
    is sent once in half a flush period's ticks at one unit per tick."""
    ticks = max(display_every * FLUSH_ROWS // 2, 1)
    return max(1, min(MIN_UNIT, n_entities), math.ceil(n_entities / ticks))


def warm_up() -> None:
    """Build (not send) what the first display rows build, so that Rerun's and pyarrow's lazy imports (the first
    ``Points2D.columns`` takes ~0.4 s) happen before the node's loop starts, not on its first ticks."""
    rr.Points2D.columns(colors=np.zeros((1, 4), dtype=np.uint8)).partition([1])
    rr.Arrows2D.columns(origins=[(0.0, 0.0)], vectors=[(1.0, 0.0)]).partition([1])
    rr.StateChange.columns(state=["warm"])
    rr.TextLog.columns(text=["warm"], level=["INFO"])
    rr.SeriesLines(names=["warm"], colors=[(0, 0, 0)])
    group = _Group(["/warm"], ["warm"], ())
    group.times[0], group.values[0] = 0.0, 0.0
    group.filled = 1
    Chunk.from_record_batch(_record_batch(_Unit(group, 0, 1)), index=TIMELINE)


class LiveRecording:
    """One process's share of the run's recording. ``role`` is "plant" or "supervisor".

    ``plant_rows`` / ``supervisor_rows`` buffer one display row of every turbine (cheap, vectorised); ``pump()``
    sends at most one unit of buffered rows per tick (module docstring).
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
        display_every: int = DISPLAY_EVERY,
    ):
        self.kind = kind
        self.role = role
        self.panel = PANELS[kind]
        self.turbines = turbines or list(range(1, n_turbines + 1))
        self.display_every = display_every
        self.rec = open_stream(recording_id, url, path)
        warm_up()
        self._groups: dict[str, _Group] = {}
        self._units: list[_Unit] = []
        self._next = 0
        self.rows = 0  # entity rows buffered
        self.sends = 0  # Rerun calls that sent rows
        self.deferred = 0  # ticks the node skipped pump() (it was behind)
        self.forced = 0  # units sent when their row came, BUFFER_ROWS behind
        self.send_s = 0.0  # wall time spent sending
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

    # -- buffering ----------------------------------------------------------------------------------------------
    def _append(
        self, suffix: str, paths: Callable[[], list[str]], key: Any, t: float, columns: dict[str, Any], size: int = 1
    ) -> None:
        """One row of ``columns`` (series name → one value per entity, or one for all) at time ``t``; a new group
        is cut into units of ``size`` entities."""
        group = self._groups.get(suffix)
        names = list(columns)
        if group is None or group.names != names or not np.array_equal(group.key, key):
            if group is not None:
                self._retire(group)
            group = self._groups[suffix] = _Group(paths(), names, np.array(key, copy=True))
            group.units = [_Unit(group, i, min(i + size, len(group.paths))) for i in range(0, len(group.paths), size)]
            self._units.extend(group.units)
        if group.filled == len(group.times):
            self._compact(group)
        row = group.filled
        group.times[row] = t
        values = group.values[row]
        for j, name in enumerate(names):
            values[:, j] = columns[name]
        group.filled += 1
        self.rows += len(group.paths)
        for unit in group.units:
            if group.filled - unit.sent >= BUFFER_ROWS:
                self.forced += 1
                self._send(unit)

    def _compact(self, group: _Group) -> None:
        """Drop the rows every unit has sent (a unit that has sent none is sent first: nothing is lost)."""
        for unit in group.units:
            if unit.sent == 0:
                self.forced += 1
                self._send(unit)
        done = min(u.sent for u in group.units)
        keep = group.filled - done
        group.times[:keep] = group.times[done : group.filled]
        group.values[:keep] = group.values[done : group.filled]
        group.filled = keep
        for unit in group.units:
            unit.sent -= done

    def _retire(self, group: _Group) -> None:
        for unit in group.units:
            self._send(unit)
        self._units = [u for u in self._units if u.group is not group]
        self._next = 0

    def _send(self, unit: _Unit) -> None:
        """The unit's unsent rows as one record batch: a time column and a Scalars column per entity."""
        group = unit.group
        lo, hi = unit.sent, group.filled
        if hi <= lo:
            return
        started = time.perf_counter()
        if not unit.declared:
            self._declare(unit)
        rr.send_record_batch(_record_batch(unit), recording=self.rec, index=TIMELINE)
        unit.sent = hi
        self.sends += 1
        self.send_s += time.perf_counter() - started

    def _declare(self, unit: _Unit) -> None:
        group = unit.group
        colors = [self.panel.colors.get(name, (90, 90, 90)) for name in group.names]
        lines = rr.SeriesLines(names=group.names, colors=colors)
        for path in group.paths[unit.start : unit.stop]:
            self.rec.log(path, lines, static=True)
        unit.declared = True

    def pump(self) -> None:
        """Send the next unit that holds a flush period's rows (round robin); cheap when there is none."""
        n = len(self._units)
        for i in range(n):
            unit = self._units[(self._next + i) % n]
            if unit.group.filled - unit.sent >= FLUSH_ROWS:
                self._send(unit)
                self._next = (self._next + i + 1) % n
                return

    def defer(self) -> None:
        """The node skipped ``pump()`` on this tick (it was behind)."""
        self.deferred += 1

    def flush_series(self) -> None:
        for unit in self._units:
            self._send(unit)

    def counters(self) -> dict[str, Any]:
        """What the display has buffered and sent so far, for the node's status."""
        pending = sum(u.group.filled - u.sent for u in self._units)
        return {
            "rows": self.rows,
            "sends": self.sends,
            "send_ms": round(1e3 * self.send_s, 1),
            "units": len(self._units),
            "pending_unit_rows": pending,
            "deferred": self.deferred,
            "forced": self.forced,
            "dropped": 0,  # by construction: a unit too far behind is sent, never dropped
        }

    # -- rows of a frame ----------------------------------------------------------------------------------------
    def _turbine_columns(self, turbines: np.ndarray, t: float, columns: Columns) -> None:
        size = unit_size(len(columns) * len(turbines), self.display_every)
        for suffix, row in columns.items():
            safe = _UNSAFE.sub("_", suffix)
            self._append(f"/turbine/*/{safe}", partial(_turbine_paths, turbines, safe), turbines, t, row, size)

    def _farm_rows(self, t: float, rows: Rows) -> None:
        for suffix, row in rows.items():
            path = f"/farm/{_UNSAFE.sub('_', suffix)}"
            self._append(path, lambda path=path: [path], (), t, row)

    def plant_rows(self, sensors: np.ndarray, truth: np.ndarray | None) -> None:
        """One display row of every turbine of the plant's frame (and of the farm), at the frame's time."""
        if not len(sensors):
            return
        t = float(sensors["t"][0])
        self._turbine_columns(np.asarray(sensors["turbine"]), t, self.panel.plant(sensors, truth))
        if self.panel.farm_plant is not None:
            self._farm_rows(t, self.panel.farm_plant(sensors, truth))
        if self.wind_arrow is not None and "mast_direction" in (sensors.dtype.names or ()):
            self.wind_arrow.update(self.rec, TIMELINE, t, float(sensors["mast_direction"][0]))

    def supervisor_rows(
        self,
        sensors: np.ndarray,
        refs: np.ndarray,
        status: Callable[[], list[dict[str, Any]]] | list[dict[str, Any]] | None = None,
    ) -> None:
        """One display row of every turbine of the supervisor's refs frame. ``status`` (the per-turbine status, or
        a function that builds it) is read only by panels that show it (``Panel.uses_status``)."""
        if not len(refs):
            return
        t = float(sensors["t"][0])
        turbine_status = None
        if self.panel.uses_status:
            turbine_status = status() if callable(status) else status
        self._turbine_columns(np.asarray(refs["turbine"]), t, self.panel.supervisor(sensors, refs, turbine_status))
        if self.panel.farm_supervisor is not None:
            self._farm_rows(t, self.panel.farm_supervisor(sensors, refs))
        if self.map_colours is not None:
            self.map_colours.update(self.rec, TIMELINE, t, refs)

    def timing(self, t: float, status: dict[str, Any]) -> None:
        """The plant's loop figures (at the status rate): latency over the last 1000 ticks, overruns so far."""
        latency = status.get("latency_recent") or {}
        nan = float("nan")
        row = {
            "latency p50 ms": latency.get("p50_ms") or nan,
            "latency p99 ms": latency.get("p99_ms") or nan,
            "overruns": status.get("overruns") or 0.0,
        }
        self._append("/run/timing", lambda: ["/run/timing"], (), t, row)

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
