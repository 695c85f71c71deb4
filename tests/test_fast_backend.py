"""The compiled backend (``wwcore.backend``, ``numba``) against the numpy reference: the same numbers.

The kernels perform the reference's floating-point operations in its order and leave its matrix products to
numpy, so the comparison asks for equality within 1e-12 (relative, of each quantity's scale) and, in practice,
gets it to the last bit: the largest difference is printed by the assertion when it is not zero.
"""

from __future__ import annotations

import copy
import importlib.util
import json
import os
import pickle
import subprocess
import sys
import tomllib

import numpy as np
import pytest

from plant_sim.turbine import TurbineBatch
from service.turbine.adaptive import HealthySpread
from service.turbine.bank import ObserverBank
from service.turbine.component_fdi import ACTUATOR_TARGET, CONVERTER_TARGET, M1_TARGET
from service.turbine.supervisor import TurbineSupervisor
from tests.live.helpers import TURBINE_SHORT
from windwarden.cli import EXIT_BAD_INPUT, main
from windwarden.evaluation.kinds import EvalOptions
from windwarden.kinds import kind_for
from wwcore import aero, aero_fast
from wwcore.backend import ENV_VAR, BackendError, available, fast_module, process_backend, resolve_backend
from wwcore.scenario import load_scenario, parse_scenario
from wwcore.turbine_params import BENCHMARK

SEED = 6151  # fresh: nothing is tuned on it
RTOL = 1e-12

# 60 s with a fault of every class the fast path treats apart: speed-sensor fixed, gain and stuck (flags, isolation,
# clearing, the observer switch), a drifting anemometer, pitch-sensor offset (parity, weighted pitch), a pitch
# actuator's dynamics and the drive train's efficiency (the per-row step matrices), a converter offset and a noisy
# torque sensor; the mean wind crosses rated, so both control zones run.
FAULTY = """
name = "fast-backend-check"
duration_s = 60.0
[plant]
kind = "turbine"
[wind]
mean = [[0.0, 10.0], [60.0, 13.5]]
turbulence_intensity = 0.12
[[faults]]
name = "generator sensor 2 fixed"
target = "omega_g_m2"
kind = "fixed"
value = 100.0
start_s = 12.0
end_s = 20.0
[[faults]]
name = "anemometer drift"
target = "v_hub_m"
kind = "drift"
value = 0.02
start_s = 8.0
[[faults]]
name = "rotor sensor 1 stuck"
target = "omega_r_m1"
kind = "stuck"
start_s = 24.0
end_s = 32.0
[[faults]]
name = "rotor sensor 2 gain"
target = "omega_r_m2"
kind = "gain"
value = 1.1
start_s = 36.0
end_s = 44.0
[[faults]]
name = "pitch sensor offset"
target = "beta_1_m1"
kind = "offset"
value = 2.0
start_s = 14.0
end_s = 30.0
[[faults]]
name = "pitch actuator dynamics"
target = "pitch_actuator_2"
kind = "pitch_dynamics"
omega_n = 3.42
zeta = 0.9
start_s = 30.0
end_s = 45.0
ramp_s = 5.0
[[faults]]
name = "drive train efficiency"
target = "drivetrain"
kind = "efficiency"
value = 0.92
start_s = 40.0
end_s = 55.0
[[faults]]
name = "converter offset"
target = "converter"
kind = "torque_offset"
value = 100.0
start_s = 46.0
end_s = 56.0
[[faults]]
name = "torque sensor noise"
target = "tau_g_m"
kind = "noise"
value = 3.0
start_s = 50.0
end_s = 58.0
"""


def assert_close(fast: np.ndarray, reference: np.ndarray, what: str) -> None:
    fast, reference = np.asarray(fast, dtype=float), np.asarray(reference, dtype=float)
    assert fast.shape == reference.shape, what
    assert np.array_equal(np.isnan(fast), np.isnan(reference)), what
    scale = np.nanmax(np.abs(reference)) if reference.size else 0.0
    diff = np.nan_to_num(np.abs(fast - reference))
    assert diff.max(initial=0.0) <= RTOL * max(scale, 1e-300), f"{what}: largest difference {diff.max():.3g}"


def turbine_trace(scenario, backend: str, runs: list[int], ticks: int, every: int = 5) -> dict[str, np.ndarray]:
    """The plant state of every tick; the sensor frame, bank χ² and x̂, FDI ratios, CUSUM, estimates and refs of
    every ``every``-th tick (a difference in any of them reaches the state within a tick); the events."""
    plant = TurbineBatch(
        scenario.plant,
        scenario.wind,
        scenario.faults,
        seed=SEED,
        runs=runs,
        mismatch=scenario.mismatch,
        backend=backend,
    )
    supervisor = TurbineSupervisor(plant.n, noise_convention=scenario.plant.noise_convention, backend=backend)
    trace: dict[str, list] = {}
    refs = None
    for k in range(ticks):
        frame = plant.measure()
        plant.control(refs)
        refs = supervisor.step(frame)
        plant.advance()
        trace.setdefault("x", []).append(plant.x.copy())
        if k % every:
            continue
        fdi = supervisor.detector.fdi
        est = supervisor.estimates
        for name, value in {
            "sensors": frame.sensors,
            "tau_g_ref": frame.tau_g_ref,
            "beta_ref": frame.beta_ref,
            "zone": frame.zone,
            "chi2": supervisor.context._bank.chi2,
            "x_hat": supervisor.context._bank.x_hat,
            "ratio": fdi.ratio,
            "cusum": fdi.clearing.statistic,
            "actuator_test": supervisor.detector.components.actuator.total,
            "actuator_glr": supervisor.detector.components.actuator_glr,
            "converter_test": supervisor.detector.components.converter_statistic,
            "converter_clear": supervisor.detector.components.converter_clear_statistic,
            "converter_mean": supervisor.detector.components._converter_mean,
            # the generator-speed arbiter's sums and the learnt covariance of its onset prediction's errors
            "arbiter": [fdi.arbiter.total, fdi.arbiter.total_power, fdi.arbiter.jump],
            "onset_covariance": fdi.arbiter.jump_covariance,
            "parity_window": supervisor.detector.components.parity.total,
            "pitch_outlier": supervisor.detector.components.outlier.total,
            # the adaptive thresholds' learnt scales and offsets (``service.turbine.adaptive``)
            "chi2_scale": fdi.spread.estimate,
            "speed_offset": fdi.calibration.mean,
            "parity_offset": supervisor.detector.components.parity_spread.mean,
            "parity_scale": supervisor.detector.components.parity_spread.estimate,
            "actuator_scale": supervisor.detector.components.actuator_spread.estimate,
            "spread_counts": fdi.spread.count,
            "residual": fdi.clearing.residual,
            # the rotor-speed bias CUSUM (``service.turbine.bias_test``): S±, A±, its predictor and learnt spread
            "rotor_bias": [fdi.bias.up, fdi.bias.down, fdi.bias.run_up, fdi.bias.run_down],  # (n, K) each
            "rotor_bias_predictor": fdi.bias.predictor,
            "rotor_bias_scale": [fdi.bias.spread.estimate, fdi.bias.spread.count],
            "flags": supervisor.flags,
            "omega_g": est.omega_g,
            "wind": est.wind,
            "wind_reference": est.wind_reference,
            "selected": est.selected,
            "refs_valid": refs.valid,
        }.items():
            trace.setdefault(name, []).append(np.array(value, dtype=float))
    out = {name: np.array(values) for name, values in trace.items()}
    events = plant.drain_events() + supervisor.drain_events()
    out["events"] = np.array([(e.t, e.turbine, e.run) for e in events], dtype=float)
    out["event_kinds"] = [(e.type.value, e.target, json.dumps(e.detail, sort_keys=True, default=str)) for e in events]
    return out


def compare(reference: dict, fast: dict) -> None:
    assert fast.keys() == reference.keys()
    assert fast.pop("event_kinds") == reference.pop("event_kinds")
    for name in reference:
        assert_close(fast[name], reference[name], name)


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


@pytest.mark.parametrize("n", [1, 2, 100])
def test_the_bank_kernel_equals_the_reference(n):
    # ``ObserverBank.step``'s numpy lines against ``fast.bank_step`` (its products by BLAS from inside the kernel),
    # through the transient gains into the steady ones, for one row, a run with its twin and a wide batch; every
    # array equal to the last bit
    rng = np.random.default_rng(SEED + n)
    design = TurbineSupervisor(n).context.bank_design
    banks = [ObserverBank(design, n), ObserverBank(design, n, fast=fast_module("service.turbine.fast"))]
    inputs = banks[0].d.H_blk.shape[1]
    scale = np.array([1.6, 1.6, 150.0, 150.0, 150.0][:inputs] + [1.0] * max(0, inputs - 5))
    x0, y0 = rng.normal(1.0, 0.3, (n, 4)), scale * rng.normal(1.0, 0.01, (n, inputs))
    for bank in banks:
        bank.initialise(x0, y0)
    for k in range(len(banks[0]._update_transient) + 30):
        y = scale * rng.normal(1.0, 0.01, (n, inputs))
        u = rng.normal(2e4, 500.0, n)
        for bank in banks:
            bank.step(y, u)
        for name in ("z", "x_hat", "chi2", "steps"):
            np.testing.assert_array_equal(getattr(banks[1], name), getattr(banks[0], name), f"tick {k}: {name}")
    assert banks[0].steps > len(banks[0]._update_transient) and banks[0].chi2.max() > 0.0


@pytest.mark.parametrize("n", [1, 3, 40])
def test_the_signature_kernel_equals_the_reference(n):
    # ``SignatureBank.block`` and ``_actuators``' block sums (``einsum``, ``sum(axis=0)``) against
    # ``fast_actuator.signature_block``, block after block from rest through ramps, steps and noise, the states
    # carried over; every array equal to the last bit (a sequential six-term sum or a loop product fails this)
    rng = np.random.default_rng(SEED + n)
    components = TurbineSupervisor(n, backend="numpy").detector.components
    ticks = components._ref_block.shape[0]
    reference_bank, fast_bank = components.signatures, copy.deepcopy(components.signatures)
    kernel = fast_module("service.turbine.fast_actuator").signature_block
    level = np.full(n, 6.0)
    for block in range(30):
        steps = rng.normal(0.0, 0.5, (ticks, n)) if block % 3 else np.zeros((ticks, n))
        reference = level + np.cumsum(steps, axis=0) + (rng.normal(0.0, 3.0, n) if block % 5 == 4 else 0.0)
        level = reference[-1]
        w = rng.normal(0.0, 10.0 ** rng.uniform(-3, 1), (ticks, n, 3))
        s = reference_bank.block(reference)
        expected = (
            np.einsum("knb,knc->nbc", w, s),
            np.einsum("knc,knc->nc", s, s),
            np.concatenate([w.sum(axis=0), s.sum(axis=0)], axis=1),
        )
        got = fast_bank.block_sums(reference, w, kernel)
        for name, a, b in zip(("correlation", "energy", "sums"), got, expected, strict=True):
            np.testing.assert_array_equal(a, b, f"block {block}: {name}")
        np.testing.assert_array_equal(fast_bank.x, reference_bank.x, f"block {block}: state")
    assert np.abs(reference_bank.x).max() > 0.01  # the signatures moved


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


def at_half_speed(text: str) -> dict:
    """A scenario with every time (duration, wind points, fault starts, ends and ramps) halved and every drift
    doubled: each fault still starts and ends, in the same order, above and below rated, in half the ticks."""
    data = tomllib.loads(text)
    data["duration_s"] /= 2
    data["wind"]["mean"] = [[t / 2, v] for t, v in data["wind"]["mean"]]
    for fault in data["faults"]:
        for key in ("start_s", "end_s", "ramp_s"):
            if key in fault:
                fault[key] /= 2
        if fault["kind"] == "drift":
            fault["value"] *= 2
    return data


@pytest.mark.parametrize("half", [True, pytest.param(False, marks=pytest.mark.slow)], ids=["30s", "60s"])
def test_turbine_tick_by_tick_through_every_fault_class(half):
    scenario = parse_scenario(at_half_speed(FAULTY) if half else tomllib.loads(FAULTY))
    ticks = round(scenario.duration_s / BENCHMARK.dt)
    reference = turbine_trace(scenario, "numpy", [0, 1], ticks)
    assert reference["flags"].any() and reference["cusum"].any()  # the isolation and the clearing both ran
    compare(reference, turbine_trace(scenario, "numba", [0, 1], ticks))


def test_a_plant_unlike_the_design_model_falls_back_and_still_matches():
    scenario = load_scenario("ftwse-2012-mismatch")
    compare(turbine_trace(scenario, "numpy", [3], 1500), turbine_trace(scenario, "numba", [3], 1500))


def test_the_scorecard_is_the_same_with_either_backend():
    # two worker processes, which take the backend from the environment ``eval --backend`` sets; fault-free twins
    scenario = parse_scenario(tomllib.loads(TURBINE_SHORT))
    cards = []
    for backend in ("numpy", "numba"):
        with process_backend(backend):
            evaluation = kind_for("turbine").evaluate(scenario, 2, SEED, EvalOptions(workers=2, progress=False))
        cards.append(json.loads(json.dumps(evaluation.scorecard, sort_keys=True)))
    assert not scorecard_differences(cards[1], cards[0])


def scorecard_differences(fast, reference, at: str = "") -> list[str]:
    """Where two scorecards differ: every key, count, verdict and string exactly; every float within ``RTOL`` of
    itself. The float figures (RMSEs, rates, means) come from sums whose last bit can differ between the backends
    on a CPU whose numpy runs ``exp``/``log`` in AVX-512 (its SIMD kernels round differently from the compiled
    code's libm); on the AVX2 machine the cards were equal text for text."""
    if isinstance(reference, dict):
        if not isinstance(fast, dict) or sorted(fast) != sorted(reference):
            return [f"{at}: keys differ"]
        return [d for k in reference for d in scorecard_differences(fast[k], reference[k], f"{at}.{k}")]
    if isinstance(reference, list):
        if not isinstance(fast, list) or len(fast) != len(reference):
            return [f"{at}: lengths differ"]
        pairs = enumerate(zip(fast, reference, strict=True))
        return [d for i, (f, r) in pairs for d in scorecard_differences(f, r, f"{at}[{i}]")]
    if isinstance(reference, float) and isinstance(fast, float):
        return (
            [] if abs(fast - reference) <= RTOL * max(abs(reference), 1e-300) else [f"{at}: {fast!r} != {reference!r}"]
        )
    return [] if type(fast) is type(reference) and fast == reference else [f"{at}: {fast!r} != {reference!r}"]


def test_scorecard_differences_sees_every_change_beyond_rounding():
    card = {"detected_pct": 100.0, "runs": 2, "name": "x", "rmse": [0.4172611798979821, None]}
    same = copy.deepcopy(card)
    same["rmse"][0] = 0.4172611798979822
    assert not scorecard_differences(same, card)
    for key, value in (("detected_pct", 99.0), ("runs", 3), ("name", "y"), ("rmse", [0.41726118, None])):
        changed = {**copy.deepcopy(card), key: value}
        assert scorecard_differences(changed, card), key
    assert scorecard_differences({**card, "runs": 2.0}, card)  # an int that became a float


def test_backend_choice_refuses_unknown_names_and_restores_the_environment(monkeypatch):
    monkeypatch.delenv(ENV_VAR, raising=False)
    assert resolve_backend() == "numpy"
    with pytest.raises(BackendError, match="numpy, numba"):
        resolve_backend("fortran")
    monkeypatch.setenv(ENV_VAR, "cuda")
    with pytest.raises(BackendError, match=ENV_VAR):
        resolve_backend()
    monkeypatch.setenv(ENV_VAR, "numpy")
    with process_backend("numba"):
        assert os.environ[ENV_VAR] == "numba" and resolve_backend() == "numba"
    assert os.environ[ENV_VAR] == "numpy"
    with pytest.raises(BackendError):
        TurbineSupervisor(1, backend="numbba")


def test_compiled_objects_copy_and_pickle():
    kernels = fast_module("plant_sim.turbine.fast")
    assert copy.deepcopy(kernels) is kernels
    assert pickle.loads(pickle.dumps(kernels)).blade_winds is kernels.blade_winds
    scenario = parse_scenario(tomllib.loads(FAULTY))
    plant = TurbineBatch(scenario.plant, scenario.wind, scenario.faults, seed=SEED, backend="numba")
    twin = copy.deepcopy(plant)  # a fault-free twin run in the same process copies the plant
    twin.measure(), plant.measure()
    np.testing.assert_array_equal(twin.last_reading, plant.last_reading)
    # a copied supervisor learns into its own adaptive state (the kernels update it in place)
    plant = TurbineBatch(scenario.plant, scenario.wind, scenario.faults, seed=SEED, backend="numba")
    supervisor, refs = TurbineSupervisor(plant.n, backend="numba"), None
    for _ in range(3):
        frame = plant.measure()
        plant.control(refs)
        refs = supervisor.step(frame)
        plant.advance()
    copied = copy.deepcopy(supervisor)
    frame = plant.measure()
    copied.step(frame)
    spreads = [(s.detector.fdi.spread, s.detector.components.parity_spread) for s in (supervisor, copied)]
    assert not np.array_equal(spreads[0][1].count, spreads[1][1].count)  # only the copy took the last frame
    supervisor.step(frame)
    for mine, its in zip(*spreads, strict=True):
        for a, b in zip(mine.state, its.state, strict=True):
            np.testing.assert_array_equal(a, b)


def test_starting_the_cli_and_the_live_nodes_does_not_import_the_compiler():
    code = (
        "import sys, windwarden.cli, plant_sim.turbine, plant_sim.farm, service.turbine.supervisor; "
        "print('numba' in sys.modules)"
    )
    env = {**os.environ}
    env.pop(ENV_VAR, None)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.strip() == "False"


def test_eval_refuses_the_numba_backend_where_numba_is_missing(monkeypatch, tmp_path, capsys):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "numba" else real(name, *a))
    with pytest.raises(BackendError, match="pip install numba"):
        available("numba")
    out = tmp_path / "out"
    assert main(["eval", "ftwse-2012", "--runs", "1", "--quiet", "--out", str(out)]) == EXIT_BAD_INPUT
    assert "--step-backend" in capsys.readouterr().err and not out.exists()  # refused before anything ran
