"""Hostile references and sensor frames against a live plant and supervisor (real time ×1, a router on loopback).

One system runs for the whole module, its probes in order (each test one probe; the last one checks the event
log): a hostile client (``hostile.HostileClient``) reads the sensor stream, so it knows the tick and the run
identity, and publishes

* forged references that look right (``valid``, the current tick) but ask ω_g = 200 rad/s (above the overspeed
  limit): the attack that took the rotor from 66 to 0.1 rad/s;
* NaN references (they crashed the plant);
* references for future ticks, one of them tick 10¹⁵ (it made the plant ignore every real reference);
* sensor frames with an old tick, a repeated tick, a foreign run identity and a far-future tick (old ticks reset the
  supervisor's observers and cleared every flagged fault).

Each is refused or dropped and counted, the plant keeps running on the supervisor's references (fresh all along,
the rotor where it was), the supervisor keeps its observers and its flag, and events.jsonl keeps every line it had.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from tests.live.helpers import LiveNodes, router, scenario, wait_for
from tests.security.hostile import HostileClient
from windwarden.live.runfolder import EVENTS, read_events
from wwcore.keys import KeyTree
from wwcore.wire import TURBINE_REFS, TURBINE_SENSORS, TURBINE_TRUTH

REGION_3 = """
name = "hostile"
duration_s = 600.0
[plant]
kind = "turbine"
[wind]
mean = [[0.0, 14.0]]
turbulence_intensity = 0.08
[[faults]]
name = "generator sensor 2 stuck"
target = "omega_g_m2"
kind = "fixed"
value = 100.0
start_s = 6.0
end_s = 600.0
"""


SUPERVISOR_REFS = KeyTree().refs("supervisor")  # the hostile client puts on the supervisor's own refs key
FIGURES: dict[str, str] = {}  # what each probe sent and what came of it, printed at the end (pytest -s)


class Truth:
    """The plant's ground truth (10 Hz): the rotor speed and the mean blade pitch, to see what an attack does."""

    def __init__(self, session, keys):
        self.rows: list[tuple[float, float, float]] = []
        self._lock = threading.Lock()
        self._sub = session.declare_subscriber(keys.truth, self._on)

    def _on(self, sample):
        r = TURBINE_TRUTH.decode_frame(sample.payload.to_bytes())[0]
        with self._lock:
            self.rows.append((float(r["t"]), float(r["omega_r"]), float(np.mean(r["pitch"]))))

    def since(self, t0):
        with self._lock:
            return np.array([row for row in self.rows if row[0] >= t0])


@pytest.fixture(scope="module")
def system(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("hostile") / "run"
    with router() as endpoint, LiveNodes(endpoint, scenario(REGION_3), run_dir, mode="realtime") as nodes:
        hostile = HostileClient(endpoint, TURBINE_SENSORS)
        truth = Truth(hostile.session, hostile.keys)
        try:
            assert wait_for(lambda: hostile.plant_status()["t"] > 9.0, 60), "the plant did not get going"
            assert hostile.plant_status()["refs_fresh"] and "omega_g_m2" in flagged(hostile)
            yield nodes, hostile, truth, (run_dir / EVENTS).read_bytes()
        finally:
            hostile.close()


def flagged(hostile):
    return hostile.supervisor_status()["turbines"][0]["flagged"]


def refused(hostile):
    return hostile.plant_status()["refs_refused"]


def refs_for(record, **fields):
    rec = TURBINE_REFS.empty(1)
    rec[["tick", "turbine", "valid", "omega_g", "omega_r", "wind"]] = (record["tick"], 1, True, 160.0, 1.7, 14.0)
    for name, value in fields.items():
        rec[name] = value
    return rec


def assert_running_on_real_refs(hostile, truth, t0, probe=""):
    """The plant goes on, on the supervisor's references (fresh again at once if the loaded machine made them late
    for a moment: the plant, the supervisor and this client share one Python process here); the rotor turns at its
    region-3 speed and the pitch stays low."""
    assert wait_for(lambda: hostile.plant_status()["refs_fresh"], 5)
    status = hostile.plant_status()
    assert status["state"] == "running"
    rows = truth.since(t0)
    assert len(rows) >= 5
    FIGURES[probe] += (
        f"; rotor {rows[:, 1].min():.3f}–{rows[:, 1].max():.3f} rad/s, pitch ≤ {rows[:, 2].max():.1f} deg over "
        f"{rows[-1, 0] - rows[0, 0]:.1f} s; refs fresh; refused so far {status['refs_refused']}"
    )
    assert rows[:, 1].min() > 1.4, rows[:, 1].min()  # rad/s; rated 1.705 (the attack took it to 0.1)
    assert rows[:, 2].max() < 25.0, rows[:, 2].max()  # deg; the attack took it to 89.9


def test_forged_refs_out_of_range_are_refused(system):
    _, hostile, truth, _ = system
    t0, before = hostile.plant_status()["t"], refused(hostile).get("out_of_range", 0)
    sent = hostile.flood(SUPERVISOR_REFS, TURBINE_REFS, lambda r: refs_for(r, omega_g=200.0), seconds=1.5)
    assert wait_for(lambda: refused(hostile).get("out_of_range", 0) - before >= 0.9 * sent, 5)
    FIGURES["ω_g = 200"] = f"{sent} sent, {refused(hostile)['out_of_range'] - before} refused out_of_range"
    time.sleep(1.0)  # what the attack would have done shows within a second
    assert_running_on_real_refs(hostile, truth, t0, "ω_g = 200")


def test_nan_refs_are_refused(system):
    nodes, hostile, truth, _ = system
    t0, before = hostile.plant_status()["t"], refused(hostile).get("non_finite", 0)
    sent = hostile.flood(SUPERVISOR_REFS, TURBINE_REFS, lambda r: refs_for(r, omega_g=np.nan), seconds=1.0)
    assert wait_for(lambda: refused(hostile).get("non_finite", 0) - before >= 0.9 * sent, 5)
    FIGURES["NaN"] = f"{sent} sent, {refused(hostile)['non_finite'] - before} refused non_finite"
    assert nodes.error is None and not nodes.done.is_set()
    assert_running_on_real_refs(hostile, truth, t0, "NaN")


def test_future_tick_refs_are_refused(system):
    _, hostile, truth, _ = system
    t0, before = hostile.plant_status()["t"], refused(hostile).get("future_tick", 0)
    hostile.put(SUPERVISOR_REFS, TURBINE_REFS, refs_for(hostile.sensed(), tick=10**15))
    sent = 1 + hostile.flood(SUPERVISOR_REFS, TURBINE_REFS, lambda r: refs_for(r, tick=r["tick"] + 1000), seconds=1.0)
    assert wait_for(lambda: refused(hostile).get("future_tick", 0) - before >= 0.9 * sent, 5)
    FIGURES["future ticks"] = f"{sent} sent, {refused(hostile)['future_tick'] - before} refused future_tick"
    received = hostile.plant_status()["refs_received"]
    assert wait_for(lambda: hostile.plant_status()["refs_received"] > received + 50, 5)  # real refs still taken
    assert_running_on_real_refs(hostile, truth, t0, "future ticks")


def test_forged_sensor_frames_are_dropped(system):
    _, hostile, _, _ = system
    before = hostile.supervisor_status()
    assert before["observer_restarts"] == 0

    def frame(record, tick, run=None):
        rec = np.array([record], dtype=TURBINE_SENSORS.dtype)
        rec["tick"] = tick
        if run is not None:
            rec["run"] = run
        return rec

    key, schema = hostile.keys.sensors, TURBINE_SENSORS
    rng = np.random.default_rng(5)
    sent = {
        "old_tick": hostile.flood(key, schema, lambda r: frame(r, r["tick"] - 100), seconds=0.5),
        "repeated_tick": hostile.flood(key, schema, lambda r: frame(r, r["tick"]), seconds=0.5),
        "foreign_run": hostile.flood(
            key, schema, lambda r: frame(r, r["tick"] + 1, int(rng.integers(1, 2**52))), seconds=0.5
        ),
        "unconfirmed_tick": hostile.flood(key, schema, lambda r: frame(r, r["tick"] + 10**6), seconds=0.5),
    }

    def dropped(reason):
        return hostile.supervisor_status()["refused"].get(reason, 0) - before["refused"].get(reason, 0)

    def counted():  # a frame of the newest tick may arrive once the next is stepped: old rather than repeated
        stale = sent["old_tick"] + sent["repeated_tick"]
        return (
            dropped("old_tick") + dropped("repeated_tick") >= 0.9 * stale
            and min(dropped("old_tick"), dropped("repeated_tick")) > 0
            and dropped("foreign_run") >= 0.9 * sent["foreign_run"]
        )

    assert wait_for(counted, 5), (sent, hostile.supervisor_status()["refused"], before["refused"])
    assert dropped("unconfirmed_tick") >= 1  # the first is checked with the plant, the others within its rate limit
    after = hostile.supervisor_status()
    FIGURES["frames"] = (
        f"sent {sent}; dropped {after['refused']}; observer restarts {after['observer_restarts']}; "
        f"flagged {flagged(hostile)}"
    )
    assert after["observer_restarts"] == 0 and "omega_g_m2" in flagged(hostile)
    assert after["stream_fresh"] and after["tick"] > before["tick"]


def test_refusals_are_logged_rate_limited_and_nothing_is_lost(system):
    nodes, _, _, before = system
    events = (nodes.run_dir / EVENTS).read_bytes()
    assert events.startswith(before)
    logged = [e for e in read_events(nodes.run_dir / EVENTS) if "refused" in e.detail]
    reasons = {(e.detail["stream"], e.detail["refused"]) for e in logged}
    assert {("refs", "out_of_range"), ("refs", "non_finite"), ("refs", "future_tick")} <= reasons
    assert {("sensors", "old_tick"), ("sensors", "repeated_tick"), ("sensors", "foreign_run")} <= reasons
    for reason in reasons:  # one event per reason and second at most; each probe lasted ≤ 1.5 s
        assert sum(1 for e in logged if (e.detail["stream"], e.detail["refused"]) == reason) <= 3
    assert not any(
        e.type.value == "detection" and e.target != "omega_g_m2" for e in read_events(nodes.run_dir / EVENTS)
    )
    FIGURES["events"] = f"{len(logged)} refusal events: " + ", ".join(
        f"{stream}:{reason} ×{sum(1 for e in logged if (e.detail['stream'], e.detail['refused']) == (stream, reason))}"
        for stream, reason in sorted(reasons)
    )
    print("\n" + "\n".join(f"{probe}: {text}" for probe, text in FIGURES.items()))
