"""What a sharded supervisor refuses: summaries the coordinator cannot trust and dispatch rows a shard cannot trust
are dropped and counted by reason, and change nothing (no farm sample decided, no reference, no event); a
farm-wide detector and bad turbine ranges are refused with a clear error."""

from __future__ import annotations

import numpy as np
import pytest
import zenoh

from service.farm.shard import FarmShard, ShardingError, coordinator_supervisor, parse_turbines
from tests.live.helpers import LiveNodes, router, scenario, wait_for
from tests.live.shard_helpers import SHARDED_SHORT, Sharded
from windwarden.cli import main
from windwarden.kinds import RunInfo
from windwarden.live.config import ZenohSettings
from windwarden.live.runfolder import EVENTS, read_events
from windwarden.live.transport import open_session
from wwcore.events import SUPERVISOR_EVENTS
from wwcore.keys import KeyTree
from wwcore.wire import FARM_REFS, FARM_SUMMARY, HEADER


def _summary(turbine: int, tick: int = 9, run: int = 0, **fields) -> bytes:
    record = FARM_SUMMARY.empty(1)
    record["tick"], record["t"], record["turbine"], record["run"] = tick, tick * 0.01, turbine, run
    record["sample_index"], record["sample_t"], record["mast"], record["demand"] = 1, 0.1, 10.0, 2e7
    for name, value in fields.items():
        record[name] = value
    return FARM_SUMMARY.encode(record)


def _put(session: zenoh.Session, key: str, payload: bytes) -> None:
    session.put(key, payload, congestion_control=zenoh.CongestionControl.BLOCK)


def test_the_coordinator_refuses_and_counts_hostile_summaries(tmp_path):
    scn = scenario(SHARDED_SHORT)
    keys = KeyTree()
    # a plant waiting for its supervisor (no shard is there, so the coordinator never says ready): the coordinator
    # has the run, and a hostile client puts summaries on the turbines' summary keys
    run_dir = tmp_path / "run"
    with (
        router() as endpoint,
        Sharded(endpoint, [], run_dir) as sharded,
        LiveNodes(endpoint, scn, run_dir, seed=1, supervisor=False, supervisor_wait_s=30.0) as nodes,
    ):
        coordinator = sharded.coordinator
        assert wait_for(lambda: coordinator.info is not None, 20), "the coordinator did not get the run"
        run = coordinator.info.run_key
        good = _summary(3, run=run)
        bad_version = good[:3] + bytes([FARM_SUMMARY.version + 1]) + good[HEADER.itemsize :]
        probes = {
            "bad_magic": [b"XX" + good[2:], b"not a summary at all"],
            "bad_length": [good[:-1], good + b"\0"],
            "bad_version": [bad_version],
            "unknown_schema": [FARM_REFS.encode(FARM_REFS.empty(1))],
            "non_finite": [
                _summary(3, run=run, scada=np.nan),
                _summary(3, run=run, power_ref_used=np.inf),
                _summary(3, run=run, statistic=np.nan),
            ],
            "out_of_range": [
                _summary(3, run=run, mast=-1.0),
                _summary(3, run=run, zone=7),
                _summary(3, run=run, statistic=-1.0),
                _summary(3, run=run, mast_direction=400.0),
                _summary(3, run=run, demand=1e12),
            ],
            "unknown_turbine": [_summary(99, run=run)],
            "old_tick": [_summary(3, tick=-5, run=run)],
        }
        # a whole tick of rows that are not one farm sample (two sample indices), and one of another run
        split = [_summary(t, tick=19, run=run, sample_index=1 + (t > 4)) for t in range(1, 10)]
        foreign = [_summary(t, tick=29, run=run + 1) for t in range(1, 10)]
        hostile = open_session(ZenohSettings(connect=endpoint))
        try:
            for payloads in probes.values():
                for payload in payloads:
                    _put(hostile, keys.summary(3), payload)
            for turbine, payload in enumerate(split + foreign, start=1):
                _put(hostile, keys.summary((turbine - 1) % 9 + 1), payload)
            expected = {f"summary:{reason}": len(p) for reason, p in probes.items()}
            expected |= {"summary:bad_body": 1, "summary:foreign_run": 1}
            assert wait_for(lambda: coordinator.status()["dropped"] == expected, 10), (
                coordinator.status()["dropped"],
                expected,
            )
        finally:
            hostile.close()
        status = coordinator.status()
        assert status["samples"] == 0 and status["tick"] is None and not status["ready"]
        assert nodes.plant.state == "waiting"
        nodes.plant.stop()
    assert not [e for e in read_events(tmp_path / "run" / EVENTS) if e.type in SUPERVISOR_EVENTS]


def test_a_shard_refuses_and_counts_hostile_dispatch_rows(tmp_path):
    keys = KeyTree()
    with router() as endpoint, Sharded(endpoint, [(endpoint, (1, 2))], tmp_path / "run") as sharded:
        shard = sharded.shards[0]

        def row(turbine: int = 1, tick: int = 5, **fields) -> bytes:
            record = FARM_REFS.empty(1)
            record["tick"], record["turbine"], record["computed_tick"], record["power_ref"] = tick, turbine, tick, 1e6
            for name, value in fields.items():
                record[name] = value
            return FARM_REFS.encode(record)

        probes = {
            "bad_magic": [b"garbage"],
            "bad_length": [row()[:-3]],
            "non_finite": [row(power_ref=np.nan), row(ripple_rate=np.inf)],
            "out_of_range": [row(power_ref=1e9), row(mode=9), row(pitch_trim=[40.0, 0.0, 0.0])],
            "unknown_turbine": [row(turbine=7)],
            "future_tick": [row(tick=5)],  # no farm sample is awaited: no tick's rows are taken
        }
        hostile = open_session(ZenohSettings(connect=endpoint))
        try:
            for payloads in probes.values():
                for payload in payloads:
                    _put(hostile, keys.dispatch(1), payload)
            expected = {f"dispatch:{reason}": len(p) for reason, p in probes.items()}
            assert wait_for(lambda: shard.status()["dropped"] == expected, 10), (shard.status()["dropped"], expected)
        finally:
            hostile.close()
        assert shard.last_dispatch is None and shard.dispatch.pending() == 0


def test_a_farm_wide_detector_and_bad_turbine_ranges_are_refused():
    scn = scenario(SHARDED_SHORT)
    info = RunInfo.of(scn, list(range(1, 10)), 0.01)
    with pytest.raises(ShardingError, match="'paper' farm detector compares turbines across the farm"):
        FarmShard(info.site, (1, 2), detector="paper")
    with pytest.raises(ShardingError, match="run one supervisor for 'paper'"):
        coordinator_supervisor(info.site, 9, detector="paper")
    with pytest.raises(ShardingError, match="cannot own"):
        FarmShard(info.site, (8, 9, 10))
    with pytest.raises(ShardingError, match="each of its turbines once"):
        FarmShard(info.site, (2, 3, 2))
    assert parse_turbines("1-4, 7,9-10") == (1, 2, 3, 4, 7, 9, 10)
    for text, message in [
        ("", "not a number"),
        ("0-3", "from 1"),
        ("5-2", "from 1"),
        ("1-3,3", "twice"),
        ("a-b", "not a number"),
    ]:
        with pytest.raises(ShardingError, match=message):
            parse_turbines(text)


def test_the_command_line_refuses_what_a_sharded_supervisor_cannot_run(tmp_path, capsys):
    paper = tmp_path / "paper.toml"
    paper.write_text(SHARDED_SHORT + '[supervisor]\ndetector = "paper"\n')
    refused = {
        ("up", "hydro-fig9", "--shards", "2"): "only a farm's supervisor is sharded",
        ("up", str(paper), "--shards", "2"): "run one supervisor for 'paper'",
        ("up", "farm-case1", "--shards", "10"): "10 shards for 9 turbines",
        ("supervise", "--turbines", "0-3"): "from 1",
        ("supervise", "--turbines", "1-4,4"): "twice",
    }
    for argv, message in refused.items():
        assert main(list(argv)) == 2, argv  # refused before anything starts (no router, no session)
        assert message in " ".join(capsys.readouterr().err.split()), argv
