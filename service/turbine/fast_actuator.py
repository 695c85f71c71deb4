"""Compiled twin of the pitch-actuator test after the block's sums (``wwcore.backend``;
``service.turbine.component_fdi.ComponentFDI._actuators``): the pushes into every window, the GLRs of the full and
the shorter windows, the learnt spread, the raise and the clearing.

As in ``service.turbine.fast``, each kernel performs the numpy reference's operations in its order, so its results
equal the reference's bit for bit (``tests/test_fast_backend.py``). ``signature_block`` computes the signature bank
and the block's sums in the order numpy's ``einsum`` and ``matmul`` give them on this numpy build (``einsum``'s
two-lane inner loop for the six-term contraction, tick order for the block's sums); the state update's product is
either a BLAS call, as numpy's stacked ``matmul`` makes one per row and candidate, or ``blas_vector_matrix``, the
arithmetic of the BLAS kernel numpy's call reaches (OpenBLAS's SkylakeX or Haswell ``dgemv_n``), used only where
``numpy_matmul_order`` found one of them equal to numpy's on this machine; the tests compare them with the numpy lines
bit for bit. With the reproduced arithmetic the candidates are the innermost loop (``_signature_block_lanes``), which
LLVM computes in SIMD lanes, one candidate a lane, each with the same operations in the same order (no ``fastmath``,
the fused multiply-adds written out), so the numbers are the same as a loop over the rows'.
"""

from __future__ import annotations

import functools

import numpy as np

from service.turbine.fast import learn_spread
from wwcore.aero_fast import maximum
from wwcore.jit import fma, inlined_kernel, kernel

# -- signature bank and block sums (``pitch_actuator.SignatureBank.block``, ``ComponentFDI._actuators``) --------------
BLAS_CALL, SKYLAKEX, HASWELL = 0, 1, 2
"""The state products' arithmetic in ``signature_block``: a BLAS call, or OpenBLAS's ``dgemv_n`` kernels of one CPU
family reproduced (``blas_vector_matrix``), as ``numpy_matmul_order`` finds them on this machine."""


@kernel
def blas_vector_matrix(a, q, j, x0, x1, x2, x3, x4, x5, order):
    """Output j of x a[q] for x = (x0 … x5) and a (K, 6, 6) in C order, with the arithmetic of the BLAS call numpy's
    ``matmul`` makes for a (1, 6) @ (6, 6) product on OpenBLAS's ``order`` kernels (``SKYLAKEX`` or ``HASWELL``;
    ``numpy_matmul_order`` checks which, if either, is numpy's on this machine).

    numpy asks for ``cblas_dgemv(RowMajor, Trans)``: OpenBLAS's ``dgemv_n`` on the column-major view of a[q], whose
    column i is a[q]'s row i, and y = +0 first (β = 0). Outputs 0–3 take the 4 × 4 micro-kernel on a's rows 0–3, then
    the 4 × 2 micro-kernel's on rows 4–5, each added to y; outputs 4–5 the scalar tail over the six rows from 0, added
    to y. On the SkylakeX kernels (OpenBLAS 0.3.31 of numpy 2.4.6, on an AVX-512 CPU that OpenBLAS names SkylakeX) the
    4 × 4 kernel is fma(a₃x₃, fma(a₂x₂, fma(a₀x₀, a₁x₁))), the 4 × 2 fma(a₄x₄, a₅x₅) and the tail a chain of fused
    multiply-adds. On the Haswell kernels (the same OpenBLAS on an AMD Zen 5 CPU, which it names Haswell) the 4 × 4
    kernel has two accumulators, fma(a₂x₂, a₀x₀) + fma(a₃x₃, a₁x₁), the 4 × 2 kernel a₄x₄ + a₅x₅, and the tail is
    the six products added in turn, unfused. Found by comparing candidate orders with numpy's products on random
    operands (0 of 800 000 values differ for SkylakeX, 0 of 960 000 for Haswell, each on its own CPU)."""
    a0, a1, a2, a3, a4, a5 = a[q, 0, j], a[q, 1, j], a[q, 2, j], a[q, 3, j], a[q, 4, j], a[q, 5, j]
    if order == HASWELL:
        if j < 4:
            return _haswell_head(a0, a1, a2, a3, a4, a5, x0, x1, x2, x3, x4, x5)
        return _haswell_tail(a0, a1, a2, a3, a4, a5, x0, x1, x2, x3, x4, x5)
    if j < 4:
        return _skylakex_head(a0, a1, a2, a3, a4, a5, x0, x1, x2, x3, x4, x5)
    return _skylakex_tail(a0, a1, a2, a3, a4, a5, x0, x1, x2, x3, x4, x5)


@kernel
def _haswell_head(a0, a1, a2, a3, a4, a5, x0, x1, x2, x3, x4, x5):
    """``blas_vector_matrix``'s outputs 0–3 on the Haswell kernels, a = the column's six coefficients."""
    head = fma(a2, x2, a0 * x0) + fma(a3, x3, a1 * x1)
    return (head + 0.0) + (a4 * x4 + a5 * x5)


@kernel
def _haswell_tail(a0, a1, a2, a3, a4, a5, x0, x1, x2, x3, x4, x5):
    """``blas_vector_matrix``'s outputs 4–5 on the Haswell kernels."""
    tail = a0 * x0 + a1 * x1 + a2 * x2 + a3 * x3 + a4 * x4
    return (tail + a5 * x5) + 0.0


@kernel
def _skylakex_head(a0, a1, a2, a3, a4, a5, x0, x1, x2, x3, x4, x5):
    """``blas_vector_matrix``'s outputs 0–3 on the SkylakeX kernels."""
    head = fma(a3, x3, fma(a2, x2, fma(a0, x0, a1 * x1)))
    return (head + 0.0) + fma(a4, x4, a5 * x5)


@kernel
def _skylakex_tail(a0, a1, a2, a3, a4, a5, x0, x1, x2, x3, x4, x5):
    """``blas_vector_matrix``'s outputs 4–5 on the SkylakeX kernels."""
    tail = fma(a0, x0, 0.0)
    tail = fma(a1, x1, tail)
    tail = fma(a2, x2, tail)
    tail = fma(a3, x3, tail)
    tail = fma(a4, x4, tail)
    return fma(a5, x5, tail) + 0.0


@kernel
def vector_matrix_rows(x, a, out, order):
    """``blas_vector_matrix`` of every x[r, q] (n, K, 6) with a[q] (K, 6, 6), into out (n, K, 6): the stacked
    ``np.matmul(x[:, :, None, :], a[None])[:, :, 0, :]`` of ``SignatureBank.block``."""
    for r in range(x.shape[0]):
        for q in range(x.shape[1]):
            x0, x1, x2, x3, x4, x5 = x[r, q, 0], x[r, q, 1], x[r, q, 2], x[r, q, 3], x[r, q, 4], x[r, q, 5]
            for j in range(6):
                out[r, q, j] = blas_vector_matrix(a, q, j, x0, x1, x2, x3, x4, x5, order)


@functools.cache
def numpy_matmul_order() -> int:
    """Which of ``blas_vector_matrix``'s orders (``SKYLAKEX``, ``HASWELL``) gives numpy's stacked ``matmul`` bit for
    bit on this machine (numpy's BLAS and the kernel it picks for this CPU), else ``BLAS_CALL``: random operands over
    twelve decades, zero rows among them, 24 000 values compared per order. Asked once per process; with
    ``BLAS_CALL``, ``signature_block`` makes BLAS calls instead."""
    rng = np.random.default_rng(20261127)
    x = rng.standard_normal((60, 40, 6)) * np.exp(6.0 * rng.standard_normal((60, 40, 1)))
    x[::7] = 0.0
    a = rng.standard_normal((40, 6, 6)) * np.exp(rng.standard_normal((40, 1, 1)))
    expected = np.matmul(x[:, :, None, :], a[None])[:, :, 0, :].view(np.int64)
    got = np.empty_like(x)
    for order in (SKYLAKEX, HASWELL):
        vector_matrix_rows(x, a, got, order)
        if np.array_equal(expected, got.view(np.int64)):
            return order
    return BLAS_CALL


WIDTH = 40
"""The candidates ``_signature_block_lanes`` computes per row and tick: K of ``pitch_actuator.SignatureBank`` (24 F,
16 T), five AVX-512 registers of doubles; a bank of fewer is padded with zeros, one of more takes
``_signature_block_calls``."""


@kernel
def signature_block(reference, x, a_t, b, c, d, w, correlation, energy, block_sums, order):
    """``SignatureBank.block`` of the block's references (ticks, n) from the states x (n, K, 6), in place, and the
    block's sums of ``ComponentFDI._actuators``: Σ_k w s_θ (n, 3, K), Σ_k s_θ² (n, K) and [Σ_k w | Σ_k s_θ]
    (n, 3 + K), with w (ticks, n, 3) the whitened residual.

    s_θ[k] = C x + r D, the six products added as numpy's ``einsum("nkj,kj->nk")`` adds them (two lanes:
    ((p0 + p2) + p4) + ((p1 + p3) + p5)); x ← x Aᵀ + r B, the product by ``blas_vector_matrix`` in ``order``
    (``numpy_matmul_order``), or with ``BLAS_CALL`` by a BLAS call (the vector-matrix product numpy's stacked
    ``matmul`` makes); the block's sums in tick order from the first tick, as ``einsum`` and ``sum(axis=0)`` add
    along the ticks. With a reproduced ``order``, ``_signature_block_lanes`` (the candidates in SIMD lanes), else
    ``_signature_block_calls``: the same operations on every element."""
    if order == BLAS_CALL or c.shape[0] > WIDTH:
        _signature_block_calls(reference, x, a_t, b, c, d, w, correlation, energy, block_sums)
    else:
        _signature_block_lanes(reference, x, a_t, b, c, d, w, correlation, energy, block_sums, order)


@kernel
def _signature_block_calls(reference, x, a_t, b, c, d, w, correlation, energy, block_sums):
    """``signature_block`` with the state products by BLAS calls (``np.dot``), one per row and candidate."""
    ticks, n = reference.shape
    k_count = c.shape[0]
    s, moved = np.empty(k_count), np.empty(6)
    _clear_sums(correlation, energy)
    for k in range(ticks):
        for r in range(n):
            rk = reference[k, r]
            for q in range(k_count):
                x0, x1, x2, x3, x4, x5 = x[r, q, 0], x[r, q, 1], x[r, q, 2], x[r, q, 3], x[r, q, 4], x[r, q, 5]
                p0, p1, p2 = x0 * c[q, 0], x1 * c[q, 1], x2 * c[q, 2]
                p3, p4, p5 = x3 * c[q, 3], x4 * c[q, 4], x5 * c[q, 5]
                s[q] = (((p0 + p2) + p4) + ((p1 + p3) + p5)) + rk * d[q]
                np.dot(x[r, q], a_t[q], moved)
                for j in range(6):
                    x[r, q, j] = moved[j] + rk * b[q, j]
            _add_tick(k, r, s, w, correlation, energy, block_sums)


@kernel
def _signature_block_lanes(reference, x, a_t, b, c, d, w, correlation, energy, block_sums, order):
    """``signature_block`` with the state products by ``blas_vector_matrix``'s arithmetic in ``order`` and the
    candidates in the innermost loop (``_lanes``, with one CPU family's column functions), whose consecutive
    iterations LLVM computes in SIMD lanes: each lane one candidate, with that candidate's operations in their order
    (no reassociation; fused multiply-adds where ``blas_vector_matrix`` has them). Here each row's state and block
    sums are one block of ``work`` (n, 3, 6, WIDTH): planes 0 and 1 the state of even and odd ticks (6, WIDTH),
    plane 2 Σ s², Σ w_i s (3) and Σ s; the coefficients (49, WIDTH); transposed in and out. Allocated here with the
    constant ``WIDTH`` and the planes named by constants (the ticks taken in pairs), so that LLVM knows every offset
    between the loop's memory accesses and the trip count (the candidates past K are zeros, never read back). Σ s_θ
    and Σ w start at −0, which adds to every number exactly (the first tick's value, as numpy's sum)."""
    ticks, n = reference.shape
    k_count = c.shape[0]
    coefficients = np.zeros((49, WIDTH))  # Aᵀ[i, j] in row 6 i + j, then B, C, D
    work = np.zeros((n, 3, 6, WIDTH))
    for q in range(k_count):
        for i in range(6):
            for j in range(6):
                coefficients[6 * i + j, q] = a_t[q, i, j]
            coefficients[36 + i, q], coefficients[42 + i, q] = b[q, i], c[q, i]
        coefficients[48, q] = d[q]
        for r in range(n):
            for j in range(6):
                work[r, 0, j, q] = x[r, q, j]
            work[r, 2, 4, q] = -0.0
    for r in range(n):
        for i in range(3):
            block_sums[r, i] = -0.0
    for k in range(ticks):
        for r in range(n):
            rk, w0, w1, w2 = reference[k, r], w[k, r, 0], w[k, r, 1], w[k, r, 2]
            w_r = (w0, w1, w2)
            if k % 2 == 0 and order == HASWELL:
                _lanes(work, 0, 1, coefficients, r, rk, w_r, _haswell_head, _haswell_tail)
            elif order == HASWELL:
                _lanes(work, 1, 0, coefficients, r, rk, w_r, _haswell_head, _haswell_tail)
            elif k % 2 == 0:
                _lanes(work, 0, 1, coefficients, r, rk, w_r, _skylakex_head, _skylakex_tail)
            else:
                _lanes(work, 1, 0, coefficients, r, rk, w_r, _skylakex_head, _skylakex_tail)
            block_sums[r, 0] += w0
            block_sums[r, 1] += w1
            block_sums[r, 2] += w2
    last = ticks % 2
    for r in range(n):
        for q in range(k_count):
            for j in range(6):
                x[r, q, j] = work[r, last, j, q]
            energy[r, q] = work[r, 2, 0, q]
            for i in range(3):
                correlation[r, i, q] = work[r, 2, 1 + i, q]
            block_sums[r, 3 + q] = work[r, 2, 4, q]


@inlined_kernel
def _signature_lane(x0, x1, x2, x3, x4, x5, rk, a, q, w, work, r):
    """s_θ = C x + r D of candidate q, the products added as ``einsum`` adds them, added to row r's block sums."""
    p0, p1, p2 = x0 * a[42, q], x1 * a[43, q], x2 * a[44, q]
    p3, p4, p5 = x3 * a[45, q], x4 * a[46, q], x5 * a[47, q]
    s = (((p0 + p2) + p4) + ((p1 + p3) + p5)) + rk * a[48, q]
    work[r, 2, 0, q] += s * s
    work[r, 2, 1, q] += w[0] * s
    work[r, 2, 2, q] += w[1] * s
    work[r, 2, 3, q] += w[2] * s
    work[r, 2, 4, q] += s


@inlined_kernel
def _column(a, j, q):
    """Column j of candidate q's Aᵀ (six numbers) in ``_signature_block_lanes``'s coefficients."""
    return a[j, q], a[6 + j, q], a[12 + j, q], a[18 + j, q], a[24 + j, q], a[30 + j, q]


@inlined_kernel
def _lanes(work, now, moved, a, r, rk, w, head, tail):
    """Row r's tick: its signatures added to the block's sums, and moved[r] = now[r] Aᵀ + r B, the product by
    ``head`` (outputs 0–3) and ``tail`` (4–5) of one CPU family's ``blas_vector_matrix`` arithmetic
    (``_signature_block_lanes``; the six outputs written out, so that the loop over the candidates is the
    innermost); w = the row's (w0, w1, w2) of the tick."""
    for q in range(WIDTH):
        x0, x1, x2 = work[r, now, 0, q], work[r, now, 1, q], work[r, now, 2, q]
        x3, x4, x5 = work[r, now, 3, q], work[r, now, 4, q], work[r, now, 5, q]
        _signature_lane(x0, x1, x2, x3, x4, x5, rk, a, q, w, work, r)
        work[r, moved, 0, q] = head(*_column(a, 0, q), x0, x1, x2, x3, x4, x5) + rk * a[36, q]
        work[r, moved, 1, q] = head(*_column(a, 1, q), x0, x1, x2, x3, x4, x5) + rk * a[37, q]
        work[r, moved, 2, q] = head(*_column(a, 2, q), x0, x1, x2, x3, x4, x5) + rk * a[38, q]
        work[r, moved, 3, q] = head(*_column(a, 3, q), x0, x1, x2, x3, x4, x5) + rk * a[39, q]
        work[r, moved, 4, q] = tail(*_column(a, 4, q), x0, x1, x2, x3, x4, x5) + rk * a[40, q]
        work[r, moved, 5, q] = tail(*_column(a, 5, q), x0, x1, x2, x3, x4, x5) + rk * a[41, q]


@kernel
def _clear_sums(correlation, energy):
    """Σ w s_θ and Σ s_θ² start at +0."""
    for r in range(energy.shape[0]):
        for q in range(energy.shape[1]):
            energy[r, q] = 0.0
            for i in range(3):
                correlation[r, i, q] = 0.0


@kernel
def _add_tick(k, r, s, w, correlation, energy, block_sums):
    """Tick k's signatures s (K,) of row r added to its block sums (``signature_block``)."""
    k_count = s.size
    for q in range(k_count):
        energy[r, q] += s[q] * s[q]
    for i in range(3):
        wi = w[k, r, i]
        for q in range(k_count):
            correlation[r, i, q] += wi * s[q]
    if k == 0:
        for q in range(k_count):
            block_sums[r, 3 + q] = s[q]
        for i in range(3):
            block_sums[r, i] = w[k, r, i]
    else:
        for q in range(k_count):
            block_sums[r, 3 + q] += s[q]
        for i in range(3):
            block_sums[r, i] += w[k, r, i]


# -- pitch-actuator test (``service.turbine.component_fdi.ComponentFDI._actuators``, after the block's sums) -----------
@kernel
def _push(ring, total, slot, x):
    """``_Window.push`` of x (any shape, flat in C order): total += x − ring[slot], ring[slot] = x."""
    r, t, v = ring[slot].reshape(x.size), total.reshape(x.size), x.reshape(x.size)  # views (contiguous)
    for i in range(v.size):
        t[i] += v[i] - r[i]
        r[i] = v[i]


@kernel
def _actuator_glr(correlation, energy, variance, n_faults, sum_w, sum_s, count, out):
    """``pitch_actuator.glr`` with the window's offset maximised out (eq. 5), Λ (n, 3) into ``out``."""
    k = energy.shape[1]
    centred = np.empty(k)
    for r in range(energy.shape[0]):
        for c in range(k):
            centred[c] = energy[r, c] - sum_s[r, c] * sum_s[r, c] / count
        for b in range(3):
            best_fault, best_tolerance = -np.inf, -np.inf
            for c in range(k):
                corr = correlation[r, b, c] - sum_w[r, b] * sum_s[r, c] / count
                likelihood = (corr - 0.5 * centred[c]) / variance[r, b]
                if c < n_faults:
                    best_fault = likelihood if c == 0 else maximum(best_fault, likelihood)
                else:
                    best_tolerance = likelihood if c == n_faults else maximum(best_tolerance, likelihood)
            out[r, b] = best_fault - best_tolerance


@kernel
def actuator_test(z1, z2, windows, short_windows, slots, thresholds, targets, state, learning, flags):
    """``ComponentFDI._actuators`` from the block's Σ w (``z1``) and Σ (w − b̂)² in units of σ_w² (``z2``) on: the
    pushes of the block's sums into the full window and into each shorter one (``slots`` in
    that order, three each), the rest counters, the full window's Λ (eq. 3 and 5, into ``glr``), ŝ² and b̂ learnt
    from the quiet rows, then, with the full window full, the raise and the clearing on the shorter windows
    (shortest first) and the full one. ``windows`` = (Σ w s_θ, Σ s_θ², [Σ w | Σ s_θ]) of the block and the full
    window's (ring, total) of each; ``short_windows``: (ring, total) × 3 of each shorter window; ``thresholds`` =
    (block, 0.75 σ_β², h, h_clear, the full window's count of samples after the push, the shorter windows' (array),
    the number of F candidates, whether the full window is full); ``targets`` = the actuator, m1 and m2 columns of
    ``flags`` (n, targets), in place; ``state`` = (blocks of rest (n,), cleared rest (n, 3), the window in blocks,
    Λ (n, 3) out); ``learning`` = (enabled, min_weight, s_max², state of the actuator's ``HealthySpread``)."""
    block, design_variance, h, h_clear, count, short_counts, n_faults, full = thresholds
    actuator_t, m1_t, m2_t = targets
    rest, cleared_rest, window_blocks, glr = state
    enabled, min_weight, max_scale2, spread = learning
    block_c, block_e, block_t, (c_ring, c_total), (e_ring, e_total), (t_ring, t_total) = windows
    n = z1.shape[0]
    q, x = np.empty((n, 3)), np.empty((n, 3))
    for r in range(n):
        for b in range(3):
            q[r, b] = z2[r, b] * (1.0 / block)
            x[r, b] = z1[r, b] * (1.0 / block)
    _push(c_ring, c_total, slots[0], block_c)
    _push(e_ring, e_total, slots[1], block_e)
    _push(t_ring, t_total, slots[2], block_t)
    for m in range(len(short_windows)):
        sc_ring, sc_total, se_ring, se_total, st_ring, st_total = short_windows[m]
        _push(sc_ring, sc_total, slots[3 + 3 * m], block_c)
        _push(se_ring, se_total, slots[4 + 3 * m], block_e)
        _push(st_ring, st_total, slots[5 + 3 * m], block_t)
    for r in range(n):
        sensor_flagged = False
        for b in range(3):
            sensor_flagged = sensor_flagged or flags[r, m1_t[b]] or flags[r, m2_t[b]]
        rest[r] = window_blocks if sensor_flagged else max(rest[r] - 1, 0)
    scale2 = spread[2]
    variance = np.empty((n, 3))
    for r in range(n):
        for b in range(3):
            variance[r, b] = design_variance * scale2[r, b]
    _actuator_glr(c_total, e_total, variance, n_faults, t_total[:, :3], t_total[:, 3:], count, glr)
    if enabled:  # w²'s healthy scale ŝ², learnt while no blade is suspected
        healthy = np.empty((n, 1), dtype=np.bool_)
        for r in range(n):
            quiet = rest[r] == 0
            for b in range(3):
                quiet = quiet and not flags[r, actuator_t[b]]
                if full:
                    quiet = quiet and glr[r, b] <= h
            healthy[r, 0] = quiet
        learn_spread(q, x, healthy, min_weight, max_scale2, spread)
    if not full:
        return
    flagged = np.empty((n, 3), dtype=np.bool_)
    any_flagged = False
    for r in range(n):
        worst = 0  # np.argmax: the first largest, the first nan if any
        for b in range(1, 3):
            if glr[r, worst] == glr[r, worst] and (glr[r, b] > glr[r, worst] or glr[r, b] != glr[r, b]):
                worst = b
        fault = glr[r, worst] > h and rest[r] == 0 and not cleared_rest[r, worst] > 0
        for b in range(3):
            flagged[r, b] = flags[r, actuator_t[b]] or (fault and b == worst)
            any_flagged = any_flagged or flagged[r, b]
    clear = np.zeros((n, 3), dtype=np.bool_)
    if any_flagged:  # the shorter windows' Λ only decide clearings
        recent_fault = np.zeros((n, 3), dtype=np.bool_)
        glr_m = np.empty((n, 3))
        for m in range(len(short_windows)):
            sc_ring, sc_total, se_ring, se_total, st_ring, st_total = short_windows[m]
            sums_w, sums_s = st_total[:, :3], st_total[:, 3:]
            _actuator_glr(sc_total, se_total, variance, n_faults, sums_w, sums_s, short_counts[m], glr_m)
            for r in range(n):
                for b in range(3):
                    clear[r, b] = clear[r, b] or (glr_m[r, b] <= -h_clear and not recent_fault[r, b])
                    recent_fault[r, b] = recent_fault[r, b] or glr_m[r, b] > h
        for r in range(n):
            for b in range(3):
                clear[r, b] = clear[r, b] or (glr[r, b] <= -h_clear and not recent_fault[r, b])
    for r in range(n):
        for b in range(3):
            kept = flagged[r, b] and not clear[r, b] and rest[r] == 0
            cleared_rest[r, b] = window_blocks if flagged[r, b] and not kept else max(cleared_rest[r, b] - 1, 0)
            flags[r, actuator_t[b]] = kept
