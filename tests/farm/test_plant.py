"""The farm plant: the three farm faults act as documented, turbines follow their references, twins are twins."""

from __future__ import annotations

import numpy as np
import pytest

from plant_sim.farm import FarmBatch
from plant_sim.farm.controller import MIN_SPEED_FRACTION, SPEED_SLEW, speed_setpoint
from service.farm.interfaces import BETA
from tests.farm.conftest import farm_spec, wind
from wwcore.farm_frames import FarmRefs
from wwcore.scenario.faults import FaultSpec
from wwcore.turbine_params import BENCHMARK as P


def _run(plant: FarmBatch, seconds: float, refs: FarmRefs | None = None, record=None) -> list:
    out = []
    for _ in range(round(seconds / plant.dt)):
        frame = plant.measure()
        plant.control(refs)
        if record is not None:
            out.append(record(plant, frame))
        plant.advance()
    return out


def test_debris_lowers_the_power_output_by_3_percent_at_unchanged_speed_and_torque():
    fault = FaultSpec(target="rotor", kind="debris", value=0.97, turbine=5, start_s=1.0)
    plant = FarmBatch(farm_spec(1), wind(9.0), [fault], seed=2, duration_s=3.0, fault_free_twins=True)
    rows = [plant.row_of(0, 5), plant.row_of(1, 5)]  # the turbine and its fault-free twin
    rec = _run(plant, 1.2, record=lambda p, f: (p.power_output()[rows], p.turbines.x[rows, 1].copy()))
    power, omega = np.array([r[0] for r in rec]), np.array([r[1] for r in rec])
    assert power[50, 0] == power[50, 1]  # before the fault the twins are identical
    k = 105  # 0.05 s into the fault, before the controller sees a difference
    assert power[k, 0] / power[k, 1] == pytest.approx(0.97, rel=1e-9)
    assert omega[k, 0] == omega[k, 1]


def test_pitch_misalignment_holds_one_blade_off_and_its_encoders_see_it():
    fault = FaultSpec(target="pitch_actuator_2", kind="offset", value=0.3, turbine=1, start_s=1.0)
    plant = FarmBatch(farm_spec(1), wind(9.0), [fault], seed=2, duration_s=6.0)
    rec = _run(plant, 6.0, record=lambda p, f: f.turbines.sensors[0, BETA].mean(axis=1))
    blades = np.array(rec)[300:]  # from 2 s on
    diff = blades[:, 1] - 0.5 * (blades[:, 0] + blades[:, 2])
    assert diff.mean() == pytest.approx(0.3, abs=0.02)


def test_drive_train_fault_makes_the_generator_swing_against_the_rotor_at_3p():
    """e(ψ) = e_0 cos 3ψ below the torsion mode: ω_g − N ω_r oscillates at 3P with amplitude N · 3 ω_r · e_0."""
    e0 = 5e-3
    fault = FaultSpec(target="drivetrain", kind="drivetrain_wear", value=e0 * 1e3, turbine=3, start_s=0.0)
    plant = FarmBatch(farm_spec(1), wind(9.0, ti=0.02), [fault], seed=2, duration_s=20.0)
    rec = _run(plant, 20.0, record=lambda p, f: (p.turbines.x[2, 1] - P.N_g * p.turbines.x[2, 0], p.turbines.x[2, 0]))
    r = np.array([a for a, _ in rec])[500:]
    omega_r = np.mean([b for _, b in rec][500:])
    amplitude = (r.max() - r.min()) / 2.0
    assert amplitude == pytest.approx(P.N_g * 3.0 * omega_r * e0, rel=0.15)


def test_a_derated_turbine_follows_its_reference_at_its_speed_set_point():
    plant = FarmBatch(farm_spec(1, coherent_ti=0.0), wind(12.0, ti=0.005), [], seed=2, duration_s=60.0)
    ref = np.full(plant.n, 2.0e6)
    rec = _run(plant, 60.0, FarmRefs(0, ref), record=lambda p, f: (p.power_output().copy(), p.turbines.x[:, 1].copy()))
    power = np.array([a for a, _ in rec])[-1000:].mean(axis=0)
    omega = np.array([b for _, b in rec])[-1000:].mean(axis=0)
    assert power == pytest.approx(ref, rel=0.01)
    assert omega == pytest.approx(speed_setpoint(P, ref), rel=0.01)


def test_derating_at_held_torque_lowers_the_speed_not_the_shaft_torque():
    """Above rated wind: the reference halves with ``hold_torque``; the speed set point carries the derating."""
    plant = FarmBatch(farm_spec(1, coherent_ti=0.0), wind(16.0, ti=0.005), [], seed=2, duration_s=170.0)
    hold = np.zeros(plant.n, dtype=bool)
    hold[4] = True
    rated = np.full(plant.n, P.rated_power)
    before = np.array(_run(plant, 20.0, FarmRefs(0, rated), record=lambda p, f: p.shaft_torque().copy()))
    torque0 = before[-500:].mean(axis=0)
    derated = rated.copy()
    derated[4] = 0.75 * P.rated_power
    rec = _run(
        plant,
        90.0,
        FarmRefs(1, derated, hold_torque=hold),
        record=lambda p, f: (p.shaft_torque().copy(), p.turbines.x[:, 1].copy(), p.power_output().copy()),
    )
    torque = np.array([r[0] for r in rec])
    omega = np.array([r[1] for r in rec])[-1000:, 4].mean()
    power = np.array([r[2] for r in rec])[-1000:, 4].mean()
    tau_hold = plant.controller.tau_hold[4]
    torque_g = tau_hold - P.B_g * omega
    assert derated[4] == pytest.approx(P.eta_gc * torque_g * omega, rel=0.01)  # ω_set from P_r = η_gc (S − B_g ω) ω
    assert omega < 0.8 * P.omega_nom
    assert power == pytest.approx(derated[4], rel=0.01)
    # the shaft torque never leaves the band of its working level (a derating at constant speed would lose 40 %)
    assert np.abs(torque[:, 4] / torque0[4] - 1.0).max() < 0.1
    assert torque[-1000:, 4].mean() == pytest.approx(torque0[4], rel=0.02)
    assert omega > MIN_SPEED_FRACTION * P.omega_nom
    others = np.array([r[1] for r in rec])[-1000:, [0, 1, 2, 3, 5, 6, 7, 8]].mean(axis=0)
    assert others == pytest.approx(P.omega_nom, rel=0.01)  # the others keep rated speed
    # release: the flag clears, the set point climbs back at SPEED_SLEW with the torque still held
    rec = _run(plant, 60.0, FarmRefs(2, rated), record=lambda p, f: (p.turbines.x[4, 1], p.controller.hold[4]))
    speed = np.array([r[0] for r in rec])
    held = np.array([r[1] for r in rec])
    climb = (P.omega_nom - omega) / (SPEED_SLEW * P.omega_nom)  # s
    assert held[: int(0.8 * climb / plant.dt)].all() and not held[-1]
    assert speed[-500:].mean() == pytest.approx(P.omega_nom, rel=0.01)


def test_a_hold_the_rotor_cannot_keep_settles_in_zone_0_instead_of_sliding_down_the_cq_curve():
    """At 16 m/s the rotor cannot make its full torque at 55 % of Ω_nom (λ ≈ 3.3): it falls into zone 0, where the
    held torque is let go with (ω_g/ω_b)⁶, and settles there (the dispatch's speed floor is there to avoid this)."""
    plant = FarmBatch(farm_spec(1, coherent_ti=0.0), wind(16.0, ti=0.005), [], seed=2, duration_s=120.0)
    hold = np.zeros(plant.n, dtype=bool)
    hold[4] = True
    derated = np.full(plant.n, P.rated_power)
    derated[4] = 0.6 * P.rated_power
    _run(plant, 5.0, FarmRefs(0, np.full(plant.n, P.rated_power)))
    _run(plant, 75.0, FarmRefs(1, derated, hold_torque=hold))
    rec = _run(plant, 20.0, FarmRefs(1, derated, hold_torque=hold), record=lambda p, f: p.turbines.x[4, 1])
    c = plant.controller
    assert c.hold[4] and c.zone[4] == 0
    speed = np.array(rec)
    assert abs(speed[-100:].mean() - speed[:100].mean()) < 0.01 * speed.mean()  # settled, not sliding
    assert speed.mean() > 0.7 * c.setpoint[4]


def test_fault_free_twins_see_the_same_wind_and_noise():
    """Twins draw the same numbers; matrix products over different rows may round differently in the last bit
    (as for any batch, tests/test_turbine_plant.py), and the dynamics do not amplify that."""
    plant = FarmBatch(farm_spec(2), wind(10.0), [], seed=4, duration_s=20.0, runs=(3,), fault_free_twins=True)
    rec = _run(plant, 20.0, record=lambda p, f: f.turbines.sensors.copy())
    y = np.array(rec)
    assert np.allclose(y[:, :9], y[:, 9:], rtol=1e-9, atol=1e-9)
    assert not np.array_equal(y[:, 0], y[:, 1])  # turbines differ from each other
