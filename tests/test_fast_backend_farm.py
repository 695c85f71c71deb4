"""The farm's compiled backend (``wwcore.backend``, ``numba``) against the numpy reference: the farm detector's learnt
levels, the farm's turbines and supervisor tick by tick, and the farm plant stepped a sample at a time.

As in ``tests/test_fast_backend.py`` (the tolerance and ``assert_close`` of ``tests/fast_compare.py``): equality
within 1e-12 of each quantity's scale, in practice to the last bit.
"""

from __future__ import annotations

import copy
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import plant_sim.wind
from plant_sim.farm import FarmBatch
from service.farm.analytic import AnalyticDetector
from service.farm.baseline import LearntLevel
from service.farm.dispatch import Dispatch
from service.farm.interfaces import BETA, OMEGA_G, OMEGA_R, P_G, TAU_G, FarmContext, FarmSample
from service.farm.power_curve import WINDS, available_power, available_power_table
from service.farm.signals import MAX_IMPROPERNESS, LockIn3P
from tests.fast_compare import SEED, assert_close
from windwarden.bench import farm_pair
from wwcore import thrust
from wwcore.backend import fast_module
from wwcore.scenario import load_scenario, parse_scenario
from wwcore.scenario.farm import FarmPlant
from wwcore.turbine_params import BENCHMARK


def test_the_farm_learnt_levels_kernel_equals_the_reference():
    # ``LearntLevel.update`` with its numpy lines and with the kernel, on the analytic detector's two shapes (per
    # turbine with a per-turbine σ_d, per blade with one σ_d and a frozen flag per turbine), blocks of 4 filling
    # and restarting, samples frozen mid-block; every array equal to the last bit
    fast = fast_module("service.farm.fast")
    rng = np.random.default_rng(SEED)
    learnt = {"level_time_s": 0.5, "spread_time_s": 0.8, "max_ratio": 9.0, "block": 4}
    for shape in ((5,), (5, 3)):
        reference, twin = LearntLevel(shape, **learnt), LearntLevel(shape, **learnt, fast=fast)
        for k in range(50):
            r = rng.normal(0.4, 2.0, shape)
            std = rng.uniform(0.5, 1.5, shape) if len(shape) == 1 else 1.3
            frozen = rng.random(shape if len(shape) == 1 else (5, 1)) < 0.15 if k % 9 else False
            reference.update(r, std, frozen)
            twin.update(r, std, frozen)
            for name in ("samples", "level", "raw_ratio", "blocks", "_block_sum", "_block_n"):
                np.testing.assert_array_equal(getattr(twin, name), getattr(reference, name), f"{shape} {k}: {name}")
        assert reference.blocks.min() >= 5 and (reference.raw_ratio != 1.0).all()
    twin = copy.deepcopy(twin)  # a copy learns into its own arrays
    twin.update(np.ones((5, 3)), 1.0)
    assert not np.array_equal(twin.level, reference.level)


@pytest.mark.parametrize("name", ["farm-case1", "farm-3x3-veer"])  # the row model; FLORIS wakes, a moving direction
def test_farm_turbines_match(name):
    states = {}
    for backend in ("numpy", "numba"):
        plant, supervisor = farm_pair(name, 1, SEED, False, backend, 19.0)  # 20 s of one run
        assert (supervisor.context.fast_aero is None) == (backend == "numpy")
        refs, trace, winds, powers = None, [], [], []
        for _ in range(1500):
            frame = plant.measure()
            plant.control(refs)
            refs = supervisor.step(frame)
            plant.advance()
            trace.append(plant.turbines.x.copy())
            if frame.sample:  # the detector's residuals, the available-power wind (eq. 20) and the references
                detector = supervisor.detector
                learnt = [detector.level1.level, detector.level2.level] if hasattr(detector, "level1") else []
                winds.append(np.concatenate([supervisor.controller.available.wind, detector.residuals.ravel()]))
                winds[-1] = np.concatenate([winds[-1], *[a.ravel() for a in learnt]])
                powers.append(refs.power_ref.copy())
        events = plant.drain_events() + supervisor.drain_events()
        states[backend] = np.array(trace), np.array(winds), np.array(powers), [(e.t, e.type, e.turbine) for e in events]
    names = ("states", "wind, residuals and levels", "power refs")
    for name, fast, reference in zip(names, states["numba"], states["numpy"], strict=False):
        assert_close(fast, reference, f"farm turbine {name}")
    assert states["numba"][3] == states["numpy"][3]


def farm_with_early_faults() -> dict:
    """farm-case1 cut to 20 s with twins' worth of faults: a debris (the power and aerodynamic factors the compiled
    sample reads), a pitch offset and a drive-train wear (whose ticks the compiled sample leaves to the calls), each
    starting and ending inside a farm sample."""
    data = tomllib.loads(Path("scenarios/farm-case1.toml").read_text())
    data["duration_s"] = 20.0
    data["faults"] = [
        {**data["faults"][0], "start_s": 2.05, "end_s": 8.02},
        {**data["faults"][1], "start_s": 9.03, "end_s": 12.0},
        {**data["faults"][2], "start_s": 13.07, "end_s": 16.0},
    ]
    return data


@pytest.mark.parametrize("name", ["early-faults", "cancel-phasor", "farm-3x3-veer"])  # FLORIS wakes; moving, rows
def test_a_farm_sample_at_a_time_equals_the_numpy_ticks(name, monkeypatch):
    """``FarmBatch.run_sample`` with the compiled backend (``sub_steps`` for a sample's common ticks, the calls for
    the rest) against the numpy reference stepped tick by tick: every tick's state, power and shaft torque, every
    sample's frame and references, the events; with fault-free twins (their noise is their run's). "cancel-phasor"
    adds the 3P cancellation and a power phasor to the references (``trimmed``) while the drive-train wear acts:
    the samples with the wear's torque pair, the cancellation and the phasor are compiled too."""
    early = name in ("early-faults", "cancel-phasor")
    scenario = parse_scenario(farm_with_early_faults()) if early else load_scenario(name)
    if name == "farm-3x3-veer":  # turbulence chunks of 5 s instead of 20: three start inside the 20 s
        monkeypatch.setattr(plant_sim.wind, "CHUNK_SAMPLES", 100)
    ticks = round(20.0 / BENCHMARK.dt)
    traces = {}
    for backend in ("numpy", "numba"):
        plant, supervisor = farm_pair(scenario, 1, SEED, True, backend, 20.0)  # 20 s of one run and its twin
        # the wakes' step compiled at a fixed direction (``wake_step``), numpy's along a moving one
        assert (plant.wakes._fast is not None) == (backend == "numba" and early)
        compiled, acting = [], []
        if backend == "numba":
            monkeypatch.setattr(plant, "_sub_steps_apply", recording(plant._sub_steps_apply, compiled, plant, acting))
        per_tick, samples, refs = [], [], None
        if backend == "numpy":  # the reference: the step contract's calls, tick by tick
            for _ in range(ticks):
                frame = plant.measure()
                plant.control(refs)
                refs = trimmed(supervisor.step(frame), name)
                per_tick.append(np.concatenate([plant.turbines.x, plant.power_output()[:, None]], axis=1))
                per_tick[-1] = np.concatenate([per_tick[-1], plant.shaft_torque()[:, None]], axis=1)
                plant.advance()
                if frame.sample:
                    samples.append(farm_sample_numbers(frame, refs))
        else:
            while plant.k < ticks:
                block = plant.run_sample(refs, ticks - plant.k, shaft_torque=True)
                refs = trimmed(supervisor.step(block.frame), name)
                power, shaft = block.power[:, :, None], block.shaft_torque[:, :, None]
                per_tick.extend(np.concatenate([block.states, power, shaft], axis=2))
                if block.frame.sample:
                    samples.append(farm_sample_numbers(block.frame, refs))
            # the calls: the first sample (the controller's band-pass not yet started) and, with faults, those where
            # one starts, ends or needs the per-tick code; a sample that starts a noise block (t = 10 s) or a
            # turbulence chunk (every 5 s on the moving direction's farm) has it made ahead and is compiled
            calls = compiled.count(False)
            assert (2 < calls < 10) if early else (calls == 1 and len(compiled) == 200)
            assert (plant.controller.pitch_trim is not None) == early  # the trims were taken
            if name == "cancel-phasor":  # compiled samples ran the cancellation, the phasor and the wear's pair
                assert {"cancel", "phasor", "wear"} <= set(acting)
        events = [(e.t, e.type, e.turbine, e.run) for e in plant.drain_events() + supervisor.drain_events()]
        traces[backend] = np.array(per_tick), np.array(samples), events, plant.truth()
    fast, reference = traces["numba"], traces["numpy"]
    assert_close(fast[0], reference[0], "state, power and shaft torque of every tick")
    assert_close(fast[1], reference[1], "readings, SCADA means, controller outputs and references of every sample")
    assert fast[2] == reference[2]
    assert len(reference[2]) >= (6 if name == "early-faults" else 0)  # every fault started and ended, on time
    for key in reference[3]:
        assert_close(fast[3][key], reference[3][key], f"truth {key} at the end")


def trimmed(refs, name: str):
    """``refs`` with a pitch trim on turbine 3's first blade from 5 s on (the early-faults farms), as a farm
    supervisor's pitch accommodation would send it: the trim reaches the pitch commands inside the compiled sample.
    "cancel-phasor" also asks turbines 5 and 6 for the 3P cancellation from 3 s to 14 s (it then fades out) and
    turbines 2 and 6 for a power phasor from 4 s to 15 s, as a drive-train accommodation would."""
    if name not in ("early-faults", "cancel-phasor") or refs is None or refs.source_tick < 300:
        return refs
    n, tick = len(refs.power_ref), refs.source_tick
    if name == "cancel-phasor" and tick < 1400:
        cancel = np.zeros(n, dtype=bool)
        cancel[4::9] = cancel[5::9] = True
        refs = replace(refs, cancel_3p=cancel)
    if name == "cancel-phasor" and 400 <= tick < 1500:
        power = np.zeros(n, dtype=complex)
        power[1::9], power[5::9] = 2.0e4 * np.exp(0.3j), -1.5e4 + 7.0e3j
        refs = replace(refs, ripple_power=power, ripple_rate=np.full(n, 3.0 * 1.267 + 0.01 * tick / 1400))
    if tick < 500:
        return refs
    trim = np.zeros((n, 3))
    trim[2::9, 0] = 0.25
    return replace(refs, pitch_trim=trim)


def recording(method, answers: list, plant=None, acting: list | None = None):
    """``method`` that also appends each answer to ``answers``; with ``plant``, what acts in each compiled sample
    to ``acting`` (the 3P cancellation, a power phasor, the drive-train wear's torque pair)."""

    def recorded(*args):
        answers.append(method(*args))
        if plant is not None and answers[-1]:
            c, tb = plant.controller, plant.turbines
            acting.extend(["cancel"] * (c.cancel_3p and (c._ripple_running or c._any_asked)))
            acting.extend(["phasor"] * (c._extra is not None))
            acting.extend(["wear"] * (tb.faults.mesh_active or tb._error_active))
        return answers[-1]

    return recorded


def farm_sample_numbers(frame, refs) -> np.ndarray:
    """A farm sample's readings, SCADA means, the mast's, the controller outputs the frame carries and the answer."""
    t = frame.turbines
    parts = [t.sensors, frame.scada, frame.power_ref_used, t.tau_g_ref, t.beta_ref, t.power_ref, t.zone]
    parts += [frame.mast, frame.demand, frame.mast_direction, refs.power_ref]
    return np.concatenate([np.ravel(p) for p in parts])


def test_the_analytic_detector_kernels_equal_the_reference():
    """``AnalyticDetector.step`` with its numpy lines and with ``analytic_residuals`` and ``analytic_decide``: SCADA
    means of two farms with a debris on one turbine, a pitch offset on another and a 3P swing on a third, each
    starting and ending, the false-alarm budget raised so that the CUSUMs and fault 3 raise and clear, with and
    without learnt levels; every residual, statistic, flag, threshold and state equal to the last bit."""
    site, n = FarmPlant().site(), 18
    p = BENCHMARK
    for options in ({"false_alarms_per_1000s": 50.0, "warmup_s": 2.0}, {"learn_levels": False, "warmup_s": 0.5}):
        detectors = [
            AnalyticDetector(context=FarmContext(site, n, backend=b), options=options) for b in ("numpy", "numba")
        ]
        assert detectors[0]._fast is None and detectors[1]._fast is not None
        rng = np.random.default_rng(SEED)
        raised = np.zeros((n, 3), dtype=bool)
        cleared = np.zeros((n, 3), dtype=bool)
        phase = np.zeros(n)
        previous = np.zeros((n, 3), dtype=bool)
        for j in range(1, 900):
            t = j * 0.1
            y = np.zeros((n, 24))
            omega_r = 1.6 + 0.05 * np.sin(0.3 * t) + rng.normal(0, 2e-3, n)
            y[:, OMEGA_R] = omega_r[:, None] + rng.normal(0, 1e-3, (n, 2))
            phase += 3.0 * omega_r * 0.1  # the 3P phase the lock-in follows
            swing = 2.0 * np.sin(phase) * (np.arange(n) == 5) * (20 < t < 50)
            y[:, OMEGA_G] = (p.N_g * omega_r + swing)[:, None] + rng.normal(0, 0.05, (n, 2))
            y[:, TAU_G] = 3e4 + rng.normal(0, 50, n)
            debris = np.where((np.arange(n) == 2) & (10 < t < 40), 0.9, 1.0)
            y[:, P_G] = debris * p.eta_gc * y[:, OMEGA_G].mean(axis=1) * y[:, TAU_G] + rng.normal(0, 1e3, n)
            pitch = 2.0 + 3.0 * np.sin(0.2 * t) + rng.normal(0, 0.02, (n, 3, 2))
            pitch[11, 1] += 0.8 * (15 < t < 60)
            y[:, BETA] = pitch
            sample = FarmSample(
                j=j,
                t=t,
                scada=y,
                zone=np.zeros(n, dtype=np.int8),
                power_ref_used=np.zeros(n),
                mast=np.full(2, 9.0),
                demand=np.full(2, 1e7),
            )
            numpy_d, numba_d = (d.step(sample) for d in detectors)
            for name in ("faulty", "statistics", "thresholds"):
                np.testing.assert_array_equal(getattr(numba_d, name), getattr(numpy_d, name), f"{options} {j}: {name}")
            for key in numpy_d.extra:
                np.testing.assert_array_equal(numba_d.extra[key], numpy_d.extra[key], f"{options} {j}: {key}")
            reference, twin = detectors
            for name in ("residuals", "flag3", "quiet3", "h3_now", "last_rate", "last_pitch"):
                np.testing.assert_array_equal(getattr(twin, name), getattr(reference, name), f"{options} {j}: {name}")
            learnt = {"level1": ("level", "raw_ratio", "samples", "blocks", "_block_sum", "_block_n")}
            learnt |= {"level2": learnt["level1"], "rate_gain": ("sxx", "sxr"), "scale3": ("mean_square", "samples")}
            learnt |= {"cusum1": ("g", "q", "flag"), "cusum2": ("g", "q", "flag")}
            for c, names in learnt.items():
                for name in names:
                    a, b = getattr(getattr(twin, c), name), getattr(getattr(reference, c), name)
                    np.testing.assert_array_equal(a, b, f"{options} {j}: {c}.{name}")
            cleared |= previous & ~numpy_d.faulty
            raised |= numpy_d.faulty
            previous = numpy_d.faulty.copy()
        assert raised[[2, 11, 5], [0, 1, 2]].all() and cleared[[2, 11, 5], [0, 1, 2]].all(), (raised, cleared)


DISPATCH_OPTIONS = [
    {},  # the defaults: the 3P cancellation with its relief, the pitch trim, the power trim, the ripple compensation
    {"accommodation_rule": "paper", "pitch_rule": "paper", "derate_floor": 0.3, "ripple_compensation": False},
    {"drivetrain_relief": 0.0, "trim_kp": 0.0, "trim_ki": 0.0, "ripple_share": 0.5},
    {"accommodation_rule": "paper", "pitch_rule": "trim", "trim_limit": 0.02},
    {"accommodation_rule": "hold-torque"},  # the hold's rule stays numpy's; the available power's kernels run
]


@pytest.mark.parametrize("options", DISPATCH_OPTIONS)
@pytest.mark.parametrize("held_rows", [False, True])
def test_the_dispatch_kernels_equal_the_reference(options, held_rows):
    """``Dispatch.step`` with its numpy lines (the wind inverted by ``wwcore.aero_fast``) and with the kernels
    (``available_front``, ``available_back``, ``available_filter``, ``dispatch_shares``) on two farms of random
    SCADA means around operating points from 5 to 20 m/s: flags of every type raised and dropped on random turbines
    (several per farm, so eq. (26) shares the headroom in turbine order), demands below and above the farms'
    maximum, and (``held_rows``) turbines held for stretches (the hold-torque rule: the available power's kernels
    under its numpy lines); every reference, mode, P_avail, wind, filter state,
    integral, pitch trim and ripple phasor equal to the last bit."""
    site, n = FarmPlant().site(), 18
    p = BENCHMARK
    dispatches = [Dispatch(context=FarmContext(site, n, backend=b), options=options) for b in ("numpy", "numba")]
    hold = options.get("accommodation_rule") == "hold-torque"
    assert dispatches[0]._kernels is None and (dispatches[1]._kernels is None) == hold
    assert dispatches[1].available._kernels is not None
    # the numpy lines with the compiled wind inversion (``wwcore.aero_fast``, whose exp may differ from numpy's in
    # the last bit): the kernels' reference to the bit
    dispatches[0] = Dispatch(context=FarmContext(site, n, backend="numba"), options=options)
    dispatches[0]._kernels = dispatches[0].available._kernels = None
    rng = np.random.default_rng(SEED)
    wind = rng.uniform(5.0, 20.0, n)
    faulty = np.zeros((n, 3), dtype=bool)
    held = np.zeros(n, dtype=bool)
    modes, flagged = set(), 0
    for j in range(1, 400):
        wind = np.clip(wind + rng.normal(0.0, 0.2, n), 4.0, 24.0)
        omega_g = np.minimum(p.N_g * 7.5 * wind / p.radius, p.omega_nom) * rng.normal(1.0, 0.01, n)
        y = np.zeros((n, 24))
        y[:, OMEGA_G] = omega_g[:, None] + rng.normal(0.0, 0.5, (n, 2))
        y[:, OMEGA_R] = (omega_g / p.N_g)[:, None] + rng.normal(0.0, 0.005, (n, 2))
        y[:, TAU_G] = np.minimum(p.k_opt * omega_g**2, p.rated_power / p.eta_gc / omega_g) * rng.normal(1.0, 0.02, n)
        y[:, P_G] = p.eta_gc * y[:, OMEGA_G].mean(axis=1) * y[:, TAU_G] + rng.normal(0.0, 2e4, n)
        y[:, BETA] = np.maximum(wind - 12.0, 0.0)[:, None, None] * 2.0 + rng.normal(0.0, 0.3, (n, 3, 2))
        if j % 25 == 0:  # flags of every type come and go, several per farm
            faulty = rng.random((n, 3)) < 0.12
            flagged += faulty.sum()
        if held_rows and j % 40 == 0:
            held = rng.random(n) < 0.2
        demand = rng.uniform(0.3, 1.3, 2) * 9 * p.rated_power * (0.5 if j % 3 else 1.0)
        sample = FarmSample(
            j=j,
            t=j * 0.1,
            scada=y,
            zone=np.zeros(n, dtype=np.int8),
            power_ref_used=np.zeros(n),
            mast=np.full(2, 10.0),
            demand=demand,
            held=held.copy() if held_rows else None,
        )
        reference, twin = dispatches
        expected, refs = reference.step(sample, faulty), twin.step(sample, faulty)
        np.testing.assert_array_equal(refs, expected, f"{options} {j}: references")
        for name in ("mode", "p_avail", "held_power", "served_demand", "wind", "pitch_trim", "ripple_power"):
            np.testing.assert_array_equal(getattr(twin, name), getattr(reference, name), f"{options} {j}: {name}")
        for name in ("wind", "slow_wind", "p_a_hat"):
            a, b = getattr(twin.available, name), getattr(reference.available, name)
            np.testing.assert_array_equal(a, b, f"{options} {j}: {name}")
        np.testing.assert_array_equal(twin.power_trim.integral, reference.power_trim.integral, f"{j}: integral")
        modes |= set(reference.mode.tolist())
    assert flagged > 50 and len(modes) >= 3, modes  # the rules acted (the paper's make modes 0–2 only)


def test_the_sum_and_interpolation_kernels_equal_numpy():
    """``row_sum`` against ``ndarray.sum`` on rows of 1–128 values of mixed signs and magnitudes (numpy's pairwise
    order: a sequential sum would differ on most of them), and ``interp`` against ``np.interp`` on the available
    power's table, inside, at and beyond its knots and on nan; equal to the last bit."""
    fast = fast_module("service.farm.fast")
    rng = np.random.default_rng(SEED)
    sequential_differs = 0
    for n in (*range(1, 20), 63, 64, 65, 80, 127, 128):
        for _ in range(20):
            a = rng.random(n) * 10.0 ** rng.integers(-3, 7, n) * np.where(rng.random(n) < 0.3, -1.0, 1.0)
            assert fast.row_sum(a, 0, n) == a.sum(), n
            row = np.concatenate([rng.random(3), a])  # a row that starts inside its array
            assert fast.row_sum(row, 3, n) == a.sum(), n
            total = 0.0
            for value in a:
                total += value
            sequential_differs += total != a.sum()
    assert sequential_differs > 100
    table = available_power_table(BENCHMARK)
    x = np.concatenate([rng.uniform(0.0, 45.0, 5000), WINDS[::7], [2.0, 40.0, 1.999, 40.001, np.nan, -np.inf, np.inf]])
    got = np.array([fast.interp(v, WINDS, table) for v in x])
    np.testing.assert_array_equal(got, available_power(BENCHMARK, x))


def test_the_thrust_grids_binned_interpolation_equals_np_interp():
    """``interp_binned`` (h⁻¹'s grid searched from h's uniform bin) against ``np.interp`` on the thrust's grid: at,
    beside and between its 4 001 knots, at and beside every bin edge (where the bin's rounding matters), dense near
    the Betz point where the knots crowd, and beyond the ends and nan; equal to the last bit."""
    fast = fast_module("wwcore.thrust_fast")
    rng = np.random.default_rng(SEED)
    knots, edges = thrust._H_GRID, np.arange(4097) / fast._H_PER_BIN
    uniform, betz = rng.uniform(0.0, thrust.H_MAX, 20000), rng.uniform(0.55, thrust.H_MAX, 20000)
    inside = [uniform, betz, (knots[1:] + knots[:-1]) / 2]
    near = [np.nextafter(v, side) for v in (knots, edges) for side in (-1.0, 2.0)]
    h = np.concatenate([*inside, knots, edges, *near, [np.nan, -1.0, -0.0, thrust.H_MAX, 1.0, np.inf]])
    got = np.array([fast.interp_binned(v, knots, thrust._CT_GRID, fast._H_BIN_FIRST, fast._H_PER_BIN) for v in h])
    np.testing.assert_array_equal(got.view(np.int64), np.interp(h, knots, thrust._CT_GRID).view(np.int64))


def test_the_thrust_coefficient_kernels_equal_the_reference():
    """``wwcore.thrust_fast.thrust_coefficient`` (three kernels around numpy's transcendental functions and product)
    against ``wwcore.thrust.thrust_coefficient`` on operating points inside and outside the fit's table (λ < 1,
    λ > 13, pitch below −2 and above 95 deg, C_p ≤ 0 and the Betz clip, nan), shapes of 1 to 2 000 values; equal
    to the last bit."""
    fast = fast_module("plant_sim.farm.fast")
    rng = np.random.default_rng(SEED)
    clipped = 0
    for n in (1, 2, 9, 18, 27, 2000):
        tsr = rng.uniform(-1.0, 16.0, n)
        pitch = rng.uniform(-6.0, 100.0, n)
        got, want = fast.thrust_coefficient(tsr, pitch), thrust.thrust_coefficient(tsr, pitch)
        np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64), f"{n}")
        clipped += int(np.sum(want == 0.0))
    assert clipped > 50  # C_p ≤ 0: h clipped at 0
    tsr = np.array([0.0, 1.0, 13.0, 14.0, np.nan, 7.0, np.inf, 8.0, 7.5]).reshape(3, 3)
    pitch = np.array([0.0, -2.0, 95.0, 100.0, 3.0, np.nan, 0.0, -10.0, 0.5]).reshape(3, 3)
    got, want = fast.thrust_coefficient(tsr, pitch), thrust.thrust_coefficient(tsr, pitch)
    assert got.shape == (3, 3)
    np.testing.assert_array_equal(got, want)


def test_the_lockin_kernel_equals_the_reference():
    """``LockIn3P`` with ``service.farm.fast.lockin_step`` against its numpy lines (numpy's complex products with
    fused multiply-adds, its complex ``abs`` and ``exp``, ``np.mod``): 1 to 45 signals over 3 000 samples, tones,
    noise and steps, rotors from standstill (|ρ| clipped at its bound) to above rated; A, Ã and every state equal
    within ``RTOL`` of their scale. On the development machine (AVX-512) they are equal to the last bit; numpy's
    complex loops differ between CPUs (fused multiply-adds, the SIMD ``abs``), so the test asks for the tolerance
    every compiled twin is held to, which a wrong formula misses by many orders."""
    fast = fast_module("service.farm.fast")
    rng = np.random.default_rng(SEED)
    bounded = 0
    for n in (1, 2, 9, 18, 45):
        reference, twin = LockIn3P(n, 1.5), LockIn3P(n, 1.5, fast=fast)
        omega = rng.uniform(0.0, 2.0, n)
        phase = np.zeros(n)
        for k in range(3000):
            speed = np.abs(omega + rng.normal(0.0, 0.05, n)) * (0.05 if 2000 < k < 2500 else 1.0)
            phase += 3.0 * speed * 0.1
            x = rng.normal(0.0, 0.3, n) + 0.4 * np.sin(phase) * (k > 1000) + 5.0 * (k % 700 == 5)
            assert_close(twin.step(x, speed), reference.step(x, speed), f"{n} {k}: A")
            for name in ("whitened", "phase", "i", "q", "mean", "w"):
                a, b = np.asarray(getattr(twin, name)), np.asarray(getattr(reference, name))
                assert_close(a.real, b.real, f"{n} {k}: {name}")
                assert_close(a.imag, b.imag, f"{n} {k}: {name} (imaginary part)")
            assert_close(np.asarray(twin.v), np.asarray(reference.v), f"{n} {k}: v")
            bounded += int(np.sum(np.abs(reference.w / reference.v) > MAX_IMPROPERNESS))
    assert bounded > 100  # the whitening's bound on |ρ| acted


def test_the_noise_draws_equal_numpys():
    """``wwcore.random_fast``: a compiled loop of ``Generator.standard_normal`` gives numpy's numbers for the same
    generator, in the same order, and leaves its state where numpy's call does (so the next block's draws follow on),
    the ziggurat's tail branch included (|x| beyond its last layer, 3.654…, on 2 million draws per seed); the scaled
    block equals the draws times σ; and a farm batch's noise block is the numpy reference's with and without a
    ``[mismatch]`` noise scale (σ per row)."""
    random_fast = fast_module("wwcore.random_fast")
    scale = np.array([0.5, 2.0, 1e-3, 90.0])
    for seed in (SEED, 1, 2):
        reference, compiled = np.random.default_rng(seed), np.random.default_rng(seed)
        expected = reference.standard_normal(2_000_000)
        got = np.empty(2_000_000)
        random_fast.standard_normals(compiled, got)
        np.testing.assert_array_equal(got, expected)
        assert np.abs(expected).max() > 3.6541528853610088  # the tail was drawn
        assert compiled.bit_generator.state == reference.bit_generator.state
        block, scaled = np.empty((1000, scale.size)), np.empty((1000, scale.size))
        reference.standard_normal(out=block)
        block *= scale
        random_fast.scaled_normals(compiled, scaled, scale)
        np.testing.assert_array_equal(scaled, block)
        assert compiled.bit_generator.state == reference.bit_generator.state
    for name in ("farm-case1", "farm-case1-mismatch"):
        blocks = {}
        for backend in ("numpy", "numba"):
            scenario = load_scenario(name)
            plant = FarmBatch(
                scenario.plant,
                scenario.wind,
                scenario.faults,
                seed=SEED,
                duration_s=5.0,
                runs=[0, 1],
                fault_free_twins=True,
                mismatch=scenario.mismatch,
                backend=backend,
            )
            plant.turbines._draw_noise()
            first = plant.turbines._draws.copy()
            plant.turbines._draw_noise()  # the next block: the streams' states followed on
            blocks[backend] = first, plant.turbines._draws.copy()
        assert blocks["numba"][0].shape == (18, plant.turbines.noise_chunk, 13)
        assert plant.turbines.sigma.ndim == (3 if name.endswith("mismatch") else 1)  # σ per row, or one per sensor
        for got, expected in zip(blocks["numba"], blocks["numpy"], strict=True):
            np.testing.assert_array_equal(got, expected, name)
        assert not np.array_equal(blocks["numpy"][0], blocks["numpy"][1])


def test_the_power_phasor_kernel_equals_the_controllers():
    """``plant_sim.farm.fast.phasor_power`` against ``FarmTurbineController._extra_power`` (numpy's complex ``exp``
    and product) on random phasors, rates and ages, within ``RTOL`` of their scale. On the development machine
    (AVX-512) they are equal to the last bit, where a product without the fused multiply-add differs on about a
    quarter of them; numpy's complex loops differ between CPUs, so the test asks for the tolerance every compiled
    twin is held to, which a wrong formula misses by many orders."""
    fast = fast_module("plant_sim.farm.fast")
    rng = np.random.default_rng(SEED)
    n = 20_000
    controller = farm_pair("farm-case1", 1, SEED, False, "numpy", 2.0)[0].controller
    controller.n = n
    for _ in range(5):
        phasor = (rng.standard_normal(n) + 1j * rng.standard_normal(n)) * 10.0 ** rng.uniform(2, 5)
        rate = rng.uniform(1.0, 6.0, n)
        since, k = rng.uniform(0.0, 100.0), int(rng.integers(10_000, 20_000))
        controller._extra = (phasor, rate, since)
        age = (k + 0.5) * BENCHMARK.dt - since
        if age > 0.5:  # within the phasor's life: k moved to a tick after t_0
            k = int(since / BENCHMARK.dt) + 10
            age = (k + 0.5) * BENCHMARK.dt - since
        expected = controller._extra_power(k)
        got = np.empty(n)
        fast.phasor_power(phasor.real.copy(), phasor.imag.copy(), rate, age, got)
        assert_close(got, expected, "Re{C e^{jω age}}")


def test_the_compiled_samples_kept_arguments_follow_the_faults():
    """``FarmBatch._sub_steps`` keeps the kernel's products of the fault factors between samples and makes them
    again when the faults change (the factors are then new arrays): on every compiled sample of the early-faults
    farm the kept power gain η_gc f_P and aerodynamic gain are the ones of the faults acting, the debris's factor
    0.97 on its turbine while it acts and 1 before and after. Kept arguments that were not made again would keep
    the gains of the first compiled sample and fail here (and, tick by tick, in
    ``test_a_farm_sample_at_a_time_equals_the_numpy_ticks``)."""
    plant, supervisor = farm_pair(parse_scenario(farm_with_early_faults()), 1, SEED, False, "numba", 20.0)
    compiled, sub_steps = [], plant._sub_steps
    plant._sub_steps = lambda *args: compiled.append(plant.k) or sub_steps(*args)  # the first ticks compiled
    p, refs, seen = plant.p, None, set()
    while plant.k < round(20.0 / BENCHMARK.dt):
        first = plant.k
        block = plant.run_sample(refs, shaft_torque=True)
        refs = supervisor.step(block.frame)
        if not compiled or compiled[-1] != first:
            continue  # the calls ran this sample
        kept, f = plant._sample_arguments, plant.turbines.faults
        np.testing.assert_array_equal(kept.power_gain, p.eta_gc * f.power_factor)
        np.testing.assert_array_equal(kept.aero[1], plant.turbines.dynamics.blade_gain * f.aero_factor)
        np.testing.assert_array_equal(kept.shaft[0], p.K_dt * f.stiffness_factor)
        seen.add(float(f.power_factor[4]))
    assert seen == {1.0, 0.97}  # compiled samples before, during and after the debris on turbine 5


def test_the_turbulence_chunks_interpolation_kernel_equals_the_reference():
    """``chunk_at_ticks`` (the compiled ``FarmWindField``'s chunk of ticks) against ``WindField._chunk_at_ticks``'s
    numpy arithmetic on random turbulence samples, positions at, between and at the ends of the samples and a
    ramping mean: (v_m, v_m + u_p, v_m + u_0, u_3) equal to the last bit; and two farms' wind fields, numpy's and the
    compiled one, refilled chunk after chunk, hold the same chunks."""
    rng = np.random.default_rng(SEED)
    n, samples, ticks = 23, 400, 2000
    last = tuple(rng.normal(0.0, 1.5, n) for _ in range(3))
    fresh = tuple(rng.normal(0.0, 1.5, (n, samples)) for _ in range(3))
    p = np.concatenate([[0.0, 0.5, samples - 1.0, samples - 1e-9], rng.uniform(0.0, samples, ticks - 4)])
    q = np.minimum(p.astype(int), samples - 1)
    frac = p - q
    vm = np.linspace(9.0, 12.5, ticks)
    field = plant_sim.wind.WindField(load_scenario("farm-case1").wind, BENCHMARK, [rng] * n, BENCHMARK.dt)
    reference = field._chunk_at_ticks(last, fresh, q, frac, vm)
    out = np.empty((4, ticks, n))
    fast_module("plant_sim.farm.fast").chunk_at_ticks(last, fresh, q, frac, vm, out)
    for got, expected in zip(out, reference, strict=True):
        np.testing.assert_array_equal(got, expected)
    fields = [farm_pair("farm-case1", 2, SEED, False, backend, 100.0)[0].field for backend in ("numpy", "numba")]
    for _ in range(3):
        for f in fields:
            f._refill()
        for got, expected in zip(fields[1].chunk, fields[0].chunk, strict=True):
            np.testing.assert_array_equal(got, expected)


def test_a_farm_sample_without_its_states_steps_as_with_them():
    """``FarmBatch.run_sample(states=False)`` (the evaluation's call: it reads the power and shaft torque only) makes
    no states block and leaves every tick's power, shaft torque and the farm samples' frames as the call with the
    states does, compiled samples and per-tick calls alike (the early-faults farm: faults start and end)."""
    scenario = parse_scenario(farm_with_early_faults())
    runs = {}
    for states in (True, False):
        plant, supervisor = farm_pair(scenario, 1, SEED, False, "numba", 12.0)
        blocks, refs = [], None
        while plant.k < round(12.0 / BENCHMARK.dt):
            block = plant.run_sample(refs, shaft_torque=True, states=states)
            refs = supervisor.step(block.frame)
            assert (block.states is None) != states
            blocks.append(np.concatenate([block.power, block.shaft_torque], axis=1))
            if block.frame.sample:
                blocks.append(farm_sample_numbers(block.frame, refs)[None, :])
        runs[states] = blocks, plant.turbines.x
    for got, expected in zip(runs[False][0], runs[True][0], strict=True):
        np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(runs[False][1], runs[True][1])
