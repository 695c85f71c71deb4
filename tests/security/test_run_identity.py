"""The run identity on every frame, end to end: one supervisor serves two plant runs one after the other (lockstep,
a router on loopback). It restarts its observers once, when the second run's identity appears and the plant
confirms it, and both runs get every reference (lockstep waits for each) and their own supervisor events."""

from __future__ import annotations

import threading

from tests.live.helpers import HYDRO_SHORT, router, scenario
from windwarden.live.config import PlantSettings, SupervisorSettings
from windwarden.live.finalize import finalize_scorecard
from windwarden.live.plant_node import PlantNode
from windwarden.live.runfolder import EVENTS, read_events
from windwarden.live.supervisor_node import SupervisorNode
from windwarden.live.transport import open_session


def test_a_new_run_restarts_the_observers_once(tmp_path):
    scn = scenario(HYDRO_SHORT, duration_s=4.0, faults=[])
    with router() as endpoint:
        sup_settings = SupervisorSettings(connect=endpoint, runs_root=tmp_path)
        with open_session(sup_settings) as sup_session:
            supervisor = SupervisorNode(sup_session, sup_settings)
            thread = threading.Thread(target=supervisor.run, daemon=True)
            thread.start()
            keys = []
            try:
                for run_id in ("first", "second"):
                    settings = PlantSettings(connect=endpoint, mode="lockstep", seed=1, run_dir=tmp_path / run_id)
                    with open_session(settings) as session:
                        plant = PlantNode(session, settings, scn, run_id, tmp_path / run_id)
                        try:
                            assert plant.run() == 0
                        finally:
                            plant.close()
                    keys.append(plant.run_key)
                status = supervisor.status()
            finally:
                supervisor.stop()
                thread.join(10)
                supervisor.close()
    assert keys[0] != keys[1]
    assert status["run_id"] == "second" and status["observer_restarts"] == 1 and status["refused"] == {}
    for run_id in ("first", "second"):
        card = finalize_scorecard(tmp_path / run_id)
        assert card["live"]["completed"] and card["live"]["ticks_without_refs"] == 0
        events = read_events(tmp_path / run_id / EVENTS)
        assert any(e.detail.get("noticed_by") == "supervisor" for e in events)  # each run has its own log
