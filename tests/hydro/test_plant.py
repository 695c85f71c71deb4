"""The plant under its baseline controller: speed holding, fault effects, integration step, events, API."""

from __future__ import annotations

import numpy as np
import pytest

from tests.hydro.conftest import offset, run_loop
from wwcore.events import EventType
from wwcore.hydro_params import NOMINAL as P


def test_generator_holds_its_speed_in_turbulent_wind(make_plant):
    out = run_loop(make_plant([], n=4, seed=11), None, 40.0)
    w_g = out["x"][:, :, 1]
    assert np.abs(w_g - P.omega_g_N).max() < 1.0
    assert np.sqrt(np.mean((w_g - P.omega_g_N) ** 2)) < 0.2
    w_r = out["x"][:, :, 0]
    assert w_r.min() > 0.5 and w_r.max() < P.omega_r_rated  # partial load, as Section 3.2 (0.7 … 1.2 rad/s)
    assert w_r.max() - w_r.min() > 0.1  # the wind is turbulent


def test_uncompensated_pump_fault_overspeeds_the_rotor(make_plant):
    faults = [offset("u_p", -0.2, 5.0, 35.0)]
    free = run_loop(make_plant([], n=4, seed=5), None, 40.0)
    faulty = run_loop(make_plant(faults, n=4, seed=5), None, 40.0)
    k = round(5.0 / P.dt)
    assert np.array_equal(free["x"][:k], faulty["x"][:k])  # twins share wind and noise
    excess = (faulty["x"][:, :, 0] - free["x"][:, :, 0]).max(axis=0)
    # the rotor runs away from its fault-free speed: 4–9 % of the rated speed within the 30 s of the fault
    assert np.all(excess > 0.04 * P.omega_r_rated) and excess.mean() > 0.05 * P.omega_r_rated
    dev = np.abs(faulty["x"][:, :, 1] - free["x"][:, :, 1]).max(axis=0)
    assert np.all(dev > 10.0)  # and the generator leaves ω_g,N by more than 10 rad/s before the PI recovers
    power = faulty["x"][:, :, 1] * faulty["x"][:, :, 3]
    power_free = free["x"][:, :, 1] * free["x"][:, :, 3]
    assert power[k + 1000 : k + 3000].mean() < power_free[k + 1000 : k + 3000].mean()  # and power drops


def test_rk4_step_is_adequate(make_plant):
    faults = [offset("u_M", -0.2, 2.0, None)]
    coarse = run_loop(make_plant(faults, n=2), None, 10.0)
    plant = make_plant(faults, n=2)
    plant.substeps = 10
    fine = run_loop(plant, None, 10.0)
    scale = np.array([1.0, P.omega_g_N, P.dp_rated, P.rated_generator_torque, 1.0, 1.0])
    assert np.abs((coarse["x"] - fine["x"]) / scale).max() < 1e-5


def test_fault_events_and_runtime_injection(make_plant):
    plant = make_plant([offset("u_p", -0.2, 0.05, 0.1, name="p")], n=2)
    run_loop(plant, None, 0.2)
    events = plant.drain_events()
    kinds = [(e.type, e.target, e.run, round(e.t, 2)) for e in events]
    assert (EventType.FAULT_INJECTED, "u_p", 0, 0.05) in kinds and (EventType.FAULT_INJECTED, "u_p", 1, 0.05) in kinds
    assert (EventType.FAULT_CLEARED, "u_p", 1, 0.1) in kinds
    assert events[0].detail["label"] == "p" and events[0].detail["value"] == -0.2
    plant.inject(offset("u_M", -0.1, plant.t, None, name="api"))
    run_loop(plant, None, 0.05)
    assert plant.truth()["f"][0].tolist() == pytest.approx([0.0, -0.1])
    plant.clear("api")
    run_loop(plant, None, 0.02)
    assert plant.truth()["f"][0].tolist() == [0.0, 0.0]
    types = [e.type for e in plant.drain_events()]
    assert types.count(EventType.FAULT_INJECTED) == 2 and types.count(EventType.FAULT_CLEARED) == 2
    with pytest.raises(ValueError):
        plant.inject(offset("u_M", -0.1, plant.t, None, name="api"))
    with pytest.raises(KeyError):
        plant.clear("nope")


def test_measurement_noise_level(make_plant):
    plant = make_plant([], n=2, noise_pct=2.0)
    ratios = []
    for _ in range(200):
        y = plant.measure().y
        ratios.append(y / plant.x[:, [0, 1, 3, 4, 5]] - 1.0)
        plant.control(None)
        plant.advance()
    r = np.array(ratios)
    assert np.abs(r).max() <= 0.02 and np.abs(r).max() > 0.019
