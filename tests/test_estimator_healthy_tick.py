"""The estimator's common compiled tick (``UIOBankEstimator.step`` → ``WindRecovery.step_healthy`` →
``fast.recovery_healthy_tick``: the map product, the filters, the speeds' gather and region 2's speed in one kernel
call, arguments kept between ticks, ω̂_r and ω̂_g in kept arrays) against the numpy reference, to the last bit on
every tick (but the wind, whose compiled inversion ``aero_fast.wind_from_torque`` may differ in the last places from
numpy's on some rows, main's as before: within ``RTOL``), through an isolation (the estimator leaves the common tick),
the return to it and a suspicion; and the common tick's Python and C calls."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from plant_sim.turbine import TurbineBatch
from service.turbine.bank import SPARSE_PRODUCT_ROWS
from service.turbine.builtin import UIOBankEstimator
from service.turbine.interfaces import TurbineContext
from service.turbine.wind_recovery import WARM_ITERATIONS, WindRecovery
from tests.fast_compare import SEED, assert_close
from wwcore import aero
from wwcore.backend import fast_module
from wwcore.channels import DIAGNOSIS_TARGETS, TARGET_INDEX
from wwcore.scenario import load_scenario
from wwcore.turbine_params import BENCHMARK

TICKS = 420
# (first tick, end tick, target, flagged): distrusted targets imposed on both estimators; flagged ones hand over on
# their return (``_take_over``), ω_g,m1's starts the encoder's fault estimate (``_compensate``), a suspected one not
DISTRUSTED = (
    (120, 220, "omega_g_m1", True),
    (150, 170, "converter", True),
    (260, 300, "omega_r_m2", False),
    (330, 345, "beta_2_m1", True),
)


def _schedule(n: int) -> tuple[np.ndarray, np.ndarray]:
    faulty = np.zeros((TICKS, n, len(DIAGNOSIS_TARGETS)), dtype=bool)
    flagged = np.zeros_like(faulty)
    for first, end, target, flag in DISTRUSTED:
        faulty[first:end, -1, TARGET_INDEX[target]] = True
        flagged[first:end, -1, TARGET_INDEX[target]] = flag
    return faulty, flagged


def _same_bits(got, expected, what: str) -> None:
    got, expected = np.asarray(got), np.asarray(expected)
    assert got.dtype == expected.dtype and got.shape == expected.shape, what
    if got.dtype.kind == "f":
        got, expected = got.view(np.int64), expected.view(np.int64)
    np.testing.assert_array_equal(got, expected, err_msg=what)


@pytest.mark.parametrize("n", [1, 3, SPARSE_PRODUCT_ROWS])
def test_the_common_compiled_tick_equals_the_reference_through_an_isolation(n):
    scenario = load_scenario("ftwse-2012")
    plant = TurbineBatch(scenario.plant, scenario.wind, (), seed=SEED, runs=list(range(n)), backend="numpy")
    estimators = [UIOBankEstimator(context=TurbineContext(BENCHMARK, n, backend=b)) for b in ("numpy", "numba")]
    reference, fast = estimators
    assert fast.recovery._map_nonzeros is None or n >= SPARSE_PRODUCT_ROWS  # from 16 rows where BLAS allows
    faulty, flagged = _schedule(n)
    kept, common = None, 0
    for k in range(TICKS):
        frame = plant.measure()
        plant.control(None)
        plant.advance()
        outputs = [e.step(frame, faulty[k].copy(), flagged=flagged[k].copy()) for e in estimators]
        for name in ("valid", "omega_r", "omega_g", "selected"):
            _same_bits(getattr(outputs[1], name), getattr(outputs[0], name), f"tick {k}: {name}")
        for name in ("wind", "wind_reference"):  # the compiled inversion's last places may differ (``aero_fast``)
            assert_close(getattr(outputs[1], name), getattr(outputs[0], name), f"tick {k}: {name}")
        ours, theirs = fast.recovery, reference.recovery
        for name, got, expected in (
            ("filtered", ours.filtered, theirs.filtered),
            ("s1", ours.filter.s1, theirs.filter.s1),
            ("s2", ours.filter.s2, theirs.filter.s2),
            ("pitch", ours.pitch.x, theirs.pitch.x),
            ("x_prev", ours._x_prev, theirs._x_prev),
        ):
            _same_bits(got, expected, f"tick {k}: {name}")
        if outputs[1].omega_r is (ours._healthy_speeds or (None,))[0]:  # the kernel's tick
            common += 1
            kept = kept or ours._healthy_arguments
            assert ours._healthy_arguments is kept, f"tick {k}: the kept arguments were rebuilt"
        else:
            assert faulty[k].any(), f"tick {k}: the kernel skipped with nothing distrusted"
    distrusted = int(faulty.any(axis=(1, 2)).sum())
    # every tick but the distrusted ones runs the kernel (the returns too, after their hand-over or the stop of the
    # encoder's compensation)
    assert common == TICKS - distrusted


def test_the_common_compiled_tick_is_a_few_calls():
    """``UIOBankEstimator.step`` on the common compiled tick (nothing distrusted, no wind inversion): the Python
    functions and C functions it calls, counted by ``sys.setprofile`` (the bank's kernel call included, already
    made by the detector in a supervisor's tick)."""
    scenario = load_scenario("ftwse-2012")
    plant = TurbineBatch(scenario.plant, scenario.wind, (), seed=SEED, runs=[0], backend="numba")
    estimator = UIOBankEstimator(context=TurbineContext(BENCHMARK, 1, backend="numba"))
    healthy = np.zeros((1, len(DIAGNOSIS_TARGETS)), dtype=bool)
    calls = []

    def count(frame, event, arg):
        if event in ("call", "c_call"):
            calls.append(arg.__qualname__ if event == "c_call" else frame.f_code.co_qualname)

    for k in range(45):
        frame = plant.measure()
        plant.control(None)
        plant.advance()
        estimator.context.bank(frame)
        if k == 41:  # not an inversion's tick (every 20th)
            sys.setprofile(count)
        estimator.step(frame, healthy)
        sys.setprofile(None)
    calls.remove("setprofile")
    # 17 before the kept arguments and the one kernel call (2 are the struct's type, 1 ``healthy_ready``)
    assert len(calls) <= 9, calls


@pytest.mark.parametrize("n", [1, 3, SPARSE_PRODUCT_ROWS, 50])
def test_the_compiled_inversion_of_the_columns_equals_the_wrapper_s(n):
    """``fast.column_winds`` (``WindRecovery.wind``'s warm inversion in one kernel) against the gathers and
    ``aero_fast.wind_from_torque`` it replaces, to the last bit: torques of winds 3–25 m/s at rotor speeds 0.9–2.2
    rad/s and pitch −2…25 deg, guesses ±15 % off, a NaN torque and a guess outside [1, 40] m/s."""
    fast = fast_module("service.turbine.fast")
    recovery = WindRecovery(BENCHMARK, TurbineContext(BENCHMARK, n).bank_design, n, 0.3, 2.0, fast=fast)
    m = recovery.n_obs
    rng = np.random.default_rng(SEED + n)
    for trial in range(4):
        speed = rng.uniform(0.9, 2.2, (n, m))
        pitch = rng.uniform(-2.0, 25.0, n)
        truth = rng.uniform(3.0, 25.0, (n, m))
        tau = aero.rotor_torque(truth, speed, pitch[:, None], BENCHMARK)
        filtered = np.column_stack([tau, speed, 97.0 * speed, pitch])
        columns = rng.integers(0, m, (2, n))
        guess = truth[np.arange(n), columns] * rng.uniform(0.85, 1.15, (2, n))
        if trial == 3:
            filtered[-1, columns[0, -1]] = np.nan
            guess[1, 0] = 45.0
        rows = np.broadcast_to(np.arange(n), columns.shape)
        expected = fast.wind_from_torque(
            filtered[rows, columns], filtered[rows, m + columns], np.broadcast_to(filtered[:, -1], columns.shape),
            guess, BENCHMARK, iterations=WARM_ITERATIONS,
        )  # fmt: skip
        got = fast.column_winds(
            filtered, 0, m, columns, guess, BENCHMARK.radius, BENCHMARK.aero_torque_gain, WARM_ITERATIONS
        )
        _same_bits(got, expected, f"trial {trial}")
