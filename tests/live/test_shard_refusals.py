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
from wwcore.wire import FARM_REFS, FARM_SUMMARY, HEADER, encode_json


def _summary_rows(turbines: list[int], tick: int = 9, run: int = 0, **fields) -> np.ndarray:
    record = FARM_SUMMARY.empty(len(turbines))
    record["tick"], record["t"], record["turbine"], record["run"] = tick, tick * 0.01, turbines, run
    record["sample_index"], record["sample_t"], record["mast"], record["demand"] = 1, 0.1, 10.0, 2e7
    for name, value in fields.items():
        record[name] = value
    return record


def _summary(turbine: int, tick: int = 9, run: int = 0, **fields) -> bytes:
    return FARM_SUMMARY.encode_frame(_summary_rows([turbine], tick, run, **fields))


def _put(session: zenoh.Session, key: str, payload: bytes) -> None:
    session.put(key, payload, congestion_control=zenoh.CongestionControl.BLOCK)


def test_the_coordinator_refuses_and_counts_hostile_summaries(tmp_path):
    scn = scenario(SHARDED_SHORT)
    keys = KeyTree()
    # a plant waiting for its supervisor (no shard is ready, so the coordinator never says ready): the coordinator
    # has the run, a hostile client says it is shard 1-9 (not ready yet) and puts summary frames on its key
    run_dir = tmp_path / "run"
    with (
        router() as endpoint,
        Sharded(endpoint, [], run_dir) as sharded,
        LiveNodes(endpoint, scn, run_dir, seed=1, supervisor=False, supervisor_wait_s=30.0) as nodes,
    ):
        coordinator = sharded.coordinator
        assert wait_for(lambda: coordinator.info is not None, 20), "the coordinator did not get the run"
        run = coordinator.info.run_key
        hostile = open_session(ZenohSettings(connect=endpoint))
        status = {"run_id": coordinator.info.run_id, "turbines": list(range(1, 10)), "ready": False}
        _put(hostile, keys.shard_status("1-9"), encode_json("shard.status", status))
        assert wait_for(lambda: "1-9" in coordinator.roster.shards, 10)
        good = _summary(3, run=run)
        bad_version = good[:3] + bytes([FARM_SUMMARY.version + 1]) + good[HEADER.itemsize :]
        probes = {
            "bad_magic": [b"XX" + good[2:], b"not a summary at all"],
            "bad_length": [good[:-1], good + b"\0", good + good[HEADER.itemsize : -1]],  # not whole rows
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
            "mixed_ticks": [FARM_SUMMARY.encode_frame(_summary_rows([3, 4], tick=np.array([9, 10]), run=run))],
            "duplicate_turbine": [FARM_SUMMARY.encode_frame(_summary_rows([3, 3], run=run))],
        }
        # a whole tick of rows that are not one farm sample (two sample indices), and one of another run
        split = FARM_SUMMARY.encode_frame(
            _summary_rows(list(range(1, 10)), tick=19, run=run, sample_index=1 + (np.arange(1, 10) > 4))
        )
        foreign = FARM_SUMMARY.encode_frame(_summary_rows(list(range(1, 10)), tick=29, run=run + 1))
        # rows a shard that has not said it owns them sends: refused, the tick is not assembled
        not_owned = FARM_SUMMARY.encode_frame(_summary_rows([5, 6, 7, 8, 9], tick=39, run=run))
        try:
            for payloads in probes.values():
                for payload in payloads:
                    _put(hostile, keys.summary("1-9"), payload)
            for payload in (split, foreign):
                _put(hostile, keys.summary("1-9"), payload)
            _put(hostile, keys.summary("5-9"), not_owned)
            expected = {f"summary:{reason}": len(p) for reason, p in probes.items()}
            expected["summary:not_owned"] = 1
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
            return FARM_REFS.encode_frame(record)

        probes = {
            "bad_magic": [b"garbage"],
            "bad_length": [row()[:-3]],
            "non_finite": [row(power_ref=np.nan), row(ripple_rate=np.inf)],
            "out_of_range": [row(power_ref=1e9), row(mode=9), row(pitch_trim=[40.0, 0.0, 0.0])],
            "unknown_turbine": [row(turbine=7)],  # another shard's turbine: never in this shard's frame
            "future_tick": [row(tick=5)],  # no farm sample is awaited: no tick's rows are taken
            "duplicate_turbine": [FARM_REFS.encode_frame(np.concatenate([FARM_REFS.decode_frame(row())] * 2))],
        }
        hostile = open_session(ZenohSettings(connect=endpoint))
        try:
            for payloads in probes.values():
                for payload in payloads:
                    _put(hostile, keys.dispatch(shard.name), payload)
            expected = {f"dispatch:{reason}": len(p) for reason, p in probes.items()}
            assert wait_for(lambda: shard.status()["dropped"] == expected, 10), (shard.status()["dropped"], expected)
        finally:
            hostile.close()
        assert shard.last_dispatch is None and shard.dispatch.pending() == 0


@pytest.mark.in_process
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


@pytest.mark.in_process
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


def test_the_plant_refuses_refs_frames_naming_turbines_their_shard_does_not_own(tmp_path):
    """The plant knows the plan (the coordinator's status: which shard owns which turbines): a refs frame on a
    shard's key naming another shard's turbine, or on a key no shard of the plan has (the single supervisor's
    included), is refused whole and counted (``not_owned``), and the lockstep run goes on on the shards' refs."""
    scn = scenario(SHARDED_SHORT)
    keys = KeyTree()
    run_dir = tmp_path / "run"
    specs = [(1, 2, 3, 4), (5, 6, 7, 8, 9)]
    with router() as endpoint, Sharded(endpoint, [(endpoint, s) for s in specs], run_dir) as sharded:
        with LiveNodes(endpoint, scn, run_dir, mode="lockstep", seed=3, supervisor=False, supervisor_wait_s=30.0) as n:
            assert wait_for(lambda: n.plant.state == "running" and n.plant.k > 5, 30)
            assert n.plant.senders.sharded and set(n.plant.senders.plan()) == {"1-4", "5-9"}
            tick = n.plant.k - 1

            def frame(turbines: list[int]) -> bytes:
                rows = FARM_REFS.empty(len(turbines))
                rows["tick"], rows["turbine"], rows["computed_tick"], rows["power_ref"] = tick, turbines, 0, 1e6
                return FARM_REFS.encode_frame(rows)

            forged = {
                keys.refs("1-4"): [frame([7]), frame([1, 2, 3, 4, 7])],  # another shard's turbine
                keys.refs("5-9"): [frame([5, 6, 1])],
                keys.refs("supervisor"): [frame(list(range(1, 10)))],  # not a sender of this plan
                keys.refs("rogue"): [frame([1])],
            }
            hostile = open_session(ZenohSettings(connect=endpoint))
            try:
                for key, payloads in forged.items():
                    for payload in payloads:
                        _put(hostile, key, payload)
            finally:
                hostile.close()
            sent = sum(len(p) for p in forged.values())
            assert wait_for(lambda: n.plant.status()["refs_refused"].get("not_owned", 0) == sent, 10), n.plant.status()[
                "refs_refused"
            ]
            assert n.wait(120) == 0
            status = n.plant.status()
        assert not sharded.errors
    assert status["refs_refused"] == {"not_owned": sent}
    assert status["refs_stale_ticks"] == 0 and status["refs_received"] == status["ticks"]
