"""Plants that differ from the supervisor's design model (``[mismatch]``): ranges refused naming the field, the
physics against closed-form answers, the draws, and the supervisor never seeing any of it."""

from __future__ import annotations

import copy
import hashlib
import json
import math
import tomllib

import numpy as np
import pytest

from plant_sim.turbine import TurbineBatch
from plant_sim.turbine.dynamics import (
    N_STATES,
    OMEGA_R,
    PITCH,
    THETA,
    DiscreteStep,
    mechanical_matrices,
    plant_power_coefficient,
    plant_torque_coefficient,
    torsion_mode,
)
from plant_sim.turbine.faults import FaultState
from plant_sim.turbine.mismatch import resolve
from plant_sim.turbine.plant import _PICK
from windwarden.cli import main
from windwarden.evaluation import turbine as turbine_eval
from windwarden.evaluation.kinds import EvalOptions
from windwarden.kinds import RunInfo
from wwcore import aero
from wwcore.channels import SENSOR_INDEX, SENSORS, noise_std
from wwcore.scenario import Mismatch, ScenarioError, WindSpec, dump_scenario, load_scenario, parse_scenario
from wwcore.scenario.mismatch import LIMITS, SENSOR_BIAS_TOLERANCE
from wwcore.scenario.turbine import TurbinePlant
from wwcore.turbine_params import BENCHMARK as P

STEADY = WindSpec(mean=[(0.0, 9.0)], turbulence_intensity=0.0, shear_exponent=0.0, tower_shadow=False)
TURBINE = {"name": "t", "duration_s": 100.0, "plant": {"kind": "turbine"}}


def steady(speed: float) -> WindSpec:
    return STEADY.model_copy(update={"mean": [(0.0, speed)]})


def run(plant: TurbineBatch, seconds: float) -> list:
    frames = []
    for _ in range(round(seconds / plant.dt)):
        frames.append(plant.measure())
        plant.control(None)
        plant.advance()
    return frames


def refused(mismatch: dict, base: dict = TURBINE) -> list[tuple[str, str]]:
    with pytest.raises(ScenarioError) as caught:
        parse_scenario({**base, "mismatch": mismatch})
    return caught.value.problems


# ---- ranges: refused naming the field, before anything runs ---------------------------------------------------
@pytest.mark.parametrize("name", sorted(LIMITS))
def test_every_quantity_outside_its_range_is_refused_naming_the_field(name):
    limit = LIMITS[name]
    for value in (limit.lo - 0.01 * (limit.hi - limit.lo) - 1e-9, limit.hi * 1.01 + 1e-9, math.nan):
        problems = refused({name: value})
        assert [f for f, _ in problems] == [f"mismatch.{name}"], problems
        assert f"{limit.lo:g} … {limit.hi:g}" in problems[0][1]
    parse_scenario({**TURBINE, "mismatch": {name: limit.lo}})  # the bounds themselves are allowed
    parse_scenario({**TURBINE, "mismatch": {name: limit.hi}})


@pytest.mark.parametrize(
    ("mismatch", "field", "words"),
    [
        ({"cp_scale": 1.0, "spread": {"cp_scale": 0.1}}, "mismatch.cp_scale", "± spread 0.1 reaches"),
        ({"spread": {"air_density_kgm3": -0.1}}, "mismatch.spread.air_density_kgm3", "half-width ≥ 0"),
        ({"spread": {"sensor_bias_fraction": 1.5}}, "mismatch.spread.sensor_bias_fraction", "above 1"),
        ({"sensor_bias": {"omega_g_m1": 0.06}}, "mismatch.sensor_bias.omega_g_m1", "tolerance ± 0.05 rad/s"),
        ({"sensor_bias": {"omega_x": 0.0}}, "mismatch.sensor_bias.omega_x", "unknown sensor"),
        (
            {"sensor_bias": {"v_hub_m": 0.4}, "spread": {"sensor_bias_fraction": 0.5}},
            "mismatch.sensor_bias.v_hub_m",
            "tolerance",
        ),
        ({"sensor_noise_scale": {"p_g_m": 5.0}}, "mismatch.sensor_noise_scale.p_g_m", "0.5 … 3"),
        ({"turbines": [{"turbine": 2, "cp_scale": 0.9}]}, "mismatch.turbines[0].turbine", "does not exist"),
        ({"turbines": [{"turbine": 1, "cp_scale": 0.5}]}, "mismatch.turbines[0].cp_scale", "0.75 … 1.05"),
        ({"rho": 1.2}, "mismatch.rho", "unknown key"),
        ({"spread": {"cp": 0.1}}, "mismatch.spread.cp", "unknown key"),
    ],
)
def test_bad_mismatch_sections_are_refused_naming_the_field(mismatch, field, words):
    problems = refused(mismatch)
    assert field in [f for f, _ in problems], problems
    assert words in " ".join(m for _, m in problems)


def test_the_hydrostatic_plant_refuses_a_mismatch_section():
    problems = refused({"cp_scale": 0.9}, {"name": "h", "duration_s": 10.0, "plant": {"kind": "hydro"}})
    assert problems[0][0] == "mismatch" and "leak_factor" in problems[0][1]


def test_cli_refuses_a_bad_mismatch_with_exit_code_2_before_running(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "bad"\nduration_s = 100.0\n[plant]\nkind = "turbine"\n[mismatch]\nair_density_kgm3 = 2.0\n')
    out = tmp_path / "out"
    assert main(["eval", str(bad), "--runs", "1", "--out", str(out)]) == 2
    assert not out.exists()
    err = capsys.readouterr().err
    assert "mismatch.air_density_kgm3" in err and "0.9 … 1.45 kg/m³" in err


def test_a_mismatch_section_round_trips_through_toml():
    data = {
        **TURBINE,
        "mismatch": {
            "cp_scale": 0.95,
            "sensor_bias": {"omega_r_m1": 0.01},
            "spread": {"pitch_zeta": 0.05},
            "turbines": [{"turbine": 1, "tsr_shift": -0.2}],
        },
    }
    scenario = parse_scenario(data)
    assert parse_scenario(tomllib.loads(dump_scenario(scenario))) == scenario


# ---- physics against closed-form answers -----------------------------------------------------------------------
def _batch(mismatch: dict | None, wind: WindSpec = STEADY, seed: int = 1, runs=(0,), **kw) -> TurbineBatch:
    spec = None if mismatch is None else Mismatch.model_validate(mismatch)
    return TurbineBatch(TurbinePlant(), wind, [], seed=seed, runs=list(runs), mismatch=spec, **kw)


def test_air_density_scales_the_aerodynamic_torque_by_rho_over_rho0_at_a_fixed_operating_point():
    wind = STEADY.model_copy(update={"turbulence_intensity": 0.1, "tower_shadow": True, "shear_exponent": 0.1})
    design, plant = _batch(None, wind), _batch({"air_density_kgm3": 1.40}, wind)
    for _ in range(50):  # same wind, a state of its own; then the plant is put at the design run's state
        design.measure(), design.control(None), design.advance()
        plant.measure(), plant.control(None), plant.advance()
    plant.x = design.x.copy()
    design.measure(), plant.measure()
    np.testing.assert_allclose(plant.blade_torque, design.blade_torque * (1.40 / 1.225), rtol=1e-13)


def test_the_surface_error_gives_the_stated_cp_at_the_shifted_tip_speed_ratio():
    s, shift = 0.9, -0.4
    lam = np.linspace(2.0, 12.0, 201)
    for pitch in (-1.0, 0.0, 4.0, 12.0):
        cp_plant = plant_torque_coefficient(lam, pitch, shift) * lam * s
        np.testing.assert_allclose(cp_plant, s * aero.power_coefficient(lam - shift, pitch), rtol=1e-14)
        np.testing.assert_allclose(cp_plant, plant_power_coefficient(lam, pitch, s, shift), rtol=1e-14)
    fine = np.linspace(6.0, 10.0, 4001)
    design_cp = aero.power_coefficient(fine, 0.0)
    plant_cp = plant_power_coefficient(fine, 0.0, s, shift)
    assert plant_cp.max() == pytest.approx(s * design_cp.max(), rel=1e-6)
    assert fine[plant_cp.argmax()] == pytest.approx(fine[design_cp.argmax()] + shift, abs=2e-3)
    # and the plant's torque is that surface: τ_r,i = s (ρπR³/6) C_p(λ − Δλ, β)/λ v² per blade
    plant = _batch({"cp_scale": s, "tsr_shift": shift})
    plant.measure()
    v, omega_r, beta = plant._wind_sample.blades[0], plant.x[0, OMEGA_R], plant.x[0, PITCH]
    tsr = omega_r * P.radius / v
    expected = s * P.rho * math.pi * P.radius**3 / 6.0 * aero.power_coefficient(tsr - shift, beta) / tsr * v * v
    np.testing.assert_allclose(plant.blade_torque[0], expected, rtol=1e-12)


def test_the_plant_starts_at_its_own_equilibrium():
    for mismatch in (
        {"cp_scale": 0.8, "tsr_shift": 0.6},
        {"air_density_kgm3": 0.95, "drivetrain_stiffness_factor": 0.75},
    ):
        for speed in (8.0, 15.0):
            plant = _batch(mismatch, steady(speed))
            start = plant.x[0].copy()
            run(plant, 5.0)
            assert plant.x[0, OMEGA_R] == pytest.approx(start[OMEGA_R], rel=2e-3)
            assert plant.x[0, THETA] == pytest.approx(start[THETA], rel=5e-3)  # no torsion ringing from a wrong twist


def _torsion_frequency_hz(theta: np.ndarray, dt: float) -> float:
    """Frequency of the oscillation in ``theta`` from its interpolated zero crossings (mean removed)."""
    x = theta - theta.mean()
    i = np.flatnonzero(np.sign(x[:-1]) != np.sign(x[1:]))
    t = (i + x[i] / (x[i] - x[i + 1])) * dt
    return (len(t) - 1) / (2.0 * (t[-1] - t[0]))


def _ringing_hz(mismatch: dict | None) -> float:
    """Frequency (Hz) at which the simulated shaft rings after a 2 % twist kick, from θ_Δ's zero crossings."""
    plant = _batch(mismatch, steady(9.0))
    plant.x[:, THETA] *= 1.02
    theta = []
    for _ in range(400):
        plant.measure(), plant.control(None), plant.advance()
        theta.append(plant.x[0, THETA])
    x = np.array(theta) - np.mean(theta)
    i = np.flatnonzero(np.sign(x[:-1]) != np.sign(x[1:]))
    t = (i + x[i] / (x[i] - x[i + 1])) * P.dt
    return (len(t) - 1) / (2.0 * (t[-1] - t[0]))


@pytest.mark.parametrize("k", [0.75, 1.25])
def test_the_drivetrain_natural_frequency_moves_as_sqrt_k(k):
    assert torsion_mode(P, k, 1.0)[1] / torsion_mode(P, 1.0, 1.0)[1] == pytest.approx(math.sqrt(k), rel=1e-4)
    # in the simulated plant, under its controller and converter, the ringing frequency scales the same way
    assert _ringing_hz({"drivetrain_stiffness_factor": k}) / _ringing_hz(None) == pytest.approx(math.sqrt(k), rel=3e-3)


def test_the_drivetrain_damping_ratio_is_the_stated_one():
    for zeta in (0.0025, 0.02, 0.05):
        for k in (0.7, 1.0, 1.3):
            plant = _batch({"drivetrain_damping_ratio": zeta, "drivetrain_stiffness_factor": k}, steady(9.0))
            f = plant.faults
            a, _ = mechanical_matrices(P, f.eta_dt[:1], f.stiffness_factor[:1], f.damping_factor[:1])
            poles = np.linalg.eigvals(a[0, :3, :3])
            mode = poles[np.argmax(np.abs(poles.imag))]
            assert -mode.real / abs(mode) == pytest.approx(zeta, rel=1e-6)
    assert resolve(None, P, 0, np.zeros(1), np.ones(1)).damping_factor[0] == 1.0  # unset: the benchmark's B_dt
    assert torsion_mode(P, 1.0, 1.0)[0] == pytest.approx(0.00195, rel=0.01)  # the design's: the friction's


@pytest.mark.parametrize(("omega_n", "zeta"), [(9.0, 0.5), (13.5, 0.75)])
def test_the_pitch_actuator_step_response_matches_the_stated_bandwidth(omega_n, zeta):
    plant = _batch({"pitch_omega_n_rads": omega_n, "pitch_zeta": zeta})
    step = DiscreteStep(P, 1)
    step.update(FaultState(1, P, plant.mismatch))
    x = np.zeros((1, N_STATES))
    t = np.arange(1, 301) * P.dt
    beta = []
    for _ in t:  # a 1-deg step on every blade's reference, zero-order held as the plant holds it (exact)
        x = step.step(x, np.zeros(1), np.zeros(1), np.ones((1, 3)))
        beta.append(x[0, PITCH])
    beta = np.array(beta)
    wd = omega_n * math.sqrt(1.0 - zeta**2)
    closed = 1.0 - np.exp(-zeta * omega_n * t) * (np.cos(wd * t) + zeta / math.sqrt(1.0 - zeta**2) * np.sin(wd * t))
    np.testing.assert_allclose(beta, np.repeat(closed[:, None], 3, axis=1), atol=1e-9)
    overshoot = beta[:, 0].max() - 1.0
    assert overshoot == pytest.approx(math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2)), rel=0.02)


def _noise(plant: TurbineBatch, ticks: int) -> np.ndarray:
    """Reading minus truth of every tick (n, ticks, sensors): the noise plus the bias."""
    out = []
    for _ in range(ticks):
        frame = plant.measure()
        out.append(frame.sensors - plant._quantities[:, _PICK])
        plant.control(None)
        plant.advance()
    return np.stack(out, axis=1)


def test_noise_scale_multiplies_the_measured_noise_std():
    design = _noise(_batch(None), 3000)
    plant = _noise(_batch({"noise_scale": 2.0, "sensor_noise_scale": {"omega_g_m1": 0.5}}), 3000)
    mean = np.array([c.noise_mean for c in SENSORS])
    scale = np.full(len(SENSORS), 2.0)
    scale[SENSOR_INDEX["omega_g_m1"]] = 0.5
    # the same noise streams: every draw is the design's times the scale
    np.testing.assert_allclose(plant - mean, (design - mean) * scale, rtol=1e-9, atol=1e-9)
    sigma = np.array([noise_std(c, "sigma") for c in SENSORS])
    np.testing.assert_allclose(plant[0].std(axis=0), sigma * scale, rtol=0.05)


def test_a_calibration_bias_shows_as_a_mean_offset():
    bias = {"omega_r_m2": 0.02, "omega_g_m1": -0.04, "beta_2_m1": 0.15, "p_g_m": -20e3, "v_hub_m": 0.3}
    offset = _noise(_batch({"sensor_bias": bias}), 4000)[0].mean(axis=0)
    mean = np.array([c.noise_mean for c in SENSORS])
    sigma = np.array([noise_std(c, "sigma") for c in SENSORS])
    expected = mean.copy()
    for name, b in bias.items():
        expected[SENSOR_INDEX[name]] += b
    assert np.all(np.abs(offset - expected) <= 5 * sigma / math.sqrt(4000)), offset - expected


def test_draws_stay_within_their_spread_differ_by_run_and_leave_wind_and_noise_alone():
    spec = {
        "cp_scale": 0.95,
        "pitch_omega_n_rads": 11.0,
        "spread": {"cp_scale": 0.03, "pitch_omega_n_rads": 1.0, "sensor_bias_fraction": 0.5},
    }
    plant = _batch(spec, seed=5, runs=(0, 1, 2, 3), fault_free_twins=True)
    m = plant.mismatch
    assert np.all(np.abs(m.cp_scale - 0.95) <= 0.03) and len(np.unique(m.cp_scale[:4])) == 4
    np.testing.assert_array_equal(m.cp_scale[:4], m.cp_scale[4:])  # twins: the same plant
    assert np.all(np.abs(m.pitch_omega_n - 11.0) <= 1.0) and len(np.unique(m.pitch_omega_n[0])) == 3  # per blade
    tol = np.array([SENSOR_BIAS_TOLERANCE[c.name] for c in SENSORS])
    assert np.all(np.abs(m.bias) <= 0.5 * tol)
    again = _batch(spec, seed=5, runs=(2,))
    np.testing.assert_array_equal(again.mismatch.cp_scale, m.cp_scale[2:3])  # a run's draws are its own
    # the same wind and noise draws as the design model's runs
    design = _batch(None, seed=5, runs=(0, 1, 2, 3), fault_free_twins=True)
    np.testing.assert_array_equal(
        plant.wind.sample(0, plant.x[:, 4]).blades, design.wind.sample(0, plant.x[:, 4]).blades
    )
    changed = _batch({**spec, "spread": {**spec["spread"], "cp_scale": 0.01}}, seed=5, runs=(0, 1, 2, 3))
    np.testing.assert_array_equal(changed.mismatch.pitch_omega_n, m.pitch_omega_n[:4])  # one spread moves one field


# ---- the design model itself, bit for bit ----------------------------------------------------------------------
NOMINAL_VALUES = {
    "cp_scale": 1.0,
    "tsr_shift": 0.0,
    "air_density_kgm3": 1.225,
    "drivetrain_stiffness_factor": 1.0,
    "pitch_omega_n_rads": 11.11,
    "pitch_zeta": 0.6,
    "noise_scale": 1.0,
}


@pytest.mark.parametrize("mismatch", [{}, NOMINAL_VALUES])
def test_a_zero_mismatch_reproduces_the_design_plant_bit_for_bit(mismatch):
    wind = STEADY.model_copy(update={"turbulence_intensity": 0.12, "tower_shadow": True, "shear_exponent": 0.1})
    design, plant = _batch(None, wind, runs=(0, 1)), _batch(mismatch, wind, runs=(0, 1))
    a, b = run(design, 20.0), run(plant, 20.0)
    np.testing.assert_array_equal(design.x, plant.x)
    np.testing.assert_array_equal(np.stack([f.sensors for f in a]), np.stack([f.sensors for f in b]))


SHORT = {
    "name": "short",
    "duration_s": 40.0,
    "plant": {"kind": "turbine"},
    "wind": {"mean": [[0.0, 10.0], [40.0, 11.0]]},
    "faults": [{"target": "omega_r_m1", "kind": "gain", "value": 1.1, "start_s": 20.0, "end_s": 30.0}],
}


def _scorecard_hash(data: dict) -> str:
    card = turbine_eval.evaluate(parse_scenario(data), 2, 11, EvalOptions(workers=1, progress=False)).scorecard
    return hashlib.sha256(json.dumps(card, sort_keys=True).encode()).hexdigest()


def test_an_empty_mismatch_section_gives_the_same_scorecard():
    assert _scorecard_hash({**SHORT, "mismatch": {}}) == _scorecard_hash(SHORT)


# ---- the supervisor never sees the mismatch --------------------------------------------------------------------
def _with_mismatch(name: str) -> tuple:
    nominal = load_scenario(name)
    data = nominal.model_dump(mode="json", exclude_none=True)
    data["mismatch"] = {
        "cp_scale": 0.913,
        "air_density_kgm3": 1.171,
        "drivetrain_damping_ratio": 0.0123,
        "sensor_bias": {"omega_g_m1": 0.0371},
        "spread": {"tsr_shift": 0.11},
    }
    return nominal, parse_scenario(data)


@pytest.mark.parametrize("name", ["ftwse-2012", "farm-case1"])
def test_no_mismatch_value_reaches_the_live_supervisor(name):
    nominal, mismatched = _with_mismatch(name)
    live = RunInfo.of(mismatched, [1], 0.01).to_json()
    assert live == RunInfo.of(nominal, [1], 0.01).to_json()
    text = json.dumps(live)
    assert "mismatch" not in text and not any(v in text for v in ("0.913", "1.171", "0.0123", "0.0371"))


class _SeenError(Exception):
    pass


def test_no_mismatch_value_reaches_the_batch_supervisor(monkeypatch):
    """``windwarden eval`` builds the supervisor from exactly what it builds it from without the mismatch."""
    seen = []

    def spy(*args, **kwargs):
        seen.append(
            copy.deepcopy((args, {k: v for k, v in kwargs.items() if k not in ("run_of_row", "turbine_of_row")}))
        )
        raise _SeenError

    monkeypatch.setattr(turbine_eval, "TurbineSupervisor", spy)
    nominal, mismatched = _with_mismatch("ftwse-2012")
    for scenario in (nominal, mismatched):
        with pytest.raises(_SeenError):
            turbine_eval.simulate_chunk([0], lambda s: None, scenario, 3, "benchmark", "uio-bank", {})
    assert seen[0] == seen[1]
