"""Observer 5-pe: the rotor-speed sensors plus the power-speed channel P_g,m / (η_gc τ_g,m), the estimate used
when both generator-speed sensors are flagged (one design per torque band)."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from plant_sim.turbine import TurbineBatch
from service.turbine.bank import GENERATOR, POWER_SPEED, ObserverBank, power_speed_estimate_observers
from service.turbine.interfaces import (
    POWER_SPEED_DESIGN_TORQUES,
    POWER_SPEED_DETECTOR_DESIGNS,
    POWER_SPEED_MIN_TORQUE,
    POWER_SPEED_REGION1_BAND,
    POWER_SPEED_REGION3_BAND,
    TurbineContext,
    power_speed,
    power_speed_band,
    power_speed_sigma,
)
from service.turbine.supervisor import TurbineSupervisor
from wwcore.channels import SENSORS, SPEED_SENSORS, noise_std
from wwcore.scenario.loader import parse_scenario
from wwcore.turbine_params import BENCHMARK as P

DESIGN = TurbineContext(P, 1).bank_design
PE = DESIGN.power_speed


def test_power_speed_inverts_the_electrical_power_and_falls_back_at_low_torque():
    omega_g = np.array([120.0, 150.0, 90.0])
    torque = np.array([2.0e4, 3.1e4, 100.0])  # the last one below POWER_SPEED_MIN_TORQUE × rated
    speed = np.column_stack([omega_g / P.N_g, omega_g / P.N_g + 0.02, omega_g, omega_g])
    power = P.eta_gc * omega_g * torque
    out = power_speed(power, torque, speed, P)
    np.testing.assert_allclose(out[:2], omega_g[:2], rtol=1e-12)
    assert out[2] == pytest.approx(P.N_g * (omega_g[2] / P.N_g + 0.01), rel=1e-12)


def test_power_speed_design_noise_is_the_first_order_propagation():
    sigma = {c.name: noise_std(c, "sigma") for c in SENSORS}
    torque = 0.5 * P.rated_torque
    omega_g = P.omega_nom * np.sqrt(0.5)
    rel = np.sqrt((sigma["p_g_m"] / (P.eta_gc * omega_g * torque)) ** 2 + (sigma["tau_g_m"] / torque) ** 2)
    assert power_speed_sigma(sigma, P, 0.5) == pytest.approx(omega_g * rel, rel=1e-12)
    # 2.5× better than one rotor-speed sensor referred to the generator: the reason the channel exists
    assert power_speed_sigma(sigma, P, 0.5) < sigma["omega_r_m1"] * P.N_g / 2.5
    # the channel gets better as the torque rises (τ_g,m's noise is fixed in N m)
    designs = [power_speed_sigma(sigma, P, t) for t in POWER_SPEED_DESIGN_TORQUES]
    assert designs == sorted(designs, reverse=True)


def test_each_torque_picks_the_design_nearest_it_on_a_log_scale():
    designs = np.array(POWER_SPEED_DESIGN_TORQUES)
    np.testing.assert_array_equal(power_speed_band(designs * P.rated_torque, P), np.arange(len(designs)))
    edges = np.sqrt(designs[:-1] * designs[1:]) * P.rated_torque
    np.testing.assert_array_equal(power_speed_band(edges * 0.999, P), np.arange(len(edges)))
    np.testing.assert_array_equal(power_speed_band(edges * 1.001, P), np.arange(1, len(designs)))
    low = POWER_SPEED_MIN_TORQUE * P.rated_torque
    last = len(designs) - 1
    assert power_speed_band(np.array([low, 2.0 * P.rated_torque, np.nan]), P).tolist() == [0, last, last]
    # in region 3 (zone 1) the band after the design bands, whatever the torque above region 1's
    zone = np.array([0, 1, 1])
    torque = np.array([0.1, 0.1, 1.0]) * P.rated_torque
    assert power_speed_band(torque, P, zone).tolist() == [0, len(designs), len(designs)]
    # region 1: the torque reference below the power-speed channel's threshold, in either zone
    below = np.array([0.0, 0.999 * low, 0.999 * low])
    assert power_speed_band(below, P, np.array([0, 0, 1])).tolist() == [POWER_SPEED_REGION1_BAND] * 3
    assert (len(designs), len(designs) + 1) == (POWER_SPEED_REGION3_BAND, POWER_SPEED_REGION1_BAND)


def test_the_selection_table_names_the_observer_of_every_band():
    """With both generator-speed sensors distrusted the estimate comes from the observer of the torque band: each
    5-pe design in its own band, observer 5 in region 1 (the channel there is the rotor-speed sensors' mean); the
    detector keeps 5-pe15 there. ``power_speed = false``: no table, observer 5 everywhere."""
    names = [DESIGN.names[j] for j in power_speed_estimate_observers(DESIGN)]
    assert names == ["5-pe15", "5-pe35", "5-pe80", "5-pe-r3", "5"]
    assert [DESIGN.names[PE[d]] for d in POWER_SPEED_DETECTOR_DESIGNS] == [
        "5-pe15",
        "5-pe35",
        "5-pe80",
        "5-pe-r3",
        "5-pe15",
    ]
    assert len(power_speed_estimate_observers(DESIGN, power_speed=False)) == 0


def test_observers_5pe_read_no_generator_speed_sensor():
    assert [DESIGN.names[j] for j in PE] == ["5-pe15", "5-pe35", "5-pe80", "5-pe-r3"]
    assert [DESIGN.observers[j].kind for j in PE] == ["kalman", "kalman", "kalman", "rigid"]
    assert min(PE) >= DESIGN.n_isolating and DESIGN.reference == len(DESIGN.names) - 1
    generator = [DESIGN.inputs.index(s) for s in GENERATOR]
    for j in PE:
        assert DESIGN.observers[j].sensors == ("omega_r_m1", "omega_r_m2", POWER_SPEED)
        block = slice(DESIGN.offsets[j], DESIGN.offsets[j] + DESIGN.observers[j].n_states)
        for gains in (DESIGN.K_blk, DESIGN.H_blk, *DESIGN.K_transient):
            assert not gains[block][:, generator].any()
    # invariant: whatever the generator-speed sensors read, observer 5-pe's states do not move
    rng = np.random.default_rng(3)
    y = np.tile([1.2, 1.2, 1.2 * P.N_g, 1.2 * P.N_g, 1.2 * P.N_g], (400, 1)) + 0.02 * rng.standard_normal((400, 5))
    wrecked = y.copy()
    wrecked[:, 2] = 140.0
    wrecked[:, 3] *= 0.9
    states = []
    for readings in (y, wrecked):
        bank = ObserverBank(DESIGN, 1)
        bank.initialise(np.array([[1.2, 1.2 * P.N_g, 1e-3, 2e4]]), readings[:1])
        for k in range(len(readings)):
            bank.step(readings[k : k + 1], np.array([2e4]))
        states.append(np.hstack([bank.states(j) for j in PE]))
    np.testing.assert_array_equal(states[0], states[1])


SHORT = """
name = "power-speed"
duration_s = 160.0
[plant]
kind = "turbine"
[wind]
mean = [[0.0, {start}], [160.0, {end}]]
turbulence_intensity = 0.12
"""


@pytest.mark.parametrize("power_speed_option", [True, False])
def test_both_generator_sensors_flagged_selects_5pe_unless_switched_off(power_speed_option):
    estimator = TurbineSupervisor(1, options={"power_speed": power_speed_option}).estimator
    both = sum(1 << SPEED_SENSORS.index(s) for s in GENERATOR)
    assert estimator.names[estimator.observer_of_mask[both]] == ("5-pe15" if power_speed_option else "5")
    five = DESIGN.index(frozenset(GENERATOR))
    assert list(estimator._observer_of_band) == ([*PE, five] if power_speed_option else [])
    # every other flag pattern keeps its observer of seed 000 (5-pe is never selected for anything else)
    others = np.delete(estimator.observer_of_mask, both)
    assert not set(PE) & set(others.tolist())


@pytest.mark.parametrize(
    ("start", "end", "bound"), [pytest.param(8.5, 10.0, 1.10, marks=pytest.mark.slow), (6.0, 6.5, 1.20)]
)
def test_5pe_wind_estimate_is_close_to_observer_1_and_better_than_observer_5(start, end, bound):
    """Fault-free closed loop, every observer's wind inverted from the same data: RMSE against the true wind
    (5-pe: the design the estimator would select at each tick's torque). At 6 m/s the torque is ~15 % of rated
    and the power-speed channel is ~1.8 % noisy, no better than the rotor-speed sensors: a looser bound."""
    scenario = parse_scenario(tomllib.loads(SHORT.format(start=start, end=end)))
    # 4 runs × 100 s after the settling minute: the 400 run-s of two 260-s runs in 62 % of the ticks (a tick of
    # 4 rows costs about what a tick of 2 does)
    plant = TurbineBatch(scenario.plant, scenario.wind, [], seed=11, runs=[0, 1, 2, 3])
    supervisor = TurbineSupervisor(plant.n)
    names = supervisor.estimator.names
    errors, refs = [], None
    for k in range(round(scenario.duration_s / plant.dt)):
        frame = plant.measure()
        plant.control(refs)
        refs = supervisor.step(frame)
        if k >= 6000 and k % 20 == 0:  # after a minute: observers and filters settled
            pe = np.array(PE)[np.array(POWER_SPEED_DETECTOR_DESIGNS)[power_speed_band(frame.tau_g_ref, P)]]
            columns = np.array([[names.index("1")] * plant.n, [names.index("5")] * plant.n, pe])
            wind = supervisor.estimator.recovery.wind(columns, np.tile(supervisor.estimates.wind, (3, 1)))
            errors.append(wind - plant.true_rotor_wind())
        plant.advance()
    rmse_1, rmse_5, rmse_pe = np.sqrt(np.mean(np.square(errors), axis=(0, 2)))
    print(f"wind RMSE observer 1 {rmse_1:.3f}, 5 {rmse_5:.3f}, 5-pe {rmse_pe:.3f} m/s")
    assert rmse_pe < rmse_5
    assert rmse_pe < bound * rmse_1
