"""The encoders' consistency test (``UIOBankEstimator._wind_columns``): while nothing is suspected the wind estimate
comes from observer 4, the mean of the two generator-speed encoders, and an encoder fault the detector has not seen
moves it; the difference of the two one-encoder observers' torques is the encoders' noise alone on a healthy plant
(``WindRecovery.pair_difference_sigma``), and beyond its level the wind is inverted from the observer that uses
neither encoder (docs/turbine.md, "The encoders' consistency test")."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

from plant_sim.turbine import TurbineBatch
from service.turbine.bank import GENERATOR, ObserverBank
from service.turbine.builtin import UIOBankEstimator
from service.turbine.interfaces import TurbineContext
from service.turbine.supervisor import TurbineSupervisor
from service.turbine.wind_recovery import WindRecovery
from wwcore.channels import DIAGNOSIS_TARGETS, SENSOR_INDEX, SENSORS, SPEED_SENSORS, TARGET_INDEX, noise_std
from wwcore.scenario.faults import FaultKind, FaultSpec
from wwcore.scenario.turbine import TurbinePlant
from wwcore.scenario.wind import WindSpec
from wwcore.turbine_params import BENCHMARK as P

DESIGN = TurbineContext(P, 1).bank_design
SIGMA_G = noise_std(SENSORS[SENSOR_INDEX["omega_g_m1"]], "sigma")


def test_the_pair_difference_is_the_encoders_noise_through_the_filter():
    """Two encoders reading a shaft whose speed swings by 20 rad/s at 0.05–0.5 Hz, each with its own white noise: the
    two one-encoder observers' filtered torques differ by what ``pair_difference_sigma`` says (σ from 48 000
    samples, 2 % is 4.6 standard errors of a σ estimate from that many correlated-over-≈100-tick samples, loosely),
    whatever the motion the two read alike."""
    rows, ticks, settle = 40, 6_000, 1_500
    rng = np.random.default_rng(3)
    recovery = WindRecovery(P, DESIGN, rows, wind_cutoff_hz=0.3, speed_cutoff_hz=2.0)
    pair = tuple(DESIGN.single_generator)
    sigma = recovery.pair_difference_sigma(DESIGN, pair)
    bank = ObserverBank(DESIGN, rows)
    t = np.arange(ticks + 1) * P.dt
    phase = rng.uniform(0, 2 * np.pi, (rows, 3))
    freq = np.array([0.05, 0.2, 0.5])

    def reading(k: int) -> np.ndarray:
        omega_g = 150.0 + (20.0 / 3) * np.sin(2 * np.pi * freq * t[k] + phase).sum(axis=1)
        true = np.column_stack([omega_g / P.N_g, omega_g / P.N_g, omega_g, omega_g, omega_g])
        noise = rng.standard_normal((rows, 5)) * [0.025, 0.025, SIGMA_G, SIGMA_G, 0.5]
        return true + noise

    y = reading(0)
    bank.initialise(np.column_stack([y[:, 2] / P.N_g, y[:, 2], np.zeros(rows), np.zeros(rows)]), y)
    recovery.start(bank.x_hat, np.zeros(rows), np.zeros(rows))
    no_pitch = np.zeros((rows, 3))
    difference = np.empty((ticks, rows))
    for k in range(1, ticks + 1):
        bank.step(reading(k), np.zeros(rows))
        recovery.step(bank.x_hat, np.zeros(rows), no_pitch, no_pitch, None, None)
        difference[k - 1] = recovery.filtered[:, pair[0]] - recovery.filtered[:, pair[1]]
    measured = difference[settle:].std()
    assert measured == pytest.approx(sigma, rel=0.04)
    # the level a healthy pair passes on a share α of the looks
    estimator = UIOBankEstimator(context=TurbineContext(P, 1), options={"encoder_pair_alpha": 1e-3})
    assert estimator._pair_level == pytest.approx(norm.isf(5e-4) * sigma, rel=1e-12)
    assert np.mean(np.abs(difference[settle:]) > estimator._pair_level) < 5e-3


def test_the_pair_difference_refuses_observers_it_does_not_describe():
    recovery = WindRecovery(P, DESIGN, 1, wind_cutoff_hz=0.3, speed_cutoff_hz=2.0)
    four = DESIGN.index(frozenset({"omega_r_m1", "omega_r_m2"}))
    with pytest.raises(ValueError, match="one generator-speed sensor"):
        recovery.pair_difference_sigma(DESIGN, (four, DESIGN.single_generator[0]))


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_the_wind_leaves_both_encoders_while_their_torques_disagree(backend):
    """Observer 4's rows whose one-encoder torques differ beyond the level invert from the observer of both
    encoders distrusted (observer 5 in region 1); the others, and rows already off observer 4, are unchanged; the
    speeds' observer (``selected``) is not the wind's."""
    estimator = UIOBankEstimator(context=TurbineContext(P, 3, backend=backend))
    four, five = estimator._both_encoders, DESIGN.index(frozenset(GENERATOR))
    one = DESIGN.single_generator[1]
    torque = estimator.recovery.filtered
    torque[:, estimator._pair[0]] = 1e5
    torque[:, estimator._pair[1]] = 1e5 - np.array([2.0, 0.5, 2.0]) * estimator._pair_level
    columns = np.array([four, four, one])
    faulty = np.zeros((3, len(DIAGNOSIS_TARGETS)), dtype=bool)
    faulty[2, TARGET_INDEX[GENERATOR[1]]] = True

    class Frame:
        tau_g_ref = np.full(3, 100.0)  # region 1: below the power-speed channel's threshold
        zone = np.zeros(3, dtype=np.int64)

    assert estimator._wind_columns(columns, faulty, Frame).tolist() == [five, four, one]
    off = UIOBankEstimator(context=TurbineContext(P, 3, backend=backend), options={"encoder_pair_alpha": 0.0})
    off.recovery.filtered[:] = torque
    assert off._wind_columns(columns, faulty, Frame).tolist() == [four, four, one]


def test_an_encoder_step_the_detector_has_not_seen_barely_moves_the_wind_estimate():
    """A −3σ step on ω_g,m1 at 4 m/s (region 1, where a torque error moves the wind estimate most): observer 4's torque
    takes half the step's impulse, J_eq · 1.5σ, and without the test the wind estimate's squared error over the 10 s
    after the step was 24–76 × its fault-free twin's on the rows the detector never suspected (this seed); with it,
    the wind is inverted from observer 5 while the one-encoder torques disagree, and the rows the detector did not
    suspect stay within 3 × their twins'."""
    rows, start, end = 4, 30.0, 40.0
    faults = [
        FaultSpec(
            target="omega_g_m1", kind=FaultKind.OFFSET, value=-3.0 * SIGMA_G, start_s=start, end_s=100.0,
            turbine=t, name=f"g1 offset -3σ #{t}",
        )
        for t in range(1, rows + 1)
    ]  # fmt: skip
    plant = TurbineBatch(
        TurbinePlant(), WindSpec(mean=[(0.0, 4.0)]), faults, seed=11, runs=(0,), turbines=list(range(1, rows + 1)),
        fault_free_twins=True,
    )  # fmt: skip
    supervisor = TurbineSupervisor(plant.n)
    refs = None
    squared = np.zeros(plant.n)
    suspected = np.zeros(plant.n, dtype=bool)
    speed = [TARGET_INDEX[s] for s in SPEED_SENSORS]
    for k in range(round(end / P.dt)):
        frame = plant.measure()
        plant.control(refs)
        refs = supervisor.step(frame)
        plant.advance()
        diagnosis = supervisor.diagnosis
        distrusted = diagnosis.faulty if diagnosis.suspect is None else diagnosis.suspect
        suspected |= distrusted[:, speed].any(axis=1)
        if k * P.dt >= start:
            error = supervisor.estimates.wind - plant.true_rotor_wind()
            squared += error * error
    ratio = squared[:rows] / squared[rows:]
    unseen = ~suspected[:rows]
    assert unseen.any() and not suspected[rows:].any()
    assert (ratio[unseen] < 3.0).all(), ratio


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_a_flagged_encoder_trusted_again_restarts_its_one_encoder_observer_from_the_healthy_one(backend):
    """When a flagged generator-speed sensor is trusted again while the other is trusted, the one-encoder observer
    on it takes the other one's filters, so the two one-encoder torques' difference restarts from zero (without it,
    the restored encoder's observer carries the fault's end for seconds and the test keeps the wind off observer 4).
    Not where the encoder was only suspected (its own readings were healthy), nor where both encoders come back at
    once (neither one-encoder observer ran on healthy readings)."""
    rows = 3
    context = TurbineContext(P, rows, backend=backend)
    estimator = UIOBankEstimator(context=context)
    bank = ObserverBank(DESIGN, rows, fast=context.fast)
    left_out_g1, left_out_g2 = estimator._pair  # observers on ω_g,m2 and on ω_g,m1
    four, five = estimator._both_encoders, DESIGN.index(frozenset(GENERATOR))
    g1, g2 = (1 << SPEED_SENSORS.index(g) for g in GENERATOR)
    recovery = estimator.recovery
    omega_g = np.full(rows, 120.0)
    y = np.column_stack([omega_g / P.N_g, omega_g / P.N_g, omega_g, omega_g, omega_g])
    bank.initialise(np.column_stack([omega_g / P.N_g, omega_g, np.zeros(rows), np.zeros(rows)]), y)
    recovery.start(bank.x_hat, np.zeros(rows), np.full(rows, 1e5))
    rng = np.random.default_rng(5)
    for state in (recovery.filter.s1, recovery.filter.s2, recovery.filtered):
        state[:] = rng.standard_normal(state.shape) * 1e4
    before = recovery.filtered.copy()
    # the previous tick: row 0 with ω_g,m1 flagged, row 1 with it suspected only, row 2 with both flagged
    previous_mask = np.array([g1, g1, g1 | g2])
    estimator._take_over(bank, np.array([left_out_g1, left_out_g1, five]), previous_mask, np.array([g1, 0, g1 | g2]))
    nothing = np.zeros(rows, dtype=np.int64)
    estimator._take_over(bank, np.full(rows, four), nothing, nothing)
    filtered = recovery.filtered
    assert filtered[0, left_out_g2] == filtered[0, left_out_g1] == before[0, left_out_g1]
    assert recovery.filter.s1[0, left_out_g2] == recovery.filter.s1[0, left_out_g1]
    assert recovery.filter.s2[0, left_out_g2] == recovery.filter.s2[0, left_out_g1]
    assert (filtered[1:, [left_out_g1, left_out_g2]] == before[1:, [left_out_g1, left_out_g2]]).all()
    off = UIOBankEstimator(context=context, options={"encoder_pair_alpha": 0.0})  # no test: nothing to restart
    off.recovery.start(bank.x_hat, np.zeros(rows), np.full(rows, 1e5))
    off.recovery.filtered[:] = before
    off._take_over(bank, np.array([left_out_g1, left_out_g1, five]), previous_mask, np.array([g1, 0, g1 | g2]))
    off._take_over(bank, np.full(rows, four), nothing, nothing)
    assert (off.recovery.filtered[:, [left_out_g1, left_out_g2]] == before[:, [left_out_g1, left_out_g2]]).all()
