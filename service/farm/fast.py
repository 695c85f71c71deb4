"""Compiled twin of the farm supervisor's per-sample arithmetic (``wwcore.backend``): the analytic detector's learnt
levels and spread ratios (``service.farm.baseline.LearntLevel.update``) and its step around the lock-in: the
residuals (``analytic_residuals``), the learning (``analytic_learn``: levels, rate gains, 3P scales) and the
decisions (``analytic_decide``: the Page CUSUMs, fault 3's flag); the available power around the aerodynamic fit's
product and eq. (21)'s ``exp`` (``available_front``, ``available_back``, ``available_filter``) and the dispatch after
it (``dispatch_shares``: the accommodation rules but the drive-train hold, eqs. (18)–(26), the farm-power trim, the
modes). The same operations in the reference's order, numpy's pairwise sums (``row_sum``) and ``np.interp``'s
arithmetic (``interp``, ``wwcore.thrust_fast``'s) included, so the same numbers bit for bit
(``tests/test_fast_backend_farm.py``); the 3P lock-in (``lockin_step``), with numpy's complex arithmetic as its
loops do it on this build (a product with two fused multiply-adds, ``abs`` as larger · √(ratio² + 1), ``exp`` of an
imaginary number as the C library's cosine and sine, which numpy's float64 ``cos`` and ``sin`` are too). The
products and ``exp`` between the kernels, the pitch trim's and the ripple's steps and the other algorithms stay numpy
code, and the wind inversion's Newton steps are ``wwcore.aero_fast``'s.
"""

from __future__ import annotations

import math

import numpy as np

from wwcore.aero_fast import _newton, maximum, minimum, pitch_features
from wwcore.farm_frames import CANCEL_3P_MODE, DEBRIS_MODE, DERATED_MODE, PITCH_TRIM_MODE
from wwcore.jit import fma, kernel
from wwcore.thrust_fast import interp, np_maximum, np_minimum


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
    (flag, quiet time) (n,), in place). ``consts`` = (h_1, h_2, δ, Δt, RELEASE_S). Returns the flags (n, 3), the
    statistics (g_1, max g_2, A) (n, 3) and their thresholds (h_1, h_2, h_3) (n, 3)."""
    h1, h2, shift, dt, release = consts
    g1, q1, flag1 = cusum1
    g2, q2, flag2 = cusum2
    flag3, quiet3 = fault3
    n = z1.size
    flags = np.empty((n, 3), dtype=np.bool_)
    stats = np.empty((n, 3))
    thresholds = np.empty((n, 3))
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
        thresholds[r, 0], thresholds[r, 1], thresholds[r, 2] = h1, h2, h3[r]
    return flags, stats, thresholds


@kernel
def analytic_learn(residuals, rate, last_rate, amplitude, settling, tests, level1, level2, rate_gain, scale3, consts):
    """The analytic detector's learning of one sample (``AnalyticDetector.step`` with ``learn_levels``), in the
    reference's order: the debris level (``LearntLevel.update``, by ``learn_level``), the pitch residual's rate gain
    (``LearntRateGain.update``) and level, the 3P scale (``LearntRayleighScale.update``), each frozen where its test
    is up or above its share of the threshold; then the residuals less their levels, the variances by the learnt
    ratios (and the pitch lag's allowance) and fault 3's threshold from the learnt scale.

    ``residuals`` = (z_1 (n,), σ_1² (n,), z_2 (n, 3)); ``tests`` = (g_1, flag_1 (n,), g_2, flag_2 (n, 6), fault 3's
    flag (n,), its threshold (n,)); ``level1`` / ``level2`` = (state of ``learn_level`` ((n,) or (n, 3) arrays),
    α_level, α_block, block, ρ_max); ``rate_gain`` = (S_xx, S_xr (n, 3), λ, P_0); ``scale3`` = (samples, mean of
    A²/8 (n,), α, kept share, s_d, s_max); ``consts`` = (h_1, h_2, the suspicion share, σ_2², σ_2, τ_u,
    √(2 ln 1/p_3)). States in place; returns (z_1, σ_1², z_2, σ_2² (n, 3), h_3 (n,), the noise ratios (ρ_1,
    max ρ_2, (s/s_d)²) (n, 3))."""
    z1, var1, z2 = residuals
    g1, flag1, g2, flag2, flag3, h3_now = tests
    state1, alpha_level1, alpha_block1, block1, max_ratio1 = level1
    state2, alpha_level2, alpha_block2, block2, max_ratio2 = level2
    sxx, sxr, forget, prior = rate_gain
    samples3, mean_square, alpha3, kept_share, design_s, s_max = scale3
    h1, h2, suspicion, var_2, std_2, lag_tolerance, rayleigh = consts
    n = z1.size
    # fault 1's level, frozen where its CUSUM is up or above its share of h_1
    frozen1 = np.empty((n, 1), dtype=np.bool_)
    std1 = np.empty((n, 1))
    for r in range(n):
        frozen1[r, 0] = flag1[r] or g1[r] >= suspicion * h1
        std1[r, 0] = math.sqrt(var1[r])
    count1, level1_state, raw_ratio1, blocks1, block_sum1, block_n1 = state1
    rows1 = (
        count1.reshape((n, 1)),
        level1_state.reshape((n, 1)),
        raw_ratio1.reshape((n, 1)),
        blocks1.reshape((n, 1)),
        block_sum1.reshape((n, 1)),
        block_n1.reshape((n, 1)),
    )
    learn_level(z1.reshape((n, 1)), std1, frozen1, alpha_level1, alpha_block1, block1, rows1)
    level1_now, ratio1 = rows1[1], rows1[2]
    # fault 2's rate gain on the residual less its level, then its level
    frozen2 = np.empty((n, 1), dtype=np.bool_)
    corrected = np.empty((n, 3))
    level2_before = state2[1]
    for r in range(n):
        up, largest = False, 0.0
        for c in range(6):
            up = up or flag2[r, c]
            largest = g2[r, c] if c == 0 else maximum(largest, g2[r, c])
        frozen = up or largest >= suspicion * h2
        frozen2[r, 0] = frozen
        x = rate[r]
        for b in range(3):
            if not frozen:
                sxx[r, b] = forget * sxx[r, b] + x * x
                sxr[r, b] = forget * sxr[r, b] + x * (z2[r, b] - level2_before[r, b])
            corrected[r, b] = z2[r, b] - sxr[r, b] / (sxx[r, b] + prior) * x
    learn_level(corrected, np.full((1, 1), std_2), frozen2, alpha_level2, alpha_block2, block2, state2)
    level2_now, ratio2 = state2[1], state2[2]
    # fault 3's scale, then every residual less its level, the variances and h_3
    h3 = np.empty(n)
    noise_ratio = np.empty((n, 3))
    z1_out, var1_out, z2_out, var2_out = np.empty(n), np.empty(n), np.empty((n, 3)), np.empty((n, 3))
    for r in range(n):
        a = amplitude[r]
        live = not (flag3[r] or a >= suspicion * h3_now[r] or settling)
        count = samples3[r] + (1.0 if live else 0.0)
        samples3[r] = count
        w = maximum(1.0 / maximum(count, 1.0), alpha3) if live else 0.0
        mean_square[r] = mean_square[r] + w * (a * a / 8.0 - mean_square[r])
        z1_out[r] = z1[r] - level1_now[r, 0]
        rho1 = minimum(maximum(ratio1[r, 0], 1.0), max_ratio1)
        var1_out[r] = var1[r] * rho1
        swing = lag_tolerance * maximum(abs(rate[r]), abs(last_rate[r]))
        largest = 0.0
        for b in range(3):
            rho2 = minimum(maximum(ratio2[r, b], 1.0), max_ratio2)
            largest = rho2 if b == 0 else maximum(largest, rho2)
            z2_out[r, b] = corrected[r, b] - level2_now[r, b]
            var2_out[r, b] = var_2 * rho2 + swing * swing
        s = minimum(maximum(math.sqrt(mean_square[r] / kept_share), design_s), s_max)
        h3[r] = 2.0 * s * rayleigh
        scale = s / design_s
        noise_ratio[r, 0], noise_ratio[r, 1], noise_ratio[r, 2] = rho1, largest, scale * scale
    return z1_out, var1_out, z2_out, var2_out, h3, noise_ratio


# -- the available power (eqs. (20)–(22)) and the dispatch (eqs. (18)–(26)) ------------------------------------


@kernel
def np_clip(x, low, high):
    """np.clip of a float between two floats (nan stays nan; ``x`` where it equals a bound)."""
    return minimum(maximum(x, low), high)


@kernel
def _block_sum(a, start, n):
    """numpy's pairwise sum of a[start : start + n] for n ≤ 128 (``PW_BLOCKSIZE``): sequential below 8, else
    eight strided partial sums added in pairs, then the remainder in order."""
    if n < 8:
        res = 0.0
        for i in range(start, start + n):
            res += a[i]
        return res
    r0, r1, r2, r3 = a[start], a[start + 1], a[start + 2], a[start + 3]
    r4, r5, r6, r7 = a[start + 4], a[start + 5], a[start + 6], a[start + 7]
    i = 8
    while i < n - (n % 8):
        j = start + i
        r0 += a[j]
        r1 += a[j + 1]
        r2 += a[j + 2]
        r3 += a[j + 3]
        r4 += a[j + 4]
        r5 += a[j + 5]
        r6 += a[j + 6]
        r7 += a[j + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[start + i]
        i += 1
    return res


@kernel
def row_sum(a, start, n):
    """``a[start : start + n].sum()`` for n ≤ 128 in numpy's order (``np.add.reduce`` of a contiguous row: 0 plus
    the pairwise sum of one block; numpy splits longer rows, which the callers leave to numpy)."""
    return 0.0 + _block_sum(a, start, n)


@kernel
def available_front(y, columns, beta, consts, f):
    """Eq. (20)'s inputs from the SCADA means ``y`` (n, sensors) (``AvailablePower.step``): ω̄_g of the two
    encoders (``columns`` = (ω_g,m1, ω_g,m2, τ_g)), ω̂_r = ω̄_g/N_g, β̄ the mean of the six pitch encoders (``beta``
    (3, 2), summed in order), τ̂_r = N_g (τ̄_g + B_g ω̄_g)/η_dt + B_r ω̂_r; the pitch features of β̄ into ``f``
    (6, n) (``aero_fast.pitch_features``). ``consts`` = (N_g, B_g, η_dt, B_r, R). Returns (τ̂_r, ω̂_r R)."""
    n_g, b_g, eta_dt, b_r, radius = consts
    wg1, wg2, tau_col = columns
    n = y.shape[0]
    tau_r, rw, pitch = np.empty(n), np.empty(n), np.empty(n)
    for r in range(n):
        omega_g = (y[r, wg1] + y[r, wg2]) / 2.0
        omega_r = omega_g / n_g
        total = 0.0
        for b in range(3):
            for s in range(2):
                total += y[r, beta[b, s]]
        pitch[r] = total / 6.0
        tau_r[r] = n_g * (y[r, tau_col] + b_g * omega_g) / eta_dt + b_r * omega_r
        rw[r] = omega_r * radius
    pitch_features(pitch, f)
    return tau_r, rw


@kernel
def available_back(tau_r, rw, wind, f, g, slow_wind, winds, table, consts):
    """Eq. (20)'s Newton steps on ``wind`` (n,) in place (``aero_fast._newton``, g = Mᵀ f), w̄ += (w − w̄) c in
    place, P_a(w) (``power_curve.available_power``: np.interp on ``winds``, ``table``) and the exponent of eq. (21)'s
    filter, −max(w, 1)/D Δt. ``consts`` = (aerodynamic gain, iterations, c, D, Δt). Returns (P_a, exponent)."""
    gain, iterations, slow_gain, diameter, dt = consts
    _newton(tau_r, rw, wind, f, g, gain, iterations)
    n = wind.size
    p_a, exponent = np.empty(n), np.empty(n)
    for r in range(n):
        slow_wind[r] = slow_wind[r] + (wind[r] - slow_wind[r]) * slow_gain
        p_a[r] = interp(wind[r], winds, table)
        exponent[r] = -np_maximum(wind[r], 1.0) / diameter * dt
    return p_a, exponent


@kernel
def available_filter(a, p_a, p_a_hat, p_ref, y, power_col):
    """Eq. (21) P̂_a ← a P̂_a + (1 − a) P_a in place (a = e^{exponent}, numpy's) and eq. (22): returns
    P_avail = pos(P̂_a − P_ref) + P_m (n,), P_m the SCADA column ``power_col`` of ``y``."""
    n = a.size
    out = np.empty(n)
    for r in range(n):
        p_a_hat[r] = a[r] * p_a_hat[r] + (1.0 - a[r]) * p_a[r]
        out[r] = np_maximum(p_a_hat[r] - p_ref[r], 0.0) + y[r, power_col]
    return out


@kernel
def dispatch_shares(p_avail, p_ref, held, held_given, faulty, demand, y, integral, consts, out):
    """``Dispatch.step`` after P_avail for the drive-train rules ``cancel`` (1) and ``paper`` (2) and the pitch
    rules ``trim`` (1) and ``paper`` (2), farm by farm in the reference's order: the held turbines' power Σ_H
    P_held and the served demand, the plan (debris (23), the pitch rule, the drive-train rule with its relief),
    (25), (26) with the headroom shared in turbine order, (19), (18), (24), the farm-power trim (D-27; its integral
    ``integral`` (farms,) in place), the clip to [0, rated], the modes and the ripple's sources and free rows (D-29).

    ``p_avail``, ``p_ref``, ``held`` (n,); ``held_given``: the sample has a ``held`` array (the trim's error is then
    the served turbines'); ``faulty`` (n, 3) the flags to accommodate; ``demand`` (farms,); ``y`` the SCADA means.
    ``consts`` = (N, derate floor share, relief r, drive-train rule, pitch rule, rated power, trim on, K_p, K_i,
    limit, Δt, P_g column, debris factor, P_min). ``out`` = (references (n,), mode (n,) int8, Σ_H P_held (farms,),
    P_ref,farm,S (farms,), ripple sources (n,), ripple free rows (n,)), filled."""
    per_farm, kept_share, relief, drivetrain, pitch_rule, rated, trim_on, kp, ki, limit, dt, power_col = consts[:12]
    debris_factor, p_min = consts[12:]
    refs, mode, held_power, served, sources, free_rows = out
    avail = np.empty(per_farm)
    values = np.empty(per_farm)
    for farm in range(demand.size):
        base = farm * per_farm
        for t in range(per_farm):
            values[t] = p_ref[base + t] if held[base + t] else 0.0
        held_sum = row_sum(values, 0, per_farm)
        held_power[farm] = held_sum
        share_of = np_maximum(demand[farm] - held_sum, 0.0)  # P_ref,farm,S
        served[farm] = share_of
        for t in range(per_farm):
            avail[t] = 0.0 if held[base + t] else p_avail[base + t]
        most = row_sum(avail, 0, per_farm)  # Σ_S P_avail (19)
        for t in range(per_farm):
            r = base + t
            if faulty[r, 0] and not (faulty[r, 1] or faulty[r, 2]):
                avail[t] = debris_factor * avail[t]  # eq. (23)
        over = row_sum(avail, 0, per_farm) - share_of  # eq. (25)
        for t in range(per_farm):  # eq. (26), turbine order (D-26)
            r = base + t
            derate = (pitch_rule == 2 and faulty[r, 1]) or (drivetrain == 2 and faulty[r, 2])
            relieved = drivetrain == 1 and faulty[r, 2] and relief > 0.0
            if (derate or relieved) and not held[r]:
                kept = 1.0 - relief if relieved else kept_share
                reduced = np_maximum(np_maximum(avail[t] - np_maximum(over, 0.0), 0.0), p_min)
                reduced = np_maximum(reduced, np_minimum(kept * avail[t], avail[t]))
                taken = avail[t] - reduced
                avail[t] = reduced
                over = over - taken
        active = share_of < most
        total = np_maximum(row_sum(avail, 0, per_farm), 1.0)
        u = 0.0
        if trim_on:  # ``power_loop.farm_power_pi``
            for t in range(per_farm):
                values[t] = 0.0 if held_given and held[base + t] else y[base + t, power_col]
            target = np_maximum(demand[farm] - held_sum, 0.0) if held_given else demand[farm]
            farm_power = row_sum(values, 0, per_farm)
            target = np_maximum(target, 1.0)
            error = (target - farm_power) / target
            now = np_clip(integral[farm] + ki * error * dt, -limit, limit)
            u = np_clip(kp * error + now, -limit, limit)
            integral[farm] = now if active else 0.0
        for t in range(per_farm):
            r = base + t
            debris = faulty[r, 0] and not (faulty[r, 1] or faulty[r, 2])
            trimmed = pitch_rule == 1 and faulty[r, 1]
            derate = (pitch_rule == 2 and faulty[r, 1]) or (drivetrain == 2 and faulty[r, 2])
            cancelled = drivetrain == 1 and faulty[r, 2]
            share = avail[t] / total * share_of  # eq. (18)
            if debris:
                share = share / debris_factor  # eq. (24)
            ref = share if active else rated
            if trim_on and active and not (derate or held[r]):
                ref = ref * (1.0 + u)
            refs[r] = p_ref[r] if held[r] else np_clip(ref, 0.0, rated)
            m = DEBRIS_MODE if debris else 0
            m = PITCH_TRIM_MODE if trimmed else m
            m = DERATED_MODE if derate else m
            mode[r] = CANCEL_3P_MODE if cancelled else m
            sources[r] = cancelled and not held[r]
            free_rows[r] = not (sources[r] or derate or held[r])


@kernel
def np_mod(a, b):
    """np.mod of two floats (numpy's ``npy_divmod``): fmod, moved to b's sign; an exact zero takes b's sign."""
    mod = np.fmod(a, b)
    if b == 0.0:
        return mod
    if mod != 0.0:
        if (b < 0.0) != (mod < 0.0):
            mod += b
    else:
        mod = math.copysign(0.0, b)
    return mod


@kernel
def complex_abs(re, im):
    """np.abs of a complex number as numpy's SIMD loop gives it: larger · √(ratio² + 1) with ratio = smaller/larger
    (a fused multiply-add; 0 where larger is 0), inf where either part is infinite, else nan where either is nan."""
    re, im = abs(re), abs(im)
    if re == math.inf or im == math.inf:
        return math.inf
    if re != re or im != im:
        return math.nan
    larger, smaller = (re, im) if re > im else (im, re)
    ratio = 0.0 if larger == 0.0 else smaller / larger
    return math.sqrt(fma(ratio, ratio, 1.0)) * larger


@kernel
def lockin_step(x, omega_r, state, consts, amplitude, whitened):
    """``signals.LockIn3P.step`` after its first sample: the high-pass mean, the phase, I and Q, A (``amplitude``)
    and the whitened Ã (``whitened``) of each row; ``state`` = (mean, phase, I, Q, Re W, Im W) in place, ``consts``
    = (a_hp, 1 − a_hp, Δt, a, 1 − a, a², (1 − a)², V_k of this sample, the bound on |ρ|). numpy's complex
    arithmetic as its loops do it: a product (a + jb)(c + jd) is (fma(a, c, −bd), fma(a, d, bc)), a real factor or
    divisor acts on each part (the divisor as a product with its inverse), e^{jy} = cos y + j sin y, |z| by
    ``complex_abs``; numpy's float64 ``cos`` and ``sin`` are the C library's, as numba's are."""
    mean, phase, i_state, q_state, w_re, w_im = state
    a_hp, one_minus_hp, dt, a, gain, a2, gain2, v, bound = consts
    inverse_v = 1.0 / v
    for r in range(x.size):
        mean[r] = a_hp * mean[r] + one_minus_hp * x[r]
        phase[r] = np_mod(phase[r] + 3.0 * omega_r[r] * dt, 2.0 * math.pi)
        xt = x[r] - mean[r]
        i = a * i_state[r] + gain * xt * math.cos(phase[r])
        q = a * q_state[r] + gain * xt * math.sin(phase[r])
        i_state[r], q_state[r] = i, q
        amplitude[r] = 2.0 * math.sqrt(i * i + q * q)
        twice = 2.0 * phase[r]
        w_re[r] = a2 * w_re[r] + gain2 * math.cos(twice)
        w_im[r] = a2 * w_im[r] + gain2 * math.sin(twice)
        rho_re, rho_im = w_re[r] * inverse_v, w_im[r] * inverse_v
        size = complex_abs(rho_re, rho_im)
        if size > bound:
            shrink = bound / np_maximum(size, 1e-300)
            rho_re, rho_im = rho_re * shrink, rho_im * shrink
        jq_re, jq_im = fma(0.0, q, -(1.0 * 0.0)), fma(0.0, 0.0, 1.0 * q)  # 1j · Q
        z_re, z_im = i + jq_re, 0.0 + jq_im
        c_re, c_im = rho_re, -rho_im  # conj(ρ)
        p_re, p_im = fma(c_re, z_re, -(c_im * z_im)), fma(c_re, z_im, c_im * z_re)  # conj(ρ) z
        pz_re = fma(p_re, z_re, -(p_im * z_im))  # Re(conj(ρ) z z)
        size_z = complex_abs(z_re, z_im)
        size_rho = complex_abs(rho_re, rho_im)
        form = (size_z * size_z - pz_re) / (1.0 - size_rho * size_rho)
        whitened[r] = 2.0 * math.sqrt(np_maximum(form, 0.0))
