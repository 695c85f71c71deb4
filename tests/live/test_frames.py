"""Frames on the wire (one message per tick per sender, a row per turbine) and their assembly into ticks: exact
round trips, and every malformed or hostile frame refused whole, counted, changing nothing."""

from __future__ import annotations

import numpy as np
import pytest

from windwarden.live.guard import RefsSenders
from windwarden.live.mailbox import TickMailbox
from wwcore.wire import (
    FARM_REFS,
    FARM_SENSORS,
    HEADER,
    MAX_FRAME_ROWS,
    TURBINE_REFS,
    DropCounter,
    DropReason,
    WireError,
)

pytestmark = pytest.mark.in_process  # no network, no process: the parallel phase (tests/conftest.py)

TURBINES = list(range(1, 10))


def rows(turbines, tick=5, schema=FARM_REFS, seed=0):
    out = schema.empty(len(turbines))
    out["tick"], out["turbine"] = tick, turbines
    rng = np.random.default_rng(seed)
    for name in schema.dtype.names:
        if schema.dtype[name].base.kind == "f":
            out[name] = rng.normal(size=out[name].shape)
    return out


def test_a_frame_round_trips_bit_for_bit_and_a_frame_of_one_is_the_one_record_message():
    frame = rows(list(range(1, 81)), schema=FARM_SENSORS)
    payload = FARM_SENSORS.encode_frame(frame)
    assert len(payload) == HEADER.itemsize + 80 * FARM_SENSORS.dtype.itemsize
    assert FARM_SENSORS.decode_frame(payload).tobytes() == frame.tobytes()
    one = rows([3])
    assert FARM_REFS.encode_frame(one) == FARM_REFS.encode(one[0])
    assert FARM_REFS.decode(FARM_REFS.encode_frame(one)).tobytes() == one[0].tobytes()


@pytest.mark.parametrize(
    "payload",
    [
        TURBINE_REFS.header,  # no row
        TURBINE_REFS.encode_frame(TURBINE_REFS.empty(2))[:-1],  # not whole rows
        TURBINE_REFS.header + bytes(TURBINE_REFS.dtype.itemsize * (MAX_FRAME_ROWS + 1)),  # too many rows
    ],
    ids=["empty", "partial row", "too many rows"],
)
def test_frames_of_no_row_part_of_a_row_or_too_many_rows_are_refused(payload):
    with pytest.raises(WireError) as error:
        TURBINE_REFS.decode_frame(payload)
    assert error.value.reason == DropReason.BAD_LENGTH
    with pytest.raises(ValueError):
        TURBINE_REFS.encode_frame(TURBINE_REFS.empty(0))


def test_one_frame_of_every_turbine_is_a_tick_in_the_mailbox_order_whatever_the_row_order():
    box = TickMailbox(FARM_REFS, TURBINES, DropCounter(), "refs")
    frame = rows(TURBINES[::-1])
    box.put(FARM_REFS.encode_frame(frame))
    (arrival,) = box.drain()
    assert arrival.tick == 5 and list(arrival.records["turbine"]) == TURBINES
    assert arrival.records.tobytes() == frame[::-1].tobytes()


def test_a_whole_tick_in_the_lists_order_is_taken_as_sent_and_refused_for_the_same_reasons():
    """The frame a plant or one supervisor sends every tick (every turbine once, in the list's order) skips the
    general checks' duplicate search and scatter; it is taken byte for byte, writable, and refused as any other."""
    drops = DropCounter()
    box = TickMailbox(FARM_REFS, TURBINES, drops, "refs", lambda tick: DropReason.FUTURE_TICK if tick > 100 else None)
    frame = rows(TURBINES)
    box.put(FARM_REFS.encode_frame(frame))
    (arrival,) = box.drain()
    assert arrival.records.tobytes() == frame.tobytes() and arrival.served is None
    arrival.records["power_ref"][0] = 1.0  # the consumer's own copy, not the message's read-only bytes
    mixed = rows(TURBINES, tick=6)
    mixed["tick"][8] = 7
    box.put(FARM_REFS.encode_frame(mixed))
    box.put(FARM_REFS.encode_frame(rows(TURBINES, tick=7)), box.owned_mask(TURBINES[:-1]))
    box.put(FARM_REFS.encode_frame(rows(TURBINES, tick=10**15)))
    box.put(FARM_REFS.encode_frame(rows(TURBINES, tick=8)), box.owned_mask(TURBINES))
    assert drops.as_dict() == {"refs:mixed_ticks": 1, "refs:not_owned": 1, "refs:future_tick": 1}
    (arrival,) = box.drain()
    assert arrival.tick == 8 and arrival.records.tobytes() == rows(TURBINES, tick=8).tobytes()


def test_two_shards_frames_make_one_tick():
    drops = DropCounter()
    box = TickMailbox(FARM_REFS, TURBINES, drops, "refs")
    box.put(FARM_REFS.encode_frame(rows([5, 6, 7, 8, 9], seed=2)), box.owned_mask([5, 6, 7, 8, 9]))
    assert box.pending() == 0
    box.put(FARM_REFS.encode_frame(rows([1, 2, 3, 4], seed=1)), box.owned_mask([1, 2, 3, 4]))
    (arrival,) = box.drain()
    assert list(arrival.records["turbine"]) == TURBINES and drops.total() == 0
    assert arrival.records[:4].tobytes() == rows([1, 2, 3, 4], seed=1).tobytes()


def _hostile_frames(box):
    shard_a = box.owned_mask([1, 2, 3, 4])
    mixed = rows([1, 2])
    mixed["tick"] = [5, 6]
    return {
        DropReason.BAD_LENGTH: [(FARM_REFS.encode_frame(rows([1]))[:-2], None)],
        DropReason.MIXED_TICKS: [(FARM_REFS.encode_frame(mixed), None)],
        DropReason.DUPLICATE_TURBINE: [(FARM_REFS.encode_frame(rows([1, 2, 1])), None)],
        DropReason.UNKNOWN_TURBINE: [
            (FARM_REFS.encode_frame(rows([1, 10])), None),
            (FARM_REFS.encode_frame(rows([0])), None),
        ],
        DropReason.NOT_OWNED: [
            (FARM_REFS.encode_frame(rows([1, 2, 7])), shard_a),  # another shard's turbine
            (FARM_REFS.encode_frame(rows([1])), np.zeros(9, bool)),  # a sender that owns nothing
        ],
        DropReason.FUTURE_TICK: [(FARM_REFS.encode_frame(rows([1], tick=10**15)), None)],
    }


def test_hostile_frames_are_refused_whole_counted_and_change_nothing():
    drops = DropCounter()
    box = TickMailbox(FARM_REFS, TURBINES, drops, "refs", lambda tick: DropReason.FUTURE_TICK if tick > 100 else None)
    box.put(FARM_REFS.encode_frame(rows([1, 2, 3, 4], seed=1)))  # a shard's genuine rows of tick 5
    hostile = _hostile_frames(box)
    for frames in hostile.values():
        for payload, owned in frames:
            box.put(payload, owned)
    # a frame overlapping a row already taken is refused whole: its other rows are not taken either
    box.put(FARM_REFS.encode_frame(rows([4, 5], seed=9)))
    assert drops.as_dict() == {f"refs:{r}": len(f) for r, f in hostile.items()} | {"refs:repeated_tick": 1}
    assert box.pending() == 0
    box.put(FARM_REFS.encode_frame(rows([5, 6, 7, 8, 9], seed=2)))  # the other shard's genuine rows
    (arrival,) = box.drain()
    assert arrival.records[:4].tobytes() == rows([1, 2, 3, 4], seed=1).tobytes()
    assert arrival.records[4:].tobytes() == rows([5, 6, 7, 8, 9], seed=2).tobytes()


def test_the_plant_knows_which_sender_owns_which_turbines():
    box = TickMailbox(FARM_REFS, TURBINES, DropCounter(), "refs")
    senders = RefsSenders(box.owned_mask, box.n, "run-a")
    assert senders.owned("supervisor") is None  # one supervisor: every turbine
    assert not senders.owned("1-4").any()
    shards = {
        "1-4": {"run_id": "run-a", "turbines": [1, 2, 3, 4], "ready": True},
        "5-9": {"run_id": "run-a", "turbines": [5, 6, 7, 8, 9], "ready": True},
        "old": {"run_id": "run-b", "turbines": TURBINES, "ready": True},  # another run's shard
        "slow": {"run_id": "run-a", "turbines": TURBINES, "ready": False},
        "odd": {"run_id": "run-a", "turbines": [1, True, "2", 99], "ready": True},
    }
    senders.update({"run_id": "run-b", "sharded": True, "shards": shards})  # another run's status: ignored
    assert senders.owned("supervisor") is None and not senders.sharded
    senders.update({"run_id": "run-a", "sharded": True, "shards": shards})
    assert senders.sharded and set(senders.plan()) == {"1-4", "5-9", "odd"}
    assert list(np.flatnonzero(senders.owned("1-4")) + 1) == [1, 2, 3, 4]
    assert list(np.flatnonzero(senders.owned("odd")) + 1) == [1]  # only integer turbines of the run
    for nobody in ("supervisor", "old", "slow", "rogue"):
        assert not senders.owned(nobody).any(), nobody
    senders.update({"run_id": "run-a", "ready": True})  # one supervisor again
    assert senders.owned("supervisor") is None and not senders.owned("1-4").any()
