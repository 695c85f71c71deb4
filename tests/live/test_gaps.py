"""Sensor frames dropped at random (bursts of 1–10 ticks, ~5 % of the frames), as a congested real-time link drops
them: the supervisor bridges each gap (observers advance on interpolated frames, detectors hold), so the drops raise
no false alarm and the faults are still detected and isolated, as in lockstep. Fed as if consecutive, the same drops
corrupt the observers: the turbine's FDI holds its decisions through them (persistence), but observer 1's
non-fault-tolerant wind estimate doubles its fault-free error, so the test can fail.

The loop is ``windwarden.live.batch.run_batch`` with ``drop``: the plant node's and the supervisor node's handling of
a lost frame (``guard.bridge_gap``, the refs age window) without a network, so it is deterministic; lockstep equals
this loop without drops bit for bit (``test_lockstep``). ``tests/security/test_frames.py`` drops frames in a live
run too.
"""

from __future__ import annotations

import pytest

from tests.live.helpers import HYDRO_SHORT, scenario
from windwarden.live.batch import random_drops, run_batch
from windwarden.live.mailbox import backlog_ticks

pytestmark = pytest.mark.in_process  # no network, no process: the parallel phase (tests/conftest.py)

AROUND_RATED = """
name = "gaps-turbine"
duration_s = 60.0
[plant]
kind = "turbine"
[wind]
mean = [[0.0, 11.0], [30.0, 13.0], [60.0, 12.0]]
turbulence_intensity = 0.12
[[faults]]
name = "generator sensor 2 stuck"
target = "omega_g_m2"
kind = "fixed"
value = 100.0
start_s = 12.0
end_s = 40.0
"""


def figures(card):
    return card["false_alarms"]["count"], [(f["detected_pct"], f["isolated_pct"]) for f in card["faults"]]


def test_turbine_drops_raise_no_false_alarm(monkeypatch):
    scn = scenario(AROUND_RATED)
    lockstep = run_batch(scn, 3).scorecard
    assert figures(lockstep) == (0, [(100.0, 100.0)])
    drop = random_drops(round(scn.duration_s / 0.01), 0.05, 10, seed=1)
    assert 0.03 < drop.mean() < 0.07
    bridged = run_batch(scn, 3, drop).scorecard
    assert figures(bridged) == figures(lockstep)
    assert bridged["false_alarms"]["observed_s"] == lockstep["false_alarms"]["observed_s"]

    from service.turbine.supervisor import TurbineSupervisor

    monkeypatch.setattr(TurbineSupervisor, "bridge", None)  # the gaps fed as if the frames were consecutive
    consecutive = run_batch(scn, 3, drop).scorecard

    def nfte_rmse(card):
        return card["metrics"]["wind_rmse"]["fault_free"]["nfte"]

    assert nfte_rmse(consecutive) > 1.5 * nfte_rmse(bridged)


@pytest.mark.parametrize("seed", [1, 2])
def test_hydro_drops_raise_no_false_alarm(seed):
    scn = scenario(HYDRO_SHORT)
    lockstep = run_batch(scn, 1).scorecard
    drop = random_drops(round(scn.duration_s / 0.01), 0.05, 10, seed=seed)
    bridged = run_batch(scn, 1, drop).scorecard
    assert bridged["false_alarms_per_1000s"] == lockstep["false_alarms_per_1000s"] == 0.0
    assert [f["detected_pct"] for f in bridged["faults"]] == [f["detected_pct"] for f in lockstep["faults"]]


def test_the_backlog_is_counted_in_ticks():
    """The plant sends one sensor frame per tick, every turbine's row in it: 299 frames queued are 299 ticks behind,
    within a 300-tick allowance, for one turbine or 80."""
    assert backlog_ticks(299) == 299.0  # one sensor frame per tick, whatever the number of turbines
    assert backlog_ticks(301) > 300
    assert backlog_ticks(14, 2) == 7.0
