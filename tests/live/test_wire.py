"""The wire contract: exact round trips, and every malformed message refused with a named reason."""

from __future__ import annotations

import contextlib
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from wwcore.keys import KeyTree
from wwcore.wire import (
    FARM_TRUTH,
    HEADER,
    HYDRO_REFS,
    JSON_SCHEMAS,
    SCHEMAS,
    TURBINE_REFS,
    TURBINE_SENSORS,
    DropCounter,
    DropReason,
    WireError,
    check_header,
    decode_json,
    encode_json,
    stack_records,
)

pytestmark = pytest.mark.in_process  # no network, no process: the parallel phase (tests/conftest.py)

FLOATS = arrays(np.float64, (13,), elements=st.floats(allow_nan=True, allow_infinity=True, width=64))


@settings(max_examples=200, deadline=None)
@given(sensors=FLOATS, tick=st.integers(0, 2**62), zone=st.integers(-128, 127))
def test_sensor_record_round_trips_bit_for_bit(sensors, tick, zone):
    rec = TURBINE_SENSORS.empty()
    rec["tick"], rec["t"], rec["turbine"], rec["sensors"], rec["zone"] = tick, tick * 0.01, 7, sensors, zone
    back = TURBINE_SENSORS.decode(TURBINE_SENSORS.encode(rec[0]))
    assert back.tobytes() == rec[0].tobytes()  # bit for bit, NaN payloads included
    assert int(back["tick"]) == tick and int(back["turbine"]) == 7


def test_every_schema_has_its_own_code_and_a_fixed_size():
    codes = [s.code for s in SCHEMAS.values()]
    assert len(set(codes)) == len(codes)
    for schema in SCHEMAS.values():
        payload = schema.encode(schema.empty()[0])
        assert len(payload) == schema.size == HEADER.itemsize + schema.dtype.itemsize
        assert check_header(payload) == (schema.code, schema.version)
        assert all(f.unit and f.doc for f in schema.fields), f"{schema.name}: every field has a unit and a meaning"


@pytest.mark.parametrize(
    "mutate, reason",
    [
        (lambda b: b[:-1], DropReason.BAD_LENGTH),
        (lambda b: b + b"\0", DropReason.BAD_LENGTH),
        (lambda b: b[:3], DropReason.BAD_LENGTH),
        (lambda b: b"XX" + b[2:], DropReason.BAD_MAGIC),
        (lambda b: b[:3] + bytes([b[3] + 1]) + b[4:], DropReason.BAD_VERSION),
        (lambda b: b[:2] + bytes([HYDRO_REFS.code]) + b[3:], DropReason.UNKNOWN_SCHEMA),
    ],
    ids=["short", "long", "no body", "magic", "version", "other schema"],
)
def test_malformed_messages_are_refused_with_a_reason(mutate, reason):
    payload = TURBINE_REFS.encode(TURBINE_REFS.empty()[0])
    with pytest.raises(WireError) as error:
        TURBINE_REFS.decode(mutate(payload))
    assert error.value.reason == reason


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=400))
def test_random_bytes_never_raise_anything_but_wire_error(payload):
    for schema in SCHEMAS.values():
        with contextlib.suppress(WireError):
            schema.decode(payload)
        with contextlib.suppress(WireError):
            schema.decode_frame(payload)
    for name in JSON_SCHEMAS:
        with contextlib.suppress(WireError):
            decode_json(name, payload)


def test_json_messages_check_schema_version_and_body():
    body = {"t": 1.0, "type": "detection"}
    assert decode_json("events", encode_json("events", body)) == body
    wrong_version = json.dumps({"schema": "events", "v": 99, "body": body}).encode()
    with pytest.raises(WireError) as error:
        decode_json("events", wrong_version)
    assert error.value.reason == DropReason.BAD_VERSION
    with pytest.raises(WireError):
        decode_json("events", encode_json("plant.status", body))
    with pytest.raises(WireError):
        decode_json("events", json.dumps({"schema": "events", "v": 1, "body": [1]}).encode())
    with pytest.raises(ValueError):
        encode_json("events", {"x": float("nan")})  # JSON on the wire is strict


def test_records_stack_by_field():
    rows = [TURBINE_SENSORS.empty()[0] for _ in range(3)]
    for i, r in enumerate(rows):
        r["turbine"], r["sensors"] = i + 1, np.full(13, float(i))
    stacked = stack_records([TURBINE_SENSORS.decode(TURBINE_SENSORS.encode(r)) for r in rows])
    assert stacked["sensors"].shape == (3, 13) and list(stacked["turbine"]) == [1, 2, 3]


def test_key_tree():
    keys = KeyTree("farm_1")
    assert keys.sensors == "windwarden/farm_1/sensors"
    assert keys.refs("supervisor") == "windwarden/farm_1/refs/supervisor"
    assert keys.sender_of(keys.refs("1-40")) == "1-40"
    assert keys.summary("41-80") == "windwarden/farm_1/summary/41-80"
    assert keys.dispatch("41-80") == "windwarden/farm_1/dispatch/41-80"
    assert keys.process_of(keys.alive("supervisor")) == "supervisor"
    assert {spec.pattern for spec in keys.registry()} >= {keys.plant_events, keys.supervisor_events, keys.faults}
    assert keys.events_all == "windwarden/farm_1/*/events"
    assert KeyTree.every_farm().refs("*") == "windwarden/*/refs/*"
    for bad in ("a/b", "*", "", "x y"):
        with pytest.raises(ValueError):
            KeyTree(bad)
    for bad in ("a/b", "", "x y", "**"):
        with pytest.raises(ValueError):
            keys.refs(bad)


def test_drop_counter():
    drops = DropCounter()
    drops.add("refs", DropReason.BAD_LENGTH)
    drops.add("refs", DropReason.BAD_LENGTH)
    drops.add("sensors", DropReason.BAD_VERSION)
    assert drops.as_dict() == {"refs:bad_length": 2, "sensors:bad_version": 1} and drops.total() == 3


def test_the_farm_truth_carries_the_true_wind_direction_in_a_new_version():
    """A field added to a frame is a new layout, so a new version (the codec refuses the old one as ``bad_version``,
    never misreads its bytes); ``wind_direction`` is in degrees, 0 … 360."""
    (field,) = [f for f in FARM_TRUTH.fields if f.name == "wind_direction"]
    assert FARM_TRUTH.version == 2 and field.unit == "deg" and field.limits == (0.0, 360.0) and field.when is None
    rows = FARM_TRUTH.empty(3)
    rows["turbine"], rows["wind_direction"] = [1, 2, 3], [0.0, 271.5, 359.99]
    payload = FARM_TRUTH.encode_frame(rows)
    assert FARM_TRUTH.decode_frame(payload)["wind_direction"].tolist() == [0.0, 271.5, 359.99]
    v1 = payload[:3] + bytes([1]) + payload[4:]
    with pytest.raises(WireError) as error:
        FARM_TRUTH.decode_frame(v1)
    assert error.value.reason == DropReason.BAD_VERSION
    for bad, reason in ((-0.1, DropReason.OUT_OF_RANGE), (360.5, DropReason.OUT_OF_RANGE), (np.nan, "non_finite")):
        rows["wind_direction"][1] = bad
        assert FARM_TRUTH.refusal(rows) == reason
