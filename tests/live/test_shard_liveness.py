"""A shard lost mid-run: the coordinator notices it within its bound, logs and counts it, names it in its status and
goes on deciding for the other shard's turbines, whose references stay fresh at the plant while the lost shard's
turbines keep their last ones; the shard restarted with the same turbines rejoins (real time, threads on loopback).
Its bad settings are refused."""

from __future__ import annotations

import time

import numpy as np
import pytest
from pydantic import ValidationError

from api.routes.supervisor import _status as api_status
from tests.live.helpers import scenario, wait_for
from tests.live.shard_helpers import sharded_farm
from windwarden.cli import main
from windwarden.kinds.farm import FARM
from windwarden.live.coordinator import CoordinatorSettings
from windwarden.live.mailbox import TickMailbox
from windwarden.live.runfolder import EVENTS, read_events
from windwarden.live.sharding import ShardRoster
from wwcore.wire import FARM_REFS, DropCounter

FARM_SCENARIO = """
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
A_ROWS = slice(0, 4)
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
    with sharded_farm(scenario(FARM_SCENARIO), run_dir, [A, B], mode="realtime", seed=3) as (sharded, nodes):
        plant, coordinator = nodes.plant, sharded.coordinator
        assert wait_for(lambda: plant.plant.t >= 1.5 and plant.freshness.fresh, 30), "the farm did not start"
        assert _computed(plant, slice(None)).min() >= 0

        killed_at = time.monotonic()
        sharded.kill(1)
        assert wait_for(lambda: "5-9" in coordinator.status()["lost_shards"], BOUND_S), coordinator.status()
        detection_s = time.monotonic() - killed_at
        status = coordinator.status()
        assert status["held_turbines"] == list(B) and status["shards_lost"] == 1 and status["ready"]
        assert status["shards"]["5-9"] == {
            "run_id": run_dir.name,
            "turbines": list(B),
            "ready": False,
            "lost": True,
        }
        assert status["coverage"] == "degraded: turbines held"
        assert [t["turbine"] for t in status["turbines"] if not t["supervised"]] == list(B)
        assert api_status(status).ready  # what GET /supervisor/status answers with
        lost = _liveliness(run_dir, alive=False)
        assert len(lost) == 1 and lost[0].detail["shard"] == "5-9" and lost[0].detail["turbines"] == list(B)
        assert lost[0].detail["noticed_by"] == "coordinator" and "farm samples" in lost[0].detail["reason"]

        # the other shard's turbines get fresh references, from farm samples decided after the loss
        decided = coordinator.last_tick
        assert wait_for(lambda: _computed(plant, A_ROWS).min() >= decided + 100, 10), _computed(plant, slice(0, 4))
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


@pytest.mark.in_process
@pytest.mark.parametrize(
    "field, value", [("shard_lost_samples", 1), ("shard_lost_samples", 601), ("shard_silent_s", 0.5)]
)
def test_the_coordinator_refuses_lost_shard_settings_out_of_range(field, value):
    with pytest.raises(ValidationError, match=field):
        CoordinatorSettings(**{field: value})


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _roster(clock: Clock) -> ShardRoster:
    roster = ShardRoster(lost_after_samples=3, silent_after_s=2.0, clock=clock)
    roster.start("run")
    roster.heard_status("1-4", "run", list(A), True)
    roster.heard_status("5-9", "run", list(B), True)
    assert roster.check(list(A + B)) == [] and roster.started and roster.admitted == {"1-4", "5-9"}
    return roster


def _summarise(roster: ShardRoster, clock: Clock, tick: int, names=("1-4", "5-9")) -> None:
    clock.now += 0.1
    for name in names:
        roster.heard_status(name, "run", list(A if name == "1-4" else B), True)
        roster.heard_summary(name, tick)


@pytest.mark.in_process
def test_a_shard_missing_from_the_samples_the_others_summarise_is_lost_then_rejoins():
    clock = Clock()
    roster = _roster(clock)
    for tick in (9, 19, 29):
        _summarise(roster, clock, tick)
    _summarise(roster, clock, 39, ["1-4"])
    _summarise(roster, clock, 49, ["1-4"])
    assert roster.check(list(A + B)) == [] and roster.missed("5-9") == 2  # two samples late: not yet
    _summarise(roster, clock, 59, ["1-4"])
    ((name, alive, reason),) = roster.check(list(A + B))
    assert (name, alive) == ("5-9", False) and "3 farm samples" in reason
    assert roster.held() == list(B) and roster.admitted == {"1-4"} and roster.lost_total == 1
    assert roster.coverage(list(A + B)) is None  # served: the lost shard's turbines held
    _summarise(roster, clock, 69, ["1-4"])
    roster.heard_summary("5-9", 39)  # a late summary of an older sample is not a return
    assert roster.check(list(A + B)) == []
    _summarise(roster, clock, 79)  # ready for the run and a newer sample: back
    assert roster.check(list(A + B)) == [("5-9", True, "summarises again (farm-sample tick 79)")]
    assert roster.held() == [] and roster.admitted == {"1-4", "5-9"} and roster.rejoined_total == 1


@pytest.mark.in_process
def test_a_silent_or_stopped_shard_is_lost_and_nothing_is_lost_before_the_run_starts():
    clock = Clock()
    roster = ShardRoster(lost_after_samples=3, silent_after_s=2.0, clock=clock)
    roster.start("run")
    roster.heard_status("1-4", "run", list(A), True)
    clock.now = 10.0  # silent for long, but the run has not started (5-9 never ready): nobody is lost
    assert roster.check(list(A + B)) == [] and not roster.started
    assert roster.coverage(list(A + B)) == f"no ready shard owns turbines {list(B)}"
    roster = _roster(clock)
    roster.heard_status("1-4", "run", list(A), False)  # its status says it stopped
    clock.now += 2.5  # and 5-9 has been silent for 2.5 s
    changes = dict((name, reason) for name, _, reason in roster.check(list(A + B)))
    assert "stopped" in changes["1-4"] and changes["5-9"] == "no status for 2.5 s"
    assert roster.coverage(list(A + B)) == "every shard is lost" and roster.held() == list(A + B)


@pytest.mark.in_process
def test_a_tick_completes_without_the_rows_no_longer_expected():
    drops = DropCounter()
    box = TickMailbox(FARM_REFS, list(A + B), drops, "refs")
    frame = FARM_REFS.empty(4)
    frame["tick"], frame["turbine"], frame["computed_tick"] = 7, list(A), 0
    box.put(FARM_REFS.encode_frame(frame))
    assert box.drain() == []  # waits for 5-9
    box.expect(box.owned_mask(A))  # 5-9 lost: the waiting tick completes now
    (arrival,) = box.drain()
    assert arrival.tick == 7 and list(arrival.served) == [True] * 4 + [False] * 5
    assert list(arrival.records["turbine"]) == list(A + B) and (arrival.records["tick"] == 7).all()
    frame["tick"] = 8
    box.put(FARM_REFS.encode_frame(frame))  # and the next one at once
    assert [a.tick for a in box.drain()] == [8] and drops.as_dict() == {}


@pytest.mark.in_process
def test_the_plant_keeps_the_last_reference_of_a_turbine_nobody_serves():
    last = FARM_REFS.empty(3)
    last["turbine"], last["tick"], last["computed_tick"] = [1, 2, 3], 40, 39
    last["power_ref"], last["mode"], last["pitch_trim"] = (
        [1e6, 2e6, 3e6],
        [0, 4, 5],
        [[0, 0, 0], [0.5, 0, 0], [0, 0, 0]],
    )
    last["ripple_power"], last["ripple_rate"] = [[0, 0], [0, 0], [4e4, 1e4]], [0, 0, 4.4]
    now = FARM_REFS.empty(3)
    now["turbine"], now["tick"], now["computed_tick"], now["power_ref"] = [1, 2, 3], 52, 49, 1.5e6
    served = np.array([True, False, False])
    held = FARM.hold_unserved(now, served, last)
    assert list(held["computed_tick"]) == [49] * 3 and list(held["tick"]) == [52] * 3
    assert list(held["power_ref"]) == [1.5e6, 2e6, 3e6] and list(held["mode"]) == [0, 4, 5]
    assert (
        held["pitch_trim"][1, 0] == 0.5 and (held["ripple_power"][1:] == 0).all() and (held["ripple_rate"] == 0).all()
    )
    refs = FARM.refs_from_records(held)
    assert refs is not None and bool(refs.cancel_3p[2]) and FARM_REFS.refusal(held) is None
    # nothing taken yet to keep: "no reference" rows, and the tick changes no turbine's reference
    empty = FARM.hold_unserved(now, served, None)
    assert list(empty["computed_tick"]) == [49, -1, -1] and FARM.refs_from_records(empty) is None
    assert FARM_REFS.refusal(empty) is None


@pytest.mark.in_process
def test_the_command_line_refuses_lost_shard_settings_out_of_range(capsys):
    for argv in (["--shard-lost-samples", "1"], ["--shard-lost-samples", "601"], ["--shard-silent", "0"]):
        assert main(["coordinate", *argv]) == 2, argv  # refused before anything starts (no session)
        assert "shard_" in capsys.readouterr().err, argv
    with pytest.raises(SystemExit) as exited:  # not a number: argparse's own refusal
        main(["coordinate", "--shard-lost-samples", "ten"])
    assert exited.value.code == 2
