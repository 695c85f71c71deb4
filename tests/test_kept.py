"""A kernel's kept arguments as one struct (``wwcore.kept.Kept``): the struct holds the very arrays Python holds
(writes on either side are seen by the other), a copy or pickle holds the copy's arrays, the three packed entry
points of the turbine tick equal their unpacked kernels to the last bit on a live tick's arguments, and a second
process loads them from numba's disk cache instead of compiling them."""

from __future__ import annotations

import copy
import os
import pickle
import subprocess
import sys
import tomllib

import numba
import numpy as np

from plant_sim.turbine import TurbineBatch
from service.turbine import fast
from service.turbine.fast_detector import PACKED, detector_tick
from tests.fast_compare import FAULTY, SEED
from windwarden.bench import _Stepper, turbine_pair
from wwcore.backend import fast_module
from wwcore.kept import Kept
from wwcore.scenario import parse_scenario


@numba.njit
def _bump(kept, x):
    a, b, c, d = kept.args
    a[0] += x
    return b[1, 0] + c + (0.0 if d is None else 1.0)


def test_a_kept_struct_holds_the_arrays_python_holds():
    a, b = np.zeros(3), np.arange(4.0).reshape(2, 2)
    kept = Kept((a, b, 2.5, None))
    assert _bump(kept, 1.0) == 4.5 and a[0] == 1.0  # written by the kernel, seen by Python
    b[1, 0] = 10.0  # written by Python, seen by the kernel
    assert _bump(kept, 1.0) == 12.5 and a[0] == 2.0
    for other in (copy.deepcopy(kept), pickle.loads(pickle.dumps(kept))):
        assert isinstance(other, Kept) and other.args[0] is not a
        assert _bump(other, 5.0) == 12.5
        assert other.args[0][0] == 7.0 and a[0] == 2.0  # the copy's arrays, not the original's


def _bits(value) -> list:
    """Every array and scalar of ``value`` through tuples and structs, arrays as their bytes."""
    if isinstance(value, Kept):
        return _bits(value.args)
    if isinstance(value, tuple):
        return [b for v in value for b in _bits(v)]
    if isinstance(value, np.ndarray):
        return [(value.dtype.str, value.shape, value.tobytes())]
    return [value]


def _unpacked_detector(y_raw, raw, x_hat, previous, tick, kept, ratio):
    flags, offset, window, learning, arbiter, bias, y, chi2_stat, over = kept.args
    return detector_tick(
        y_raw, raw, x_hat, previous, tick, flags, offset, window, learning, arbiter, bias, (y, chi2_stat, ratio, over)
    )


def _unpacked_component(sensors, tau_g_ref, tick, previous, kept):
    (m12, tau_col, cross), blocks, (sums, outlier_sums), scales, betas, (parity, window), adapt, tau_hat, converter = (
        kept.args
    )
    j, slot, outlier_slot, buffer, first, warm = tick
    return fast.component_step(
        (sensors, m12, tau_col, tau_g_ref, j, cross), blocks, (sums, slot), (outlier_sums, outlier_slot), scales,
        (betas[buffer], parity, window), previous, adapt, (tau_hat, first, warm, *converter),
    )  # fmt: skip


def _unpacked_bank(sensors, subtract, offset, speed, read, z, u_prev, y_prev, stat, kept):
    columns, threshold, n_g, eta_gc, update, output, work, sparse = kept.args
    return fast.bank_tick(
        (sensors, columns, threshold, n_g, eta_gc), subtract, offset, speed, read, z, u_prev, y_prev, update, output,
        work, stat, sparse,
    )  # fmt: skip


PACKED_CALLS = (  # (module, the packed entry point, its unpacked kernel call)
    ("service.turbine.fast_detector", "detector_tick_kept", _unpacked_detector),
    ("service.turbine.fast", "component_step_kept", _unpacked_component),
    ("service.turbine.fast", "bank_tick_kept", _unpacked_bank),
)


def test_the_packed_calls_equal_the_unpacked_kernels_on_a_live_tick(monkeypatch):
    """Each packed entry's arguments captured on live ticks of two compiled ``ftwse-2012`` runs (the bank just out
    of its transient matrices, the FDIs before and after their warm-up): the packed call and the unpacked kernel on
    copies of them return the same values and leave every array equal to the last bit."""
    plant, supervisor = turbine_pair("ftwse-2012", 2, 0, False, "numba")
    supervisor._folded = None  # the entries called one by one, from Python (one call: ``test_fast_supervisor.py``)
    stepper = _Stepper(plant, supervisor)
    captured: dict[str, list] = {name: [] for _, name, _ in PACKED_CALLS}
    packed = {}
    for module, name, _ in PACKED_CALLS:
        kernels = fast_module(module)
        packed[name] = real = getattr(kernels, name)

        def capture(*args, _real=real, _name=name):
            if stepper.ticks in (20, 498, 505, 700):
                captured[_name].append(copy.deepcopy(args))
            return _real(*args)

        monkeypatch.setattr(kernels, name, capture)
    for _ in range(701):
        stepper.run(1)
    for _, name, unpacked in PACKED_CALLS:
        assert len(captured[name]) == 4, name  # the supervisor calls the packed entry every tick
        for args in captured[name]:
            packed_args, unpacked_args = copy.deepcopy(args), copy.deepcopy(args)
            got = packed[name](*packed_args)
            expected = unpacked(*unpacked_args)
            assert _bits(got) == _bits(expected), name
            assert _bits(packed_args) == _bits(unpacked_args), name


def test_detector_arguments_pack_the_kept_arguments_in_order():
    plant, supervisor = turbine_pair("ftwse-2012", 1, 0, False, "numba")
    _Stepper(plant, supervisor).run(3)
    kept = supervisor.detector.fdi._kept
    assert all(a is kept[name] for a, name in zip(kept["packed"].args, PACKED, strict=True))


def _packed_state(supervisor) -> list:
    detector = supervisor.detector
    return _bits((detector.fdi._kept["packed"], detector.components._kept["packed"], supervisor.context._bank.kept))


def test_a_compiled_supervisor_copied_mid_run_holds_its_own_packed_arguments():
    """A deep copy and a pickle of a compiled supervisor taken once its three structs are built hold structs of
    their own arrays, and go on with the original's numbers."""
    plant, supervisor = turbine_pair("ftwse-2012", 1, 0, False, "numba")
    stepper = _Stepper(plant, supervisor)
    stepper.run(30)  # past the bank's transient matrices: all three structs built
    copies = [copy.deepcopy(supervisor), pickle.loads(pickle.dumps(supervisor))]
    for other in copies:
        fdi, components, bank = other.detector.fdi, other.detector.components, other.context._bank
        assert fdi._kept["packed"].args[0] is fdi._flags is not supervisor.detector.fdi._flags
        assert components._kept["packed"].args[2][0] is components.parity.sums
        assert bank.kept.args[5] is bank._output
    refs = stepper.refs
    for _ in range(20):
        frame = plant.measure()
        plant.control(refs)
        refs = supervisor.step(frame)
        for other in copies:
            other.step(frame)
        plant.advance()
    for other in copies:
        assert _packed_state(other) == _packed_state(supervisor)
        np.testing.assert_array_equal(other.context._bank.chi2, supervisor.context._bank.chi2)
        np.testing.assert_array_equal(other.detector.fdi.ratio, supervisor.detector.fdi.ratio)


def test_a_compiled_plant_copied_mid_run_carries_on_with_its_own_kept_arguments():
    """A deep copy and a pickle of a compiled plant (its measurement's and its controller's arguments kept as
    ``Kept`` structs) taken mid-run hold structs of their own arrays, and go on with the original's numbers to the
    last bit through the sensor faults that start after the copy (FAULTY's drift, fixed and offset: the structs
    rebuilt at each fault change) while the original's arrays are left alone."""
    scenario = parse_scenario(tomllib.loads(FAULTY))
    plant = TurbineBatch(scenario.plant, scenario.wind, scenario.faults, seed=SEED, runs=(0,), backend="numba")
    assert plant._one_measure_kernel and plant._fused_control

    def tick(batch):
        frame = batch.measure()
        batch.control(None)
        batch.advance()
        return frame

    for _ in range(700):
        tick(plant)
    copies = [copy.deepcopy(plant), pickle.loads(pickle.dumps(plant))]
    for other in copies:
        per_blade, per_row, quantities = other._kept.args[3]
        assert per_blade is other._per_blade is not plant._per_blade and quantities is other._quantities
        assert other._kept.args[2][3] is other._draws is not plant._draws
        _, zone, _, _, _, _, blades, rows, _, z, _ = other._control_kept.args
        assert zone is other.controller.zone is not plant.controller.zone
        assert z is other.discrete.inputs is not plant.discrete.inputs
        assert blades is per_blade and rows is per_row is not plant._per_row and other.tau_aero.base is per_row
    for k in range(700, 1500):
        frames = [tick(batch) for batch in (plant, *copies)]
        for other, frame in zip(copies, frames[1:], strict=True):
            np.testing.assert_array_equal(frame.sensors, frames[0].sensors, f"tick {k}")
            np.testing.assert_array_equal(other.x, plant.x, f"tick {k}")
            np.testing.assert_array_equal(other.controller.integrator, plant.controller.integrator, f"tick {k}")
    assert plant.faults.sensor_faults_active


_CACHE_PROBE = """
from windwarden.bench import _Stepper, turbine_pair
from wwcore.backend import fast_module
from wwcore import kept
plant, supervisor = turbine_pair("ftwse-2012", 1, 0, False, "numba")
_Stepper(plant, supervisor).run(25)
kernels = [kept.keep] + [getattr(fast_module(m), name) for m, name in (
    ("service.turbine.fast_detector", "detector_tick_kept"), ("service.turbine.fast", "component_step_kept"),
    ("service.turbine.fast", "bank_tick_kept"))]
for k in kernels:
    print(k.__name__, sum(k.stats.cache_hits.values()), sum(k.stats.cache_misses.values()))
"""


def test_a_second_process_loads_the_packed_kernels_from_the_cache():
    """The struct's builder and the three packed entry points are found in numba's disk cache by a fresh process
    (the first one here may compile them; a later one must not). Up to two later processes are asked: another
    test process compiling new signatures of ``keep`` at the same time rewrites its cache index and can drop an
    entry the first probe wrote (numba's index is read, extended and written back, not locked)."""
    counts = {}
    for attempt in range(3):
        out = subprocess.run(
            [sys.executable, "-c", _CACHE_PROBE], capture_output=True, text=True, env={**os.environ}, check=True
        )
        counts = {name: (int(hits), int(misses)) for name, hits, misses in map(str.split, out.stdout.splitlines())}
        if attempt and all(hits >= 1 and misses == 0 for hits, misses in counts.values()):
            break
    assert set(counts) == {"keep", "detector_tick_kept", "component_step_kept", "bank_tick_kept"}
    for name, (hits, misses) in counts.items():
        assert hits >= 1 and misses == 0, (name, hits, misses)
