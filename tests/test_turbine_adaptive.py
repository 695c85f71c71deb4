"""Adaptive thresholds (``service.turbine.adaptive``): closed-form behaviour, and the supervisor on a plant that
differs from its design model (a mismatch other than the shipped scenarios')."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from plant_sim.turbine import TurbineBatch
from service.turbine.adaptive import HealthySpread
from service.turbine.supervisor import TurbineSupervisor
from wwcore.channels import DIAGNOSIS_TARGETS
from wwcore.scenario import FaultSpec, WindSpec
from wwcore.scenario.mismatch import Mismatch
from wwcore.scenario.turbine import TurbinePlant

DT = 0.01


def _white(sigma: float, ticks: int, shape=(3,), seed=5) -> np.ndarray:
    return sigma * np.random.default_rng(seed).standard_normal((ticks, *shape))


@pytest.mark.parametrize("sigma", [1.0, 1.3, 2.2])
def test_the_scale_converges_to_the_true_sigma_of_white_noise(sigma):
    spread = HealthySpread((3,), DT, adapt_time_s=20.0, max_scale=3.0)
    healthy = np.ones(3, dtype=bool)
    for z in _white(sigma, 20_000):  # 200 s, ten adaptation times
        spread.update(z * z, healthy)
    # an EWMA of χ²₁ over T_a/Δt = 2000 samples: relative sd √(2/(2·2000)) ≈ 2.2 %, so 10 % is > 4 sd
    assert spread.estimate == pytest.approx(np.full(3, sigma**2), rel=0.1)
    assert np.array_equal(spread.scale2, np.clip(spread.estimate, 1.0, 9.0))
    assert spread.scale == pytest.approx(np.sqrt(spread.scale2), rel=1e-15)


def test_the_design_sigma_is_a_floor_and_max_noise_scale_a_ceiling():
    quiet, loud = HealthySpread((3,), DT, 20.0, 3.0), HealthySpread((3,), DT, 20.0, 3.0)
    healthy = np.ones(3, dtype=bool)
    for zq, zl in zip(_white(0.5, 5000), _white(5.0, 5000, seed=6), strict=True):
        quiet.update(zq * zq, healthy)
        loud.update(zl * zl, healthy)
    assert np.all(quiet.estimate < 0.5) and np.all(quiet.scale2 == 1.0)
    assert np.all(loud.estimate > 15.0) and np.all(loud.scale2 == 9.0)


def test_the_estimate_follows_a_step_with_the_adaptation_time_and_is_frozen_while_unhealthy():
    t_a = 10.0
    spread = HealthySpread((1,), DT, t_a, 3.0)
    on, off = np.ones(1, dtype=bool), np.zeros(1, dtype=bool)
    for _ in range(round(5 * t_a / DT)):
        spread.update(np.ones(1), on)
    for _ in range(round(t_a / DT)):  # q steps from 1 to 4: after T_a, 4 − 3 (1 − Δt/T_a)^(T_a/Δt) ≈ 4 − 3/e
        spread.update(np.full(1, 4.0), on)
    expected = 4.0 - 3.0 * (1.0 - DT / t_a) ** round(t_a / DT)
    assert spread.estimate[0] == pytest.approx(expected, rel=1e-12)
    assert expected == pytest.approx(4.0 - 3.0 / math.e, rel=1e-3)
    before = (spread.estimate.copy(), spread.count.copy())
    for _ in range(1000):  # a flag is up: huge samples are not learnt
        spread.update(np.full(1, 100.0), off)
    assert np.array_equal(spread.estimate, before[0]) and np.array_equal(spread.count, before[1])


def test_the_offset_is_learnt_and_clipped_to_the_calibration_tolerance():
    spread = HealthySpread((2,), DT, 20.0, 3.0, offset_limit=0.5)
    healthy = np.ones(2, dtype=bool)
    bias = np.array([0.3, 2.0])  # within, beyond the tolerance
    for n in _white(1.0, 20_000, shape=(2,)):
        x = bias + n
        spread.update((x - spread.offset) ** 2, healthy, x)
    assert spread.offset[0] == pytest.approx(0.3, abs=0.1)
    assert spread.offset[1] == 0.5, "a bias beyond the tolerance is never absorbed beyond it"


def test_zero_adaptation_time_keeps_the_design_thresholds():
    spread = HealthySpread((2,), DT, 0.0, 3.0, offset_limit=1.0)
    spread.update(np.full(2, 9.0), np.ones(2, dtype=bool), np.full(2, 1.0))
    assert not spread.enabled and np.all(spread.scale2 == 1.0) and np.all(spread.offset == 0.0)


# -- the supervisor on a plant that is not its design model ------------------------------------------------------

# Not the shipped scenarios' values: a heavier soiling, denser air, a stiffer drive train, faster pitch
# actuators, noisier sensors, and every calibration bias drawn up to 0.8 of its tolerance.
OTHER_MISMATCH = Mismatch(
    cp_scale=0.9,
    tsr_shift=0.4,
    air_density_kgm3=1.3,
    drivetrain_stiffness_factor=1.15,
    drivetrain_damping_ratio=0.02,
    pitch_omega_n_rads=12.5,
    pitch_zeta=0.55,
    noise_scale=1.5,
    spread={"noise_scale": 0.2, "pitch_omega_n_rads": 0.5, "sensor_bias_fraction": 0.8},
)


def _start(faults, wind, options=None, runs=2, seed=23):
    plant = TurbineBatch(TurbinePlant(), wind, faults, seed=seed, runs=list(range(runs)), mismatch=OTHER_MISMATCH)
    return plant, TurbineSupervisor(plant.n, options=options)


def _run(plant, supervisor, seconds, refs=None, until_flag=False):
    """Step ``seconds`` of closed loop; the flags and the bank's χ² spread estimate of every tick, and the last
    refs (to continue the run). ``until_flag``: stop at the first tick with a flag (when only its existence counts)."""
    flagged, estimates = [], []
    for _ in range(round(seconds / plant.dt)):
        frame = plant.measure()
        plant.control(refs)
        refs = supervisor.step(frame)
        flagged.append(supervisor.diagnosis.faulty.copy())
        estimates.append(supervisor.detector.fdi.spread.estimate.copy())
        plant.advance()
        if until_flag and flagged[-1].any():
            break
    return np.array(flagged), np.array(estimates), refs


def _flags(faults, seconds, wind, options=None, runs=2, seed=23, until_flag=False):
    plant, supervisor = _start(faults, wind, options, runs, seed)
    flags, estimates, _ = _run(plant, supervisor, seconds, until_flag=until_flag)
    return flags, estimates, supervisor


@pytest.mark.parametrize("wind", [8.0, pytest.param(16.0, marks=pytest.mark.slow)])  # region 3 again: ~30 s
def test_no_false_alarm_under_a_model_mismatch_and_the_fixed_thresholds_do_raise_them(wind):
    spec = WindSpec(mean=[(0.0, wind)])
    flags, _, supervisor = _flags([], 150.0, spec)
    assert not flags.any(), [DIAGNOSIS_TARGETS[i] for i in np.flatnonzero(flags.any(axis=(0, 1)))]
    fdi, components = supervisor.detector.fdi, supervisor.detector.components
    assert np.all(fdi.spread.scale > 1.2), "the bank's residuals are about 1.5 × their design spread"
    assert np.all(components.converter_spread.scale > 1.2)
    fixed = {"adapt_time_s": 0.0, "component_adapt_time_s": 0.0}
    flags, _, _ = _flags([], 150.0, spec, options=fixed, until_flag=True)  # within the same 150 s
    assert flags.any(), "without adaptation the same plant raises false alarms (the test can fail)"


FAULT_START_S = 60.0


@pytest.fixture(scope="module")
def healthy_minute():
    """The first 60 s at 10 m/s, fault-free (the faults below start at 60 s): the plant, the supervisor, the last
    refs, and the flags and χ² spread estimates of every tick. A fault scheduled from the start changes nothing
    before its start tick (``TurbineBatch.inject``; the noise streams do not depend on the schedule), so each fault
    case continues a copy of this history instead of simulating the same minute again."""
    plant, supervisor = _start([], WindSpec(mean=[(0.0, 10.0)]))
    flags, estimates, refs = _run(plant, supervisor, FAULT_START_S)
    return plant, supervisor, refs, flags, estimates


# the rotor-speed gain is 0.14 rad/s at 10 m/s: 3.7 σ of this plant's noisier sensor (5.6 σ of the design's)
@pytest.mark.parametrize(
    ("fault", "target", "within_s"),
    [
        (FaultSpec(target="omega_r_m1", kind="gain", value=1.1, start_s=60.0, end_s=80.0), "omega_r_m1", 0.5),
        (FaultSpec(target="omega_g_m2", kind="fixed", value=100.0, start_s=60.0, end_s=80.0), "omega_g_m2", 0.05),
        (FaultSpec(target="beta_2_m1", kind="fixed", value=5.0, start_s=60.0, end_s=80.0), "beta_2_m1", 0.05),
        (FaultSpec(target="converter", kind="torque_offset", value=100.0, start_s=60.0, end_s=80.0), "converter", 1.5),
    ],
)
def test_faults_of_the_benchmark_size_are_still_flagged_under_mismatch_and_nothing_is_learnt_meanwhile(
    healthy_minute, fault, target, within_s
):
    plant, supervisor, refs, before, estimates_before = copy.deepcopy(healthy_minute)
    assert plant.k == round(fault.start_s / DT)
    plant.inject(fault)
    after, estimates_after, _ = _run(plant, supervisor, 15.0, refs)  # 75 s in all
    flags, estimates = np.concatenate([before, after]), np.concatenate([estimates_before, estimates_after])
    start, col = round(fault.start_s / DT), DIAGNOSIS_TARGETS.index(target)
    assert not flags[:start].any(), "no false alarm before the fault"
    hits = flags[start:, :, col]
    assert hits.any(axis=0).all()
    assert hits.argmax(axis=0).max() * DT <= within_s
    first = hits.argmax(axis=0)
    others = np.delete(flags[start:], col, axis=2)
    assert not others[: first.max() + 1].any(), "the first flag names the fault's target only"
    if target.startswith("omega"):  # the bank's χ² scale is frozen from the first flag to the window's end
        for row, k in enumerate(first):
            frozen = estimates[start + k + 1 :, row]
            assert np.array_equal(frozen, np.broadcast_to(frozen[0], frozen.shape))
