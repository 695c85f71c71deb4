"""Physics of the benchmark turbine simulator: closed-form checks, invariants and two implementations agreeing."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from plant_sim.turbine import TurbineBatch
from plant_sim.turbine.controller import BenchmarkController
from plant_sim.turbine.dynamics import (
    OMEGA_G,
    OMEGA_R,
    PITCH,
    THETA,
    TurbineDynamics,
    mechanical_matrices,
)
from plant_sim.turbine.trim import power_curve, trim
from wwcore.channels import SENSOR_INDEX, SENSOR_NAMES, SENSORS, noise_std
from wwcore.scenario import FaultSpec, WindSpec
from wwcore.scenario.turbine import TurbinePlant
from wwcore.turbine_frames import TurbineRefs
from wwcore.turbine_params import BENCHMARK as P

STEADY = WindSpec(mean=[(0.0, 9.0)], turbulence_intensity=0.0, shear_exponent=0.0, tower_shadow=False)


def steady(speed: float) -> WindSpec:
    return STEADY.model_copy(update={"mean": [(0.0, speed)]})


def run(plant: TurbineBatch, seconds: float, refs=None) -> list:
    frames = []
    for _ in range(round(seconds / plant.dt)):
        frames.append(plant.measure())
        plant.control(refs)
        plant.advance()
    return frames


def test_drivetrain_eigenfrequency_is_4_5_hz():
    A, _ = mechanical_matrices(P, np.array([P.eta_dt]), np.ones(1), np.ones(1))
    freqs = np.abs(np.linalg.eigvals(A[0]).imag) / (2 * np.pi)
    # the undamped two-mass formula ignores η_dt, which softens the generator side by 3 %
    assert freqs.max() == pytest.approx(P.drivetrain_eigenfrequency_hz, rel=0.02)
    assert 4.4 < freqs.max() < 4.7  # PARAMETERS.md a.1: ≈ 4.5 Hz


def test_power_curve_reaches_rated_power_near_12_mps():
    winds = np.array([5.0, 8.0, 10.0, 11.0, 12.0, 12.5, 13.5, 18.0, 24.0])
    power = power_curve(P, winds)
    assert np.all(np.diff(power) >= -1.0), "power must not fall with wind"
    assert power[0] < 1.0e6 and power[3] < 0.7 * P.rated_power
    assert power[-3:] == pytest.approx(P.rated_power, rel=1e-6)

    def rated_wind(params) -> float:
        fine = np.arange(11.0, 14.0, 0.02)
        return float(fine[np.argmax(power_curve(params, fine) >= 0.999 * params.rated_power)])

    # Without generator friction the region-2 law (K_opt from C_p,max at λ_opt = 8) reaches P_r where
    # ½ρπR²C_p,max v³ η_dt η_gc = P_r: 12.03 m/s (PARAMETERS.md a.1).
    assert rated_wind(replace(P, B_g=0.0)) == pytest.approx(12.03, abs=0.1)
    # The benchmark's B_g = 45.6 N m s/rad dissipates 7.4 kN m at Ω_nom, a quarter of the rated torque, so the
    # rotor runs below λ_opt in region 2 and rated power arrives about 0.9 m/s later.
    assert 12.6 <= rated_wind(P) <= 13.2
    op = trim(P, 8.0)
    assert op.zone == 0 and 7.0 < op.omega_r * P.radius / 8.0 < 8.0


@pytest.mark.parametrize("speed", [8.0, 15.0])
def test_trimmed_operating_point_is_an_equilibrium_of_the_simulator(speed):
    plant = TurbineBatch(TurbinePlant(), steady(speed), [], seed=0)
    op = trim(P, speed)
    run(plant, 20.0)
    x = plant.x[0]
    assert x[OMEGA_R] == pytest.approx(op.omega_r, rel=2e-3)
    assert x[OMEGA_G] == pytest.approx(op.omega_g, rel=2e-3)
    assert plant.truth()["power"][0] == pytest.approx(op.power, rel=5e-3)
    assert x[PITCH].mean() == pytest.approx(op.pitch, abs=0.1)


def test_zone_switching_has_hysteresis():
    c = BenchmarkController(P, 1, P.rated_power)
    low_power = np.array([1e6])
    zones = []
    for omega in [150.0, 160.0, 162.5, 155.0, 148.0, 146.0, 150.0, 161.0]:
        c.step(0, np.array([omega]), low_power, None)
        zones.append(int(c.zone[0]))
    # up at Ω_nom = 162, down only below Ω_nom − Ω_Δ = 147, up again only at 162
    assert zones == [0, 0, 1, 1, 1, 0, 0, 0]
    c.step(0, np.array([150.0]), np.array([P.rated_power]), None)
    assert c.zone[0] == 1, "P_g ≥ P_r also switches to region 3"


def test_exact_step_agrees_with_fine_runge_kutta_of_the_continuous_model():
    """Two implementations: the plant's exact ZOH step vs RK4 at Ts/50 of the continuous model (τ_r re-evaluated)."""
    wind = WindSpec(mean=[(0.0, 14.0)], turbulence_intensity=0.0, shear_exponent=0.0, tower_shadow=False)
    plant = TurbineBatch(TurbinePlant(), wind, [], seed=0)
    plant.x[:, OMEGA_R] *= 1.02  # start off equilibrium so everything moves
    plant.x[:, THETA] *= 1.1
    x_fine = plant.x.copy()
    dyn = TurbineDynamics(P)
    theta_exact, theta_fine = [], []
    for _ in range(300):
        frame = plant.measure()
        plant.control(None)
        blades, pitch_ref = plant._wind_sample.blades, plant.controller.beta_ref[:, None] + plant._pitch_error
        tau_ref = plant.controller.tau_g_ref
        h = plant.dt / 50
        for _ in range(50):
            k1 = dyn.derivative(x_fine, tau_ref, pitch_ref, blades, plant.faults)
            k2 = dyn.derivative(x_fine + 0.5 * h * k1, tau_ref, pitch_ref, blades, plant.faults)
            k3 = dyn.derivative(x_fine + 0.5 * h * k2, tau_ref, pitch_ref, blades, plant.faults)
            k4 = dyn.derivative(x_fine + h * k3, tau_ref, pitch_ref, blades, plant.faults)
            x_fine = x_fine + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        plant.advance()
        theta_exact.append(plant.x[0, THETA])
        theta_fine.append(x_fine[0, THETA])
        del frame
    # holding τ_r over 10 ms (the plant) vs re-evaluating it continuously (fine RK4): 3 s apart by < 3e-4
    assert plant.x[0, OMEGA_R] == pytest.approx(x_fine[0, OMEGA_R], rel=3e-4)
    assert plant.x[0, OMEGA_G] == pytest.approx(x_fine[0, OMEGA_G], rel=3e-4)
    # the torsion (4.5 Hz, barely damped): same mean and same oscillation over the last second
    a, b = np.array(theta_exact[-100:]), np.array(theta_fine[-100:])
    assert a.mean() == pytest.approx(b.mean(), rel=2e-3)
    assert a.std() == pytest.approx(b.std(), rel=0.05)


def test_sensor_noise_follows_the_convention():
    truth_of = {"omega_g_m1": "omega_g", "omega_r_m2": "omega_r", "tau_g_m": "tau_g", "v_hub_m": "wind_hub"}
    for convention in ("sigma", "variance"):
        plant = TurbineBatch(TurbinePlant(noise_convention=convention), WindSpec(mean=[(0.0, 10.0)]), [], seed=3)
        errors = {name: [] for name in truth_of}
        for _ in range(3000):
            frame = plant.measure()
            truth = plant.truth()
            for name, key in truth_of.items():
                errors[name].append(frame.sensors[0, SENSOR_INDEX[name]] - truth[key][0])
            plant.control(None)
            plant.advance()
        for name in truth_of:
            channel = SENSORS[SENSOR_INDEX[name]]
            e = np.array(errors[name])
            assert e.std() == pytest.approx(noise_std(channel, convention), rel=0.06), (convention, name)
            assert e.mean() == pytest.approx(channel.noise_mean, abs=4 * e.std() / np.sqrt(len(e)) + 1e-9)


SENSOR_FAULTS = [
    ("omega_r_m1", "fixed", 1.4),
    ("omega_r_m2", "gain", 1.1),
    ("omega_g_m1", "offset", 5.0),
    ("omega_g_m2", "drift", 2.0),
    ("beta_2_m1", "stuck", None),
    ("tau_g_m", "noise", 20.0),
    ("v_hub_m", "offset", 3.0),
    ("p_g_m", "gain", 0.5),
]


@pytest.mark.parametrize(("channel", "kind", "value"), SENSOR_FAULTS)
def test_each_sensor_fault_changes_exactly_its_channel(channel, kind, value):
    fault = FaultSpec(target=channel, kind=kind, value=value, start_s=1.0, end_s=3.0)
    clean = TurbineBatch(TurbinePlant(), steady(13.0), [], seed=5)
    faulty = TurbineBatch(TurbinePlant(), steady(13.0), [fault], seed=5)
    a, b = run(clean, 1.5), run(faulty, 1.5)
    first = round(1.0 / clean.dt) + (1 if kind == "drift" else 0)  # a drift starts from zero
    diff = a[first].sensors[0] != b[first].sensors[0]
    assert list(np.array(SENSOR_NAMES)[diff]) == [channel]
    assert all(np.array_equal(a[i].sensors, b[i].sensors) for i in range(first if kind != "drift" else first - 1))
    events = faulty.drain_events()
    assert [(e.type.value, e.target, e.t) for e in events] == [("fault_injected", channel, 1.0)]


def test_pitch_sensor_errors_reach_the_true_pitch_with_the_benchmarks_sign():
    """β_i,f = mean measurement error of blade i is added to its actuator's reference (PARAMETERS.md a.2)."""
    fault = FaultSpec(target="beta_1_m1", kind="fixed", value=5.0, start_s=1.0)
    plant = TurbineBatch(TurbinePlant(), steady(16.0), [fault], seed=4)
    run(plant, 20.0)
    # steady state: β = ref + (5 + β)/2 − β  ⇒  β = (2 ref + 5)/3, blades 2 and 3 stay at ref
    beta = plant.x[0, PITCH]
    assert beta[0] == pytest.approx((2 * plant.controller.beta_ref[0] + 5.0) / 3.0, abs=0.3)
    assert beta[1] == pytest.approx(plant.controller.beta_ref[0], abs=0.3)
    assert beta[1] - beta[0] == pytest.approx((plant.controller.beta_ref[0] - 5.0) / 3.0, abs=0.3)


def test_fixed_and_stuck_faults_carry_no_noise_and_end_on_time():
    faults = [
        FaultSpec(target="omega_g_m1", kind="fixed", value=140.0, start_s=1.0, end_s=2.0),
        FaultSpec(target="omega_g_m2", kind="stuck", start_s=1.0, end_s=2.0),
    ]
    plant = TurbineBatch(TurbinePlant(), steady(9.0), faults, seed=1)
    y = np.array([f.sensors[0] for f in run(plant, 2.5)])
    g1, g2 = y[:, SENSOR_INDEX["omega_g_m1"]], y[:, SENSOR_INDEX["omega_g_m2"]]
    assert np.all(g1[100:200] == 140.0) and g1[200] != 140.0
    assert np.all(g2[100:200] == g2[99]) and g2[200] != g2[99]
    assert [e.type.value for e in plant.drain_events()] == ["fault_injected"] * 2 + ["fault_cleared"] * 2


@pytest.mark.parametrize(
    ("fault", "truth_key"),
    [
        (FaultSpec(target="pitch_actuator_1", kind="pitch_offset", value=2.0, start_s=0.5), "tau_aero"),
        (FaultSpec(target="converter", kind="torque_offset", value=1000.0, start_s=0.5), "tau_g"),
        (FaultSpec(target="drivetrain", kind="efficiency", value=0.8, start_s=0.5), "omega_g"),
    ],
)
def test_actuator_and_system_faults_act_on_the_plant_not_the_sensors(fault, truth_key):
    clean = TurbineBatch(TurbinePlant(), steady(14.0), [], seed=2)
    faulty = TurbineBatch(TurbinePlant(), steady(14.0), [fault], seed=2)
    a, b = run(clean, 0.51), run(faulty, 0.51)
    assert np.array_equal(a[-1].sensors, b[-1].sensors), "the first faulty tick's readings are unchanged"
    run(clean, 1.0)
    run(faulty, 1.0)
    assert not np.allclose(clean.truth()[truth_key], faulty.truth()[truth_key], rtol=1e-6)


def test_pitch_dynamics_fault_slows_the_actuator():
    fast = TurbineBatch(TurbinePlant(), steady(15.0), [], seed=0)
    slow_fault = FaultSpec(target="pitch_actuator_3", kind="pitch_dynamics", omega_n=3.42, zeta=0.9, start_s=0.0)
    slow = TurbineBatch(TurbinePlant(), steady(15.0), [slow_fault], seed=0)
    for plant in (fast, slow):
        plant.measure()
        plant.controller.beta_ref[:] += 5.0  # a 5 deg step on every actuator
        plant.advance()
        for _ in range(29):
            plant.measure()
            plant.advance()
    assert abs(fast.x[0, PITCH[2]] - fast.x[0, PITCH[0]]) < 0.2  # only the pitch-sensor noise tells them apart
    assert slow.x[0, PITCH[2]] < fast.x[0, PITCH[2]] - 1.0  # blade 3 lags after 0.3 s
    assert abs(slow.x[0, PITCH[0]] - fast.x[0, PITCH[0]]) < 0.2  # and the other blades do not


def test_ramped_fault_follows_its_ramp():
    fault = FaultSpec(target="converter", kind="torque_offset", value=1000.0, start_s=1.0, end_s=9.0, ramp_s=3.0)
    assert [fault.intensity(t) for t in (0.5, 1.0, 2.5, 4.0, 6.0, 7.5, 9.0)] == pytest.approx(
        [0.0, 0.0, 0.5, 1.0, 1.0, 0.5, 0.0]
    )
    plant = TurbineBatch(TurbinePlant(), steady(9.0), [fault], seed=0)
    seen = []
    for _ in range(1000):
        plant.measure()
        plant.control(None)
        seen.append(plant.faults.torque_offset[0])
        plant.advance()
    assert seen[250] == pytest.approx(500.0, rel=0.01) and seen[500] == 1000.0 and seen[999] == 0.0


def test_rows_do_not_depend_on_the_batch():
    """A run's random streams depend only on (seed, run); matrix products over different batch sizes may round
    differently in the last bit, so rows agree to rounding, not bit for bit."""
    wind = WindSpec(mean=[(0.0, 11.0)])
    fault = [FaultSpec(target="omega_r_m1", kind="gain", value=1.1, start_s=0.5)]
    alone = TurbineBatch(TurbinePlant(), wind, fault, seed=9, runs=[2])
    batch = TurbineBatch(TurbinePlant(), wind, fault, seed=9, runs=[0, 1, 2, 3])
    ya, yb = run(alone, 2.0), run(batch, 2.0)
    assert all(np.allclose(fa.sensors[0], fb.sensors[2], rtol=1e-9, atol=0) for fa, fb in zip(ya, yb, strict=True))


def test_controller_uses_fresh_estimates_and_falls_back_when_stale():
    c = BenchmarkController(P, 2, P.rated_power)
    refs = TurbineRefs(
        tick=10, valid=np.array([True, False]), omega_g=np.array([170.0, 170.0]), omega_r=np.zeros(2), wind=np.zeros(2)
    )
    c.step(11, np.array([100.0, 100.0]), np.array([1e6, 1e6]), refs)
    assert list(c.using_estimates) == [True, False]
    assert c.zone[0] == 1 and c.zone[1] == 0, "the estimate (170 rad/s > Ω_nom) drives row 0 only"
    c2 = BenchmarkController(P, 2, P.rated_power)
    c2.step(11 + c2.max_ref_age + 1, np.array([100.0, 100.0]), np.array([1e6, 1e6]), refs)
    assert not c2.using_estimates.any() and not c2.zone.any(), "stale references are ignored"


def test_the_controller_keeps_its_own_estimate_flags_in_place():
    """Fresh references' ``valid`` is copied into the controller's own ``using_estimates`` array (in place, as stale
    references clear it): the array is the same object from tick to tick, and it does not follow ``refs.valid``."""
    c = BenchmarkController(P, 2, P.rated_power)
    own = c.using_estimates
    valid = np.array([True, False])
    refs = TurbineRefs(tick=10, valid=valid, omega_g=np.full(2, 170.0), omega_r=np.zeros(2), wind=np.zeros(2))
    c.step(11, np.array([100.0, 100.0]), np.array([1e6, 1e6]), refs)
    assert c.using_estimates is own and list(own) == [True, False]
    valid[:] = False
    assert list(c.using_estimates) == [True, False], "the controller's flags are its own, not a view of refs.valid"
    c.step(11 + c.max_ref_age + 1, np.array([100.0, 100.0]), np.array([1e6, 1e6]), refs)
    assert c.using_estimates is own and not own.any()


@pytest.mark.parametrize("runs", [[0], [0, 1]])
@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_a_frame_kept_past_its_tick_holds_its_own_values(backend, runs):
    """A frame kept while the plant runs on (a sensor fault starting and ending meanwhile) keeps the readings and the
    controller outputs it was built with: every tick's frame is new arrays, its time k·dt."""
    wind = WindSpec(mean=[(0.0, 14.0)])
    fault = [FaultSpec(target="omega_g_m1", kind="offset", value=5.0, start_s=0.2, end_s=0.4)]
    plant = TurbineBatch(TurbinePlant(), wind, fault, seed=86400, runs=runs, backend=backend)
    frames, copies = [], []
    for _ in range(60):
        frame = plant.measure()
        frames.append(frame)
        copies.append([a.copy() for a in (frame.sensors, frame.tau_g_ref, frame.beta_ref, frame.power_ref, frame.zone)])
        plant.control(None)
        plant.advance()
    for k, (frame, kept) in enumerate(zip(frames, copies, strict=True)):
        assert frame.k == k and frame.t == k * plant.dt
        arrays = (frame.sensors, frame.tau_g_ref, frame.beta_ref, frame.power_ref, frame.zone)
        assert all(np.array_equal(a, b) for a, b in zip(arrays, kept, strict=True))
    assert not np.shares_memory(frames[0].tau_g_ref, plant.controller.tau_g_ref)
