"""Lockstep over Zenoh equals batch mode, for one scenario and seed: same event log, same scorecard.

The lockstep run crosses a real Zenoh router on loopback (plant and supervisor in their own sessions). The batch
reference is the kind objects' one-process loop (``windwarden.live.batch``): the step contract with the constructors
``windwarden eval`` uses. For the hydrostatic kind the reconstruction figures also equal ``windwarden eval``'s
compensated twin exactly. For the turbine kind ``windwarden eval --no-twins`` (a live run has no fault-free
twin either; the twins add their own figures and change none of the runs') gives the same detection figures and
wind RMSE bit for bit.
"""

from __future__ import annotations

import copy
import json

import pytest

from tests.live.helpers import FARM_SHORT, HYDRO_SHORT, TURBINE_SHORT, LiveNodes, router, scenario
from windwarden.evaluation.kinds import EvalOptions
from windwarden.kinds import kind_for
from windwarden.live.batch import run_batch
from windwarden.live.finalize import finalize_scorecard
from windwarden.live.runfolder import EVENTS, read_events
from wwcore.events import PLANT_EVENTS, SUPERVISOR_EVENTS

SCORED = PLANT_EVENTS | SUPERVISOR_EVENTS


def _keys(events):
    """Everything that must agree between two runs (no wall time), in a canonical order."""
    return sorted((*e.scoring_key(), json.dumps(e.detail, sort_keys=True)) for e in events if e.type in SCORED)


def _lockstep(tmp_path, text, seed):
    scn = scenario(text)
    with router() as endpoint, LiveNodes(endpoint, scn, tmp_path / "run", mode="lockstep", seed=seed) as nodes:
        assert nodes.wait(120) == 0
    card = finalize_scorecard(tmp_path / "run")
    return scn, read_events(tmp_path / "run" / EVENTS), card


@pytest.fixture(scope="module")
def lockstep_run(tmp_path_factory):
    """``_lockstep`` once per (scenario, seed) in this module: the hydro and turbine runs are each checked against
    the batch loop and against ``windwarden eval``, from the same lockstep run. Each caller gets its own copy."""
    done: dict[tuple[str, int], tuple] = {}

    def run(text: str, seed: int):
        if (text, seed) not in done:
            done[text, seed] = _lockstep(tmp_path_factory.mktemp("lockstep"), text, seed)
        return copy.deepcopy(done[text, seed])

    return run


FARM_SHORT_HOLD = FARM_SHORT + '[supervisor.params]\naccommodation_rule = "hold-torque"\n'
"""FARM_SHORT with the drive-train hold (``hold_torque``, ``held_torque`` on the wire) instead of the default rule"""


@pytest.mark.parametrize(
    "text, seed",
    [
        (HYDRO_SHORT, 1),
        (TURBINE_SHORT, 3),
        (FARM_SHORT, 5),
        pytest.param(FARM_SHORT_HOLD, 5, marks=pytest.mark.slow),  # the farm again, with another rule: ~45 s
    ],
    ids=["hydro", "turbine", "farm", "farm-hold"],
)
def test_lockstep_equals_batch(lockstep_run, text, seed):
    scn, events, card = lockstep_run(text, seed)
    batch = run_batch(scn, seed)
    assert _keys(events) == _keys(batch.events)
    assert any(e.type.value == "detection" for e in events), "the scenario must exercise detection"
    if scn.plant.kind == "farm":  # and the accommodation's every request on the wire
        modes = {e.detail.get("to") for e in events if e.type.value == "dispatch"}
        drive_train = "held torque" if text == FARM_SHORT_HOLD else "3P cancelled"
        assert {drive_train, "pitch trim", "debris"} <= modes
    live = card.pop("live")
    assert live["completed"] and live["ticks_without_refs"] == 0 and live["dropped"] == {}
    assert card == json.loads(json.dumps(batch.scorecard))  # bit for bit, through JSON as both are written


def test_hydro_lockstep_reconstruction_equals_windwarden_eval(lockstep_run):
    scn, _, card = lockstep_run(HYDRO_SHORT, 1)
    evaluation = kind_for(scn.plant.kind).evaluate(scn, 1, 1, EvalOptions(workers=1, progress=False))
    assert card["metrics"]["reconstruction"] == evaluation.scorecard["metrics"]["reconstruction"]


def test_turbine_lockstep_matches_windwarden_eval(lockstep_run):
    scn, _, card = lockstep_run(TURBINE_SHORT, 3)
    evaluation = (
        kind_for(scn.plant.kind).evaluate(scn, 1, 3, EvalOptions(workers=1, progress=False, twins=False)).scorecard
    )
    assert card["faults"] == evaluation["faults"]
    assert card["false_alarms"] == evaluation["false_alarms"]
    assert card["false_alarms_per_1000s"] == evaluation["false_alarms_per_1000s"]
    assert card["metrics"]["wind_rmse"] == evaluation["metrics"]["wind_rmse"]


FARM_LAYOUT_SHORT = """
name = "farm-layout-short"
duration_s = 30.0
[plant]
kind = "farm"
wake_model = "gauss"
wakes = false
wind_direction_deg = 200.0
layout = { kind = "coordinates", x_m = [0.0, 600.0, 250.0], y_m = [0.0, 80.0, -700.0] }
[plant.demand]
mode = "profile"
points = [[0.0, 9.0]]
[wind]
mean = [[0.0, 10.0]]
[[faults]]
name = "F1 debris wt3"
target = "rotor"
kind = "debris"
value = 0.97
turbine = 3
start_s = 20.0
end_s = 26.0
"""
"""Three turbines at explicit coordinates: a farm of N ≠ 9 over the wire (rows, mast, vane, references)."""


@pytest.mark.slow  # ~18 s on the loaded 2-core machine
def test_lockstep_equals_batch_for_a_farm_of_three_turbines(tmp_path):
    scn, events, card = _lockstep(tmp_path, FARM_LAYOUT_SHORT, 6)
    batch = run_batch(scn, 6)
    assert _keys(events) == _keys(batch.events)
    assert {(e.turbine, e.target) for e in events if e.type.value == "detection"} == {(3, "debris")}
    live = card.pop("live")
    assert live["completed"] and live["ticks_without_refs"] == 0 and live["dropped"] == {}
    assert card == json.loads(json.dumps(batch.scorecard))
    assert card["turbines"] == 3 and card["wind_direction_deg"] == 200.0
