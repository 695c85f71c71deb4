"""The residual tests for the benchmark's pitch sensors, pitch actuators and converter, on the simulated plant."""

from __future__ import annotations

import numpy as np
import pytest

from plant_sim.turbine import TurbineBatch
from service.turbine.component_fdi import actuator_whitener
from service.turbine.supervisor import TurbineSupervisor
from wwcore.channels import DIAGNOSIS_TARGETS
from wwcore.scenario import FaultSpec, WindSpec
from wwcore.scenario.turbine import TurbinePlant
from wwcore.turbine_params import BENCHMARK as P

REGION3 = WindSpec(mean=[(0.0, 16.0)])  # turbulent, pitching


def flags_over_time(faults, seconds, wind=REGION3, seed=11, runs=2, mismatch=None):
    plant = TurbineBatch(TurbinePlant(), wind, faults, seed=seed, runs=list(range(runs)), mismatch=mismatch)
    supervisor = TurbineSupervisor(plant.n)
    refs, flagged = None, []
    for _ in range(round(seconds / plant.dt)):
        frame = plant.measure()
        plant.control(refs)
        refs = supervisor.step(frame)
        flagged.append(supervisor.diagnosis.faulty.copy())
        plant.advance()
    return np.array(flagged)  # (ticks, rows, targets)


def first_tick(flags, target) -> np.ndarray:
    col = DIAGNOSIS_TARGETS.index(target)
    hits = flags[:, :, col]
    return np.where(hits.any(axis=0), hits.argmax(axis=0), -1)


def test_actuator_whitener_is_the_inverse_of_one_plus_the_nominal_actuator():
    b, a = actuator_whitener(P)
    assert np.all(np.abs(np.roots(a)) < 1.0), "stable"
    assert b.sum() / a.sum() == pytest.approx(0.5), "(1 + G)⁻¹ at DC, G(1) = 1"


def test_no_component_flag_in_healthy_turbulent_operation():
    flags = flags_over_time([], 120.0, runs=3)
    assert not flags.any()


COMPONENT_FAULTS = [
    (FaultSpec(target="beta_1_m1", kind="fixed", value=5.0, start_s=10.0, end_s=30.0), "beta_1_m1", 0.05),
    (FaultSpec(target="beta_2_m2", kind="gain", value=1.2, start_s=10.0, end_s=30.0), "beta_2_m2", 0.05),
    (FaultSpec(target="beta_3_m1", kind="fixed", value=10.0, start_s=10.0, end_s=30.0), "beta_3_m1", 0.05),
    (FaultSpec(target="converter", kind="torque_offset", value=100.0, start_s=10.0, end_s=30.0), "converter", 1.5),
]


@pytest.fixture(scope="module")
def component_fault_flags():
    """Each fault on a turbine of its own (turbine i + 1 for fault i, two runs each), all in one batch: rows are
    independent plants with their own wind and noise streams, and a tick of eight rows costs about what a tick of
    two does. Returns the flags and each row's turbine."""
    faults = [fault.model_copy(update={"turbine": i + 1}) for i, (fault, _, _) in enumerate(COMPONENT_FAULTS)]
    plant = TurbineBatch(
        TurbinePlant(), REGION3, faults, seed=11, runs=[0, 1], turbines=list(range(1, len(faults) + 1))
    )
    supervisor = TurbineSupervisor(plant.n)
    refs, flagged = None, []
    for _ in range(round(35.0 / plant.dt)):
        frame = plant.measure()
        plant.control(refs)
        refs = supervisor.step(frame)
        flagged.append(supervisor.diagnosis.faulty.copy())
        plant.advance()
    return np.array(flagged), plant.turbine_of_row


@pytest.mark.parametrize("case", range(len(COMPONENT_FAULTS)), ids=[t for _, t, _ in COMPONENT_FAULTS])
def test_component_faults_are_detected_and_isolated(component_fault_flags, case):
    fault, target, within_s = COMPONENT_FAULTS[case]
    all_flags, turbine_of_row = component_fault_flags
    flags = all_flags[:, turbine_of_row == case + 1]
    assert flags.shape[1] == 2
    start = round(fault.start_s / P.dt)
    first = first_tick(flags, target)
    assert np.all(first >= start), "no flag before the fault"
    assert np.all(first - start <= round(within_s / P.dt)), first - start
    others = [i for i, name in enumerate(DIAGNOSIS_TARGETS) if name != target]
    assert not flags[:, :, others].any(), "only the faulty target is flagged"
    end = round(fault.end_s / P.dt)
    assert not flags[end + round(1.5 / P.dt) :, :, DIAGNOSIS_TARGETS.index(target)].any(), "cleared after the end"


@pytest.mark.parametrize(
    ("fault", "within_s"),
    [
        (
            FaultSpec(
                target="pitch_actuator_2", kind="pitch_dynamics", omega_n=5.73, zeta=0.45, start_s=10.0, end_s=50.0
            ),
            25.0,
        ),
        pytest.param(  # the ramped fault needs a 100 s run: about 1.5 min, so in `make test-slow`
            FaultSpec(
                target="pitch_actuator_3",
                kind="pitch_dynamics",
                omega_n=3.42,
                zeta=0.9,
                start_s=10.0,
                end_s=100.0,
                ramp_s=30.0,
            ),
            45.0,
            marks=pytest.mark.slow,
        ),
    ],
)
def test_pitch_actuator_faults_are_isolated_to_their_blade(fault, within_s):
    flags = flags_over_time([fault], fault.end_s, runs=2, seed=5)
    first = first_tick(flags, fault.target)
    start = round(fault.start_s / P.dt)
    assert np.all(first >= start) and np.all(first - start <= round(within_s / P.dt)), (first - start) * P.dt
    others = [i for i, name in enumerate(DIAGNOSIS_TARGETS) if name != fault.target]
    assert not flags[:, :, others].any()
