"""The split of runs into process chunks changes no number: every row draws from its own streams."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from tests.live.helpers import TURBINE_SHORT
from windwarden.evaluation.parallel import Branch, chunk_runs
from windwarden.evaluation.turbine import CLEAN_TURBINE, TWIN_TURBINE, simulate_chunk
from windwarden.evaluation.turbine_scoring import WARMUP_S
from wwcore.scenario import parse_scenario


def test_chunks_cover_every_run_once_and_depend_on_the_run_count_only():
    assert chunk_runs(1) == [[0]]
    assert chunk_runs(10, 5) == [[0, 2, 4, 6, 8], [1, 3, 5, 7, 9]]
    assert chunk_runs(20, 50) == [list(range(0, 20, 2)), list(range(1, 20, 2))]  # two cores busy below 50 runs
    for runs, chunk in ((2, 25), (3, 25), (25, 25), (51, 25), (100, 50), (100, 25), (101, 50), (7, 1)):
        chunks = chunk_runs(runs, chunk)
        fewest = -(-runs // chunk)
        assert len(chunks) == min(runs, fewest + fewest % 2)  # the fewest, in pairs (one per run at most)
        assert max(len(c) for c in chunks) <= chunk
        assert max(len(c) for c in chunks) - min(len(c) for c in chunks) <= 1
        assert sorted(r for c in chunks for r in c) == list(range(runs))


def _key(events) -> list[tuple]:
    return sorted((e.run, round(e.t, 9), e.type.value, e.target, e.turbine) for e in events)


@pytest.fixture(scope="module")
def runs_0_and_1_with_twins():
    """TURBINE_SHORT's runs 0 and 1 in one chunk, with fault-free twins: two tests compare against it."""
    scenario = parse_scenario(tomllib.loads(TURBINE_SHORT))
    return simulate_chunk([0, 1], lambda s: None, scenario, 77, "benchmark", "uio-bank", {}, True)


def test_turbine_runs_give_the_same_events_and_errors_in_one_chunk_or_two(runs_0_and_1_with_twins):
    scenario = parse_scenario(tomllib.loads(TURBINE_SHORT))
    args = (scenario, 77, "benchmark", "uio-bank", {}, True)
    together = runs_0_and_1_with_twins
    apart = [simulate_chunk([r], lambda s: None, *args) for r in (0, 1)]
    assert _key(together.events) == _key(apart[0].events + apart[1].events)
    assert any(e.type.value == "detection" for e in together.events)  # the comparison has something to compare
    for name, total in together.sq_err.items():
        np.testing.assert_allclose(total, apart[0].sq_err[name] + apart[1].sq_err[name], rtol=1e-9, atol=1e-12)
    assert together.counts == pytest.approx(apart[0].counts + apart[1].counts)


def test_a_fault_free_twin_branches_off_its_window_from_the_runs_own_state():
    """A window whose fault changes nothing (a gain of 1): its twin, forked at the window's start with the fault
    ended, must reproduce the runs' FTE errors in that window bit for bit (same state, same streams)."""
    text = TURBINE_SHORT.replace("value = 1.1", "value = 1.0").replace("value = 0.9", "value = 1.0")
    scenario = parse_scenario(tomllib.loads(text))
    result = simulate_chunk([0, 1], lambda s: None, scenario, 77, "benchmark", "uio-bank", {}, True)
    harmless = 2  # the double fault, now two gains of 1
    assert result.sq_err["fte"][harmless] > 0.0
    assert result.sq_err["fte_fault_free"][harmless] == result.sq_err["fte"][harmless]
    # the stuck sensor does change the readings: its twin's errors are its own
    assert result.sq_err["fte_fault_free"][1] not in (0.0, result.sq_err["fte"][1])
    assert result.sq_err["fte_fault_free"][0] == 0.0  # no twin outside the fault windows
    assert result.twin_seconds == pytest.approx(5.0 + 6.0)
    assert {e.turbine for e in result.events if e.type.value == "detection"} == {1}  # the twins raised none


def _runs_own(events) -> list:
    return [e for e in events if e.turbine not in (TWIN_TURBINE, CLEAN_TURBINE)]


def test_fault_free_twins_add_nothing_to_the_runs_figures(runs_0_and_1_with_twins):
    scenario = parse_scenario(tomllib.loads(TURBINE_SHORT))
    with_twins = runs_0_and_1_with_twins
    without = simulate_chunk([0, 1], lambda s: None, scenario, 77, "benchmark", "uio-bank", {}, False)
    assert _key(_runs_own(with_twins.events)) == _key(without.events)
    assert any(e.turbine == CLEAN_TURBINE for e in with_twins.events)  # the clean runs ran beside them
    for name in ("fte", "nfte", "anemometer"):  # the clean runs' rows share the batch: equal to rounding, as a
        # different split of the runs into chunks is (BLAS picks its blocking by the batch's size)
        np.testing.assert_allclose(with_twins.sq_err[name], without.sq_err[name], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(with_twins.counts, without.counts)
    assert not without.sq_err["fte_fault_free"].any() and without.twin_seconds == 0.0
    assert not without.sq_err["fte_clean"].any() and without.clean_seconds == 0.0
    assert with_twins.sq_err["fte_fault_free"][1:].all()


def test_the_clean_run_is_the_same_run_without_any_fault(runs_0_and_1_with_twins):
    """The clean run's FTE (traced for run 0) is the FTE of the scenario run with its faults taken out, its error
    is scored in every metric window, the fault-free time included, and its flags are its own (``CLEAN_TURBINE``)."""
    data = tomllib.loads(TURBINE_SHORT)
    scenario = parse_scenario(data)
    faultless = simulate_chunk(
        [0, 1], lambda s: None, parse_scenario({**data, "faults": []}), 77, "benchmark", "uio-bank", {}, False
    )
    with_twins = runs_0_and_1_with_twins
    np.testing.assert_allclose(with_twins.trace["fte_clean"], faultless.trace["fte"], rtol=1e-9, atol=1e-12)
    assert not np.allclose(with_twins.trace["fte"], faultless.trace["fte"])  # the faults do move the runs' FTE
    assert with_twins.sq_err["fte_clean"].all()
    assert with_twins.clean_seconds == pytest.approx(scenario.duration_s - WARMUP_S)
    clean_flags = sorted(k[:4] for k in _key(e for e in with_twins.events if e.turbine == CLEAN_TURBINE))
    assert clean_flags == sorted(k[:4] for k in _key(faultless.events))


def test_a_failing_branch_raises_in_the_parent_with_its_traceback():
    def broken():
        raise ValueError("no wind in the branch")

    with pytest.raises(RuntimeError, match="no wind in the branch"):
        Branch(broken).result()
    assert Branch(lambda: {"value": 3}).result() == {"value": 3}
