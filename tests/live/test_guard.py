"""The live nodes' checks, without a network: refs ranges (against an independent implementation), the plant's tick
window, the supervisor's frame decisions, gap interpolation and rate-limited refusal events."""

from __future__ import annotations

import numpy as np
import pytest

from windwarden.live.guard import (
    CONFIRM_EVERY_S,
    FrameSequencer,
    RefsFreshness,
    RefsGuard,
    RefusalLog,
    Verdict,
    interpolated_records,
)
from wwcore.turbine_frames import OMEGA_G_MAX
from wwcore.wire import (
    FARM_REFS,
    FARM_SUMMARY,
    HYDRO_REFS,
    HYDRO_SENSORS,
    TURBINE_REFS,
    TURBINE_SENSORS,
    DropCounter,
    DropReason,
)

pytestmark = pytest.mark.in_process  # no network, no process: the parallel phase (tests/conftest.py)

REFS = [TURBINE_REFS, HYDRO_REFS, FARM_REFS]


def reference_refusal(schema, records):
    """Row by row, field by field, in plain Python: the independent implementation ``refusal`` must agree with."""
    outside = False
    for row in records:
        for f in schema.limited:
            if f.when is not None:
                name, op, value = f.when
                held = row[name] >= value if op == ">=" else bool(row[name] == value)
                if not held:
                    continue
            for x in np.atleast_1d(row[f.name]).ravel():
                if not np.isfinite(x):
                    return DropReason.NON_FINITE
                if not f.limits[0] <= x <= f.limits[1]:
                    outside = True
    return DropReason.OUT_OF_RANGE if outside else None


def random_records(schema, n, rng, outside=0.01):
    """Records whose limited fields are mostly inside and, each value with probability ``outside``, above or below
    its range, NaN or ±inf, with the conditions' fields random too."""
    rec = schema.empty(n)
    for f in schema.fields:
        kind = np.dtype(f.dtype).kind
        shape = (n, *f.shape)
        if kind == "b":
            rec[f.name] = rng.random(shape) < 0.7
        elif kind in "iu" and f.limits is None:
            rec[f.name] = rng.integers(-2, 6, shape)
        elif f.limits is not None:
            lo, hi = f.limits
            pick = rng.random(shape) / outside  # < 1: outside, in four equal parts
            if kind == "f":
                x = rng.uniform(max(lo, -1e9), min(hi, 1e9), shape)  # a range as wide as all floats: its middle
                x = np.where(pick < 0.25, hi + abs(hi) * 1e-9 + 1.0, x)  # just above, for hi near the largest too
                x = np.where((pick >= 0.25) & (pick < 0.5), lo - abs(lo) * 1e-9 - 1.0, x)
                x = np.where((pick >= 0.5) & (pick < 0.75), np.nan, x)
                x = np.where((pick >= 0.75) & (pick < 1.0), np.inf, x)
            else:  # integers exactly, one past each end (2**62 + 1 is no float)
                x = rng.integers(int(lo), min(int(hi), int(lo) + 10**6) + 1, shape)
                x = np.where(pick < 0.5, int(hi) + 1, x)
                x = np.where((pick >= 0.5) & (pick < 1.0), int(lo) - 1, x)
            rec[f.name] = x
        else:
            rec[f.name] = rng.normal(size=shape)
    return rec


@pytest.mark.parametrize("schema", [*REFS, FARM_SUMMARY], ids=lambda s: s.name)
def test_refusal_agrees_with_a_plain_implementation(schema):
    """Both ways of the range check (row by row for small frames, column by column for large ones: Horns Rev 1's
    80 rows), and the one ``refusal`` picks, against the plain implementation."""
    rng = np.random.default_rng(7)
    check = schema.range_check
    reasons = {n: set() for n in (1, 9, 80)}
    for _ in range(600):
        n = int(rng.choice([1, 9, 80]))
        rec = random_records(schema, n, rng, outside=0.1 / n)  # about one frame in ten with a value outside
        expected = reference_refusal(schema, rec)
        assert schema.refusal(rec) == expected
        assert check.by_rows(rec) == expected and check.by_columns(rec) == expected
        reasons[n].add(expected)
    for n, seen in reasons.items():  # every outcome exercised at every size
        assert seen == {None, DropReason.NON_FINITE, DropReason.OUT_OF_RANGE}, (n, seen)


def test_large_frames_are_checked_by_columns_once_per_distinct_values(monkeypatch):
    """Small frames row by row; a large frame by columns, unless the values the limits read are byte for byte those
    of the last large frame checked (the farm's refs re-stamped between samples): then its verdict, unchecked."""
    check = FARM_REFS.range_check
    rows_seen, columns_seen = [], []
    by_rows, by_columns = check.by_rows, check._by_columns
    monkeypatch.setattr(check, "by_rows", lambda rec: rows_seen.append(len(rec)) or by_rows(rec))
    monkeypatch.setattr(check, "_by_columns", lambda picked: columns_seen.append(len(picked)) or by_columns(picked))
    monkeypatch.setattr(check, "_last", None)
    frame = FARM_REFS.empty(80)
    frame["computed_tick"], frame["power_ref"] = 9, 1e6
    assert [check(FARM_REFS.empty(n)) for n in (1, 9)] == [None, None] and rows_seen == [1, 9]
    assert check(frame) is None and columns_seen == [80]
    frame["tick"] += 1  # re-stamped: the tick is not read by the limits
    assert check(frame) is None and columns_seen == [80]
    frame["power_ref"][79] = np.nan
    assert check(frame) == DropReason.NON_FINITE and columns_seen == [80, 80]
    assert check(frame.copy()) == DropReason.NON_FINITE and columns_seen == [80, 80]
    frame["power_ref"][79] = 5e6
    assert check(frame) == DropReason.OUT_OF_RANGE and columns_seen == [80, 80, 80]
    assert check(FARM_REFS.empty(80)) is None and columns_seen == [80, 80, 80, 80]


def test_the_reported_attacks_are_refused():
    rec = TURBINE_REFS.empty(1)
    rec[["valid", "omega_g", "omega_r", "wind"]] = (True, 160.0, 1.7, 12.0)
    assert TURBINE_REFS.refusal(rec) is None
    rec["omega_g"] = 200.0  # the forged reference that stopped the rotor
    assert TURBINE_REFS.refusal(rec) == DropReason.OUT_OF_RANGE and OMEGA_G_MAX < 200.0
    rec["omega_g"] = np.nan  # the NaN references that crashed the plant
    assert TURBINE_REFS.refusal(rec) == DropReason.NON_FINITE
    rec["valid"] = False  # not valid: the controller ignores the estimates, whatever they are
    assert TURBINE_REFS.refusal(rec) is None
    hydro = HYDRO_REFS.empty(1)
    hydro["apply"], hydro["correction"] = True, [[np.inf, 0.0]]
    assert HYDRO_REFS.refusal(hydro) == DropReason.NON_FINITE
    farm = FARM_REFS.empty(9)
    farm["computed_tick"], farm["power_ref"], farm["held_torque"] = -1, np.nan, np.nan  # no reference yet: fine
    assert FARM_REFS.refusal(farm) is None
    farm["computed_tick"], farm["power_ref"] = 10, 1e6
    farm["mode"][4] = 3  # a hold without a torque
    assert FARM_REFS.refusal(farm) == DropReason.NON_FINITE
    farm["mode"][4], farm["mode"][5] = 0, 9  # no such mode
    assert FARM_REFS.refusal(farm) == DropReason.OUT_OF_RANGE


def good_refs(tick):
    rec = TURBINE_REFS.empty(1)
    rec[["tick", "valid", "omega_g", "omega_r", "wind"]] = (tick, True, 160.0, 1.7, 12.0)
    return rec


def test_refs_guard_window():
    drops = DropCounter()
    guard = RefsGuard(TURBINE_REFS, max_ref_age=10, drops=drops)
    guard.k = 100
    assert guard.window(100) is None and guard.window(101) == DropReason.FUTURE_TICK
    assert guard.window(10**15) == DropReason.FUTURE_TICK  # the tick that made the plant ignore every real one
    assert guard.judge(99, good_refs(99), 100) == Verdict.TAKE
    assert guard.judge(99, good_refs(99), 100) == Verdict.REFUSED  # a second refs for tick 99
    assert guard.judge(100, good_refs(100), 100) == Verdict.REFUSED  # tick 100 has not been measured
    assert guard.judge(89, good_refs(89), 100) == Verdict.LATE  # older than the window: scored, not used
    bad = good_refs(95)
    bad["omega_r"] = -1.0
    assert guard.judge(95, bad, 100) == Verdict.REFUSED
    assert guard.judge(95, good_refs(95), 100) == Verdict.TAKE  # the refused one did not take its place
    assert drops.of("refs") == {"repeated_tick": 1, "future_tick": 1, "stale_tick": 1, "out_of_range": 1}


def test_refs_guard_forgets_old_ticks():
    guard = RefsGuard(TURBINE_REFS, max_ref_age=10, drops=DropCounter())
    for k in range(1, 5000):
        assert guard.judge(k - 1, good_refs(k - 1), k) == Verdict.TAKE
    assert len(guard._taken) < 200


def frames(schema, ticks, run=7):
    out = []
    for tick in ticks:
        rec = schema.empty(1)
        rec["tick"], rec["run"], rec["t"] = tick, run, 0.01 * tick
        out.append(rec)
    return out


class Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def test_frame_sequencer():
    drops, clock = DropCounter(), Clock()
    asked = {"run": [], "tick": []}
    plant = {"run": 7, "tick": 1000}

    def confirm_run(run):
        asked["run"].append(run)
        return {"run_key": run} if run == plant["run"] else None

    def confirm_tick(tick):
        asked["tick"].append(tick)
        return tick <= plant["tick"]

    seq = FrameSequencer(50, drops, confirm_run, confirm_tick, clock)
    seq.start(7)

    def decide(tick, run=7):
        decision = seq.decide(frames(TURBINE_SENSORS, [tick], run)[0])
        if decision[0] != FrameSequencer.DROP:
            seq.stepped(tick)
        return decision

    assert decide(0) == ("step", 0) and decide(1) == ("step", 0)
    assert decide(5) == ("step", 3)  # a gap of three ticks to bridge
    assert decide(5) == ("drop", 0) and decide(2) == ("drop", 0)  # repeated, old: dropped, never a restart
    assert decide(3, run=99) == ("drop", 0)  # a foreign run: the plant does not confirm it
    assert decide(4, run=98) == ("drop", 0) and asked["run"] == [99]  # within CONFIRM_EVERY_S: not even asked
    assert decide(10**12) == ("drop", 0)  # far ahead: asked? no, rate-limited; dropped
    clock.now += CONFIRM_EVERY_S
    assert decide(10**12) == ("drop", 0) and asked["tick"] == [10**12]  # asked: beyond the plant's tick
    clock.now += CONFIRM_EVERY_S
    assert decide(900) == ("restart", 0)  # a long gap the plant confirms: observers restart
    assert decide(901) == ("step", 0)
    plant["run"] = 8  # the plant starts a new run
    clock.now += CONFIRM_EVERY_S
    assert decide(0, run=8)[0] == "new run" and seq.confirmed == {"run_key": 8}
    assert drops.of("sensors") == {
        "repeated_tick": 1,
        "old_tick": 1,
        "foreign_run": 2,
        "unconfirmed_tick": 2,
    }
    mixed = frames(TURBINE_SENSORS, [902, 902])
    rows = np.concatenate(mixed)
    rows["run"][1] = 5  # one forged row assembled with a real one
    seq.start(8)
    assert seq.decide(rows) == ("drop", 0)


def test_interpolated_records():
    before, after = frames(HYDRO_SENSORS, [10, 14])
    before["y"], after["y"] = [[0.0, 1.0, 2.0, 3.0, 4.0]], [[4.0, 5.0, 6.0, 7.0, 8.0]]
    middle = interpolated_records(before, after)
    assert [int(m["tick"][0]) for m in middle] == [11, 12, 13]
    np.testing.assert_allclose(middle[1]["y"][0], [2.0, 3.0, 4.0, 5.0, 6.0])
    np.testing.assert_allclose([m["t"][0] for m in middle], [0.11, 0.12, 0.13])
    assert all(m["run"][0] == 7 for m in middle)
    assert interpolated_records(before, frames(HYDRO_SENSORS, [11])[0]) == []


def test_refusal_log_is_rate_limited():
    drops, clock, written = DropCounter(), Clock(), []
    log = RefusalLog(drops, "refs", "plant", written.extend, every_s=1.0, clock=clock)
    log.poll(0.0)
    assert written == []
    for _ in range(50):
        drops.add("refs", DropReason.NON_FINITE)
        log.poll(0.0)
    drops.add("refs", DropReason.STALE_TICK)  # counted, never an event
    log.poll(0.0)
    assert [e.detail["count"] for e in written] == [1]  # the first at once, the next 49 wait
    clock.now = 1.0
    log.poll(1.0)
    assert [(e.detail["refused"], e.detail["count"], e.detail["total"]) for e in written] == [
        ("non_finite", 1, 1),
        ("non_finite", 49, 50),
    ]
    assert log.counts() == {"non_finite": 50, "stale_tick": 1}
    clock.now = 5.0
    log.poll(5.0)
    assert len(written) == 2


def test_refs_freshness():
    events = []
    fresh = RefsFreshness(max_ref_age=10, stale_event_ticks=20, event=events.append)
    assert fresh.update(0, None) is False and fresh.fresh is None  # nothing yet: not counted as stale
    assert fresh.update(1, 0) and events == [True]
    for k in range(2, 20):  # stale from tick 11 on: 9 ticks, a hiccup (counted, no event)
        fresh.update(k, 0)
    assert fresh.fresh is False and fresh.stale_ticks == 9 and fresh.stale_episodes == 1 and events == [True]
    for k in range(20, 31):  # the 20th stale tick in a row: an outage, logged
        fresh.update(k, 0)
    assert events == [True, False]
    assert fresh.update(31, 30) and events == [True, False, True]
