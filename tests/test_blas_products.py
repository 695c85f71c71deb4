"""The compiled code's reproductions of numpy's BLAS products (``wwcore.blas_fast``, ``fast_actuator``) against numpy's
``@`` on this machine, to the last bit: the observer bank's and the wind recovery's sparse products over their
matrices' nonzeros with the layout ``gemm_layout`` finds (odd partitions' tail rows included), the signature bank's
vector-matrix products and the plant's one-row step product. Skipped where numpy's BLAS is not a kernel they
reproduce. The other kernels one by one: ``tests/test_fast_kernels.py``.
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np
import pytest

from plant_sim.turbine.dynamics import N_STATES, DiscreteStep
from plant_sim.turbine.faults import FaultState
from service.turbine.bank import SPARSE_PRODUCT_ROWS, ObserverBank
from service.turbine.supervisor import TurbineSupervisor
from service.turbine.wind_recovery import WindRecovery
from tests.fast_compare import SEED
from wwcore.backend import fast_module
from wwcore.turbine_params import BENCHMARK


@pytest.mark.parametrize("n", [2, 7, 17, 49, 50, 100, 450])
def test_the_sparse_product_equals_numpy_matmul(n):
    # ``fast.gemm_product`` over a sparse matrix's nonzeros against numpy's dense ``@`` (BLAS's gemm), for the
    # observer bank's and the wind recovery's shapes and random sparse matrices, with zero entries, a zero row,
    # an inf and a NaN row: equal to the last bit; a plain loop product differs on the same operands
    fast = fast_module("service.turbine.fast")
    rng = np.random.default_rng(SEED + n)
    layouts = {shape: fast.gemm_layout(n, *shape) for shape in ((82, 76), (81, 108), (152, 54))}
    if all(layout is None for layout in layouts.values()):
        pytest.skip("numpy's BLAS on this machine is not the kernel gemm_product reproduces")
    for (k_count, n_columns), layout in layouts.items():
        if layout is None:  # the recovery's map at odd row counts: BLAS's product
            continue
        matrix = rng.standard_normal((k_count, n_columns)) * (rng.random((k_count, n_columns)) < 0.08)
        a = rng.standard_normal((n, k_count)) * np.exp(3.0 * rng.standard_normal((n, 1)))
        a[0] = 0.0
        a[1, 3], a[-1, 5] = np.inf, np.nan
        with np.errstate(invalid="ignore"):  # inf · 0
            expected = a @ matrix
        got = np.empty_like(expected)
        fast.gemm_product(a, matrix, fast.nonzeros(matrix, layout), got)
        np.testing.assert_array_equal(got, expected)
        finite = np.isfinite(expected)
        np.testing.assert_array_equal(got[finite].view(np.int64), expected[finite].view(np.int64))
        rows, dense = rng.standard_normal((8, k_count)), rng.standard_normal((k_count, n_columns))
        assert (np.einsum("nk,kj->nj", rows, dense, optimize=False) != rows @ dense).any()


@pytest.mark.parametrize("n", [17, 25, 49, 65, 100])
def test_the_layout_takes_the_odd_partitions_tail_rows(n):
    # ``gemm_layout`` at row counts where OpenBLAS's thread partitions have an odd row count (an odd count's last
    # row at one or two BLAS threads; 100 rows' four at two): their last rows sum in four accumulators, the others
    # in one chain; with them the layout reproduces numpy's product for both of the bank's shapes, and the bank
    # takes the sparse products
    fast = fast_module("service.turbine.fast")
    if fast.gemm_layout(50, 82, 76) is None:
        pytest.skip("numpy's BLAS on this machine is not the kernel gemm_product reproduces")
    layouts = [fast.gemm_layout(n, k_count, n_columns) for k_count, n_columns in ((82, 76), (81, 108))]
    assert None not in layouts and (n % 2 == 0 or any(layout.tails for layout in layouts))
    assert ObserverBank(TurbineSupervisor(n).context.bank_design, n, fast=fast)._sparse[0]


@pytest.mark.parametrize("n", [2, SPARSE_PRODUCT_ROWS, 50])
def test_the_recovery_map_product_equals_numpy_matmul(n):
    # ``WindRecovery._mapped`` (the map from [x̂[n], x̂[n−1]] to every observer's raw τ̂_r, ω̂_r, ω̂_g) on the compiled
    # backend against numpy's ``stacked @ map``: over the map's nonzeros from ``SPARSE_PRODUCT_ROWS`` rows where
    # ``gemm_layout`` finds BLAS's arithmetic, BLAS's product below; equal to the last bit, zeros' signs included,
    # with a zero row and a NaN reading
    design = TurbineSupervisor(n).context.bank_design
    fast = fast_module("service.turbine.fast")
    recovery = WindRecovery(BENCHMARK, design, n, 0.3, 2.0, fast=fast)
    sparse = n >= SPARSE_PRODUCT_ROWS and fast.gemm_layout(n, *recovery._map.shape) is not None
    assert (recovery._map_nonzeros is not None) == sparse
    assert WindRecovery(BENCHMARK, design, n, 0.3, 2.0)._map_nonzeros is None
    assert np.count_nonzero(recovery._map) < 0.05 * recovery._map.size
    rng = np.random.default_rng(SEED + n)
    scale = np.abs(rng.normal(1e3, 1e3, recovery._map.shape[0]))
    for k in range(5):
        stacked = scale * rng.standard_normal((n, recovery._map.shape[0]))
        stacked[0] = 0.0
        if k == 3:
            stacked[-1, 7] = np.nan
        expected, got = stacked @ recovery._map, recovery._mapped(np.ascontiguousarray(stacked))
        np.testing.assert_array_equal(got, expected)
        np.testing.assert_array_equal(np.signbit(got), np.signbit(expected))


def _blas_core() -> str:
    """The kernel family numpy's bundled OpenBLAS picked for this CPU (``openblas_get_corename``), or "" where numpy
    bundles none."""
    for path in sorted((Path(np.__file__).parent.parent / "numpy.libs").glob("lib*openblas*.so*")):
        library = ctypes.CDLL(str(path))
        for symbol in ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename", "openblas_get_corename"):
            name = getattr(library, symbol, None)
            if name is not None:
                name.restype = ctypes.c_char_p
                return name().decode()
    return ""


def test_the_reproduced_blas_product_equals_numpy_matmul():
    # ``fast_actuator.blas_vector_matrix`` against numpy's stacked ``(1, 6) @ (6, 6)`` (one BLAS ``dgemv`` per
    # product) on random states of the bank's own matrices and on random matrices over twelve decades, zeros among
    # them, to the last bit; on the random matrices a plain loop product and the other CPU family's order differ. On
    # OpenBLAS's SkylakeX and Haswell kernels the self-check must find its order (a wide batch otherwise takes the
    # numpy path, N-20)
    fast_actuator = fast_module("service.turbine.fast_actuator")
    core = _blas_core()
    expected_order = {"SkylakeX": fast_actuator.SKYLAKEX, "Haswell": fast_actuator.HASWELL}.get(core)
    if expected_order is not None:
        assert fast_actuator.numpy_matmul_order() == expected_order, core
    order = fast_actuator.numpy_matmul_order()
    if order == fast_actuator.BLAS_CALL:
        pytest.skip(f"numpy's BLAS on this machine ({core or 'unknown'}) is not a kernel blas_vector_matrix reproduces")
    rng = np.random.default_rng(SEED)
    bank_matrices = TurbineSupervisor(1, backend="numpy").detector.components.signatures._At
    random_matrices = rng.standard_normal((40, 6, 6)) * np.exp(rng.standard_normal((40, 1, 1)))
    for a_t in (bank_matrices, random_matrices):
        x = rng.standard_normal((500, len(a_t), 6)) * np.exp(6.0 * rng.standard_normal((500, len(a_t), 1)))
        x[::11, :, 2:] = 0.0
        x[5::13] = -0.0
        expected = np.matmul(x[:, :, None, :], a_t[None])[:, :, 0, :]
        got = np.empty_like(x)
        fast_actuator.vector_matrix_rows(x, a_t, got, order)
        np.testing.assert_array_equal(got.view(np.int64), expected.view(np.int64))
    other = fast_actuator.HASWELL if order == fast_actuator.SKYLAKEX else fast_actuator.SKYLAKEX
    fast_actuator.vector_matrix_rows(x, random_matrices, got, other)
    assert (got != expected).mean() > 0.1
    loop = np.einsum("nqi,qij->nqj", x, random_matrices, optimize=False)  # the six products added in turn, unfused
    assert (loop != expected).mean() > 0.1


def test_the_plant_s_one_row_step_product_equals_numpy_matmul():
    # ``wwcore.blas_fast.vector_matrix`` against numpy's one-row (1, 16) @ (16, 11) (one BLAS ``dgemv``) on the
    # plant's own step matrices (nominal, and with a slower pitch actuator and a lower drive-train efficiency) and on
    # random matrices over twelve decades, zeros and −0 among the inputs, to the last bit and zeros' signs; the
    # plain loop (the sixteen products added in turn) differs. On OpenBLAS's Haswell kernels the self-check must hold
    # (a one-row plant otherwise keeps numpy's product in ``advance``)
    blas_fast = fast_module("wwcore.blas_fast")
    core, shape = _blas_core(), (N_STATES + 5, N_STATES)
    if core == "Haswell":
        assert blas_fast.vector_matrix_is_numpys(*shape), core
    if not blas_fast.vector_matrix_is_numpys(*shape):
        pytest.skip(f"numpy's BLAS on this machine ({core or 'unknown'}) is not the kernel vector_matrix reproduces")
    rng = np.random.default_rng(SEED)
    step, faults, matrices = DiscreteStep(BENCHMARK, 1), FaultState(1, BENCHMARK), []
    for change in (None, "pitch", "efficiency"):
        if change == "pitch":  # blade 2's actuator at ω_n = 3.42 rad/s, ζ = 0.9
            faults.pitch_a0 = faults.pitch_a0 * [1.0, 3.42**2 / faults.pitch_a0[0, 1], 1.0]
            faults.pitch_a1 = faults.pitch_a1 * [1.0, 2 * 0.9 * 3.42 / faults.pitch_a1[0, 1], 1.0]
        if change == "efficiency":
            faults.eta_dt = 0.92 * faults.eta_dt
        step.update(faults)
        matrices.append(step.shared.copy())
    assert not np.array_equal(matrices[0], matrices[1]) and not np.array_equal(matrices[1], matrices[2])
    matrices.append(rng.standard_normal(shape) * np.exp(rng.standard_normal((shape[0], 1))))
    got, differ = np.empty(shape[1]), 0
    for a in matrices:
        for i in range(500):
            x = rng.standard_normal(shape[0]) * np.exp(6.0 * rng.standard_normal())
            x[i % shape[0]] = 0.0 if i % 2 else -0.0
            expected = (x[None] @ a)[0]
            blas_fast.vector_matrix(x, a, got)
            np.testing.assert_array_equal(got.view(np.int64), expected.view(np.int64))
            loop = np.zeros(shape[1])
            for k in range(shape[0]):
                loop = loop + x[k] * a[k]
            differ += not np.array_equal(loop, expected)
    assert differ > 0.2 * 500 * len(matrices)
