"""The compiled turbine kernels (``wwcore.backend``, ``numba``) one by one against their numpy lines: the aerodynamic
inversion, the adaptive thresholds, the pitch parity, the rotor-speed bias test, the converter, the arbiter's
history, the observer bank's step, the pitch-actuator signatures and test; every array equal to the last bit. The
reproduced BLAS products: ``tests/test_blas_products.py``; the whole tick, scorecards and backend choice:
``tests/test_fast_backend.py``.
"""

from __future__ import annotations

import copy
from types import SimpleNamespace

import numpy as np
import pytest

from service.turbine.adaptive import HealthySpread
from service.turbine.bank import GENERATOR, SPARSE_PRODUCT_ROWS, ObserverBank
from service.turbine.builtin import SPEED_TARGETS, BenchmarkDetector, UIOBankEstimator
from service.turbine.component_fdi import ACTUATOR_TARGET, CONVERTER_TARGET, M1_TARGET
from service.turbine.interfaces import POWER_SPEED_MIN_TORQUE, TurbineContext
from service.turbine.supervisor import TurbineSupervisor
from tests.fast_compare import FAULTY, SEED, assert_close, at_half_speed
from wwcore import aero, aero_fast
from wwcore.backend import fast_module
from wwcore.channels import DIAGNOSIS_TARGETS, SENSOR_INDEX, SENSORS
from wwcore.scenario import parse_scenario
from wwcore.turbine_frames import TurbineFrame
from wwcore.turbine_params import BENCHMARK


def test_aero_kernels_equal_the_reference_inside_and_outside_the_table():
    rng = np.random.default_rng(SEED)
    for shape in [(1, 3), (9, 3), (2, 5)]:
        tsr, pitch = rng.uniform(-1.0, 16.0, shape), rng.uniform(-5.0, 100.0, shape)
        assert_close(aero_fast.torque_coefficient(tsr, pitch), aero.torque_coefficient(tsr, pitch), "C_q")
        tau, omega = rng.uniform(-1e5, 3e6, shape), rng.uniform(0.3, 2.5, shape)
        guess = rng.uniform(0.5, 45.0, shape)
        for iterations in (3, 8):
            assert_close(
                aero_fast.wind_from_torque(tau, omega, pitch, guess, BENCHMARK, iterations),
                aero.wind_from_torque(tau, omega, pitch, guess, BENCHMARK, iterations),
                "wind",
            )


def spread_pair(shape: tuple[int, ...], limit: float | None) -> tuple[HealthySpread, HealthySpread]:
    """A ``HealthySpread`` of the numpy reference and its compiled twin, T_a 0.05 s: both weights matter."""
    fast = fast_module("service.turbine.fast")
    return HealthySpread(shape, 0.01, 0.05, 2.0, limit), HealthySpread(shape, 0.01, 0.05, 2.0, limit, fast=fast)


def assert_same_spread(fast: HealthySpread, reference: HealthySpread, what: str) -> None:
    for name in ("count", "estimate", "scale2", "scale", "mean", "offset"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(reference, name), f"{what}: {name}")


def test_the_adaptive_thresholds_kernel_equals_the_reference():
    # per element and per row, (n, m) and (n,), with no row healthy, rows healthy then not, a nan and an inf where
    # a sample is not learnt (numpy's 0 × inf carries them), values beyond both clips; every array equal to the
    # last bit
    rng = np.random.default_rng(SEED)
    for shape, limit in (((4, 3), 0.3), ((4, 3), None), ((12,), 0.3)):  # (n,): the converter's
        reference, fast = spread_pair(shape, limit)
        for k in range(40):
            q, x = rng.uniform(0.0, 6.0, (4, 3)) * [0.2, 1.0, 2.0], rng.normal(0.3, 0.5, (4, 3))
            healthy = rng.random((4, 3)) < (0.0 if k % 7 == 3 else 0.7)
            if k == 30:
                q[0, 0], x[1, 2] = np.nan, np.inf
                healthy[0, 0] = healthy[1, 2] = False
            q, x, healthy = q.reshape(shape), x.reshape(shape), healthy.reshape(shape)
            with np.errstate(invalid="ignore"):  # 0 × inf
                reference.update(q, healthy, x)
            fast.update(q, healthy, x)
            assert_same_spread(fast, reference, f"limit {limit}, sample {k}")
        assert np.isnan(reference.estimate.flat[0]) and np.nanmin(reference.scale2) == 1.0
        assert np.nanmax(reference.scale2) == 4.0 and (np.nanmax(reference.offset) == 0.3 if limit else True)
        for k in range(20 if len(shape) == 2 else 0):
            rows = rng.random(4) < 0.6
            q, x = rng.uniform(0.0, 6.0, (4, 3)), rng.normal(0.0, 0.5, (4, 3))
            reference.update_rows(q if k % 2 else None, rows, x)
            fast.update_rows(q if k % 2 else None, rows, x)
            assert_same_spread(fast, reference, f"limit {limit}, rows, sample {k}")
    with pytest.raises(AssertionError):  # the comparison can fail: one more sample on one side
        reference.update(np.full(12, 5.0), np.ones(12, dtype=bool))
        assert_same_spread(fast, reference, "one side updated")


def test_the_pitch_parity_kernel_equals_the_reference():
    # ``ComponentFDI._adapt_parity`` with its numpy lines and with the kernel, through flags, outliers and learning
    scenario = parse_scenario(at_half_speed(FAULTY))
    rng = np.random.default_rng(SEED)
    detectors = [
        TurbineSupervisor(3, backend=backend, noise_convention=scenario.plant.noise_convention).detector.components
        for backend in ("numpy", "numba")
    ]
    detectors[0].parity_spread.min_weight = detectors[1].parity_spread.min_weight = 0.05
    for k in range(60):
        parity, window = rng.normal(0.0, 1.5, (3, 3)), rng.normal(0.0, 1.5, (3, 3))
        flags = rng.random((3, detectors[0].flags.shape[1])) < 0.1
        outs = []
        for detector in detectors:
            detector.flags[:] = flags
            outs.append(detector._adapt_parity(parity, window))
        for a, b in zip(outs[1][:2], outs[0][:2], strict=True):
            np.testing.assert_array_equal(a, b, f"sample {k}")
        suspicious = np.maximum(np.abs(outs[0][0]), np.abs(outs[0][1])) > detectors[0].z_single
        assert outs[0][2] is None and outs[1][2] == suspicious.any()
        assert_same_spread(detectors[1].parity_spread, detectors[0].parity_spread, f"sample {k}")
    assert detectors[0].parity_spread.count.min() > 0 and detectors[0].parity_spread.count.max() < 60


def test_the_rotor_bias_kernel_equals_the_reference():
    # ``RotorBiasTest.step_flags`` with its numpy lines and with the kernel: predictors changing with the flags and
    # pending isolations, biases of either sign on either sensor (raises, both signs at once), a nan reading on a
    # row not tested (numpy's 0 × nan carries it into the learnt spread), the spread learning; every array equal
    rng = np.random.default_rng(SEED)
    fdis = [TurbineSupervisor(4, backend=backend).detector.fdi for backend in ("numpy", "numba")]
    tests = [fdi.bias for fdi in fdis]
    for test in tests:
        test.spread.min_weight = 0.05
    table, width = fdis[0]._bias_predictor, fdis[0].bank.F_blk.shape[0]
    raised = 0
    for k in range(400):
        if k % 25 == 0:  # the flags hold for a while: the statistics run between the predictor's changes
            flagged = rng.choice([0, 0, 0, 4, 8, 12, 1], 4)
        deadline = np.where(rng.random(4) < 0.01, 7, -1)
        x_hat = rng.normal(1.2, 0.1, (4, width))
        predictor = np.maximum(table[flagged], 0)
        y = x_hat[np.arange(4)[:, None], tests[0].column[predictor]] + rng.normal(0.0, 0.03, (4, 2))
        y[:, 0] += (0.2 if k // 40 % 2 else -0.2) if k % 40 > 25 else 0.0  # a bias on a sensor for a while: raises
        y[:, 1] -= 0.2 if k % 60 > 50 else 0.0
        if k == 150:
            y[2, 0], flagged[2] = np.nan, 1  # row 2 not tested this tick
        outs = [test.step_flags(y, x_hat, flagged, deadline, table) for test in tests]
        assert (outs[0] is None) == (outs[1] is None), f"tick {k}"
        if outs[0] is not None:
            np.testing.assert_array_equal(outs[1], outs[0], f"tick {k}")
            for test, out in zip(tests, outs, strict=True):
                test.reset(out.any(axis=1))
            raised += 1
        for name in ("up", "down", "run_up", "run_down", "predictor"):
            np.testing.assert_array_equal(getattr(tests[1], name), getattr(tests[0], name), f"tick {k}: {name}")
        assert_same_spread(tests[1].spread, tests[0].spread, f"tick {k}")
    assert raised >= 3 and np.isnan(tests[0].spread.estimate[2]) and (tests[0].spread.count > 10).all()


def test_the_converter_kernel_equals_the_reference():
    # ``ComponentFDI._converter`` and ``_converter_clearing`` with their numpy lines and with ``converter_tick``:
    # the warm-up, offsets of either sign (raises on small and large shifts, clearings once they end), a learnt
    # offset and scale, a nan reading on one row (numpy's 0 × nan carries it into the clearing's mean); every
    # array equal to the last bit
    rng = np.random.default_rng(SEED)
    detectors = [TurbineSupervisor(4, backend=backend).detector.components for backend in ("numpy", "numba")]
    sigma = detectors[0].sigma_tau
    for detector in detectors:
        detector.warmup_ticks = 20
        detector.converter_spread.offset[:] = [0.0, 0.3, -0.2, 0.1]
        detector.converter_spread.scale[:] = [1.0, 1.2, 1.0, 1.5]
    raised = cleared = 0
    for k in range(1200):
        offset = np.array([4.0, -1.0, 0.6, -8.0]) * sigma if k % 300 > 150 else np.zeros(4)
        tau_g_m = 2.0e4 + rng.normal(0.0, sigma, 4) + offset
        if k == 700:
            tau_g_m[3] = np.nan
        tau_g_ref = np.full(4, 2.0e4)
        before = detectors[0].flags[:, CONVERTER_TARGET].copy()
        for detector in detectors:
            detector.ticks += 1
            detector._converter(tau_g_m, tau_g_ref)
        after = detectors[0].flags[:, CONVERTER_TARGET]
        raised += (after & ~before).sum()
        cleared += (before & ~after).sum()
        np.testing.assert_array_equal(detectors[1].flags, detectors[0].flags, f"tick {k}")
        for name in (
            "converter_statistic",
            "_converter_run",
            "converter_clear_statistic",
            "_converter_mean",
            "_converter_count",
        ):
            np.testing.assert_array_equal(getattr(detectors[1], name), getattr(detectors[0], name), f"{k}: {name}")
        for name in ("_tau_hat", "_converter_block_sum"):
            np.testing.assert_array_equal(getattr(detectors[1], name), getattr(detectors[0], name), f"{k}: {name}")
    assert raised >= 8 and cleared >= 4 and np.isnan(detectors[0]._converter_mean[3])


def test_the_arbiter_history_kernels_equal_the_reference():
    # ``GeneratorArbiter.observe`` with its numpy lines and with ``arbiter_push``/``arbiter_learn``: rows learning
    # and not, jumps of either sensor that start an isolation (ℓ_J grown over the next ticks from the change point);
    # every array equal to the last bit
    rng = np.random.default_rng(SEED)
    arbiters = [TurbineSupervisor(4, backend=backend).detector.fdi.arbiter for backend in ("numpy", "numba")]
    sigma = np.sqrt(arbiters[0].generator_variance)
    started = 0
    for k in range(400):
        y = 150.0 + np.cumsum(rng.normal(0.0, 0.02, (4, 1)), axis=0) + rng.normal(0.0, sigma, (4, 4))
        if k % 50 > 30:
            y[k // 50 % 4, 2 + k // 100 % 2] += 8.0 * sigma
        learn = rng.random(4) < 0.7
        for arbiter in arbiters:
            arbiter.observe(y, learn)
        if k % 50 == 33:
            rows, jump = rng.random(4) < 0.5, rng.random(4) < 0.8
            started += (rows & jump).sum()
            for arbiter in arbiters:
                arbiter.reset(rows, jump)
        for name in ("_means", "_parities", "jump_covariance", "total", "total_power", "jump", "_onset"):
            np.testing.assert_array_equal(getattr(arbiters[1], name), getattr(arbiters[0], name), f"{k}: {name}")
    assert started >= 4 and (arbiters[0].jump != 0.0).sum() >= 2


def test_the_region2_speed_kernel_equals_the_reference():
    # ``WindRecovery.region2_generator_speed``'s numpy lines against ``fast.region2_speed``: rows in region 2 and 3,
    # no observer selected (−1), observers with and without a generator-speed sensor (5, 5-pe: none); the speeds
    # equal, and rows left alone keep the filtered speed (the kernel writes in place)
    rng = np.random.default_rng(SEED)
    recoveries = [TurbineSupervisor(12, backend=backend).estimator.recovery for backend in ("numpy", "numba")]
    encoder = recoveries[0]._encoder_speed_state
    assert (encoder >= 0).any() and (encoder < 0).any()
    replaced = 0
    for _ in range(50):
        x_hat = rng.normal(150.0, 5.0, (12, int(encoder.max()) + 3))
        selected = rng.integers(-1, len(encoder), 12)
        zone = rng.integers(0, 2, 12).astype(np.int8)
        omega_g = rng.normal(150.0, 5.0, 12)
        reference = recoveries[0].region2_generator_speed(x_hat, selected, zone, omega_g.copy())
        fast = recoveries[1].region2_generator_speed(x_hat, selected, zone, omega_g.copy())
        np.testing.assert_array_equal(fast, reference)
        replaced += (reference != omega_g).sum()
    assert replaced > 50


def test_the_observer_selection_kernels_equal_the_reference():
    # ``UIOBankEstimator.select`` (the estimator's observer of each row) and ``UIOBankDetector.power_speed_inputs``
    # (the detector's 5-pe design and power-speed channel) with their numpy lines against ``fast.select_observers``
    # and ``fast.power_speed_test``: every distrusted set, torque references in every band of
    # ``interfaces.power_speed_band`` (region 1, the design bands and their edges, NaN) in both zones
    n = 64
    rng = np.random.default_rng(SEED)
    rated = BENCHMARK.rated_torque
    bands_seen, selected_seen = set(), set()
    for options in ({}, {"power_speed": False}, {"estimate_from": "seed000"}):
        contexts = [TurbineContext(BENCHMARK, n, backend=backend) for backend in ("numpy", "numba")]
        estimators = [UIOBankEstimator(context=c, options=options) for c in contexts]
        detectors = [BenchmarkDetector(context=c) for c in contexts]
        for _ in range(20):
            faulty = np.zeros((n, len(DIAGNOSIS_TARGETS)), dtype=bool)
            faulty[:, SPEED_TARGETS] = rng.random((n, len(SPEED_TARGETS))) < 0.6
            torque = rated * np.exp(rng.uniform(np.log(1e-3), np.log(1.5), n))
            torque[:4] = [POWER_SPEED_MIN_TORQUE * rated, np.nan, 0.0, np.sqrt(0.15 * 0.35) * rated]
            zone = rng.integers(0, 2, n).astype(np.int8)
            reference = estimators[0].select(faulty, torque, zone)
            compiled = estimators[1].select(faulty, torque, zone)
            np.testing.assert_array_equal(compiled[0], reference[0])
            np.testing.assert_array_equal(compiled[1], reference[1])
            selected_seen |= set(reference[1].tolist())
            sensors = rng.normal(1.0, 0.1, (n, len(SENSORS))) * 1e3
            sensors[:, SENSOR_INDEX["tau_g_m"]] = torque * rng.normal(1.0, 0.5, n)
            frame = TurbineFrame(0, 0.0, sensors, torque, np.zeros(n), np.zeros(n), zone)
            band, channel = detectors[0].power_speed_inputs(frame)
            fast_band, fast_channel = detectors[1].power_speed_inputs(frame)
            np.testing.assert_array_equal(fast_band, band)
            np.testing.assert_array_equal(fast_channel, channel)
            bands_seen |= set(band.tolist())
    design = contexts[0].bank_design
    assert bands_seen == set(range(len(design.power_speed)))
    assert {*design.power_speed, design.index(frozenset(GENERATOR))} <= selected_seen


@pytest.mark.parametrize("n", [1, 2, 7, 8, 9, 16, 17, 25, 49, 50, 100])
def test_the_bank_kernel_equals_the_reference(n):
    # ``ObserverBank.step``'s numpy lines against ``fast.bank_step`` (its products by BLAS from inside the kernel
    # for few rows, over the matrices' nonzeros with BLAS's arithmetic for more where ``gemm_layout`` finds it),
    # through the transient gains into the steady ones, for one row, a run with its twin and wide batches, a NaN
    # reading on one row of several at tick 25; every array equal to the last bit, zeros' signs included
    rng = np.random.default_rng(SEED + n)
    design = TurbineSupervisor(n).context.bank_design
    fast = fast_module("service.turbine.fast")
    banks = [ObserverBank(design, n), ObserverBank(design, n, fast=fast)]
    assert banks[1]._sparse[0] == (
        n >= SPARSE_PRODUCT_ROWS and fast.gemm_layout(n, *banks[1]._update.shape) is not None
    )
    inputs = banks[0].d.H_blk.shape[1]
    scale = np.array([1.6, 1.6, 150.0, 150.0, 150.0][:inputs] + [1.0] * max(0, inputs - 5))
    x0, y0 = rng.normal(1.0, 0.3, (n, 4)), scale * rng.normal(1.0, 0.01, (n, inputs))
    for bank in banks:
        bank.initialise(x0, y0)
    for k in range(len(banks[0]._update_transient) + 30):
        y = scale * rng.normal(1.0, 0.01, (n, inputs))
        if k == 25 and n > 1:
            y[n // 2, 0] = np.nan
        u = rng.normal(2e4, 500.0, n)
        for bank in banks:
            bank.step(y, u)
        for name in ("z", "x_hat", "chi2", "steps"):
            got, expected = getattr(banks[1], name), getattr(banks[0], name)
            np.testing.assert_array_equal(got, expected, f"tick {k}: {name}")
            np.testing.assert_array_equal(np.signbit(got), np.signbit(expected), f"tick {k}: {name}")
    healthy = np.arange(n) != n // 2 if n > 1 else np.ones(1, dtype=bool)
    assert np.isnan(banks[1].z[~healthy]).all() and np.isfinite(banks[1].z[healthy]).all()
    assert banks[0].steps > len(banks[0]._update_transient) and banks[0].chi2[healthy].max() > 0.0


@pytest.mark.parametrize("n", [1, 16])
@pytest.mark.parametrize("offset", [False, True])
def test_the_bank_tick_from_the_readings_equals_the_reference(n, offset):
    # ``TurbineContext.bank``'s numpy lines (``_bank_inputs``, ``ObserverBank.step``) against the compiled context's
    # one kernel call from the frame's readings (``fast.bank_tick``), with and without the speed sensors'
    # calibration offsets, through region 1's fallback channel, a NaN reading and -0.0; every array equal to the
    # last bit, the speed readings kept before the offsets
    rng = np.random.default_rng(SEED + 3 * n + offset)
    contexts = [TurbineContext(BENCHMARK, n, backend="numpy"), TurbineContext(BENCHMARK, n, backend="numba")]
    shift = rng.normal(0.0, 0.01, (n, 4))
    for context in contexts:
        context.speed_calibration = SimpleNamespace(offset=shift.copy()) if offset else None
    scale = {"omega_r_m1": 1.6, "omega_r_m2": 1.6, "omega_g_m1": 150.0, "omega_g_m2": 150.0, "p_g_m": 4.8e6}
    torques = []
    for k in range(40):
        sensors = rng.normal(1.0, 0.2, (n, len(SENSORS)))
        for name, value in scale.items():
            sensors[:, SENSOR_INDEX[name]] *= value
        # the torque reading across the power-speed channel's threshold (region 1's fallback below it)
        sensors[:, SENSOR_INDEX["tau_g_m"]] = BENCHMARK.rated_torque * rng.uniform(0.0, 1.0, n)
        sensors[:, SENSOR_INDEX["omega_g_m1"]] = -0.0 if k == 7 else sensors[:, SENSOR_INDEX["omega_g_m1"]]
        if k == 20:
            sensors[0, SENSOR_INDEX["omega_r_m2"]] = np.nan
        tau_g_ref = rng.normal(2e4, 500.0, n)
        frame = TurbineFrame(k, 0.01 * k, sensors, tau_g_ref, np.zeros(n), np.full(n, 5e6), np.zeros(n, np.int8))
        banks = [context.bank(frame) for context in contexts]
        for name in ("z", "x_hat", "chi2", "steps", "_y_prev"):
            got, expected = getattr(banks[1], name), getattr(banks[0], name)
            np.testing.assert_array_equal(got, expected, f"tick {k}: {name}")
            np.testing.assert_array_equal(np.signbit(got), np.signbit(expected), f"tick {k}: {name}")
        np.testing.assert_array_equal(contexts[1].speed_readings(frame), contexts[0].speed_readings(frame))
        if offset:
            contexts[0].speed_calibration.offset += 0.001  # updated in place, as the detector does
            contexts[1].speed_calibration.offset += 0.001
        threshold = POWER_SPEED_MIN_TORQUE * BENCHMARK.rated_torque
        torques.append(sensors[:, SENSOR_INDEX["tau_g_m"]])
    torques = np.concatenate(torques)
    assert banks[0].steps == 39 and (torques < threshold).any() and (torques > threshold).any()


def test_the_record_test_equals_the_reference():
    # ``TurbineSupervisor._record``'s "nothing changed" test against numpy's comparisons: a flag or a selection
    # changed anywhere (first row, last row, last column) is seen
    fast = fast_module("service.turbine.fast")
    rng = np.random.default_rng(SEED)
    for n in (1, 2, 50):
        flags = rng.random((n, len(DIAGNOSIS_TARGETS))) < 0.1
        selected = rng.integers(-1, 20, n)
        for _ in range(60):
            faulty, chosen = flags.copy(), selected.copy()
            where = rng.integers(0, 4)
            if where == 1:
                faulty[rng.integers(n), rng.integers(faulty.shape[1])] ^= True
            elif where == 2:
                chosen[rng.integers(n)] += 1
            elif where == 3:
                faulty[-1, -1] ^= True
            expected = bool((faulty == flags).all() and (chosen == selected).all())
            assert fast.record_unchanged(flags, faulty, selected, chosen) is expected


def _compare_signature_blocks(bank, kernel, order, rng):
    # ``SignatureBank.block`` and ``_actuators``' block sums (``einsum``, ``sum(axis=0)``) against ``kernel`` on a
    # copy of ``bank``, block after block from rest through ramps, steps and noise, the states carried over; every
    # array equal to the last bit
    n, ticks = bank.n, 10
    fast_bank = copy.deepcopy(bank)
    level = np.full(n, 6.0)
    for block in range(30):
        steps = rng.normal(0.0, 0.5, (ticks, n)) if block % 3 else np.zeros((ticks, n))
        reference = level + np.cumsum(steps, axis=0) + (rng.normal(0.0, 3.0, n) if block % 5 == 4 else 0.0)
        level = reference[-1]
        w = rng.normal(0.0, 10.0 ** rng.uniform(-3, 1), (ticks, n, 3))
        if block == 7:  # zeros of both signs: the sums' first terms keep their sign
            w[0, : n // 2 + 1] = -0.0
        s = bank.block(reference)
        expected = (
            np.einsum("knb,knc->nbc", w, s),
            np.einsum("knc,knc->nc", s, s),
            np.concatenate([w.sum(axis=0), s.sum(axis=0)], axis=1),
        )
        got = fast_bank.block_sums(reference, w, kernel, order)
        for name, a, b in zip(("correlation", "energy", "sums"), got, expected, strict=True):
            np.testing.assert_array_equal(a.view(np.int64), b.view(np.int64), f"block {block}: {name}")
        np.testing.assert_array_equal(fast_bank.x, bank.x, f"block {block}: state")
    assert np.abs(bank.x).max() > 0.01  # the signatures moved


@pytest.mark.parametrize("reproduced", [False, True])
@pytest.mark.parametrize("n", [1, 3, 7, 8, 9, 50])
def test_the_signature_kernel_equals_the_reference(n, reproduced):
    # ``fast_actuator.signature_block`` against the numpy lines (``_compare_signature_blocks``) with the state
    # products by BLAS calls and by the reproduced BLAS arithmetic, the candidates in SIMD lanes; row counts around
    # a SIMD register's 8 doubles (a sequential six-term sum or a loop product fails this)
    fast_actuator = fast_module("service.turbine.fast_actuator")
    order = fast_actuator.numpy_matmul_order() if reproduced else fast_actuator.BLAS_CALL
    if reproduced and order == fast_actuator.BLAS_CALL:
        pytest.skip("numpy's BLAS on this machine is not a kernel blas_vector_matrix reproduces")
    components = TurbineSupervisor(n, backend="numpy").detector.components
    assert components._ref_block.shape[0] == 10
    _compare_signature_blocks(
        components.signatures, fast_actuator.signature_block, order, np.random.default_rng(SEED + n)
    )


@pytest.mark.parametrize("k_count", [1, 8, 37])
def test_the_signature_lanes_equal_the_reference_for_fewer_candidates(k_count):
    # the SIMD kernel computes ``WIDTH`` candidates, the pitch-actuator bank's K, in every row's tick; a bank of fewer
    # (the first k_count: padded lanes, a remainder of 8) gives the numpy lines' numbers, and the real bank has K =
    # ``WIDTH`` (a bank of more would take the slower BLAS calls)
    fast_actuator = fast_module("service.turbine.fast_actuator")
    order = fast_actuator.numpy_matmul_order()
    if order == fast_actuator.BLAS_CALL:
        pytest.skip("numpy's BLAS on this machine is not a kernel blas_vector_matrix reproduces")
    bank = TurbineSupervisor(9, backend="numpy").detector.components.signatures
    assert len(bank.candidates) == fast_actuator.WIDTH
    bank.candidates, bank._steady = bank.candidates[:k_count], bank._steady[:k_count]
    bank._At, bank._B, bank._C, bank._D = bank._At[:k_count], bank._B[:k_count], bank._C[:k_count], bank._D[:k_count]
    _compare_signature_blocks(bank, fast_actuator.signature_block, order, np.random.default_rng(SEED + k_count))


def test_the_pitch_actuator_kernel_equals_the_reference():
    # ``ComponentFDI._actuators`` with its numpy lines and with ``actuator_test``, block after block through the
    # windows filling, raises, clearings on the shorter and the full windows and a pitch-sensor flag's rest; the
    # thresholds lowered so that random blocks cross them both ways; every array equal to the last bit
    rng = np.random.default_rng(SEED)
    detectors = [TurbineSupervisor(3, backend=backend).detector.components for backend in ("numpy", "numba")]
    for detector in detectors:
        detector.h_actuator, detector.h_actuator_clear = -90.0, 90.0  # Λ of these blocks: −20 to −170
        detector.actuator_spread.min_weight = 0.05
    raised = cleared = 0
    for k in range(4 * detectors[0].actuator.size + 10):
        e = rng.normal(0.0, 0.3, detectors[0]._e_block.shape) + (
            0.4 * rng.normal(0.0, 1.0, (1, 3, 3)) if k % 7 < 3 else 0
        )
        reference = 8.0 + np.cumsum(rng.normal(0.0, 0.5, detectors[0]._ref_block.shape), axis=0)
        sensor_flag = rng.random(3) < 0.01
        before = detectors[0].flags[:, ACTUATOR_TARGET].copy()
        for detector in detectors:
            detector._e_block[:], detector._ref_block[:] = e, reference
            detector.flags[:, M1_TARGET[0]] = sensor_flag
            detector._actuators()
        after = detectors[0].flags[:, ACTUATOR_TARGET]
        raised += (after & ~before).sum()
        cleared += (before & ~after).sum()
        np.testing.assert_array_equal(detectors[1].flags, detectors[0].flags, f"block {k}")
        np.testing.assert_array_equal(detectors[1].actuator_glr, detectors[0].actuator_glr, f"block {k}")
        for name in ("_actuator_rest", "_actuator_cleared_rest", "_w_block"):
            np.testing.assert_array_equal(getattr(detectors[1], name), getattr(detectors[0], name), f"{k}: {name}")
        np.testing.assert_array_equal(detectors[1].signatures.x, detectors[0].signatures.x, f"block {k}")
        windows = [[d.actuator, d.actuator_energy, d.actuator_sums, *sum(d.actuator_short, ())] for d in detectors]
        for fast, numpy_window in zip(*windows, strict=True):
            assert fast.count == numpy_window.count
            np.testing.assert_array_equal(fast.total, numpy_window.total, f"block {k}")
            np.testing.assert_array_equal(fast.ring, numpy_window.ring, f"block {k}")
        assert_same_spread(detectors[1].actuator_spread, detectors[0].actuator_spread, f"block {k}")
    assert raised >= 5 and cleared >= 3 and detectors[0].actuator_spread.count.max() > 5
