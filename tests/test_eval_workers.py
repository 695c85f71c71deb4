"""The number of workers and the way a twin branches off change no number: the chunks are fixed by the run count,
and every place they run gives the same scorecard bit for bit."""

from __future__ import annotations

import json
import os
import tomllib

import numpy as np
import pytest

from tests.live.helpers import TURBINE_SHORT
from windwarden.evaluation.branch import branch_mode
from windwarden.evaluation.cluster import ClusterError, check_environments
from windwarden.evaluation.kinds import EvalOptions, unused_switches
from windwarden.evaluation.provenance import environment
from windwarden.evaluation.turbine import simulate_chunk
from windwarden.evaluation.usage import ResourceMonitor, available_cores
from windwarden.kinds import kind_for
from wwcore.scenario import parse_scenario

SEED = 4242  # fresh: no figure is tuned on it


def scorecard_text(evaluation) -> str:
    """The scorecard as ``eval --out`` writes it; equal texts are equal numbers to the last bit (repr round-trips)."""
    return json.dumps(evaluation.scorecard, indent=2, sort_keys=True)


def test_one_process_or_two_give_the_same_scorecard_bit_for_bit():
    scenario = parse_scenario(tomllib.loads(TURBINE_SHORT))
    evaluate = kind_for(scenario.plant.kind).evaluate
    one = evaluate(scenario, 3, SEED, EvalOptions(workers=1, progress=False))  # chunks [0, 2], [1] in turn
    with ResourceMonitor() as usage:
        two = evaluate(scenario, 3, SEED, EvalOptions(workers=2, progress=False))  # the same chunks, side by side
    assert scorecard_text(one) == scorecard_text(two)
    assert one.scorecard["runs"] == 3 and one.scorecard["metrics"]["wind_rmse"]  # something to compare
    report = usage.report()
    assert report["largest_process_peak_rss_bytes"] > 0 and report["peak_rss_sum_bytes"] > 0
    assert report["wall_s"] > 0 and report["cpu_s"] > 0


def test_a_twin_copied_in_process_equals_a_forked_twin_bit_for_bit():
    scenario = parse_scenario(tomllib.loads(TURBINE_SHORT))
    args = (scenario, SEED, "benchmark", "uio-bank", {}, True)
    forked = simulate_chunk([0, 1], lambda s: None, *args)
    with branch_mode("copy"):
        copied = simulate_chunk([0, 1], lambda s: None, *args)
    assert forked.sq_err["fte_fault_free"][1:].all()  # the twins ran
    for name, value in forked.sq_err.items():
        np.testing.assert_array_equal(copied.sq_err[name], value)
    assert [(e.run, e.t, e.type, e.turbine) for e in copied.events] == [
        (e.run, e.t, e.type, e.turbine) for e in forked.events
    ]
    assert copied.twin_seconds == forked.twin_seconds


def test_available_cores_is_within_what_the_machine_has():
    assert 1 <= available_cores() <= (os.cpu_count() or 1)


def test_workers_with_a_scheduler_is_refused():
    refused = unused_switches("turbine", EvalOptions(workers=2, scheduler="tcp://127.0.0.1:8786"))
    assert [flag for flag, _ in refused] == ["--workers"]
    assert unused_switches("turbine", EvalOptions(scheduler="tcp://127.0.0.1:8786")) == []


def test_a_worker_with_other_code_or_libraries_is_refused_with_what_differs():
    here = environment()
    check_environments(here, {"tcp://a:1": dict(here)})  # the same: accepted
    other = {**here, "numpy": "0.0.1", "code": "0" * 16}
    with pytest.raises(ClusterError, match=r"tcp://b:2: numpy 0\.0\.1") as caught:
        check_environments(here, {"tcp://a:1": dict(here), "tcp://b:2": other, "tcp://c:3": ModuleNotFoundError("x")})
    assert "tcp://a:1" not in str(caught.value) and "code 0000000000000000" in str(caught.value)
    assert "tcp://c:3: ModuleNotFoundError" in str(caught.value)
