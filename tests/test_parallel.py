"""The split of runs into process chunks changes no number: every row draws from its own streams."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from tests.live.helpers import TURBINE_SHORT
from windwarden.evaluation.parallel import chunk_runs
from windwarden.evaluation.turbine import TWIN_TURBINE, simulate_chunk, twin_seconds
from wwcore.scenario import parse_scenario


def test_chunks_cover_every_run_once_and_depend_on_the_run_count_only():
    assert chunk_runs(1) == [[0]]
    assert chunk_runs(10, 5) == [[0, 2, 4, 6, 8], [1, 3, 5, 7, 9]]
    for runs, chunk in ((3, 25), (25, 25), (51, 25), (100, 50), (100, 25)):
        chunks = chunk_runs(runs, chunk)
        assert len(chunks) == -(-runs // chunk)
        assert max(len(c) for c in chunks) <= chunk
        assert sorted(r for c in chunks for r in c) == list(range(runs))


def _key(events) -> list[tuple]:
    return sorted((e.run, round(e.t, 9), e.type.value, e.target, e.turbine) for e in events)


def test_turbine_runs_give_the_same_events_and_errors_in_one_chunk_or_two():
    scenario = parse_scenario(tomllib.loads(TURBINE_SHORT))
    args = (scenario, 77, "benchmark", "uio-bank", {}, True)
    together = simulate_chunk([0, 1], lambda s: None, *args)
    apart = [simulate_chunk([r], lambda s: None, *args) for r in (0, 1)]
    assert _key(together.events) == _key(apart[0].events + apart[1].events)
    assert any(e.type.value == "detection" for e in together.events)  # the comparison has something to compare
    for name, total in together.sq_err.items():
        np.testing.assert_allclose(total, apart[0].sq_err[name] + apart[1].sq_err[name], rtol=1e-9, atol=1e-12)
    assert together.counts == pytest.approx(apart[0].counts + apart[1].counts)


def test_fault_free_twins_in_a_batch_of_their_own_match_the_twins_in_the_runs_batch():
    scenario = parse_scenario(tomllib.loads(TURBINE_SHORT))
    base = (scenario, 77, "benchmark", "uio-bank", {})
    together = simulate_chunk([0, 1], lambda s: None, *base, True)
    main = simulate_chunk([0, 1], lambda s: None, *base, False, "main")
    twin = simulate_chunk([0, 1], lambda s: None, *base, False, "twin")
    end = twin_seconds(scenario)
    assert end == 26.0  # a batch of twins stops at the end of the last fault window, 4 s before the runs
    twin_turbine = {e.turbine for e in twin.events} | {TWIN_TURBINE}
    kept = [e for e in together.events if e.turbine != TWIN_TURBINE or e.t < end]
    assert _key(kept) == _key(main.events + twin.events)
    assert twin_turbine == {TWIN_TURBINE}  # the twins' detections are labelled as twins'
    for name in ("fte", "nfte", "anemometer"):
        np.testing.assert_allclose(main.sq_err[name], together.sq_err[name], rtol=1e-9, atol=1e-12)
    # in every fault window (index 0 is the fault-free time, which the twins' batch does not cover)
    np.testing.assert_allclose(
        twin.sq_err["fte_fault_free"][1:], together.sq_err["fte_fault_free"][1:], rtol=1e-9, atol=1e-12
    )
    assert set(twin.sq_err) == {"fte_fault_free"} and not twin.counts.any()  # counted once, in the main chunk
    assert main.counts == pytest.approx(together.counts)
