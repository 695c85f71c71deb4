"""The live display's schedule (``dashboards.live``): one buffered row of every turbine per display tick, sent in
units of a few entities, at most one unit per tick, every turbine's rows once each at their own sample times, no
row dropped when nobody sends; and the supervisor's refs never wait on the display."""

from __future__ import annotations

import threading
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import rerun as rr
from rerun.chunk import RrdReader

from dashboards.live import BUFFER_ROWS, FLUSH_ROWS, MIN_UNIT, LiveRecording, unit_size
from tests.live.helpers import FARM_SHORT, router, scenario
from windwarden.live.config import PlantSettings, SupervisorSettings
from windwarden.live.plant_node import PlantNode
from windwarden.live.supervisor_node import SupervisorNode
from windwarden.live.transport import open_session
from wwcore.wire import FARM_REFS, FARM_SENSORS, TURBINE_SENSORS

N = 80  # Horns Rev 1's turbines
EVERY = 10  # display_every: 10 Hz rows of a 100 Hz loop


def _frames(n: int, tick: int) -> tuple[np.ndarray, np.ndarray]:
    sensors, refs = FARM_SENSORS.empty(n), FARM_REFS.empty(n)
    sensors["turbine"] = refs["turbine"] = np.arange(1, n + 1)
    sensors["tick"] = refs["tick"] = tick
    sensors["t"] = 0.01 * tick
    refs["power_ref"] = 1e3 * np.arange(1, n + 1) + tick  # turbine and tick can be read back from the value
    refs["statistic"] = 0.5
    refs["threshold"] = 1.0
    return sensors, refs


def _rows_by_entity(path: Path) -> tuple[dict[str, list[tuple[int, float]]], dict[str, dict]]:
    """Each entity's (time ns, first scalar) rows in a recording, and its Scalars column's field metadata."""
    rows: dict[str, list[tuple[int, float]]] = {}
    meta: dict[str, dict] = {}
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        if "sim_time" not in batch.schema.names or "Scalars:scalars" not in batch.schema.names:
            continue
        times = batch.column("sim_time").cast("int64").to_pylist()
        values = batch.column("Scalars:scalars").to_pylist()
        rows.setdefault(chunk.entity_path, []).extend((t, v[0]) for t, v in zip(times, values, strict=True))
        meta[chunk.entity_path] = dict(batch.schema.field("Scalars:scalars").metadata)
    return rows, meta


def _run(recording: LiveRecording, ticks: int, pump: bool = True) -> list[int]:
    """Ticks of a supervisor: a display row every EVERY ticks, a pump every tick; the sends each pump made."""
    per_pump = []
    for k in range(ticks):
        if k % EVERY == 0:
            recording.supervisor_rows(*_frames(N, k))
        if pump:
            before = recording.sends
            recording.pump()
            per_pump.append(recording.sends - before)
    return per_pump


@pytest.mark.in_process
def test_every_turbine_gets_each_display_row_once_at_its_own_sample_time(tmp_path):
    recording = LiveRecording("farm", "supervisor", "sched", path=str(tmp_path / "s.rrd"), n_turbines=N)
    ticks = 20 * EVERY * FLUSH_ROWS  # 20 flush periods (20 s)
    per_pump = _run(recording, ticks)
    assert max(per_pump) == 1, "at most one send per tick"
    counters = recording.counters()
    assert counters["forced"] == 0 and counters["dropped"] == 0 and counters["deferred"] == 0
    assert counters["units"] <= EVERY * FLUSH_ROWS // 2  # every unit fits in half a period at one per tick
    assert max(u.stop - u.start for u in recording._units) <= max(MIN_UNIT, unit_size(2 * N, EVERY))
    # steady state: in every period each unit is sent once, so the sends per period are the units
    period = EVERY * FLUSH_ROWS
    sends_per_period = [sum(per_pump[i : i + period]) for i in range(period, ticks - period, period)]
    assert min(sends_per_period) >= counters["units"] - 1 and max(sends_per_period) <= counters["units"] + 1
    assert sum(per_pump) == pytest.approx(counters["units"] * ticks / period, abs=counters["units"])
    recording.close()

    rows, meta = _rows_by_entity(tmp_path / "s.rrd")
    samples = [round(0.01 * k * 1e9) for k in range(0, ticks, EVERY)]
    for turbine in range(1, N + 1):
        for suffix in ("power/supervisor", "detector/supervisor"):
            entity = f"/turbine/{turbine}/{suffix}"
            got = rows[entity]
            assert [t for t, _ in got] == samples, entity  # each row once, in order, at its sample time
            if suffix == "power/supervisor":
                expected = [(1e3 * turbine + k) / 1e6 for k in range(0, ticks, EVERY)]
                assert [v for _, v in got] == pytest.approx(expected)
    assert rows["/farm/power/supervisor"] and [t for t, _ in rows["/farm/power/supervisor"]] == samples
    # the record batches declare what ``rr.Scalars.columns`` declares: the viewer sees the same series
    (column,) = rr.Scalars.columns(scalars=[1.0])
    descriptor = column.component_descriptor()
    for entity, fields in meta.items():
        assert fields[b"rerun:component"].decode() == descriptor.component, entity
        assert fields[b"rerun:archetype"].decode() == descriptor.archetype, entity
        assert fields[b"rerun:component_type"].decode() == descriptor.component_type, entity


@pytest.mark.in_process
def test_nothing_is_dropped_when_nobody_pumps(tmp_path):
    """A node that never gets to send (always behind): a unit ``BUFFER_ROWS`` behind is sent when its next row
    comes, counted as forced, and every row still reaches the recording once."""
    recording = LiveRecording("farm", "supervisor", "starved", path=str(tmp_path / "s.rrd"), n_turbines=N)
    ticks = 7 * BUFFER_ROWS * EVERY
    _run(recording, ticks, pump=False)
    for _ in range(3):
        recording.defer()
    counters = recording.counters()
    assert counters["forced"] >= counters["units"] and counters["dropped"] == 0 and counters["deferred"] == 3
    assert counters["pending_unit_rows"] < counters["units"] * BUFFER_ROWS
    recording.close()
    rows, _ = _rows_by_entity(tmp_path / "s.rrd")
    samples = [round(0.01 * k * 1e9) for k in range(0, ticks, EVERY)]
    for turbine in (1, 40, 80):
        assert [t for t, _ in rows[f"/turbine/{turbine}/detector/supervisor"]] == samples
    assert Counter(len(r) for e, r in rows.items() if e.startswith("/turbine/")) == {len(samples): 2 * N}


@pytest.mark.in_process
def test_a_turbine_run_sends_each_group_as_its_own_unit(tmp_path):
    recording = LiveRecording("turbine", "plant", "one", path=str(tmp_path / "p.rrd"))
    assert unit_size(4, EVERY) == 4 and unit_size(2 * N, EVERY) == MIN_UNIT and unit_size(10_000, EVERY) == 200
    sensors = TURBINE_SENSORS.empty(1)
    sensors["turbine"] = 1
    for k in range(0, 300, EVERY):
        sensors["t"] = 0.01 * k
        recording.plant_rows(sensors, None)
        for _ in range(EVERY):
            recording.pump()
    assert all(u.stop - u.start == 1 for u in recording._units) and recording.counters()["forced"] == 0
    recording.close()
    rows, _ = _rows_by_entity(tmp_path / "p.rrd")
    assert len(rows["/turbine/1/speed/omega_g/plant"]) == 30


class _BlockingDisplay:
    """A display stub: the rows of display tick ``hold`` wait, inside the supervisor's loop, until the plant has
    taken that tick's refs (``taken``, or a timeout), recording whether it did."""

    def __init__(self, hold: int):
        self.hold = hold
        self.taken = threading.Event()
        self.rows_ticks: list[int] = []
        self.refs_taken_while_displaying: bool | None = None
        self.released = threading.Event()
        self.pumps = 0

    def supervisor_rows(self, records, refs, status) -> None:
        tick = int(refs["tick"][0])
        self.rows_ticks.append(tick)
        if tick == self.hold:
            self.refs_taken_while_displaying = self.taken.wait(20.0)
            self.released.set()

    def pump(self) -> None:
        self.pumps += 1

    def defer(self) -> None:
        pass

    def counters(self) -> dict:
        return {}

    def event(self, event) -> None:
        pass

    def close(self) -> None:
        pass


def test_the_refs_of_a_tick_reach_the_plant_while_its_display_work_still_runs(tmp_path):
    """Lockstep: the supervisor's display work for tick 50 does not end until the plant holds refs_50, which
    would never happen if the refs waited on the display."""
    run_dir = tmp_path / "run"
    display = _BlockingDisplay(hold=50)
    with router() as endpoint:
        sup_settings = SupervisorSettings(connect=endpoint, run_dir=run_dir)
        plant_settings = PlantSettings(connect=endpoint, mode="lockstep", run_dir=run_dir)
        sup_session, plant_session = open_session(sup_settings), open_session(plant_settings)
        supervisor = SupervisorNode(sup_session, sup_settings, lambda info: display)
        sup_thread = threading.Thread(target=supervisor.run, daemon=True)
        sup_thread.start()
        scn = scenario(FARM_SHORT, duration_s=1.0)
        plant = PlantNode(plant_session, plant_settings, scn, "run", run_dir)
        refs_for = plant._refs_for

        def refs_for_and_tell(k: int):  # the plant's tick k, once it has taken the refs that arrived
            if plant.latest_refs_tick >= display.hold:
                display.taken.set()
            return refs_for(k)

        plant._refs_for = refs_for_and_tell
        try:
            assert plant.run() == 0
            assert display.released.wait(20.0)
        finally:
            supervisor.stop()
            sup_thread.join(10)
            supervisor.close()
            plant.close()
            sup_session.close()
            plant_session.close()
    assert display.refs_taken_while_displaying is True
    assert display.rows_ticks == list(range(0, 100, EVERY))  # every display tick, once
    assert display.pumps >= 90  # a pump per tick (deferred when a frame waits)
