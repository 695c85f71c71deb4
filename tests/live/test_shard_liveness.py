"""A shard lost mid-run: the coordinator notices it within its bound, logs and counts it, names it in its status and
goes on deciding for the other shard's turbines, whose references stay fresh at the plant while the lost shard's
turbines keep their last ones; the shard restarted with the same turbines rejoins (real time, threads on loopback).
Its bad settings are refused."""

from __future__ import annotations

import time

import numpy as np
import pytest
from pydantic import ValidationError

from tests.live.helpers import LiveNodes, router, scenario, wait_for
from tests.live.shard_helpers import Sharded
from windwarden.live.coordinator import CoordinatorSettings
from windwarden.live.runfolder import EVENTS, read_events

FARM = """
name = "farm-shard-liveness"
duration_s = 60.0
[plant]
kind = "farm"
[plant.demand]
mode = "available_fraction"
fraction = 0.8
update_s = 10.0
[wind]
mean = [[0.0, 10.0], [60.0, 11.0]]
"""
A, B = (1, 2, 3, 4), (5, 6, 7, 8, 9)
LOST_AFTER = CoordinatorSettings().shard_lost_samples  # farm samples, 10 Hz
BOUND_S = LOST_AFTER * 0.1 + 2.0  # the rule's 1 s of farm time and what a loaded 2-core machine adds to it


def _liveliness(run_dir, alive: bool) -> list:
    events = read_events(run_dir / EVENTS)
    shard = [e for e in events if e.type.value == "liveliness" and e.detail.get("process") == "shard"]
    return [e for e in shard if e.detail["alive"] is alive]


def _computed(plant, rows: slice) -> np.ndarray:
    refs = plant.latest_refs
    return np.array([-1]) if refs is None else np.array(refs["computed_tick"][rows])


def test_a_killed_shard_is_noticed_the_farm_goes_on_and_the_restarted_shard_rejoins(tmp_path):
    run_dir = tmp_path / "run"
    with router() as endpoint, Sharded(endpoint, [(endpoint, A), (endpoint, B)], run_dir) as sharded:
        with LiveNodes(
            endpoint, scenario(FARM), run_dir, mode="realtime", seed=3, supervisor=False, supervisor_wait_s=30.0
        ) as nodes:
            plant, coordinator = nodes.plant, sharded.coordinator
            assert wait_for(lambda: plant.plant.t >= 1.5 and plant.freshness.fresh, 30), "the farm did not start"
            assert _computed(plant, slice(None)).min() >= 0

            killed_at = time.monotonic()
            sharded.kill(1)
            assert wait_for(lambda: "5-9" in coordinator.status()["lost_shards"], BOUND_S), coordinator.status()
            detection_s = time.monotonic() - killed_at
            status = coordinator.status()
            assert status["held_turbines"] == list(B) and status["shards_lost"] == 1 and status["ready"]
            assert status["shards"]["5-9"] == {"run_id": run_dir.name, "turbines": list(B), "ready": False, "lost": True}
            assert status["coverage"] == "degraded: turbines held"
            assert [t["turbine"] for t in status["turbines"] if not t["supervised"]] == list(B)
            lost = _liveliness(run_dir, alive=False)
            assert len(lost) == 1 and lost[0].detail["shard"] == "5-9" and lost[0].detail["turbines"] == list(B)
            assert lost[0].detail["noticed_by"] == "coordinator" and "farm samples" in lost[0].detail["reason"]

            # the other shard's turbines get fresh references, from farm samples decided after the loss
            decided = coordinator.last_tick
            assert wait_for(lambda: _computed(plant, slice(0, 4)).min() >= decided + 100, 10), _computed(plant, slice(0, 4))
            assert plant.freshness.fresh and plant.status()["refs_unserved"] == list(B)
            # ... while the lost shard's turbines keep the last reference they had, farm sample after farm sample
            held = np.array(plant.latest_refs["power_ref"][4:])
            decided = coordinator.last_tick
            assert wait_for(lambda: _computed(plant, slice(None)).min() >= decided + 100, 10)
            assert np.array_equal(plant.latest_refs["power_ref"][4:], held)
            assert (plant.latest_refs["ripple_rate"][4:] == 0).all()

            rejoined_at = time.monotonic()
            sharded.restart(1)
            assert wait_for(lambda: coordinator.status()["shards_rejoined"] == 1, 20), coordinator.status()
            rejoin_s = time.monotonic() - rejoined_at
            status = coordinator.status()
            assert status["lost_shards"] == {} and status["held_turbines"] == [] and status["coverage"] == "complete"
            back = _liveliness(run_dir, alive=True)
            assert len(back) == 1 and back[0].detail["shard"] == "5-9" and back[0].detail["turbines"] == list(B)
            # every turbine's references fresh again, from one farm sample
            since = coordinator.last_tick
            assert wait_for(lambda: _computed(plant, slice(None)).min() >= since, 10), _computed(plant, slice(None))
            assert plant.status()["refs_unserved"] == []
            plant.stop()
            assert nodes.wait(30) == 0
        assert not sharded.errors
    print(f"lost shard noticed {detection_s:.2f} s after the kill (bound {BOUND_S:.1f} s); rejoined {rejoin_s:.2f} s")


@pytest.mark.parametrize(
    "field, value", [("shard_lost_samples", 1), ("shard_lost_samples", 601), ("shard_silent_s", 0.5)]
)
def test_the_coordinator_refuses_lost_shard_settings_out_of_range(field, value):
    with pytest.raises(ValidationError, match=field):
        CoordinatorSettings(**{field: value})
