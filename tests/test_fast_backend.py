"""The compiled backend (``wwcore.backend``, ``numba``) against the numpy reference: the same numbers, tick by tick
through every fault class and in the scorecard; the backend's choice, copies and imports. The kernels one by one:
``tests/test_fast_kernels.py``.

The kernels perform the reference's floating-point operations in its order and leave its matrix products to
numpy, so the comparison asks for equality within 1e-12 (relative, of each quantity's scale) and, in practice,
gets it to the last bit: the largest difference is printed by the assertion when it is not zero.
"""

from __future__ import annotations

import copy
import importlib.util
import json
import os
import pickle
import subprocess
import sys
import tomllib

import numpy as np
import pytest

from plant_sim.turbine import TurbineBatch
from service.turbine.supervisor import TurbineSupervisor
from tests.fast_compare import FAULTY, RTOL, SEED, assert_close, at_half_speed
from tests.live.helpers import TURBINE_SHORT
from windwarden.cli import EXIT_BAD_INPUT, main
from windwarden.evaluation.kinds import EvalOptions
from windwarden.kinds import kind_for
from wwcore import jit
from wwcore.backend import ENV_VAR, BackendError, available, fast_module, process_backend, resolve_backend
from wwcore.scenario import load_scenario, parse_scenario
from wwcore.turbine_params import BENCHMARK


def turbine_trace(scenario, backend: str, runs: list[int], ticks: int, every: int = 5) -> dict[str, np.ndarray]:
    """The plant state of every tick; the sensor frame, bank χ² and x̂, FDI ratios, CUSUM, estimates and refs of
    every ``every``-th tick (a difference in any of them reaches the state within a tick); the events."""
    plant = TurbineBatch(
        scenario.plant,
        scenario.wind,
        scenario.faults,
        seed=SEED,
        runs=runs,
        mismatch=scenario.mismatch,
        backend=backend,
    )
    supervisor = TurbineSupervisor(plant.n, noise_convention=scenario.plant.noise_convention, backend=backend)
    trace: dict[str, list] = {}
    refs = None
    for k in range(ticks):
        frame = plant.measure()
        plant.control(refs)
        refs = supervisor.step(frame)
        plant.advance()
        trace.setdefault("x", []).append(plant.x.copy())
        if k % every:
            continue
        fdi = supervisor.detector.fdi
        est = supervisor.estimates
        for name, value in {
            "sensors": frame.sensors,
            "tau_g_ref": frame.tau_g_ref,
            "beta_ref": frame.beta_ref,
            "zone": frame.zone,
            "chi2": supervisor.context._bank.chi2,
            "x_hat": supervisor.context._bank.x_hat,
            "ratio": fdi.ratio,
            "cusum": fdi.clearing.statistic,
            "actuator_test": supervisor.detector.components.actuator.total,
            "actuator_glr": supervisor.detector.components.actuator_glr,
            "converter_test": supervisor.detector.components.converter_statistic,
            "converter_clear": supervisor.detector.components.converter_clear_statistic,
            "converter_mean": supervisor.detector.components._converter_mean,
            # the generator-speed arbiter's sums and the learnt covariance of its onset prediction's errors
            "arbiter": [fdi.arbiter.total, fdi.arbiter.total_power, fdi.arbiter.jump],
            "onset_covariance": fdi.arbiter.jump_covariance,
            "parity_window": supervisor.detector.components.parity.total,
            "pitch_outlier": supervisor.detector.components.outlier.total,
            # the adaptive thresholds' learnt scales and offsets (``service.turbine.adaptive``)
            "chi2_scale": fdi.spread.estimate,
            "speed_offset": fdi.calibration.mean,
            "parity_offset": supervisor.detector.components.parity_spread.mean,
            "parity_scale": supervisor.detector.components.parity_spread.estimate,
            "actuator_scale": supervisor.detector.components.actuator_spread.estimate,
            "spread_counts": fdi.spread.count,
            "residual": fdi.clearing.residual,
            # the rotor-speed bias CUSUM (``service.turbine.bias_test``): S±, A±, its predictor and learnt spread
            "rotor_bias": [fdi.bias.up, fdi.bias.down, fdi.bias.run_up, fdi.bias.run_down],  # (n, K) each
            "rotor_bias_predictor": fdi.bias.predictor,
            "rotor_bias_scale": [fdi.bias.spread.estimate, fdi.bias.spread.count],
            "flags": supervisor.flags,
            "omega_g": est.omega_g,
            "wind": est.wind,
            "wind_reference": est.wind_reference,
            "selected": est.selected,
            "refs_valid": refs.valid,
        }.items():
            trace.setdefault(name, []).append(np.array(value, dtype=float))
    out = {name: np.array(values) for name, values in trace.items()}
    events = plant.drain_events() + supervisor.drain_events()
    out["events"] = np.array([(e.t, e.turbine, e.run) for e in events], dtype=float)
    out["event_kinds"] = [(e.type.value, e.target, json.dumps(e.detail, sort_keys=True, default=str)) for e in events]
    return out


def compare(reference: dict, fast: dict) -> None:
    assert fast.keys() == reference.keys()
    assert fast.pop("event_kinds") == reference.pop("event_kinds")
    for name in reference:
        assert_close(fast[name], reference[name], name)


@pytest.mark.parametrize("half", [True, pytest.param(False, marks=pytest.mark.slow)], ids=["30s", "60s"])
def test_turbine_tick_by_tick_through_every_fault_class(half):
    scenario = parse_scenario(at_half_speed(FAULTY) if half else tomllib.loads(FAULTY))
    ticks = round(scenario.duration_s / BENCHMARK.dt)
    reference = turbine_trace(scenario, "numpy", [0, 1], ticks)
    assert reference["flags"].any() and reference["cusum"].any()  # the isolation and the clearing both ran
    compare(reference, turbine_trace(scenario, "numba", [0, 1], ticks))


def test_a_plant_unlike_the_design_model_falls_back_and_still_matches():
    scenario = load_scenario("ftwse-2012-mismatch")
    compare(turbine_trace(scenario, "numpy", [3], 1500), turbine_trace(scenario, "numba", [3], 1500))


def test_the_scorecard_is_the_same_with_either_backend():
    # two worker processes, which take the backend from the environment ``eval --backend`` sets; fault-free twins
    scenario = parse_scenario(tomllib.loads(TURBINE_SHORT))
    cards = []
    for backend in ("numpy", "numba"):
        with process_backend(backend):
            evaluation = kind_for("turbine").evaluate(scenario, 2, SEED, EvalOptions(workers=2, progress=False))
        cards.append(json.loads(json.dumps(evaluation.scorecard, sort_keys=True)))
    assert not scorecard_differences(cards[1], cards[0])


def scorecard_differences(fast, reference, at: str = "") -> list[str]:
    """Where two scorecards differ: every key, count, verdict and string exactly; every float within ``RTOL`` of
    itself. The float figures (RMSEs, rates, means) come from sums whose last bit can differ between the backends
    on a CPU whose numpy runs ``exp``/``log`` in AVX-512 (its SIMD kernels round differently from the compiled
    code's libm); on the AVX2 machine the cards were equal text for text."""
    if isinstance(reference, dict):
        if not isinstance(fast, dict) or sorted(fast) != sorted(reference):
            return [f"{at}: keys differ"]
        return [d for k in reference for d in scorecard_differences(fast[k], reference[k], f"{at}.{k}")]
    if isinstance(reference, list):
        if not isinstance(fast, list) or len(fast) != len(reference):
            return [f"{at}: lengths differ"]
        pairs = enumerate(zip(fast, reference, strict=True))
        return [d for i, (f, r) in pairs for d in scorecard_differences(f, r, f"{at}[{i}]")]
    if isinstance(reference, float) and isinstance(fast, float):
        return (
            [] if abs(fast - reference) <= RTOL * max(abs(reference), 1e-300) else [f"{at}: {fast!r} != {reference!r}"]
        )
    return [] if type(fast) is type(reference) and fast == reference else [f"{at}: {fast!r} != {reference!r}"]


def test_scorecard_differences_sees_every_change_beyond_rounding():
    card = {"detected_pct": 100.0, "runs": 2, "name": "x", "rmse": [0.4172611798979821, None]}
    same = copy.deepcopy(card)
    same["rmse"][0] = 0.4172611798979822
    assert not scorecard_differences(same, card)
    for key, value in (("detected_pct", 99.0), ("runs", 3), ("name", "y"), ("rmse", [0.41726118, None])):
        changed = {**copy.deepcopy(card), key: value}
        assert scorecard_differences(changed, card), key
    assert scorecard_differences({**card, "runs": 2.0}, card)  # an int that became a float


def test_backend_choice_refuses_unknown_names_and_restores_the_environment(monkeypatch):
    monkeypatch.delenv(ENV_VAR, raising=False)
    assert resolve_backend() == "numpy"
    with pytest.raises(BackendError, match="numpy, numba"):
        resolve_backend("fortran")
    monkeypatch.setenv(ENV_VAR, "cuda")
    with pytest.raises(BackendError, match=ENV_VAR):
        resolve_backend()
    monkeypatch.setenv(ENV_VAR, "numpy")
    with process_backend("numba"):
        assert os.environ[ENV_VAR] == "numba" and resolve_backend() == "numba"
    assert os.environ[ENV_VAR] == "numpy"
    with pytest.raises(BackendError):
        TurbineSupervisor(1, backend="numbba")


PLANT_FAULTS = """
name = "kept-arguments-check"
duration_s = 4.0
[plant]
kind = "turbine"
[wind]
mean = [[0.0, 12.0], [4.0, 13.0]]
turbulence_intensity = 0.1
[[faults]]
name = "blade 2 pitch offset"
target = "pitch_actuator_2"
kind = "pitch_offset"
value = 2.0
start_s = 1.0
end_s = 2.5
[[faults]]
name = "generator sensor 1 offset"
target = "omega_g_m1"
kind = "offset"
value = 3.0
start_s = 3.0
"""


def test_the_plant_kernels_kept_arguments_follow_the_faults():
    # the compiled measurement keeps its arguments between ticks (``TurbineBatch._measure_arguments``); the fault
    # factors are new arrays whenever a fault starts or ends: a pitch offset (the blade torques' pitch) on and off,
    # a sensor fault after it; every tick's state, readings and torques equal to numpy's within ``RTOL`` (the blade
    # torques' kernel can differ from numpy's in the last place, ``docs/cluster.md``)
    scenario = parse_scenario(tomllib.loads(PLANT_FAULTS))
    plants = [
        TurbineBatch(scenario.plant, scenario.wind, scenario.faults, seed=SEED, runs=[0, 1], backend=backend)
        for backend in ("numpy", "numba")
    ]
    assert plants[1]._one_measure_kernel
    offsets = set()
    for _ in range(round(scenario.duration_s / plants[0].dt)):
        frames = [plant.measure() for plant in plants]
        k = plants[0].k
        assert_close(frames[1].sensors, frames[0].sensors, f"tick {k}: readings")
        assert_close(plants[1].tau_aero, plants[0].tau_aero, f"tick {k}: τ_r")
        assert_close(plants[1].blade_torque, plants[0].blade_torque, f"tick {k}: blade torques")
        offsets.add(float(plants[0].faults.pitch_offset.max()))
        for plant in plants:
            plant.control(None)
            plant.advance()
        assert_close(plants[1].x, plants[0].x, f"tick {k}: state")
        np.testing.assert_array_equal(plants[1].controller.zone, plants[0].controller.zone)
    assert offsets == {0.0, 2.0}


@pytest.mark.parametrize("runs, twins", [([0], False), ([0, 1], True)])
def test_the_kept_and_fused_plant_tick_equals_the_separate_calls(runs, twins):
    # the one-kernel measurement (its arguments kept, the wind chunk's row and the noise block's column read by the
    # kernel, its outputs planes of two blocks) and the controller's law with the shared step's inputs in one call
    # (``TurbineBatch.control``) against the same compiled plant making the separate calls (``WindField.sample``,
    # ``blade_torques``, ``readings``, ``BenchmarkController.step``, ``step_inputs``): every tick's frame, torques,
    # pitch errors, controller state, truth and plant state equal to the last bit, with the supervisor's references,
    # through FAULTY's first 48 s (a fixed, a stuck and a gain speed sensor, a drifting anemometer, a pitch-sensor
    # offset, a pitch actuator's dynamics and the drive train's efficiency: per-row steps where rows differ, a
    # converter offset in the step's inputs), across noise blocks and the wind's second and third chunks; one row (the
    # step's product inside the call, numpy's ``gemv`` reproduced), and two runs with their twin rows (which repeat
    # their run's noise; numpy's ``gemm``)
    scenario = parse_scenario(tomllib.loads(FAULTY))
    options = {"seed": SEED, "runs": runs, "backend": "numba", "noise_chunk": 700, "fault_free_twins": twins}
    plants = [TurbineBatch(scenario.plant, scenario.wind, scenario.faults, **options) for _ in range(2)]
    fused, separate = plants
    separate._one_measure_kernel = separate._fused_control = False
    assert fused._one_measure_kernel and fused._fused_control and fused._step_product == (len(runs) == 1)
    supervisor, refs, shared, estimated = TurbineSupervisor(fused.n, backend="numba"), None, set(), set()
    for k in range(4800):
        frames = [plant.measure() for plant in plants]
        for name in ("sensors", "tau_g_ref", "beta_ref", "power_ref", "zone"):
            np.testing.assert_array_equal(getattr(frames[0], name), getattr(frames[1], name), f"tick {k}: {name}")
        for name in ("tau_aero", "blade_torque", "_pitch_error"):
            np.testing.assert_array_equal(getattr(fused, name), getattr(separate, name), f"tick {k}: {name}")
        for plant in plants:
            plant.control(refs)
        for name in ("tau_g_ref", "beta_ref", "zone", "integrator", "using_estimates"):
            mine, its = (getattr(plant.controller, name) for plant in plants)
            np.testing.assert_array_equal(mine, its, f"tick {k}: controller {name}")
        shared.add(fused._inputs_ready)
        estimated.add(bool(fused.controller.using_estimates.any()))
        refs = supervisor.step(frames[0])
        if k % 100 == 0:
            for (name, mine), its in zip(fused.truth().items(), separate.truth().values(), strict=True):
                np.testing.assert_array_equal(mine, its, f"tick {k}: truth {name}")
        for plant in plants:
            plant.advance()
        np.testing.assert_array_equal(fused.x, separate.x, f"tick {k}: state")
    assert estimated == {True, False}
    # with twin rows the pitch actuator's dynamics make the rows differ: the per-row step (no shared step's inputs)
    assert shared == ({True, False} if twins else {True})


def test_compiled_objects_copy_and_pickle():
    kernels = fast_module("plant_sim.turbine.fast")
    assert copy.deepcopy(kernels) is kernels
    assert pickle.loads(pickle.dumps(kernels)).blade_winds is kernels.blade_winds
    scenario = parse_scenario(tomllib.loads(FAULTY))
    plant = TurbineBatch(scenario.plant, scenario.wind, scenario.faults, seed=SEED, backend="numba")
    twin = copy.deepcopy(plant)  # a fault-free twin run in the same process copies the plant
    twin.measure(), plant.measure()
    np.testing.assert_array_equal(twin.last_reading, plant.last_reading)
    # a copied supervisor learns into its own adaptive state (the kernels update it in place)
    plant = TurbineBatch(scenario.plant, scenario.wind, scenario.faults, seed=SEED, backend="numba")
    supervisor, refs = TurbineSupervisor(plant.n, backend="numba"), None
    for _ in range(3):
        frame = plant.measure()
        plant.control(refs)
        refs = supervisor.step(frame)
        plant.advance()
    copied = copy.deepcopy(supervisor)
    frame = plant.measure()
    copied.step(frame)
    spreads = [(s.detector.fdi.spread, s.detector.components.parity_spread) for s in (supervisor, copied)]
    assert not np.array_equal(spreads[0][1].count, spreads[1][1].count)  # only the copy took the last frame
    supervisor.step(frame)
    for mine, its in zip(*spreads, strict=True):
        for a, b in zip(mine.state, its.state, strict=True):
            np.testing.assert_array_equal(a, b)


def test_starting_the_cli_and_the_live_nodes_does_not_import_the_compiler():
    code = (
        "import sys, windwarden.cli, plant_sim.turbine, plant_sim.farm, service.turbine.supervisor; "
        "print('numba' in sys.modules)"
    )
    env = {**os.environ}
    env.pop(ENV_VAR, None)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.strip() == "False"


def test_eval_refuses_the_numba_backend_where_numba_is_missing(monkeypatch, tmp_path, capsys):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "numba" else real(name, *a))
    with pytest.raises(BackendError, match="pip install numba"):
        available("numba")
    out = tmp_path / "out"
    assert main(["eval", "ftwse-2012", "--runs", "1", "--quiet", "--out", str(out)]) == EXIT_BAD_INPUT
    assert "--step-backend" in capsys.readouterr().err and not out.exists()  # refused before anything ran


def test_the_kernel_cache_is_keyed_on_every_kernel_module_not_only_the_kernel_s_own(tmp_path, monkeypatch):
    """numba re-checks a cached kernel against its own file only; the cache's subdirectory is named by a hash of
    every module of the kernel packages, so a changed callee in another module compiles afresh (``wwcore.jit``)."""
    for package in jit.KERNEL_PACKAGES:
        (tmp_path / package).mkdir()
        (tmp_path / package / "kernels.py").write_text("x = 1\n")
    (tmp_path / "notes.py").write_text("y = 1\n")
    key = jit.source_key(tmp_path)
    assert len(key) == 16 and key == jit.source_key(tmp_path)
    (tmp_path / "notes.py").write_text("y = 2\n")  # outside the kernel packages
    assert jit.source_key(tmp_path) == key
    (tmp_path / "wwcore" / "kernels.py").write_text("x = 2\n")  # a callee changed
    changed = jit.source_key(tmp_path)
    assert changed != key
    (tmp_path / "service" / "new.py").write_text("")  # a module added
    assert jit.source_key(tmp_path) != changed
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba"))
    assert jit.cache_dir() == tmp_path / "numba" / f"source-{jit.source_key()}"
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    monkeypatch.setenv("WINDWARDEN_CACHE", str(tmp_path / "cache"))
    assert jit.cache_dir() == tmp_path / "cache" / "numba" / f"source-{jit.source_key()}"
