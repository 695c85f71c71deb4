"""A sharded farm supervisor: two supervisor shards and the farm coordinator, in lockstep over Zenoh, give the same
events and references as one supervisor (bit for bit), on one router and across two meshed routers; summaries a
coordinator cannot trust are refused and counted."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from tests.live.helpers import LiveNodes, router, scenario
from tests.live.shard_helpers import SHARDED_SHORT, RefsListener, Sharded, meshed_routers, one_supervisor
from tests.live.test_lockstep import _keys
from windwarden.live.finalize import finalize_scorecard
from windwarden.live.router import free_port
from windwarden.live.runfolder import EVENTS, read_events

SHARDS = ((1, 2, 3, 4), (5, 6, 7, 8, 9))
SEED = 8


@pytest.fixture(scope="module")
def one():
    return one_supervisor(scenario(SHARDED_SHORT), SEED)


def _sharded_lockstep(tmp_path, plant_endpoint, shard_endpoints):
    scn = scenario(SHARDED_SHORT)
    run_dir = tmp_path / "run"
    specs = list(zip(shard_endpoints, SHARDS, strict=True))
    with RefsListener(plant_endpoint) as listener, Sharded(plant_endpoint, specs, run_dir) as sharded:
        with LiveNodes(
            plant_endpoint, scn, run_dir, mode="lockstep", seed=SEED, supervisor=False, supervisor_wait_s=30.0
        ) as nodes:
            assert nodes.wait(120) == 0
            plant_status = nodes.plant.status()
        assert not sharded.errors
        shard_status = [s.status() for s in sharded.shards]
        coordinator_status = sharded.coordinator.status()
    card = finalize_scorecard(run_dir)
    return scn, read_events(run_dir / EVENTS), card, listener, plant_status, shard_status, coordinator_status


@pytest.mark.parametrize("mesh", [False, True], ids=["one-router", "two-meshed-routers"])
def test_two_shards_and_the_coordinator_equal_one_supervisor(tmp_path, one, mesh):
    if mesh:  # the plant, the coordinator and shard 1-4 on one router, shard 5-9 on another, the routers meshed
        with meshed_routers() as (first, second):
            result = _sharded_lockstep(tmp_path, first, [first, second])
    else:
        with router() as endpoint:
            result = _sharded_lockstep(tmp_path, endpoint, [endpoint, endpoint])
    scn, events, card, listener, plant, shards, coordinator = result
    assert _keys(events) == _keys(one.events)
    detected = {(e.turbine, e.target) for e in events if e.type.value == "detection"}
    assert {(4, "drivetrain"), (7, "pitch_misalignment"), (5, "debris")} <= detected
    modes = {e.detail.get("to") for e in events if e.type.value == "dispatch"}
    assert {"3P cancelled", "pitch trim", "debris"} <= modes
    # every reference message of every tick and turbine, byte for byte (flags, statistics, modes, trims, ripple)
    assert listener.repeated == 0 and listener.refs.keys() == one.refs.keys()
    differing = [key for key in one.refs if listener.refs[key] != one.refs[key]]
    assert not differing, f"{len(differing)} refs messages differ, first {min(differing)}"
    live = card.pop("live")
    assert live["completed"] and live["ticks_without_refs"] == 0 and live["dropped"] == {}
    assert card == json.loads(json.dumps(one.scorecard))
    assert plant["refs_refused"] == {} and plant["dropped"] == {}
    assert coordinator["samples"] == round(scn.duration_s / 0.1) and coordinator["dropped"] == {}
    for status in shards:
        assert status["coordinator_timeouts"] == 0 and status["coordinator_late"] == 0 and status["dropped"] == {}
        assert status["frames"] == round(scn.duration_s / 0.01)


@pytest.mark.slow  # processes: the router with access control, the plant, the coordinator, two shards (~40 s)
def test_up_with_shards_in_lockstep_equals_one_supervisor(tmp_path, one):
    (tmp_path / "s.toml").write_text(SHARDED_SHORT)
    env = {k: v for k, v in os.environ.items() if not k.startswith("WINDWARDEN_")} | {"RERUN_ANALYTICS": "0"}
    argv = [sys.executable, "-m", "windwarden.cli", "up", str(tmp_path / "s.toml"), "--shards", "2"]
    argv += ["--mode", "lockstep", "--seed", str(SEED), "--no-api", "--quiet", "--no-restart"]
    argv += ["--runs-root", str(tmp_path / "runs"), "--run-id", "sharded", "--listen", f"tcp/127.0.0.1:{free_port()}"]
    done = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=300)
    run_dir = tmp_path / "runs" / "sharded"
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert {"coordinator.log", "shard-1-4.log", "shard-5-9.log"} <= {p.name for p in (run_dir / "logs").iterdir()}
    assert _keys(read_events(run_dir / EVENTS)) == _keys(one.events)
    card = json.loads((run_dir / "scorecard.json").read_text())
    live = card.pop("live")
    assert live["completed"] and live["ticks_without_refs"] == 0
    assert card == json.loads(json.dumps(one.scorecard))
    assert json.loads((run_dir / "router.json").read_text())["denied_total"] == 0  # access control let it all through
