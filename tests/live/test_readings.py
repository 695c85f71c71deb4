"""Non-finite readings on the way to the supervisor (``windwarden.live.readings.ReadingHold``): held at the channel's
last finite value and counted; a frame with nothing to hold is refused and changes nothing. End to end
(``batch.run_batch`` with ``corrupt``, the supervisor node's handling without a network): a turbine's dead
rotor-speed sensor is flagged as a stuck sensor and the supervisor keeps control through it; a hydrostatic turbine's
and a farm's scorecards do not change when a reading goes missing outside their fault windows."""

from __future__ import annotations

import numpy as np
import pytest

from tests.live.helpers import FARM_SHORT, HYDRO_SHORT, scenario
from windwarden.live.batch import run_batch
from windwarden.live.readings import ReadingHold
from windwarden.live.supervisor_node import SupervisorNode
from wwcore.channels import SENSOR_NAMES
from wwcore.events import EventType
from wwcore.wire import TURBINE_SENSORS, DropCounter, DropReason

pytestmark = pytest.mark.in_process

OMEGA_R_M1 = SENSOR_NAMES.index("omega_r_m1")


def turbine_records(k: int, rows: int = 1, value: float = 1.0) -> np.ndarray:
    records = np.zeros(rows, dtype=TURBINE_SENSORS.dtype)
    records["tick"], records["t"], records["turbine"] = k, 0.01 * k, np.arange(rows)
    records["sensors"] = value + np.arange(len(SENSOR_NAMES))
    records["tau_g_ref"] = 3e4
    return records


def test_finite_frames_pass_untouched():
    hold = ReadingHold(TURBINE_SENSORS)
    records = turbine_records(0)
    assert hold.take(records) is records and not hold.held


def test_a_non_finite_reading_is_held_at_the_last_finite_one():
    hold = ReadingHold(TURBINE_SENSORS)
    hold.take(turbine_records(0, rows=2, value=1.0))
    bad = turbine_records(1, rows=2, value=2.0)
    bad["sensors"][1, OMEGA_R_M1] = np.nan
    bad["sensors"][0, 3] = np.inf
    bad["tau_g_ref"][1] = -np.inf
    sent = bad.copy()
    out = hold.take(bad)
    assert bad.tobytes() == sent.tobytes()  # the frame received is not changed
    expected = turbine_records(1, rows=2, value=2.0)
    expected["sensors"][1, OMEGA_R_M1] = 1.0 + OMEGA_R_M1
    expected["sensors"][0, 3] = 1.0 + 3
    expected["tau_g_ref"][1] = 3e4
    assert out.tobytes() == expected.tobytes()
    assert dict(hold.held) == {"sensors.omega_r_m1": 1, f"sensors.{SENSOR_NAMES[3]}": 1, "tau_g_ref": 1}
    again = turbine_records(2, rows=2, value=3.0)
    again["sensors"][1, OMEGA_R_M1] = np.nan
    assert hold.take(again)["sensors"][1, OMEGA_R_M1] == 1.0 + OMEGA_R_M1  # held while it stays dead
    assert hold.held["sensors.omega_r_m1"] == 2


def test_a_frame_with_nothing_to_hold_is_refused_and_changes_nothing():
    hold = ReadingHold(TURBINE_SENSORS)
    first = turbine_records(0)
    first["sensors"][0, OMEGA_R_M1] = np.nan
    assert hold.take(first) is None and hold.last is None and not hold.held  # no finite value yet
    good = turbine_records(1)
    hold.take(good)
    for field, value in (("t", np.nan), ("t", np.inf)):
        bad = turbine_records(2, value=5.0)
        bad["sensors"][0, 0] = np.nan
        bad[field] = value
        assert hold.take(bad) is None and hold.last is good and not hold.held
    other = turbine_records(2, rows=3)  # a frame of other rows than the one held: nothing to hold from
    other["sensors"][2, 0] = np.nan
    assert hold.take(other) is None and hold.last is good and not hold.held
    hold.restart()
    assert hold.take(first) is None


def test_the_supervisor_node_counts_refusals_and_logs_each_channel_once():
    node = object.__new__(SupervisorNode)
    node.drops, node.readings, written = DropCounter(), ReadingHold(TURBINE_SENSORS), []
    node._write = written.extend
    first = turbine_records(0)
    first["sensors"][0, OMEGA_R_M1] = np.nan
    assert node._hold_non_finite(first) is None
    assert node.drops.of("sensors") == {DropReason.NON_FINITE: 1} and not written
    node._hold_non_finite(turbine_records(1))
    for k in (2, 3):
        dead = turbine_records(k)
        dead["sensors"][0, OMEGA_R_M1] = np.nan
        assert np.isfinite(node._hold_non_finite(dead)["sensors"]).all()
    assert len(written) == 1 and written[0].type == EventType.STREAM
    assert written[0].detail["held_non_finite"] == ["sensors.omega_r_m1"]


DEAD_SENSOR = """
name = "dead-rotor-speed-sensor"
duration_s = 60.0
[plant]
kind = "turbine"
[wind]
mean = [[0.0, 11.0], [60.0, 11.0]]
turbulence_intensity = 0.12
"""


def test_a_dead_rotor_speed_sensor_is_flagged_and_the_supervisor_keeps_control():
    """ω_r,m1 reads NaN from 12 s to 40 s: held, it is a sensor stuck at its last reading, flagged within a few ticks
    and cleared once it reads again; no other flag (the scenario has no fault, so the flag is scored as a false
    alarm: the only one)."""

    def dead(k: int, records: np.ndarray) -> np.ndarray:
        if 1200 <= k < 4000:
            records["sensors"][:, OMEGA_R_M1] = np.nan
        return records

    result = run_batch(scenario(DEAD_SENSOR), 3, corrupt=dead)
    assert result.held == {"sensors.omega_r_m1": 2800} and result.refused == 0
    detections = [e.t for e in result.events if e.type == EventType.DETECTION]
    recoveries = [e.t for e in result.events if e.type == EventType.RECOVERY]
    assert len(detections) == 1 and 12.0 <= detections[0] <= 12.1
    assert len(recoveries) == 1 and 40.0 <= recoveries[0] <= 41.0
    false_alarms = result.scorecard["false_alarms"]
    assert false_alarms["by_target"] == {"omega_r_m1": 1}
    assert 27.9 <= false_alarms["flagged_s"] <= 29.0


def test_hydro_and_farm_scorecards_do_not_change_when_a_reading_is_missing_outside_the_fault_windows():
    def hydro_dead(k: int, records: np.ndarray) -> np.ndarray:
        if 200 <= k < 260:  # 2.0–2.6 s, before the pump fault at 3 s
            records["y"][:, 0] = np.nan
        return records

    hydro = scenario(HYDRO_SHORT)
    held = run_batch(hydro, 3, corrupt=hydro_dead)
    assert held.held == {"y.omega_r": 60} and held.refused == 0
    assert held.scorecard["faults"] == run_batch(hydro, 3).scorecard["faults"]

    def farm_dead(k: int, records: np.ndarray) -> np.ndarray:
        if 1000 <= k < 1500:  # 10–15 s: one turbine's rotor-speed sensor and the met mast
            records["sensors"][2, OMEGA_R_M1] = np.nan
            records["mast"] = np.inf
        if records["sample"][0] and 2000 <= k < 2500:  # a SCADA mean of another turbine
            records["scada"][4, 2] = np.nan
        return records

    farm = scenario(FARM_SHORT)
    held = run_batch(farm, 3, corrupt=farm_dead)
    assert held.held == {"mast": 9 * 500, "scada.omega_g_m1": 50, "sensors.omega_r_m1": 500} and held.refused == 0
    base = run_batch(farm, 3).scorecard
    assert held.scorecard["faults"] == base["faults"]
    assert held.scorecard["false_alarms"] == base["false_alarms"]
