"""Compiled twin of the farm supervisor's per-sample arithmetic (``wwcore.backend``): the analytic detector's learnt
levels and spread ratios (``service.farm.baseline.LearntLevel.update``). The same operations in the reference's
order, so the same numbers bit for bit (``tests/test_fast_backend_farm.py``); the lock-in, the CUSUMs and the decisions
stay numpy code around it, and the available power's wind inversion is ``wwcore.aero_fast``'s.
"""

from __future__ import annotations

import numpy as np

from wwcore.aero_fast import maximum
from wwcore.jit import kernel


@kernel
def learn_level(r, design_std, frozen, alpha_level, alpha_block, block, state):
    """``LearntLevel.update`` on (n, m) arrays, in place: where not ``frozen`` (each of ``r``, ``design_std`` and
    ``frozen`` (n, m), or of one row or one column to broadcast), count the sample, m += w (r − m) with
    w = max(1/count, ``alpha_level``), add u = (r − m)/σ_d to the block; where a block of ``block`` samples is full,
    ρ += v (block ū² − ρ) with v = max(1/blocks, ``alpha_block``), and the block restarts. ``state`` = (samples,
    level, raw_ratio, blocks, block_sum, block_n)."""
    samples, level, raw_ratio, blocks, block_sum, block_n = state
    n, m = level.shape
    any_full = False
    for i in range(n):
        for j in range(m):
            live = not frozen[min(i, frozen.shape[0] - 1), min(j, frozen.shape[1] - 1)]
            count = samples[i, j] + (1.0 if live else 0.0)
            samples[i, j] = count
            w = maximum(1.0 / maximum(count, 1.0), alpha_level) if live else 0.0
            x = r[min(i, r.shape[0] - 1), min(j, r.shape[1] - 1)]
            new_level = level[i, j] + w * (x - level[i, j])
            level[i, j] = new_level
            u = (x - new_level) / design_std[min(i, design_std.shape[0] - 1), min(j, design_std.shape[1] - 1)]
            block_sum[i, j] = block_sum[i, j] + u if live else 0.0
            block_n[i, j] = block_n[i, j] + 1 if live else 0
            if block_n[i, j] >= block:
                any_full = True
    if not any_full:
        return
    for i in range(n):
        for j in range(m):
            full = block_n[i, j] >= block
            count = blocks[i, j] + (1.0 if full else 0.0)
            blocks[i, j] = count
            mean = block_sum[i, j] / block
            v = maximum(1.0 / maximum(count, 1.0), alpha_block) if full else 0.0
            raw_ratio[i, j] = raw_ratio[i, j] + v * (block * mean * mean - raw_ratio[i, j])
            if full:
                block_sum[i, j] = 0.0
                block_n[i, j] = 0


def as_rows(a, shape: tuple[int, ...]) -> np.ndarray:
    """``a`` (a scalar, or an array broadcastable to ``shape``) as a 2-D array that ``learn_level`` broadcasts:
    (n, m) for ``shape`` (n, m), (n, 1) for ``shape`` (n,); a scalar (1, 1)."""
    a = np.asarray(a)
    if a.ndim == 0:
        return a.reshape(1, 1)
    return a.reshape(a.shape[0], 1) if len(shape) == 1 else a


@kernel
def analytic_residuals(y, columns, beta, consts):
    """The analytic detector's residuals of one sample (``AnalyticDetector.step``, before the lock-in) from the SCADA
    means ``y`` (n, sensors): ``columns`` = (ω_g,m1, ω_g,m2, ω_r,m1, ω_r,m2, τ_g, P_g) indices, ``beta`` (3, 2) the
    blades' encoders; ``consts`` = (η_gc, σ_P²/10, σ_ωg²/20, σ_τ²/10, N_g, 1 − 0.97). Returns (ω̄_g, z_1, σ_1², μ_1,
    β̄ (n, 3), z_2 (n, 3), max |z_2|, z_3 = ω̄_g − N_g ω̄_r, ω̄_g/N_g, the collective β̄), each mean as numpy's
    (the sum in order, divided by the count)."""
    eta, var_p, var_w, var_t, n_g, debris_share = consts
    wg1, wg2, wr1, wr2, tau_col, p_col = columns
    n = y.shape[0]
    omega_g, z1, var1, mu1 = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    blades, z2 = np.empty((n, 3)), np.empty((n, 3))
    worst, z3, omega_r, collective = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    for r in range(n):
        wg = (y[r, wg1] + y[r, wg2]) / 2.0
        wr = (y[r, wr1] + y[r, wr2]) / 2.0
        tau = y[r, tau_col]
        p_gen = eta * wg * tau
        omega_g[r] = wg
        z1[r] = p_gen - y[r, p_col]
        torque_part = eta * tau
        speed_part = eta * wg
        var1[r] = var_p + torque_part * torque_part * var_w + speed_part * speed_part * var_t
        mu1[r] = debris_share * abs(p_gen)
        for b in range(3):
            blades[r, b] = (y[r, beta[b, 0]] + y[r, beta[b, 1]]) / 2.0
        total = blades[r, 0] + blades[r, 1] + blades[r, 2]
        largest = 0.0
        for b in range(3):
            z = 1.5 * blades[r, b] - 0.5 * total
            z2[r, b] = z
            largest = abs(z) if b == 0 else maximum(largest, abs(z))
        worst[r] = largest
        z3[r] = wg - n_g * wr
        omega_r[r] = wg / n_g
        collective[r] = total / 3.0
    return omega_g, z1, var1, mu1, blades, z2, worst, z3, omega_r, collective


@kernel
def _page_step(g, q, flag, llr, h, h_end):
    """``cusum.PageCusum.step`` of one statistic; returns (g, q, flag)."""
    g = maximum(g + llr, 0.0)
    q = maximum(q - llr, 0.0) if flag else 0.0
    rise = not flag and g >= h
    fall = flag and q >= h_end
    flag = (flag or rise) and not fall
    if fall:
        g, q = 0.0, 0.0
    return g, q, flag


@kernel
def analytic_decide(z1, mu1, var1, z2, var2, amplitude, h3, cusum1, cusum2, fault3, consts):
    """The analytic detector's decisions of one sample after its warm-up (``AnalyticDetector.step``): the LLR
    increments (``cusum.llr_increment``) of z_1 (design shift μ_1) and of ±z_2 per blade (±δ), both Page CUSUMs
    (``cusum.PageCusum.step``; ``cusum1`` = (g, q, flag) (n,) and ``cusum2`` the same (n, 6), the +δ tests then the
    −δ ones, in place), and fault 3's raise at A ≥ h_3 and release after A < h_3/2 for ``RELEASE_S`` (``fault3`` =
    (flag, quiet time) (n,), in place). ``consts`` = (h_1, h_2, δ, Δt, RELEASE_S). Returns the flags (n, 3) and the
    statistics (g_1, max g_2, A) (n, 3)."""
    h1, h2, shift, dt, release = consts
    g1, q1, flag1 = cusum1
    g2, q2, flag2 = cusum2
    flag3, quiet3 = fault3
    n = z1.size
    flags = np.empty((n, 3), dtype=np.bool_)
    stats = np.empty((n, 3))
    mu0 = 0.0
    for r in range(n):
        s1 = (mu1[r] - mu0) / var1[r] * (z1[r] - 0.5 * (mu0 + mu1[r]))
        g1[r], q1[r], flag1[r] = _page_step(g1[r], q1[r], flag1[r], s1, h1, h1)
        any2 = False
        largest = 0.0
        for c in range(6):
            z = z2[r, c] if c < 3 else -z2[r, c - 3]
            var = var2[r, c % 3]
            s2 = (shift - mu0) / var * (z - 0.5 * (mu0 + shift))
            g2[r, c], q2[r, c], flag2[r, c] = _page_step(g2[r, c], q2[r, c], flag2[r, c], s2, h2, h2)
            any2 = any2 or flag2[r, c]
            largest = g2[r, c] if c == 0 else maximum(largest, g2[r, c])
        a = amplitude[r]
        rise = a >= h3[r]
        low = a < 0.5 * h3[r]
        quiet = quiet3[r] + dt if flag3[r] and low else 0.0
        flag = (flag3[r] or rise) and not (quiet >= release)
        flag3[r] = flag
        quiet3[r] = quiet if flag else 0.0
        flags[r, 0], flags[r, 1], flags[r, 2] = flag1[r], any2, flag
        stats[r, 0], stats[r, 1], stats[r, 2] = g1[r], largest, a
    return flags, stats
