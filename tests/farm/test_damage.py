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


def _rough_signals(rng: np.random.Generator, n: int, ticks: int) -> np.ndarray:
    """Random walks with plateaus and repeated values (the cases the reversal filter treats specially)."""
    steps = rng.standard_normal((n, ticks)) * 4e4
    steps[rng.random((n, ticks)) < 0.2] = 0.0  # plateaus: equal consecutive samples
    x = np.cumsum(steps, axis=1) + 1e5 * np.sin(np.arange(ticks) * 0.05)
    x[0] = np.round(x[0], -5)  # a row whose values repeat exactly
    x[1, 5:] = x[1, 4]  # a row with one turning point after the start
    return x


@pytest.mark.parametrize("flush_ticks", [1, 7, 500, 10**9])
def test_streaming_damage_equals_rainflow_of_the_whole_sequence_bit_for_bit(flush_ticks):
    from plant_sim.farm.rainflow_stream import StreamingDamage

    x = _rough_signals(np.random.default_rng(11), 5, 3000)
    edges = np.array([0, 700, 701, 2500, 3000])
    whole = ReversalRecorder(5)
    streaming = StreamingDamage(5, edges, flush_ticks=flush_ticks)
    for k in range(x.shape[1]):
        whole.step(k, x[:, k])
        streaming.step(k, x[:, k])
    whole.finish(x.shape[1])
    streaming.finish(x.shape[1])
    reference = np.stack([damage_sums(tk, v, edges) for tk, v in whole.sequences()])
    assert reference[2:].sum() > 0  # cycles were counted
    assert np.array_equal(streaming.sums, reference)


def test_rainflow_counter_fed_in_pieces_yields_the_packages_cycles():
    from plant_sim.farm.rainflow_stream import RainflowCounter

    rng = np.random.default_rng(5)
    for n in (0, 1, 2, 3, 4, 50, 400):
        values = np.round(rng.standard_normal(n) * 3.0)  # small integers: many equal neighbours
        ticks = np.arange(n) * 10
        counter = RainflowCounter()
        cuts = np.sort(rng.integers(0, n + 1, size=4))
        for a, b in zip(np.r_[0, cuts], np.r_[cuts, n], strict=True):
            counter.feed(ticks[a:b], values[a:b])
        counter.finish()
        got = counter.take()
        expected = [(r, c, ticks[i1]) for r, _m, c, _i0, i1 in rainflow.extract_cycles(values)]
        assert list(zip(*(g.tolist() for g in got), strict=True)) == [
            (float(r), float(c), int(t)) for r, c, t in expected
        ]


def test_streaming_damage_keeps_only_the_residue_between_flushes():
    from plant_sim.farm.rainflow_stream import StreamingDamage

    rng = np.random.default_rng(3)
    streaming = StreamingDamage(4, np.array([0, 10**6]), flush_ticks=1000)
    for k in range(60_000):  # a stationary turbulent-like signal: thousands of turning points per row
        streaming.step(k, 1e6 * np.sin(0.05 * k + np.arange(4)) + 2e5 * rng.standard_normal(4))
    held = max(c.kept() for c in streaming.counters)
    assert held < 40  # the residue of a stationary signal, not the ~10^4 turning points seen
    assert sum(len(v) for _t, v in streaming.recorder.sequences()) <= 1000 * 4  # at most one flush's worth
