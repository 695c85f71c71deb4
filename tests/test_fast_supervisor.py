"""The compiled supervisor's common tick in one kernel call (``service.turbine.fast_supervisor.supervisor_tick``)
against the same supervisor making the bank's, the power-speed test's, the speed FDI's, the component tests', the
estimator's and the event test's kernel calls one by one, tick by tick through every fault class: the same flags,
statistics, estimates and events to the last bit, with every way the one call ends taken (the numpy reference:
``tests/test_fast_backend.py``); and a second process loads the kernel from numba's disk cache."""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
from collections import Counter

import numpy as np
import pytest

from plant_sim.turbine import TurbineBatch
from service.turbine import fast_supervisor
from service.turbine.supervisor import TurbineSupervisor
from tests.fast_compare import FAULTY, SEED
from wwcore.scenario import parse_scenario
from wwcore.stepping import run_ticks
from wwcore.turbine_params import BENCHMARK


def _trace(scenario, runs: list[int], folded: bool, outcomes: Counter) -> dict[str, list]:
    plant = TurbineBatch(scenario.plant, scenario.wind, scenario.faults, seed=SEED, runs=runs, backend="numba")
    supervisor = TurbineSupervisor(plant.n, noise_convention=scenario.plant.noise_convention, backend="numba")
    assert supervisor._folded is not None
    if not folded:
        supervisor._folded = None  # the kernels one call each
    detector, estimator = supervisor.detector, supervisor.estimator
    trace: dict[str, list] = {}

    def stepped(_k, _frame, refs) -> None:
        fdi, components, bank = detector.fdi, detector.components, supervisor.context._bank
        recovery, diagnosis, estimates = estimator.recovery, supervisor.diagnosis, supervisor.estimates
        for name, value in {
            "chi2": bank.chi2, "x_hat": bank.x_hat, "z": bank.z, "y_prev": bank._y_prev, "steps": bank.steps,
            "speed": supervisor.context._speed, "ratio": fdi.ratio, "flagged": fdi.flagged, "deadline": fdi.deadline,
            "provisional": fdi.provisional, "cusum": fdi.clearing.statistic, "bias": fdi.bias.up,
            "arbiter": fdi.arbiter.total, "window_sum": fdi._window_sum, "spread": fdi.spread.state,
            "fdi_frozen": fdi.readings.count, "fdi_ticks": fdi.ticks, "parity": components.parity.total,
            "outlier": components.outlier.total, "converter": components.converter_statistic,
            "actuator": components.actuator.total, "ref_block": components._ref_block,
            "component_flags": components.flags, "pitch_frozen": components.readings.count,
            "component_ticks": components.ticks, "faulty": diagnosis.faulty,
            "suspect": diagnosis.faulty if diagnosis.suspect is None else diagnosis.suspect,
            "filtered": recovery.filtered, "pitch_model": recovery.pitch.x[0], "x_prev": recovery._x_prev,
            "selected": estimates.selected, "valid": estimates.valid, "omega_r": refs.omega_r,
            "omega_g": refs.omega_g, "wind": refs.wind, "flags": supervisor.flags,
            "observers": supervisor.selected, "events": len(supervisor._events),
        }.items():  # fmt: skip
            trace.setdefault(name, []).append(np.array(value, dtype=float))

    one_call = fast_supervisor.supervisor_tick

    def counted(*arguments):
        results = one_call(*arguments)
        *_, quiet, healthy, unchanged = results
        outcomes[("quiet" if quiet else "not quiet", healthy, unchanged)] += 1
        return results

    fast_supervisor.supervisor_tick = counted
    try:
        run_ticks(plant, supervisor, range(round(scenario.duration_s / BENCHMARK.dt)), stepped=stepped)
    finally:
        fast_supervisor.supervisor_tick = one_call
    return trace


@pytest.mark.parametrize("runs", [[0, 1], [0, 1, 2]])
def test_the_one_call_tick_equals_the_kernels_called_one_by_one(runs):
    scenario = parse_scenario(tomllib.loads(FAULTY))
    separate = _trace(scenario, runs, False, Counter())
    outcomes: Counter = Counter()
    folded = _trace(scenario, runs, True, outcomes)
    ticks = len(folded["flags"])
    # every tick after the bank's first kept step (its 20th): quiet ones with the estimator's tick done (and no
    # event, or one due), quiet ones with a target distrusted (the estimator's tick not done), and ticks not quiet
    assert sum(outcomes.values()) == ticks - 20
    assert outcomes[("quiet", 1, True)] > ticks / 10 and outcomes[("quiet", 1, False)] > 0
    assert outcomes[("quiet", 0, False)] > 0 and outcomes[("not quiet", -1, False)] > 0
    assert np.array(separate["flags"]).any() and np.array(separate["cusum"]).any()  # isolation and clearing ran
    assert np.array(separate["events"])[-1] > 0
    for name, values in separate.items():
        np.testing.assert_array_equal(np.array(folded[name]), np.array(values), err_msg=name)


_CACHE_PROBE = """
from windwarden.bench import _Stepper, turbine_pair
from service.turbine import fast_supervisor
plant, supervisor = turbine_pair("ftwse-2012", 1, 0, False, "numba")
_Stepper(plant, supervisor).run(25)
k = fast_supervisor.supervisor_tick
print(sum(k.stats.cache_hits.values()), sum(k.stats.cache_misses.values()))
"""


def test_a_second_process_loads_the_one_call_tick_from_the_cache():
    """A fresh process finds ``supervisor_tick`` in numba's disk cache (the first one here may compile it; a later
    one must not; up to two later ones are asked, as ``tests/test_kept.py`` does)."""
    hits = misses = None
    for attempt in range(3):
        out = subprocess.run(
            [sys.executable, "-c", _CACHE_PROBE], capture_output=True, text=True, env={**os.environ}, check=True
        )
        hits, misses = map(int, out.stdout.split())
        if attempt and hits >= 1 and misses == 0:
            break
    assert hits >= 1 and misses == 0, (hits, misses)
