"""Damage measures: online turning points + rainflow equal rainflow on the series; damage numbers 1 and > 1."""

from __future__ import annotations

import numpy as np
import pytest
import rainflow

from plant_sim.farm.damage import ReversalRecorder, damage_sums, del_from_sums, imbalance_phasor


def test_turning_points_and_rainflow_match_rainflow_of_the_whole_series():
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 200.0, 0.01)
    x = np.stack(
        [1e6 * np.sin(2 * np.pi * 0.8 * t) + 3e6 * t / 200.0, 2e5 * np.sin(0.6 * t) + 2e3 * rng.standard_normal(len(t))]
    )
    rec = ReversalRecorder(2)
    for k in range(len(t)):
        rec.step(k, x[:, k])
    rec.finish(len(t))
    edges = np.array([0, len(t) // 2, len(t)])
    for i, (ticks, values) in enumerate(rec.sequences()):
        sums = damage_sums(ticks, values, edges)
        direct = sum(n * s**4 for s, n in rainflow.count_cycles(x[i]))
        assert sums.sum() == pytest.approx(direct, rel=1e-4)  # the gate drops cycles < 30 kN m only
    assert del_from_sums(np.array([16.0 * 200.0]), 200.0)[0] == pytest.approx(2.0)  # (Σ n S⁴ / T)^(1/4)


def test_imbalance_of_a_symmetric_rotor_is_zero_and_of_one_blade_is_its_excess():
    assert abs(imbalance_phasor(np.array([[5.0, 5.0, 5.0]]))[0]) == pytest.approx(0.0, abs=1e-12)
    assert abs(imbalance_phasor(np.array([[7.0, 5.0, 5.0]]))[0]) == pytest.approx(2.0)


def test_damage_number_is_one_fault_free_and_above_one_with_the_drive_train_fault():
    from plant_sim.farm import FarmBatch
    from tests.farm.conftest import farm_spec, wind
    from windwarden.evaluation.farm import DAMAGE_BIN_S
    from wwcore.scenario.faults import FaultSpec

    fault = FaultSpec(target="drivetrain", kind="drivetrain_wear", value=5.0, turbine=4, start_s=20.0)
    plant = FarmBatch(farm_spec(1), wind(14.0), [fault], seed=6, duration_s=60.0, fault_free_twins=True)
    rec = ReversalRecorder(plant.n)
    for k in range(6000):
        plant.measure()
        plant.control(None)
        rec.step(k, plant.shaft_torque())
        plant.advance()
    rec.finish(6000)
    edges = np.array([0, 2000, 6000])  # before / during the fault
    sums = np.stack([damage_sums(tk, v, edges) for tk, v in rec.sequences()])
    fault_row, twin_row, other, other_twin = (
        plant.row_of(0, 4),
        plant.row_of(1, 4),
        plant.row_of(0, 7),
        plant.row_of(1, 7),
    )
    assert sums[other] == pytest.approx(sums[other_twin])  # no fault: damage number 1 by construction
    during = del_from_sums(sums[fault_row, 1], 40.0) / del_from_sums(sums[twin_row, 1], 40.0)
    assert during > 1.5
    assert DAMAGE_BIN_S > 0
