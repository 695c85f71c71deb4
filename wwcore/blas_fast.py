"""Matrix products with the arithmetic of numpy's BLAS, for the compiled twins (``wwcore.backend``): ``gemm`` over a
sparse matrix's nonzeros (the turbine observer bank's two products and the wind recovery's map,
``service.turbine.fast``, decision N-20) and one row's ``gemv`` (the turbine plant's exact step,
``plant_sim.turbine.fast``). ``gemm_layout`` and ``vector_matrix_is_numpys`` find, once per shape (and row count),
whether this machine's BLAS adds the products as the kernels do; callers keep numpy's product where it does not.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np

from wwcore.jit import fma, kernel


@kernel
def gemm_product(a, matrix, nonzeros, out):
    """out = a @ matrix for a (n, K) and matrix (K, N), with the arithmetic of numpy's BLAS product (``gemm``, ≥ 2
    rows) as ``gemm_layout`` found it for these shapes and rows, over the matrix's nonzeros ``nonzeros`` = (starts
    (N + 1,), ks, values, lanes_from, tails): column j's nonzeros are values[starts[j]:starts[j + 1]] at rows
    ks[...], in row order.

    Columns before ``lanes_from``: one chain of fused multiply-adds over k from +0 (OpenBLAS's SkylakeX kernels'
    per-output accumulator), except on the rows ``tails`` (the last row of each of OpenBLAS's thread partitions
    with an odd row count): four accumulators, k's below K − K mod 4 by k mod 4, the last K mod 4 k's into
    accumulator 0 in turn, then (l₀ + l₁) + (l₂ + l₃) (the kernel's one-row tail); from ``lanes_from`` on: eight
    accumulators, k's by k mod 8, then ((l₀ + l₁) + (l₂ + l₃)) + ((l₄ + l₅) + (l₆ + l₇)) (its small-matrix
    kernel's last columns). Leaving out a zero coefficient changes no result: the accumulators start at +0 and
    never become −0 (a fused multiply-add rounds an exact zero sum to +0), so adding x · 0 = ±0 to one leaves it
    as it was, for finite x. A row with a non-finite entry takes every k (its products with the zeros are NaN, as
    BLAS's). The rows' chains are independent: the loops run over the rows innermost, so that they overlap, on
    a's columns transposed, only those a nonzero reads (the wind recovery's map reads 67 of its 152); the tail
    rows are then summed again one by one."""
    starts, ks, values, lanes_from, tails = nonzeros
    n, k_count = a.shape
    used = np.zeros(k_count, dtype=np.bool_)
    for e in range(ks.size):
        used[ks[e]] = True
    a_t = np.empty((k_count, n))  # (K, n): a coefficient's products with every row, contiguous; rows read only
    for k in range(k_count):
        if used[k]:
            for r in range(n):
                a_t[k, r] = a[r, k]
    acc = np.empty(n)
    lanes = np.empty((8, n))
    for j in range(out.shape[1]):
        if j < lanes_from:
            acc[:] = 0.0
            for e in range(starts[j], starts[j + 1]):
                row, value = a_t[ks[e]], values[e]
                for r in range(n):
                    acc[r] = fma(row[r], value, acc[r])
            for r in range(n):
                out[r, j] = acc[r]
            continue
        lanes[:] = 0.0
        for e in range(starts[j], starts[j + 1]):
            k = ks[e]
            row, value, lane = a_t[k], values[e], lanes[k % 8]
            for r in range(n):
                lane[r] = fma(row[r], value, lane[r])
        for r in range(n):
            low = (lanes[0, r] + lanes[1, r]) + (lanes[2, r] + lanes[3, r])
            out[r, j] = low + ((lanes[4, r] + lanes[5, r]) + (lanes[6, r] + lanes[7, r]))
    four = lanes[:4, 0]
    for t in range(tails.size):  # the tail rows' columns before lanes_from: four accumulators
        r = tails[t]
        for j in range(min(lanes_from, out.shape[1])):
            four[:] = 0.0
            for e in range(starts[j], starts[j + 1]):
                k = ks[e]
                _four_add(four, k, k_count, a[r, k], values[e])
            out[r, j] = (four[0] + four[1]) + (four[2] + four[3])
    for r in range(n):  # rows with a non-finite entry: every k, the zeros' products included
        non_finite = 0
        for k in range(k_count):
            non_finite += 0 if np.isfinite(a[r, k]) else 1
        if non_finite == 0:
            continue
        tail = False
        for t in range(tails.size):
            tail = tail or tails[t] == r
        for j in range(out.shape[1]):
            if j < lanes_from and tail:
                four = lanes[:4, 0]
                four[:] = 0.0
                for k in range(k_count):
                    _four_add(four, k, k_count, a[r, k], matrix[k, j])
                out[r, j] = (four[0] + four[1]) + (four[2] + four[3])
                continue
            if j < lanes_from:
                total = 0.0
                for k in range(k_count):
                    total = fma(a[r, k], matrix[k, j], total)
                out[r, j] = total
                continue
            for i in range(8):
                lanes[i, 0] = 0.0
            for k in range(k_count):
                lanes[k % 8, 0] = fma(a[r, k], matrix[k, j], lanes[k % 8, 0])
            low = (lanes[0, 0] + lanes[1, 0]) + (lanes[2, 0] + lanes[3, 0])
            out[r, j] = low + ((lanes[4, 0] + lanes[5, 0]) + (lanes[6, 0] + lanes[7, 0]))


@kernel
def _four_add(four, k, k_count, x, value):
    """x · value fused into accumulator k mod 4 of ``four``, or into accumulator 0 for the last K mod 4 k's."""
    i = k % 4 if k < k_count - k_count % 4 else 0
    four[i] = fma(x, value, four[i])


class Layout(NamedTuple):
    """``gemm_product``'s arithmetic for one product's shape and row count (``gemm_layout``): the first column
    summed in eight lanes, and the rows summed in four accumulators."""

    lanes_from: int
    tails: tuple[int, ...] = ()


def nonzeros(matrix: np.ndarray, layout: Layout | int) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, np.ndarray]:
    """``gemm_product``'s form of ``matrix`` (K, N): its nonzeros column by column, in row order, and ``layout``
    (a ``Layout``, or the first column in eight lanes with no four-accumulator rows)."""
    layout = layout if isinstance(layout, Layout) else Layout(int(layout))
    columns, rows = np.nonzero(matrix.T)  # sorted by column, then row
    starts = np.searchsorted(columns, np.arange(matrix.shape[1] + 1)).astype(np.int64)
    values = np.ascontiguousarray(matrix[rows, columns])
    return starts, rows.astype(np.int64), values, int(layout.lanes_from), np.array(layout.tails, dtype=np.int64)


@functools.cache
def gemm_layout(n: int, k_count: int, n_columns: int, seed: int = 20261127) -> Layout | None:
    """``gemm_product``'s layout for an (n, K) @ (K, N) product such that it equals numpy's ``@`` bit for bit on
    this machine, or None where none does (another BLAS or CPU, or one row, which numpy multiplies by ``gemv``).
    For each candidate first column in eight lanes (none; the last N mod 8 columns), each row is matched with
    numpy's product of random dense operands over six decades as one chain or four accumulators (``tails``: the
    rows where only the latter equals it; a row neither equals rejects the candidate), three times; the layout is
    then checked on a fourth product with zero entries and a zero row. Asked once per process and shape."""
    if n < 2:
        return None
    rng = np.random.default_rng(seed)
    operands = []
    for _ in range(4):
        a = rng.standard_normal((n, k_count)) * np.exp(3.0 * rng.standard_normal((n, 1)))
        operands.append((a, rng.standard_normal((k_count, n_columns))))
    a, _ = operands[-1]
    a[:, ::7] = 0.0
    a[n // 2] = 0.0
    every_row = tuple(range(n))
    for lanes_from in (n_columns, n_columns - n_columns % 8):
        chain, four = np.ones(n, dtype=bool), np.ones(n, dtype=bool)
        for a, matrix in operands[:-1]:
            expected = (a @ matrix).view(np.int64)
            for layout, matches in ((Layout(lanes_from), chain), (Layout(lanes_from, every_row), four)):
                got = np.empty((n, n_columns))
                gemm_product(a, matrix, nonzeros(matrix, layout), got)
                matches &= (got.view(np.int64) == expected).all(axis=1)
        if not (chain | four).all():
            continue
        layout = Layout(lanes_from, tuple(int(r) for r in np.flatnonzero(~chain)))
        a, matrix = operands[-1]
        got = np.empty((n, n_columns))
        gemm_product(a, matrix, nonzeros(matrix, layout), got)
        if np.array_equal(got.view(np.int64), (a @ matrix).view(np.int64)):
            return layout
    return None


@kernel
def vector_matrix(x, a, out):
    """out = x @ a for x (K,), K a multiple of 4, and a (K, N) in C order, with the arithmetic of numpy's one-row
    product (1, K) @ (K, N): ``cblas_dgemv(RowMajor, Trans)``, OpenBLAS's ``dgemv_n`` on a's column-major view
    (column i is a's row i) onto y = +0 (β = 0), on its Haswell kernels (the ones OpenBLAS picks on this machine,
    decision N-40). Outputs below N − N mod 4 take the 4 × 4 micro-kernel, each block of four inputs as
    fma(a₂x₂, a₀x₀) + fma(a₃x₃, a₁x₁) added to y in turn; the last N mod 4 outputs the scalar tail, the K products
    added in turn, unfused, from 0, then added to y. ``vector_matrix_is_numpys`` checks it on this machine."""
    k_count, n = a.shape
    blocked = n - n % 4
    for j in range(blocked):
        y = 0.0
        for i in range(0, k_count, 4):
            y = y + (fma(a[i + 2, j], x[i + 2], a[i, j] * x[i]) + fma(a[i + 3, j], x[i + 3], a[i + 1, j] * x[i + 1]))
        out[j] = y
    for j in range(blocked, n):
        total = 0.0
        for i in range(k_count):
            total = total + a[i, j] * x[i]
        out[j] = 0.0 + total


@functools.cache
def vector_matrix_is_numpys(k_count: int, n_columns: int, seed: int = 20261128) -> bool:
    """Whether ``vector_matrix`` equals numpy's (1, K) @ (K, N) bit for bit on this machine (numpy's BLAS and the
    kernels it picks for this CPU): 200 random matrices with a fifth of their entries zero, 10 rows each over twelve
    decades with zero entries, every output compared. Asked once per process and shape."""
    if k_count % 4:
        return False
    rng = np.random.default_rng(seed)
    got = np.empty(n_columns)
    for _ in range(200):
        a = rng.standard_normal((k_count, n_columns)) * np.exp(rng.standard_normal((k_count, 1)))
        a[rng.random(a.shape) < 0.2] = 0.0
        x = rng.standard_normal((10, k_count)) * np.exp(6.0 * rng.standard_normal((10, 1)))
        x[:, ::5] = 0.0
        for row in x:
            vector_matrix(row, a, got)
            if not np.array_equal(got.view(np.int64), (row[None] @ a)[0].view(np.int64)):
                return False
    return True
