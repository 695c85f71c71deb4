"""Compiled twin of the turbine supervisor's per-tick arithmetic (``wwcore.backend``): the observer bank's inputs
and χ² statistics, the FDI's window tests and the pitch-sensor parity, and, imported from their own modules, the
wind recovery's (``service.turbine.fast_recovery``) and the observer bank's (``service.turbine.fast_bank``); the
pitch-actuator test's kernels are ``service.turbine.fast_actuator``.

Each kernel performs the numpy reference's operations in its order, row by row, so its results equal the
reference's bit for bit (``tests/test_fast_backend.py``). The bank's two products and the recovery's map are
``wwcore.blas_fast.gemm_product``'s, over the matrices' nonzeros with the arithmetic of numpy's BLAS product
(``gemm_layout`` checks it on this machine for their shapes and rows), else BLAS (numba's product from inside the
kernel calls the routine numpy's does, with the same numbers: the tests compare them bit for bit).
Decisions (isolation, clearing, events) stay in Python: they run on the rare ticks where something is suspected.
``wind_from_torque`` is ``wwcore.aero_fast``'s, for the wind recovery.
"""

from __future__ import annotations

import numpy as np

from service.turbine.fast_bank import bank_step, bank_tick, bank_tick_kept  # noqa: F401 (the observer bank's)
from service.turbine.fast_converter import converter_tick
from service.turbine.fast_recovery import (  # noqa: F401 (the wind recovery's)
    column_winds,
    gather_speeds,
    map_product,
    pitch_model,
    recovery_filter,
    recovery_healthy_tick,
    recovery_tick,
    region2_speed,
    stack,
)
from wwcore.aero_fast import maximum, wind_from_torque, wind_from_torque_flat  # noqa: F401 (the wind's inversion)
from wwcore.blas_fast import gemm_layout, gemm_product, nonzeros  # noqa: F401 (the bank's and recovery's set-up)
from wwcore.jit import kernel
from wwcore.kept import Kept  # noqa: F401 (the kept arguments' struct, for the objects that build one)


# -- speed-sensor FDI (``service.turbine.fdi.SpeedSensorFDI.step``) -----------------------------------------------
@kernel
def window_ratio(stat, history, slot, window_sum, h_detect, h_window, ratio):
    """Σ over the window of χ²_j (ring ``history``, slot ``slot`` replaced), and max(χ²_j/h_j, Σχ²_j/h_w,j)."""
    for r in range(window_sum.shape[0]):
        for j in range(window_sum.shape[1]):
            x = stat[r, j]
            window_sum[r, j] += x - history[slot, r, j]
            history[slot, r, j] = x
            ratio[r, j] = maximum(x / h_detect[j], window_sum[r, j] / h_window[j])


@kernel
def window_test(raw, scale2, history, slot, window_sum, h_detect, h_window, column, chi2_stat, ratio):
    """χ²_j/ŝ²_j into ``chi2_stat``, then ``window_ratio`` of it; returns whether any row's ratio of observer
    ``column`` (the all-sensor one) exceeds 1 (``SpeedSensorFDI.step``)."""
    for r in range(raw.shape[0]):
        for j in range(raw.shape[1]):
            chi2_stat[r, j] = raw[r, j] / scale2[r, j]
    window_ratio(chi2_stat, history, slot, window_sum, h_detect, h_window, ratio)
    return any_above(ratio, column, 1.0)


@kernel
def window_test_learn(raw, scale2, history, slot, window_sum, h_detect, h_window, column, chi2_stat, ratio, learn):
    """``window_test``, then ``fdi_learn`` of its ratios with ``learn`` = (flagged, deadline, rank, y, gear ratio,
    spread, calibration): ``SpeedSensorFDI.step``'s two kernels in one call; returns ``window_test``'s answer."""
    exceeded = window_test(raw, scale2, history, slot, window_sum, h_detect, h_window, column, chi2_stat, ratio)
    flagged, deadline, rank, y, gear_ratio, spread, calibration = learn
    fdi_learn(flagged, deadline, ratio, raw, rank, y, gear_ratio, spread, calibration)
    return exceeded


@kernel
def fdi_learn(flagged, deadline, ratio, raw, rank, y, gear_ratio, spread, calibration):
    """``fdi_learning_inputs``, then ``learn_spread`` of the χ² scales from q and of the calibration offsets from
    the deviations (``SpeedSensorFDI.step``); ``spread``, ``calibration`` = (min_weight, s_max², state) of each
    ``HealthySpread``."""
    n = raw.shape[0]
    healthy, q, deviation = np.empty((n, 1), dtype=np.bool_), np.empty(raw.shape), np.empty(y.shape)
    fdi_learning_inputs(flagged, deadline, ratio, raw, rank, y, gear_ratio, healthy, q, deviation)
    learn_spread(q, None, healthy, spread[0], spread[1], spread[2])
    learn_spread(None, deviation, healthy, calibration[0], calibration[1], calibration[2])


@kernel
def any_equal(a, b):
    """Whether any element of ``a`` equals ``b``'s (``FrozenReadings.push``'s repeated reading)."""
    for r in range(a.shape[0]):
        for c in range(a.shape[1]):
            if a[r, c] == b[r, c]:
                return True
    return False


@kernel
def fdi_learning_inputs(flagged, deadline, ratio, raw, rank, y, gear_ratio, healthy, q, deviation):
    """What ``SpeedSensorFDI.step`` learns its adaptive thresholds from: ``healthy`` (n, 1), the rows with nothing
    flagged, pending or inconsistent (every ratio ≤ 1); q = χ²_j / rank_j; the speed sensors' ``deviation`` from
    the redundant ones: ω_r,mi − ω̄_g/N_g and ω_g,mi − ω̄_g, ω̄_g = ½(ω_g,m1 + ω_g,m2)."""
    for r in range(raw.shape[0]):
        consistent = True
        for j in range(ratio.shape[1]):
            if not ratio[r, j] <= 1.0:
                consistent = False
        healthy[r, 0] = flagged[r] == 0 and deadline[r] < 0 and consistent
        for j in range(raw.shape[1]):
            q[r, j] = raw[r, j] / rank[j]
        generator = 0.5 * (y[r, 2] + y[r, 3])
        rotor = generator / gear_ratio
        deviation[r, 0] = y[r, 0] - rotor
        deviation[r, 1] = y[r, 1] - rotor
        deviation[r, 2] = y[r, 2] - generator
        deviation[r, 3] = y[r, 3] - generator


# -- adaptive thresholds (``service.turbine.adaptive.HealthySpread.update``) ---------------------------------------
@kernel
def clip(x, low, high):
    """np.clip of a float: min(max(x, low), high), nan kept."""
    x = x if x > low or x != x else low
    return x if x < high or x != x else high


@kernel
def learn_spread(q, x, healthy, min_weight, max_scale2, state):
    """One sample of ``HealthySpread.update``: where ``healthy`` (n, m, or n, 1: one flag per row) and if any is,
    count += 1, w = max(1/count, ``min_weight``) (0 elsewhere), ŝ² += w (q − ŝ²), scale2 = clip(ŝ², 1, s_max²),
    scale = √scale2; b̂ += w (x − b̂), offset = clip(b̂, −b_max, b_max). ``q`` or ``x`` None: not learnt.
    ``state`` = ``HealthySpread.state``, its planes (count, ŝ², scale2, scale, b̂, offset, b_max) (n, m) each, in
    place."""
    count, estimate, scale2, scale, mean, offset, limit = (state[0], state[1], state[2], state[3], state[4], state[5],
                                                           state[6])  # fmt: skip
    learn = False
    for r in range(healthy.shape[0]):
        for c in range(healthy.shape[1]):
            if healthy[r, c]:
                learn = True
    if not learn:
        return
    per_row = healthy.shape[1] != count.shape[1]
    for r in range(count.shape[0]):
        for c in range(count.shape[1]):
            h = healthy[r, 0] if per_row else healthy[r, c]
            n = count[r, c] + (1.0 if h else 0.0)
            count[r, c] = n
            w = maximum(1.0 / maximum(n, 1.0), min_weight) if h else 0.0
            if q is not None:
                e = estimate[r, c] + w * (q[r, c] - estimate[r, c])
                estimate[r, c] = e
                s = clip(e, 1.0, max_scale2)
                scale2[r, c] = s
                scale[r, c] = np.sqrt(s)
            if x is not None:
                b = mean[r, c] + w * (x[r, c] - mean[r, c])
                mean[r, c] = b
                offset[r, c] = clip(b, -limit[r, c], limit[r, c])


# -- pitch-sensor parity (``service.turbine.component_fdi.ComponentFDI._pitch_sensors``) ---------------------------
@kernel
def component_tick(y, m12, tau_col, tau_g_ref, j, cross, e_block, tau_block, ring, outlier, scales, beta, par, window):
    """``ComponentFDI.step``'s per-tick arithmetic: β = y[:, m12] ([β_i,m1 | β_i,m2]); parity = (β_m1 − β_m2) s,
    its running window sum (``ring`` = (``_Window.sums``: the ring and its total as one block, slot), slot replaced),
    window = Σ × s_w; the block's e[j] = ½(β_m1 + β_m2) @ ``cross`` and [τ_g,m, τ_g,r]; each sensor's distance from
    the mean of the other two blades' four sensors into its window sum (``outlier``, as ``ring``;
    ``ComponentFDI._push_outlier``). True when any |parity| or |window| exceeds z (``scales`` = (s, s_w, z)).
    ``cross`` is CROSS_BLADE, whose entries 1 and −½ make every product exact: the three terms added left to right
    are numpy's product bit for bit (the one product computed in a kernel; checked by the tests)."""
    sums, slot = ring
    ring_values, total = sums[:-1], sums[-1]
    outlier_sums, outlier_slot = outlier
    outlier_values, outlier_total = outlier_sums[:-1], outlier_sums[-1]
    scale, window_scale, z_single = scales
    suspicious = False
    for r in range(y.shape[0]):
        for c in range(6):
            beta[r, c] = y[r, m12[c]]
        for b in range(3):  # the other two blades o < p: 0.25 (β_o,m1 + β_p,m1 + (β_o,m2 + β_p,m2))
            o, p = (1, 2) if b == 0 else ((0, 2) if b == 1 else (0, 1))
            others = 0.25 * ((beta[r, o] + beta[r, p]) + (beta[r, 3 + o] + beta[r, 3 + p]))
            for c in (b, 3 + b):
                x = abs(beta[r, c] - others)
                outlier_total[r, c] += x - outlier_values[outlier_slot, r, c]
                outlier_values[outlier_slot, r, c] = x
        mean0 = 0.5 * (beta[r, 0] + beta[r, 3])
        mean1 = 0.5 * (beta[r, 1] + beta[r, 4])
        mean2 = 0.5 * (beta[r, 2] + beta[r, 5])
        for c in range(3):
            e_block[j, r, c] = mean0 * cross[0, c] + mean1 * cross[1, c] + mean2 * cross[2, c]
        tau_block[j, 0, r] = y[r, tau_col]
        tau_block[j, 1, r] = tau_g_ref[r]
        for b in range(3):
            x = (beta[r, b] - beta[r, 3 + b]) * scale
            par[r, b] = x
            total[r, b] += x - ring_values[slot, r, b]
            ring_values[slot, r, b] = x
            w = total[r, b] * window_scale
            window[r, b] = w
            if maximum(abs(x), abs(w)) > z_single:
                suspicious = True
    return suspicious


@kernel
def component_step(tick, blocks, ring, outlier, scales, outputs, previous, adapt, converter):
    """``ComponentFDI.step``'s kernels of a tick in one call, in the order of their effects: ``component_tick``
    (``tick`` = (y, m12, τ_g,m column, τ_g,r, j, cross); ``outputs`` = (β, parity, window)); whether any reading of
    β equals ``previous``'s (``any_equal``, the frozen readings' repeat test; ``previous`` None: not tested);
    ``adapt_parity`` when ``adapt`` = (learning, flags, m1 targets, m2 targets, √W, z, the spread's learning,
    parity_n, window_n) says the parity's spread learns; ``converter_tick`` on the block's [τ_g,m, τ_g,r] of tick j
    (``converter`` = (τ̂_g, first, warm, spread, test, state), flags ``adapt[1]``: it reads and writes
    only the converter's column, the parity only the pitch sensors'). (any suspicious, repeated)."""
    y, m12, tau_col, tau_g_ref, j, cross = tick
    e_block, tau_block = blocks
    beta, parity, window = outputs
    suspicious = component_tick(
        y, m12, tau_col, tau_g_ref, j, cross, e_block, tau_block, ring, outlier, scales, beta, parity, window
    )
    repeated = previous is not None and any_equal(beta, previous)
    learning, flags, m1_target, m2_target, root_window, z_single, spread, parity_n, window_n = adapt
    if learning:
        suspicious = adapt_parity(
            parity, window, flags, m1_target, m2_target, root_window, z_single, spread, parity_n, window_n
        )
    tau_hat, first, warm, converter_spread, test, state = converter
    converter_tick(tau_block[j, 0], tau_block[j, 1], tau_hat, first, warm, converter_spread, test, flags, state)
    return suspicious, repeated


@kernel
def component_step_kept(sensors, tau_g_ref, tick, previous, kept):
    """``component_step`` with the arguments ``ComponentFDI`` keeps from tick to tick as one ``wwcore.kept.Kept``
    (``kept.args`` = ((m12, τ_g,m column, cross), blocks, the parity window's and the outlier window's sums, scales,
    the two β buffers, (parity, window), adapt, τ̂_g, the converter's (spread, test, state))) and the tick's: the
    frame's readings and τ_g,r, ``tick`` = (j, the two windows' slots, which β buffer, first, warm), ``previous``."""
    constants, blocks, (sums, outlier_sums), scales, betas, (parity, window), adapt, tau_hat, converter = kept.args
    m12, tau_col, cross = constants
    j, slot, outlier_slot, buffer, first, warm = tick
    spread, test, state = converter
    return component_step(
        (sensors, m12, tau_col, tau_g_ref, j, cross), blocks, (sums, slot), (outlier_sums, outlier_slot), scales,
        (betas[buffer], parity, window), previous, adapt, (tau_hat, first, warm, spread, test, state),
    )  # fmt: skip


@kernel
def adapt_parity(parity, window, flags, m1_target, m2_target, root_window, z_single, learning, parity_n, window_n):
    """``ComponentFDI._adapt_parity``: (p − b̂)/ŝ and (Σ_W p/√W − b̂ √W)/ŝ per blade (``root_window`` = √W), then
    ``learn_spread`` of (p − b̂)² and p from the blades with neither sensor flagged whose two statistics are
    within ±``z_single``. ``learning`` = (min_weight, s_max², state) of the parity's ``HealthySpread``. True when
    any blade's |(p − b̂)/ŝ| or |(Σ_W p/√W − b̂ √W)/ŝ| exceeds ``z_single``."""
    min_weight, max_scale2, state = learning
    suspicious = False
    offset, scale = state[5], state[3]
    n = parity.shape[0]
    squared, healthy = np.empty((n, 3)), np.empty((n, 3), dtype=np.bool_)
    for r in range(n):
        for b in range(3):
            centred = parity[r, b] - offset[r, b]
            p = centred / scale[r, b]
            w = (window[r, b] - offset[r, b] * root_window) / scale[r, b]
            parity_n[r, b], window_n[r, b] = p, w
            squared[r, b] = centred * centred
            flagged = flags[r, m1_target[b]] or flags[r, m2_target[b]]
            healthy[r, b] = not flagged and maximum(abs(p), abs(w)) <= z_single
            if maximum(abs(p), abs(w)) > z_single:
                suspicious = True
    learn_spread(squared, parity, healthy, min_weight, max_scale2, state)
    return suspicious


@kernel
def torque_band(torque, zone, edges, region1_torque):
    """``interfaces.power_speed_band`` of one row: region 1 (``edges.size + 2``) below ``region1_torque``, region 3
    (``edges.size + 1``) in zone 1, else the edges below the torque reference (NaN: after every edge, as
    searchsorted puts it)."""
    if torque < region1_torque:
        return edges.size + 2
    if zone == 1:
        return edges.size + 1
    if torque != torque:
        return edges.size
    below = 0
    for e in edges:
        if e < torque:
            below += 1
    return below


@kernel
def power_speed_test(sensors, power_col, torque_col, threshold, eta_gc, tau_g_ref, zone, edges, designs, channel, band):
    """The detector's power-speed channel P_g,m/(η_gc τ_g,m) (nan where τ_g,m < ``threshold``) and the 5-pe design
    of each row: ``designs`` (``interfaces.POWER_SPEED_DETECTOR_DESIGNS``) of its torque band (``torque_band``,
    region 1 below ``threshold``)."""
    for r in range(sensors.shape[0]):
        torque = sensors[r, torque_col]
        channel[r] = sensors[r, power_col] / (eta_gc * torque) if torque >= threshold else np.nan
        band[r] = designs[torque_band(tau_g_ref[r], zone[r], edges, threshold)]


@kernel
def whiten_block(e, b0, b1, b2, a1, a2, s1, s2, w):
    """w = (1 + G)⁻¹ e over the block's ticks (ticks, n, 3), written into ``w``, by the second-order section in
    transposed direct form II, states ``s1``, ``s2`` in place; returns Σ_k w_k² (n, 3) added in tick order
    (``ComponentFDI._actuators``)."""
    n = e.shape[1]
    z2 = np.zeros((n, 3))
    for k in range(e.shape[0]):
        for r in range(n):
            for b in range(3):
                ek = e[k, r, b]
                wk = b0 * ek + s1[r, b]
                s1[r, b] = b1 * ek - a1 * wk + s2[r, b]
                s2[r, b] = b2 * ek - a2 * wk
                w[k, r, b] = wk
                z2[r, b] += wk * wk
    return z2


@kernel
def any_above(values, column, level):
    """Whether any row's ``values[:, column]`` exceeds ``level``."""
    for r in range(values.shape[0]):  # noqa: SIM110 (a loop: numba compiles no generator into any())
        if values[r, column] > level:
            return True
    return False


# -- flag clearing (``service.turbine.clearing.FlagClearing.step``) -------------------------------------------------
@kernel
def cusum(y, x_hat, mask, frozen, predictor, column, scale, min_weight, floor, partner, h, state, ready):
    """Advance the CUSUM of every flagged speed sensor: e = (y − C x̂_j) / σ_e with j the row's ``predictor``
    (−1: none), or for a flagged rotor-speed sensor whose partner is not flagged e = (y_s − y_o) / (√2 σ_r) with the
    floor ``partner`` = (1/(√2 σ_r), floor/√2); μ̂ ← μ̂ + w (e − μ̂), w = max(1/count, w_min), S ← max(0, S + m (m/2
    − sign(μ̂) e)), m = max(|μ̂|, floor); ``ready`` where S ≥ h. ``state`` = (count, mean, statistic, residual),
    (n, 4) each, in place."""
    count, mean, statistic, residual = state
    partner_scale, partner_floor = partner
    for r in range(y.shape[0]):
        j = predictor[r]
        if mask[r] == 0 or j < 0:
            continue
        for s in range(y.shape[1]):
            sc = scale[j, s]
            active = ((mask[r] >> s) & 1) == 1 and np.isfinite(sc)
            e = (y[r, s] - x_hat[r, column[j, s]]) * sc if active else 0.0
            lower = floor
            if active and s < 2 and ((mask[r] >> (1 - s)) & 1) == 0:  # a rotor-speed sensor, its partner healthy
                e = (y[r, s] - y[r, 1 - s]) * partner_scale
                lower = partner_floor
            c = count[r, s] + (1.0 if active else 0.0)
            weight = maximum(1.0 / maximum(c, 1.0), min_weight) if active else 0.0
            mu = mean[r, s] + weight * (e - mean[r, s])
            m = maximum(abs(mu), lower)
            llr = m * (0.5 * m - (-e if mu < 0.0 else e))
            stat = maximum(0.0, statistic[r, s] + llr) if active and not frozen[r, s] else 0.0
            count[r, s], mean[r, s], statistic[r, s], residual[r, s] = c, mu, stat, e
            ready[r, s] = active and stat >= h


# -- the estimator's observer (``service.turbine.builtin.UIOBankEstimator.step`` with a flag raised) ----------------
@kernel
def select_observers(
    faulty, speed_targets, weights, observer_of_mask, observer_of_band, tau_g_ref, zone, edges, region1, mask, out
):
    """The bitmask of the distrusted speed sensors and the observer each row's estimate comes from: the mask's
    (``observer_of_mask``), or where that is the first 5-pe design (both generator-speed sensors distrusted), the
    observer of the row's torque band (``observer_of_band``, ``bank.power_speed_estimate_observers``;
    ``torque_band``, region 1 below the torque ``region1``)."""
    for r in range(faulty.shape[0]):
        m = 0
        for t in range(speed_targets.size):
            if faulty[r, speed_targets[t]]:
                m += weights[t]
        mask[r] = m
        j = observer_of_mask[m]
        if observer_of_band.size and j == observer_of_band[0]:
            j = observer_of_band[torque_band(tau_g_ref[r], zone[r], edges, region1)]
        out[r] = j


@kernel
def handover(previous, previous_mask, selected, mask):
    """(any sensor distrusted now, any row whose estimate moves to another observer as a sensor is trusted again)
    (``UIOBankEstimator._take_over``)."""
    distrusted, moving = False, False
    for r in range(selected.size):
        if mask[r] != 0:
            distrusted = True
        if (previous_mask[r] & ~mask[r]) != 0 and selected[r] != previous[r] and selected[r] >= 0 and previous[r] >= 0:
            moving = True
    return distrusted, moving


@kernel
def record_unchanged(flags, faulty, selected, chosen):
    """Whether the detector's ``faulty`` (n, targets) equals the supervisor's ``flags`` and the estimator's
    ``chosen`` observers (n,) its ``selected`` ones everywhere: a tick with no event (``TurbineSupervisor._record``)."""
    for r in range(flags.shape[0]):
        if selected[r] != chosen[r]:
            return False
        for c in range(flags.shape[1]):
            if flags[r, c] != faulty[r, c]:
                return False
    return True


# -- rotor-speed bias CUSUM (``service.turbine.bias_test.RotorBiasTest.step``) ----------------------------------------
@kernel
def rotor_bias(y, x_hat, flagged, deadline, predictor_of_mask, column, scale, test, state, learning, over):
    """One tick of the rotor-speed parity's bank of CUSUMs: each row's predictor j (``predictor_of_mask`` of its
    flags, −1 while an isolation is pending; a changed j starts the row from zero), e_s = (y_s − x̂[column[j, s]])
    scale[j, s] (j = 0 and scale 0 on rows not tested), raw = (e_1 − e_2)/√2, d = raw/ŝ, for each shift m_k
    S±_k ← max(0, S±_k + m_k (±d − m_k/2)) on tested rows (0 elsewhere), A±_k ← A±_k + (e_1 + e_2) while S±_k > 0,
    raised where some S± ≥ h; then ``learn_spread`` of raw² from the tested rows not raised, and ``over`` (n, 2) the
    sensor named at a raise by the largest statistic (the first of equals). ``test`` = (m (K,), h); ``state`` = (S⁺,
    S⁻, A⁺, A⁻ as the planes of one (4, n, K) array, predictor), in place; ``learning`` = (enabled, min_weight,
    s_max², ŝ's ``HealthySpread.state``, (7, n)). Returns whether any row raised."""
    m, h = test
    sums, predictor = state
    up, down, run_up, run_down = sums[0], sums[1], sums[2], sums[3]
    enabled, min_weight, max_scale2, spread = learning
    n, bank = up.shape
    root_two = np.sqrt(2.0)
    squared, healthy = np.empty((n, 1)), np.empty((n, 1), dtype=np.bool_)
    any_over = False
    for r in range(n):
        j = predictor_of_mask[flagged[r]] if deadline[r] < 0 else -1
        if j != predictor[r]:
            for k in range(bank):
                up[r, k], down[r, k], run_up[r, k], run_down[r, k] = 0.0, 0.0, 0.0, 0.0
        predictor[r] = j
        active = j >= 0
        c = j if active else 0
        e1 = (y[r, 0] - x_hat[r, column[c, 0]]) * (scale[c, 0] if active else 0.0)
        e2 = (y[r, 1] - x_hat[r, column[c, 1]]) * (scale[c, 1] if active else 0.0)
        raw = (e1 - e2) / root_two
        d = raw / spread[3][r]
        total = e1 + e2
        raised_up, raised_down = False, False
        top_up, top_down, best_up, best_down = 0.0, 0.0, 0, 0
        for k in range(bank):
            s_up = maximum(0.0, up[r, k] + m[k] * (d - 0.5 * m[k])) if active else 0.0
            s_down = maximum(0.0, down[r, k] + m[k] * (-d - 0.5 * m[k])) if active else 0.0
            run_up[r, k] = run_up[r, k] + total if s_up > 0.0 else 0.0
            run_down[r, k] = run_down[r, k] + total if s_down > 0.0 else 0.0
            up[r, k], down[r, k] = s_up, s_down
            raised_up = raised_up or s_up >= h
            raised_down = raised_down or s_down >= h
            if k == 0 or s_up > top_up:
                top_up, best_up = s_up, k
            if k == 0 or s_down > top_down:
                top_down, best_down = s_down, k
        squared[r, 0] = raw * raw
        healthy[r, 0] = active and not raised_up and not raised_down
        # of each sign the largest statistic of the bank, and of the two signs, which cannot both be right, the larger
        use_up = raised_up and (not raised_down or top_up >= top_down)
        use_down = raised_down and not use_up
        first = (use_up and run_up[r, best_up] > 0.0) or (use_down and run_down[r, best_down] < 0.0)
        over[r, 0] = first
        over[r, 1] = (use_up or use_down) and not first
        any_over = any_over or use_up or use_down
    if enabled:
        columns = spread.reshape((spread.shape[0], n, 1))  # the planes as (n, 1) columns
        learn_spread(squared, None, healthy, min_weight, max_scale2, columns)
    return any_over
