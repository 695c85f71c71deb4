"""State kept as named planes of one block (``wwcore.planes``): the planes stay views of their block through a copy
and a pickle, a compiled supervisor copied mid-run goes on with the original's numbers, and the speed FDI's
compiled tick takes its per-row state as a few blocks (each array a kernel call unboxes costs about 0.1 µs)."""

from __future__ import annotations

import copy
import pickle
from typing import ClassVar

import numpy as np

from service.turbine.adaptive import HealthySpread
from service.turbine.fast_detector import detector_arguments
from windwarden.bench import _Stepper, turbine_pair
from wwcore.planes import Planes, planes


class _Owner(Planes):
    PLANES: ClassVar[dict[str, tuple]] = {"block": ("a", "b")}

    def __init__(self):
        self.block = np.zeros((2, 3, 4))
        self.__dict__.update(planes(self.block, self.PLANES["block"]))
        self.other = self.block  # another holder of the block


def _assert_views(owner: Planes) -> None:
    for block_name, names in owner.PLANES.items():
        block = getattr(owner, block_name)
        for i, name in enumerate(names):
            plane = getattr(owner, name)
            assert plane.base is block and np.shares_memory(plane, block[i]), f"{type(owner).__name__}.{name}"


def test_planes_stay_views_of_their_block_through_a_copy_and_a_pickle():
    owner = _Owner()
    owner.a += 1.0
    for other in (copy.deepcopy(owner), pickle.loads(pickle.dumps(owner))):
        _assert_views(other)
        assert other.other is other.block
        other.b += 2.0  # written by name, seen in the block
        np.testing.assert_array_equal(other.block[0], 1.0)
        np.testing.assert_array_equal(other.block[1], 2.0)
    assert (owner.block[1] == 0.0).all()  # the original is untouched


def test_a_replaced_plane_is_copied_as_it_is():
    owner = _Owner()
    owner.b = np.full((3, 4), 5.0)  # as the numpy reference may replace an array
    other = copy.deepcopy(owner)
    np.testing.assert_array_equal(other.b, 5.0)
    _assert_views(_Owner())


def test_a_spread_learns_into_its_block():
    spread = HealthySpread((2, 3), 0.01, 1.0, 2.0, 0.5)
    spread.update(np.full((2, 3), 3.0), np.ones((2, 3), dtype=bool), np.ones((2, 3)))
    _assert_views(spread)
    np.testing.assert_array_equal(spread.state[2], spread.scale2)
    np.testing.assert_array_equal(spread.offset_limit, 0.5)


def _planes_objects(supervisor) -> list[Planes]:
    fdi = supervisor.detector.fdi
    found = [fdi, fdi.spread, fdi.calibration, fdi.arbiter]
    return found + ([fdi.bias, fdi.bias.spread] if fdi.bias is not None else [])


def test_a_compiled_supervisor_copied_mid_run_goes_on_with_the_original_s_numbers():
    plant, supervisor = turbine_pair("ftwse-2012", 2, 84301, False, "numba")
    stepper = _Stepper(plant, supervisor)
    stepper.run(600)
    twin = copy.deepcopy(stepper)  # as ``Branch`` copies a chunk where it cannot fork
    for obj in _planes_objects(twin.supervisor):
        _assert_views(obj)
    assert twin.supervisor.detector.context.speed_offset is not None
    for _ in range(400):
        stepper.run(1)
        twin.run(1)
    for mine, its in zip(_planes_objects(stepper.supervisor), _planes_objects(twin.supervisor), strict=True):
        for block_name in mine.PLANES:
            np.testing.assert_array_equal(getattr(its, block_name), getattr(mine, block_name))
    fdi, twin_fdi = stepper.supervisor.detector.fdi, twin.supervisor.detector.fdi
    np.testing.assert_array_equal(twin_fdi.ratio, fdi.ratio)
    np.testing.assert_array_equal(twin_fdi.spread.scale2, fdi.spread.scale2)


def _arrays(value) -> int:
    if isinstance(value, np.ndarray):
        return 1
    if isinstance(value, tuple | list):
        return sum(_arrays(v) for v in value)
    if isinstance(value, dict):
        return sum(_arrays(v) for v in value.values())
    return 0


def test_the_speed_fdi_s_kept_kernel_arguments_are_a_few_blocks():
    _, supervisor = turbine_pair("ftwse-2012", 2, 84302, False, "numba")
    fdi = supervisor.detector.fdi
    assert fdi.bias is not None and fdi.spread.enabled and fdi.calibration.enabled
    # flags 1, offset 1, window 5, learning 3, arbiter 5, bias 7, the outputs 3 (before the planes: 48)
    assert _arrays(detector_arguments(fdi)) <= 25
