"""The scoring policy (``windwarden.evaluation.scoring``).

Closed-form figures on hand-made event logs: every figure of ``docs/scorecards.md`` has a case whose answer
follows from the definitions by hand. Then detectors built to game the scorecard, registered through the plug-in
registries and scored by the real evaluators on short scenarios: each scores badly on the figure it games. And the
live run folder's scorecard equals ``windwarden eval``'s for the same events.
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from service.plugins import FARM_DETECTORS, TURBINE_DETECTORS
from service.turbine.interfaces import Diagnosis
from windwarden.evaluation.kinds import EvalOptions
from windwarden.evaluation.report import render
from windwarden.evaluation.scoring import FaultWindow, score_detection, twin_false_alarms, windows_from_faults
from windwarden.evaluation.scoring_policy import POLICIES, ScoringPolicy, policy_for, policy_table
from windwarden.kinds import kind_for
from windwarden.live.batch import run_batch
from windwarden.live.finalize import finalize_scorecard
from windwarden.live.runfolder import EVENTS, LIVE, RUN, SCENARIO, encode_line, write_json
from wwcore.channels import DIAGNOSIS_TARGETS, SPEED_SENSORS, TARGET_INDEX
from wwcore.events import Event, EventType
from wwcore.scenario import FaultSpec, parse_scenario
from wwcore.scenario.farm import N_TURBINES

POLICY = ScoringPolicy("test", warmup_s=10.0, grace_s=2.0, time_base="s", warmup_reason="", grace_reason="")
DURATION = 1000.0
WINDOW = FaultWindow("w", ("a",), 1, 100.0, 200.0)
QUIET = DURATION - POLICY.warmup_s - (WINDOW.end_s + POLICY.grace_s - WINDOW.start_s)  # 888 s


def log(*changes: str, run: int = 0, turbine: int = 1) -> list[Event]:
    """Events from "t+target" (raise) and "t-target" (drop), e.g. log("100.5+a", "200.3-a")."""
    out = []
    for change in changes:
        t, sign, target = re.fullmatch(r"([\d.]+)([+-])(\w+)", change).groups()
        kind = EventType.DETECTION if sign == "+" else EventType.RECOVERY
        out.append(Event(float(t), kind, turbine, target, run))
    return out


def score(events, windows=(WINDOW,), runs=1, turbines=(1,)):
    return score_detection(events, list(windows), runs=runs, duration_s=DURATION, policy=POLICY, turbines=turbines)


def entry(events, **kw):
    [out] = score(events, **kw).faults
    return out


def test_a_detector_that_never_flags_has_nothing_detected_and_no_end_recognised():
    e = entry([])
    assert (e["detected_pct"], e["isolated_pct"], e["end_recognised_pct"]) == (0.0, 0.0, 0.0)
    assert e["delay_s_mean"] is None and e["end_delay_s_mean"] is None and e["isolated_time_pct"] == 0.0


def test_a_clean_detection_and_its_end():
    e = entry(log("100.5+a", "200.3-a"))
    assert (e["detected_pct"], e["isolated_pct"], e["end_recognised_pct"]) == (100.0, 100.0, 100.0)
    assert e["delay_s_mean"] == pytest.approx(0.5) and e["end_delay_s_mean"] == pytest.approx(0.3)
    assert e["isolated_time_pct"] == pytest.approx(99.5)  # right flags over [100.5, 200) of [100, 200)
    assert (e["flaps_mean"], e["flaps_max"], e["lost"], e["lost_pct"], e["wrong_isolations"]) == (0, 0, 0, 0, 0)


def test_a_detection_on_the_fault_s_first_tick_has_no_delay_despite_binary_tick_times():
    e = entry(log(f"{10000 * 0.01}+a", f"{20000 * 0.01}-a"))  # 100.00000000000001 and 200.00000000000003
    assert e["delay_s_mean"] == 0.0 and e["end_delay_s_mean"] == 0.0 and e["isolated_pct"] == 100.0


def test_a_wrong_first_flag_is_a_wrong_isolation_and_the_right_one_after_it_is_still_a_detection():
    e = entry(log("100.2+b", "100.7-b", "100.7+a", "200.1-a"))
    assert e["isolated_pct"] == 0.0 and e["detected_pct"] == 100.0 and e["delay_s_mean"] == pytest.approx(0.7)
    assert e["wrong_isolations"] == 1 and e["wrong_isolation_pct"] == 100.0
    assert e["isolated_time_pct"] == pytest.approx(99.3)


def test_a_flag_on_another_target_only_is_neither_a_detection_nor_a_false_alarm():
    s = score(log("150+b", "160-b"))
    [e] = s.faults
    assert e["detected_pct"] == 0.0 and e["isolated_pct"] == 0.0 and e["wrong_isolations"] == 1
    assert s.false_alarms["count"] == 0 and s.wrong_isolations == {"count": 1, "by_target": {"b": 1}}


def test_the_first_flag_must_name_exactly_the_targets():
    both = FaultWindow("double", ("a", "b"), 1, 100.0, 200.0)
    one_then_other = entry(log("100.1+a", "100.3+b", "200.1-a", "200.1-b"), windows=[both])
    together = entry(log("100.1+a", "100.1+b", "200.1-a", "200.1-b"), windows=[both])
    too_many = entry(log("100.1+a", "100.1+b", "100.1+c", "100.2-c", "200.1-a", "200.1-b"), windows=[both])
    assert one_then_other["isolated_pct"] == 0.0 and one_then_other["detected_pct"] == 100.0
    assert one_then_other["isolated_time_pct"] == pytest.approx(99.7)
    assert together["isolated_pct"] == 100.0 and together["end_recognised_pct"] == 100.0
    assert too_many["isolated_pct"] == 0.0 and too_many["wrong_isolations"] == 1


def test_a_flag_already_up_when_the_fault_starts_is_no_detection_of_it():
    s = score(log("50+a"))  # raised before the fault, never cleared
    [e] = s.faults
    assert e["detected_pct"] == 0.0 and e["isolated_pct"] == 0.0 and e["end_recognised_pct"] == 0.0
    assert s.false_alarms["count"] == 1
    assert s.false_alarms["flagged_s"] == pytest.approx(QUIET - (50.0 - POLICY.warmup_s))  # from 50 s on


def test_a_cycling_detector_is_not_isolated_and_flaps():
    changes = []
    for i in range(200):  # a, b, c, d in turn, 0.5 s each, from 99.9 s on
        t = 99.9 + 0.5 * i
        changes += [f"{t:.1f}-{'abcd'[(i - 1) % 4]}"] if i else []
        changes.append(f"{t:.1f}+{'abcd'[i % 4]}")
    s = score(log(*changes))
    [e] = s.faults
    assert e["isolated_pct"] == 0.0  # the first flag raised in the window is b (100.4 s)
    assert e["detected_pct"] == 100.0 and e["delay_s_mean"] == pytest.approx(1.9)  # a again at 101.9 s
    # a is up over [100, 100.4) (raised before the window) and for 0.5 s from each of its 49 raises inside it
    assert e["isolated_time_pct"] == pytest.approx(0.4 + 49 * 0.5)
    assert e["flaps_mean"] == 48 and e["lost"] == 49  # dropped at 102.4 s, …, 198.4 s
    assert e["wrong_isolations"] == 199 - 49 and e["end_recognised_pct"] == 0.0  # b, c and d raised in the span
    # outside the span: a raised at 99.9 s (up for 0.1 s), and d, raised last (199.4 s), up to the end of the run
    assert s.false_alarms["count"] == 1 and s.false_alarms["by_target"] == {"a": 1}
    assert s.false_alarms["flagged_s"] == pytest.approx(0.1 + (DURATION - 202.0))


def test_a_lost_flag_is_no_end_recognised():
    e = entry(log("101+a", "150-a"))
    assert e["lost"] == 1 and e["lost_pct"] == 100.0 and e["end_recognised_pct"] == 0.0
    assert e["end_delay_s_mean"] is None and e["isolated_pct"] == 100.0
    assert e["isolated_time_pct"] == pytest.approx(49.0)


def test_a_flap_is_counted_and_the_end_still_recognised():
    e = entry(log("101+a", "150-a", "150.5+a", "200.1-a"))
    assert (e["flaps_mean"], e["flaps_max"], e["lost"]) == (1.0, 1, 1)
    assert e["end_recognised_pct"] == 100.0 and e["end_delay_s_mean"] == pytest.approx(0.1)


def test_a_flag_raised_after_the_fault_ended_is_late_not_a_detection_and_not_a_false_alarm():
    late = score(log("200.5+a", "201-a"))
    [e] = late.faults
    assert e["detected_pct"] == 0.0 and e["flaps_mean"] == 0.0 and late.false_alarms["count"] == 0
    slow = entry(log("199.9+a", "200.2-a"))
    assert slow["detected_pct"] == 100.0 and slow["delay_s_mean"] == pytest.approx(99.9)


def test_an_end_not_cleared_within_the_grace_is_not_recognised_and_its_flag_is_flagged_time():
    s = score(log("101+a", "203-a"))
    [e] = s.faults
    assert e["end_recognised_pct"] == 0.0 and s.false_alarms["count"] == 0
    assert s.false_alarms["flagged_s"] == pytest.approx(1.0)  # 202–203 s, outside the span


def test_an_end_is_when_the_flags_are_cleared_for_good_within_the_grace():
    e = entry(log("101+a", "200.2-a", "201+a", "201.5-a"))
    assert e["end_recognised_pct"] == 100.0 and e["end_delay_s_mean"] == pytest.approx(1.5)
    e = entry(log("101+a", "200.2-a", "201.5+a"))
    assert e["end_recognised_pct"] == 0.0 and e["flaps_mean"] == 1.0


def test_false_alarm_onsets_and_flagged_time_per_1000_s():
    s = score(log("300+c", "301-c", "500+c", "500.5-c", "600+c", "600+d", "602-c", "602-d"))
    fa = s.false_alarms
    assert fa["count"] == 4 and fa["observed_s"] == pytest.approx(QUIET)
    assert fa["per_1000s"] == pytest.approx(4000.0 / QUIET) == s.false_alarms_per_1000s
    assert fa["flagged_s"] == pytest.approx(3.5)  # two flags up at once on one turbine: that turbine's time once
    assert fa["flagged_s_per_1000s"] == pytest.approx(3500.0 / QUIET) and fa["by_target"] == {"c": 3, "d": 1}
    assert s.card_fields()["false_alarm_flagged_s_per_1000s"] == fa["flagged_s_per_1000s"]


def test_flags_raised_in_the_warm_up_and_still_up_are_raised_when_scoring_starts():
    early = score(log("5+a", "5+b", "7-b", "8+c"))  # a and c still up at 10 s, never cleared
    assert early.false_alarms["count"] == 2 and early.false_alarms["by_target"] == {"a": 1, "c": 1}
    assert early.false_alarms["flagged_s"] == pytest.approx(QUIET)
    assert early.false_alarms["flagged_s_per_1000s"] == pytest.approx(1000.0)
    cleared = score(log("5+a", "9.99-a", "10+b", "11-b"))  # a cleared inside the warm-up; b at its end
    assert cleared.false_alarms["count"] == 1 and cleared.false_alarms["flagged_s"] == pytest.approx(1.0)


def test_percentages_and_delays_are_over_all_runs():
    events = log("100.1+a", "200.1-a", run=0) + log("100.3+a", "200.3-a", run=2)  # run 1 never flags
    e = entry(events, runs=4)
    assert e["detected_pct"] == 50.0 and e["isolated_pct"] == 50.0 and e["end_recognised_pct"] == 50.0
    assert e["delay_s_mean"] == pytest.approx(0.2) and e["delay_s_max"] == pytest.approx(0.3)
    assert e["end_delay_s_max"] == pytest.approx(0.3)


def test_overlapping_windows_on_one_turbine_allow_each_other_s_targets():
    pump, motor = FaultWindow("pump", ("u_p",), 1, 10.0, 40.0), FaultWindow("motor", ("u_M",), 1, 30.0, 70.0)
    s = score(log("10.05+u_p", "30.05+u_M", "40.5-u_p", "70.5-u_M"), windows=[pump, motor])
    p, m = s.faults
    assert p["isolated_pct"] == m["isolated_pct"] == 100.0 and s.wrong_isolations["count"] == 0
    assert p["end_delay_s_mean"] == pytest.approx(0.5) and m["end_delay_s_mean"] == pytest.approx(0.5)
    assert m["isolated_time_pct"] == pytest.approx(100.0 * (70.0 - 30.05) / 40.0)
    wrong = score(log("10.05+u_p", "20+u_M", "20.1-u_M", "40.5-u_p"), windows=[pump, motor])
    assert wrong.faults[0]["wrong_isolations"] == 1 and wrong.faults[1]["detected_pct"] == 0.0


def test_a_farm_flag_on_another_turbine_during_a_window_is_a_wrong_isolation():
    window = FaultWindow("debris wt5", ("debris",), 5, 100.0, 200.0)
    events = log("100.1+debris", turbine=4) + log("100.2+debris", "200.5-debris", turbine=5)
    events += log("100.3-debris", "400+drivetrain", "401-drivetrain", turbine=4)
    s = score(events, windows=[window], turbines=range(1, 10))
    [e] = s.faults
    assert e["isolated_pct"] == 0.0 and e["detected_pct"] == 100.0 and e["wrong_isolations"] == 1
    assert s.false_alarms["count"] == 1 and s.false_alarms["observed_s"] == pytest.approx(9 * QUIET)
    rows = {t: s.by_target(t, plant_seconds=DURATION - POLICY.warmup_s) for t in ("debris", "drivetrain")}
    assert rows["debris"]["false_positives"] == 1 and rows["drivetrain"]["false_positives"] == 1
    assert rows["debris"]["false_positives_per_1000s"] == pytest.approx(1000.0 / 990.0)
    allowed = 202.0 - 100.0  # debris is the fault on wt5 during its span
    assert rows["debris"]["false_positives_per_1000_turbine_s"] == pytest.approx(1000.0 / (9 * 990.0 - allowed))
    assert rows["debris"]["isolated_pct"] == 0.0 and rows["debris"]["delay_s_mean"] == pytest.approx(0.2)


def test_a_window_inside_the_warm_up_is_not_scored_and_one_to_the_end_of_the_run_has_no_end():
    early, open_ended = FaultWindow("early", ("a",), 1, 2.0, 8.0), FaultWindow("open", ("b",), 1, 900.0, DURATION)
    s = score(log("901+b"), windows=[early, open_ended])
    assert "detected_pct" not in s.faults[0] and s.faults[0]["note"].startswith("inside the warm-up")
    assert s.faults[1]["end_recognised_pct"] is None and s.faults[1]["detected_pct"] == 100.0


def test_a_window_starting_in_the_warm_up_is_scored_from_its_end():
    window = FaultWindow("w", ("a",), 1, 5.0, 50.0)
    e = entry(log("6+a", "50.1-a"), windows=[window])
    assert e["detected_pct"] == 100.0 and e["delay_s_mean"] == pytest.approx(5.0) and e["isolated_pct"] == 100.0


def test_twin_false_alarms_start_empty_in_each_segment():
    events = log("105-a", "150+b", "160-b", "500+c")  # 105 s: a flag the twin inherited from its run, dropped
    fa = twin_false_alarms(events, observed_s=200.0, policy=POLICY, segments=[(100.0, 200.0), (450.0, 550.0)])
    assert fa["count"] == 2 and fa["per_1000s"] == pytest.approx(10.0)
    assert fa["flagged_s"] == pytest.approx(10.0 + 50.0)


def test_double_faults_share_a_window():
    faults = [
        FaultSpec(target="omega_g_m1", kind="gain", value=0.9, start_s=10.0, end_s=20.0),
        FaultSpec(target="omega_g_m2", kind="fixed", value=140.0, start_s=10.0, end_s=20.0),
        FaultSpec(target="omega_r_m1", kind="fixed", value=1.4, start_s=30.0),
    ]
    double, single = windows_from_faults(faults, 40.0)
    assert double.targets == ("omega_g_m1", "omega_g_m2") and double.flags == {(1, "omega_g_m1"), (1, "omega_g_m2")}
    assert single.end_s == 40.0


def test_one_policy_per_kind_and_the_docs_show_it_as_the_code_applies_it():
    assert set(POLICIES) == {"turbine", "farm", "hydro"}
    assert policy_for("farm").warmup_s == 60.0
    with pytest.raises(KeyError, match="no scoring policy for plant kind 'ship'"):
        policy_for("ship")
    docs = (Path(__file__).resolve().parents[1] / "docs" / "scorecards.md").read_text()
    assert policy_table() in docs  # the values and the reasons for them, as the code has them


# ---- detectors built to game the scorecard, through the plug-in interface and the real evaluators -------------
SPEED_COLUMNS = [TARGET_INDEX[s] for s in SPEED_SENSORS]
GAMED = """
name = "gamed"
duration_s = 30.0
[plant]
kind = "turbine"
[wind]
mean = [[0.0, 12.0], [30.0, 12.75]]
[[faults]]
name = "generator sensor 2 stuck"
target = "omega_g_m2"
kind = "fixed"
value = 100.0
start_s = 12.0
end_s = 22.0
"""
RUNS = 2


class _Adversary:
    """Flags from the frame alone (``flags``), as any plug-in detector sees it; never the fault schedule."""

    def __init__(self, *, context, options=None):
        self.context, self.n = context, context.n

    def step(self, frame):
        return Diagnosis(self.flags(frame))

    def none(self):
        return np.zeros((self.n, len(DIAGNOSIS_TARGETS)), dtype=bool)


@TURBINE_DETECTORS.register("adversary-never")
class NeverFlags(_Adversary):
    def flags(self, frame):
        return self.none()


@TURBINE_DETECTORS.register("adversary-everything")
class FlagsEverythingAlways(_Adversary):
    def flags(self, frame):
        return ~self.none()


@TURBINE_DETECTORS.register("adversary-cycle")
class CyclesThroughTheSpeedSensors(_Adversary):
    def flags(self, frame):  # one speed sensor after another, 0.5 s each
        out = self.none()
        out[:, SPEED_COLUMNS[(frame.k // 50) % 4]] = True
        return out


@TURBINE_DETECTORS.register("adversary-early")
class FlagsEarlyNeverClears(_Adversary):
    def flags(self, frame):  # every speed sensor from 5 s on (inside the warm-up), never cleared
        out = self.none()
        out[:, SPEED_COLUMNS] = frame.t >= 5.0
        return out


class _Wrapped(_Adversary):
    """The shipped detector's verdict, altered."""

    def __init__(self, *, context, options=None):
        super().__init__(context=context, options=options)
        self.inner = TURBINE_DETECTORS.create("benchmark", context=context, options=options)


@TURBINE_DETECTORS.register("adversary-wrong-target")
class FlagsTheWrongTarget(_Wrapped):
    def flags(self, frame):  # perfect timing, but each speed sensor's flag on the next sensor
        out = self.inner.step(frame).faulty.copy()
        out[:, SPEED_COLUMNS] = np.roll(out[:, SPEED_COLUMNS], 1, axis=1)
        return out


@TURBINE_DETECTORS.register("adversary-late")
class FlagsLate(_Wrapped):
    LAG = 300  # ticks (3 s)

    def __init__(self, *, context, options=None):
        super().__init__(context=context, options=options)
        self.past: list[np.ndarray] = []

    def flags(self, frame):  # the shipped detector's verdict of 3 s ago
        self.past.append(self.inner.step(frame).faulty.copy())
        return self.past.pop(0) if len(self.past) > self.LAG else self.none()


@pytest.fixture(scope="module")
def gamed_cards():
    scenario = parse_scenario(tomllib.loads(GAMED))
    names = ("benchmark", "never", "everything", "cycle", "early", "wrong-target", "late")
    cards = {}
    for name in names:
        detector = name if name == "benchmark" else f"adversary-{name}"
        options = EvalOptions(detector=detector, workers=1, progress=False, twins=False)
        cards[name] = kind_for(scenario.plant.kind).evaluate(scenario, RUNS, 11, options).scorecard
    return cards


def test_the_shipped_detector_scores_well_on_the_gamed_scenario(gamed_cards):
    [f] = gamed_cards["benchmark"]["faults"]
    assert (f["detected_pct"], f["isolated_pct"], f["end_recognised_pct"]) == (100.0, 100.0, 100.0)
    assert f["delay_s_max"] <= 0.03 and f["wrong_isolations"] == 0 and f["flaps_max"] == 0
    assert gamed_cards["benchmark"]["false_alarms"]["count"] == 0


def test_a_detector_that_never_flags_recognises_no_end(gamed_cards):
    [f] = gamed_cards["never"]["faults"]
    assert (f["detected_pct"], f["isolated_pct"], f["end_recognised_pct"]) == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("name, flags_per_run", [("everything", len(DIAGNOSIS_TARGETS)), ("early", 4)])
def test_flags_raised_in_the_warm_up_and_never_cleared_are_false_alarms(gamed_cards, name, flags_per_run):
    card = gamed_cards[name]
    [f] = card["faults"]
    assert f["detected_pct"] == 0.0 and f["isolated_pct"] == 0.0 and f["isolated_time_pct"] == 0.0
    assert card["false_alarms"]["count"] == RUNS * flags_per_run
    assert card["false_alarm_flagged_s_per_1000s"] == pytest.approx(1000.0)
    assert card["false_alarms_per_1000s"] > 100.0


def test_a_detector_cycling_through_the_sensors_is_not_isolated(gamed_cards):
    card = gamed_cards["cycle"]
    [f] = card["faults"]
    assert f["isolated_pct"] == 0.0 and f["isolated_time_pct"] < 30.0 and f["end_recognised_pct"] == 0.0
    assert f["delay_s_mean"] == pytest.approx(1.5)  # its first flag in the window is omega_r_m1 (12.0 s)
    assert f["wrong_isolation_pct"] == 100.0 and f["flaps_max"] >= 4 and f["lost_pct"] == 100.0
    assert card["false_alarms_per_1000s"] > 100.0


def test_a_detector_flagging_the_wrong_sensor_detects_nothing(gamed_cards):
    card = gamed_cards["wrong-target"]
    [f] = card["faults"]
    assert f["detected_pct"] == 0.0 and f["isolated_pct"] == 0.0 and f["end_recognised_pct"] == 0.0
    assert f["wrong_isolation_pct"] == 100.0 and card["wrong_isolations"]["by_target"] == {"omega_r_m1": RUNS}
    assert card["false_alarms"]["count"] == 0  # inside the window it is a wrong isolation, not a false alarm


def test_a_late_detector_shows_its_delay_and_misses_the_end(gamed_cards):
    card = gamed_cards["late"]
    [f] = card["faults"]
    assert f["detected_pct"] == 100.0 and f["isolated_pct"] == 100.0 and f["delay_s_mean"] >= 3.0
    assert f["end_recognised_pct"] == 0.0
    assert card["false_alarm_flagged_s_per_1000s"] > 0.0  # its flag outlives the grace


# ---- one policy: the live run folder scores the events of a run as windwarden eval does ----------------------
FARM_GAMED = """
name = "farm-gamed"
duration_s = 72.0
[plant]
kind = "farm"
wind_case = 2
[plant.demand]
mode = "available_fraction"
fraction = 0.8
update_s = 10.0
[wind]
mean = [[0.0, 10.0], [72.0, 10.8]]
[[faults]]
name = "F1 debris wt5"
target = "rotor"
kind = "debris"
value = 0.97
turbine = 5
start_s = 62.0
end_s = 70.0
"""
DETECTION_FIELDS = (
    "scoring",
    "false_alarms_per_1000s",
    "false_alarm_flagged_s_per_1000s",
    "false_alarms",
    "wrong_isolations",
    "faults",
)


@FARM_DETECTORS.register("adversary-wrong-turbine")
class FlagsTheNextTurbine:
    """The shipped farm detector's verdict, each turbine's flags moved to the next turbine of its farm."""

    def __init__(self, *, context, options=None):
        self.inner = FARM_DETECTORS.create("analytic", context=context, options=options)

    def step(self, sample):
        diagnosis = self.inner.step(sample)
        faulty = np.roll(diagnosis.faulty.reshape(-1, N_TURBINES, 3), 1, axis=1).reshape(diagnosis.faulty.shape)
        return replace(diagnosis, faulty=faulty)


def _live_scorecard(run_dir: Path, text: str, seed: int, events: list[Event], faults) -> dict:
    """A live run folder holding ``events`` as the nodes write them, scored by ``finalize_scorecard``."""
    run_dir.mkdir()
    (run_dir / SCENARIO).write_text(text)
    write_json(run_dir / RUN, {"run_id": "same-events", "seed": seed})
    timing = dict.fromkeys(("overruns", "overrun_pct", "resyncs", "real_time_factor", "latency", "dropped"), 0)
    live = {
        "effective_faults": [f.model_dump(mode="json") for f in faults],
        "metrics": {},
        "timing": {**timing, "mode": "lockstep", "speed": 1.0},
        "completed": True,
        "ticks_run": 0,
    }
    write_json(run_dir / LIVE, live)
    (run_dir / EVENTS).write_bytes(b"".join(encode_line(e) for e in events))
    return finalize_scorecard(run_dir)


@pytest.mark.parametrize(
    "text, detector",
    [(GAMED, "adversary-cycle"), (FARM_GAMED, "adversary-wrong-turbine")],
    ids=["turbine", "farm"],
)
def test_the_live_run_folder_and_eval_give_the_same_scorecard_for_the_same_events(tmp_path, text, detector):
    text = f'{text}\n[supervisor]\ndetector = "{detector}"\n'
    scenario = parse_scenario(tomllib.loads(text))
    seed = 5
    run = run_batch(scenario, seed)  # run 0 of eval, through the live reference loop: the events a live run logs
    live = _live_scorecard(tmp_path / "run", text, seed, run.events, scenario.faults)
    batch = (
        kind_for(scenario.plant.kind)
        .evaluate(scenario, 1, seed, EvalOptions(workers=1, progress=False, twins=False))
        .scorecard
    )
    for key in DETECTION_FIELDS:
        assert live[key] == batch[key], key
    if scenario.plant.kind == "farm":
        assert live["metrics"]["detection"] == batch["metrics"]["detection"]
        [f] = live["faults"]  # and the adversary scores badly: the right type on the wrong turbine
        assert f["detected_pct"] == 0.0 and f["isolated_pct"] == 0.0 and f["wrong_isolation_pct"] == 100.0
        assert live["wrong_isolations"]["by_target"] == {"debris": 1}
        assert live["metrics"]["detection"]["debris"]["false_positives"] == 1
    else:
        assert live["wrong_isolations"]["count"] > 0 and live["false_alarms"]["count"] > 0


def test_the_printed_scorecard_shows_the_new_figures_within_100_columns():
    window, early = (
        FaultWindow("double: rotor and generator sensors", ("omega_r_m2", "omega_g_m1"), 1, 100.0, 200.0),
        (FaultWindow("early", ("a",), 1, 2.0, 8.0)),
    )
    s = score(
        log("100.1+omega_r_m2", "100.1+omega_g_m1", "150+b", "150.1-b", "200.1-omega_r_m2", "200.1-omega_g_m1"),
        windows=[window, early],
    )
    card = {"scenario": "printed", "runs": 1, "seed": 7, **s.card_fields(), "metrics": {"x": 1.0}}
    console = Console(width=100, record=True)
    console.print(render(card))
    text = console.export_text()
    assert max(len(line) for line in text.splitlines()) <= 100
    flat = " ".join(text.split())
    for word in ("first", "time", "wrong", "lost", "flaps", "recognised", "warm-up:", "flagged"):  # headers wrap
        assert word in flat, word
    assert "warm-up 10 s, grace 2 s" in flat
