"""Compiled twin of the observer bank's tick (``wwcore.backend``): its inputs from a frame's readings
(``TurbineContext._bank_inputs``), the two products and the χ² statistics (``ObserverBank.step``), and the two in
one call (``bank_tick``; ``bank_tick_kept`` with its kept arguments as one struct). ``service.turbine.fast``
exports them with the supervisor's other kernels.

Each kernel performs the numpy reference's operations in its order, row by row, so its results equal the
reference's bit for bit (``tests/test_fast_backend.py``, ``tests/test_fast_kernels.py``). The two products are
``wwcore.blas_fast.gemm_product``'s over the matrices' nonzeros where ``gemm_layout`` finds numpy's arithmetic for
their shapes and rows (each row's: one chain, or four accumulators on the last row of an odd OpenBLAS thread
partition), else BLAS (numba's product calls the routine numpy's does).
"""

from __future__ import annotations

import numpy as np

from wwcore.blas_fast import gemm_product
from wwcore.jit import kernel


# -- observer bank (``service.turbine.bank.ObserverBank.step``, ``TurbineContext._bank_inputs``) --------------------
@kernel
def bank_inputs(sensors, columns, threshold, n_g, eta_gc, read):
    """read = sensors[:, columns] (n, 6: ω_r,m1..ω_g,m2, P_g,m, τ_g,m) with column 4 the power-speed channel
    P_g,m / (η_gc τ_g,m), or N_g × the rotor-speed mean where τ_g,m < ``threshold`` (``interfaces.power_speed``)."""
    for r in range(sensors.shape[0]):
        for c in range(columns.size):
            read[r, c] = sensors[r, columns[c]]
        torque = read[r, 5]
        if torque < threshold:
            read[r, 4] = n_g * 0.5 * (read[r, 0] + read[r, 1])
        else:
            read[r, 4] = read[r, 4] / (eta_gc * torque)


@kernel
def bank_inputs_offset(sensors, columns, threshold, n_g, eta_gc, offset, speed, read):
    """``bank_inputs``, then the speed readings (columns 0–3) kept in ``speed`` and their calibration ``offset``
    (n, 4) subtracted in ``read`` (``TurbineContext._bank_inputs`` with ``speed_offset``)."""
    bank_inputs(sensors, columns, threshold, n_g, eta_gc, read)
    for r in range(read.shape[0]):
        for c in range(4):
            speed[r, c] = read[r, c]
            read[r, c] -= offset[r, c]


@kernel
def chi2(out, width, terms, n_res, stat):
    """χ²_j = w_a² + (w_b² + w_c²) over the segment's whitened residuals (``terms``: first, second, third column
    of each segment, ``n_res`` where the segment is shorter: a zero), ``out[:, width:]`` the residuals."""
    m = stat.shape[1]
    for r in range(out.shape[0]):
        for j in range(m):
            acc = _square(out, r, width, terms[j], n_res)
            acc += _square(out, r, width, terms[m + j], n_res) + _square(out, r, width, terms[2 * m + j], n_res)
            stat[r, j] = acc


@kernel
def bank_step(z, u_prev, y_prev, update, update_in, y, output, output_in, terms, n_res, advance, stat, sparse):
    """``ObserverBank.step`` in one call: when ``advance``, z ← [z | u[n−1] | y[n−1]] · update (eq. 11), then
    out = [z | y[n]] · output (eq. 12) and χ² into ``stat`` (``chi2``); (z, out). The stacking as ``stack``; the two
    products by ``gemm_product`` over the matrices' nonzeros where ``sparse`` = (reproduced, update's nonzeros,
    output's nonzeros) says so (``gemm_layout``), else by BLAS (numba's product calls the BLAS routine numpy's does,
    with the same numbers: the tests)."""
    n, width = z.shape
    reproduced, update_nonzeros, output_nonzeros = sparse
    if advance:
        for r in range(n):
            for c in range(width):
                update_in[r, c] = z[r, c]
            update_in[r, width] = u_prev[r]
            for c in range(y_prev.shape[1]):
                update_in[r, width + 1 + c] = y_prev[r, c]
        if reproduced:
            z = np.empty((n, update.shape[1]))
            gemm_product(update_in, update, update_nonzeros, z)
        else:
            z = update_in @ update
    for r in range(n):
        for c in range(width):
            output_in[r, c] = z[r, c]
        for c in range(y.shape[1]):
            output_in[r, width + c] = y[r, c]
    if reproduced:
        out = np.empty((n, output.shape[1]))
        gemm_product(output_in, output, output_nonzeros, out)
    else:
        out = output_in @ output
    chi2(out, width, terms, n_res, stat)
    return z, out


@kernel
def bank_tick(inputs, subtract, offset, speed, read, z, u_prev, y_prev, update, output, work, stat, sparse):
    """``TurbineContext.bank``'s tick after the first in one call: the bank's inputs from the frame's readings
    (``inputs`` = (sensors, columns, threshold, N_g, η_gc): ``bank_inputs``, or ``bank_inputs_offset`` into
    ``speed`` when ``subtract``), then ``bank_step`` with y[n] = ``read[:, :5]``, always advancing; ``work`` =
    (update_in, output_in, terms, n_res). (z, out)."""
    sensors, columns, threshold, n_g, eta_gc = inputs
    if subtract:
        bank_inputs_offset(sensors, columns, threshold, n_g, eta_gc, offset, speed, read)
    else:
        bank_inputs(sensors, columns, threshold, n_g, eta_gc, read)
    update_in, output_in, terms, n_res = work
    y = read[:, :5]
    return bank_step(z, u_prev, y_prev, update, update_in, y, output, output_in, terms, n_res, True, stat, sparse)


@kernel
def bank_tick_kept(sensors, subtract, offset, speed, read, z, u_prev, y_prev, stat, kept):
    """``bank_tick`` with the arguments the bank keeps from tick to tick once its transient update matrices are
    used up as one ``wwcore.kept.Kept`` (``kept.args`` = (columns, threshold, N_g, η_gc, update, output, work,
    sparse)) and the tick's: the frame's readings, the offset, the fresh outputs, z, u[n−1], y[n−1]. (z, out)."""
    columns, threshold, n_g, eta_gc, update, output, work, sparse = kept.args
    inputs = (sensors, columns, threshold, n_g, eta_gc)
    return bank_tick(inputs, subtract, offset, speed, read, z, u_prev, y_prev, update, output, work, stat, sparse)


@kernel
def _square(out, r, width, column, n_res):
    if column == n_res:
        return 0.0
    w = out[r, width + column]
    return w * w
