"""Compiled twin of the converter test's tick (``service.turbine.component_fdi.ComponentFDI._converter`` and
``_converter_clearing``, ``wwcore.backend``): the first-order converter's prediction τ̂_g, the residual's block
sum, Page's two-sided raise CUSUMs and the clearing CUSUM, row by row.

The kernel performs the numpy reference's floating-point operations in its order, so its results equal the
reference's bit for bit (``tests/test_fast_backend.py``); ``np.maximum``'s rule (the first argument where it is
not smaller, NaN propagated) is spelt out where the reference uses it.
"""

from __future__ import annotations

from wwcore.jit import kernel


@kernel
def _at_least(value, floor):
    """np.maximum(value, floor) for a scalar floor: ``value`` where value ≥ floor or value is NaN."""
    return value if (value >= floor or value != value) else floor


@kernel
def _positive_part(value):
    """np.maximum(0.0, value): 0 where 0 ≥ value, else ``value`` (NaN stays NaN)."""
    return 0.0 if value <= 0.0 else value


@kernel
def converter_tick(tau_g_m, tau_g_ref_previous, tau_hat, first, warm, spread, test, flags, state):
    """One tick of the converter test on every row, states in place.

    tau_hat (n,) τ̂_g (set to τ_g,m where ``first``); ``warm``: the tests run (past the warm-up). spread = the
    residual's healthy spread (``HealthySpread.state``, (7, n)), of which the offset and scale planes; test = (a,
    1/σ_τ, shifts (2K,), signs (2K,), h, memory weight, clear floor, clear h); flags (n, targets) with the
    converter's column ``column`` = test[8]; state = (the planes statistic and run (ticks since each statistic was
    last zero) of one (2, n, 2K) array, the planes count, mean, clear statistic and the block's Σ r of one (4, n)
    array)."""
    offset, scale = spread[5], spread[3]
    a, inv_sigma, shifts, signs, h, memory_weight, clear_floor, clear_h, column = test
    cusums, sums = state
    statistic, run = cusums[0], cusums[1]
    count, mean, clear_statistic, block_sum = sums[0], sums[1], sums[2], sums[3]
    k = shifts.shape[0]
    for r in range(tau_g_m.shape[0]):
        if first:
            tau_hat[r] = tau_g_m[r]
        else:
            tau_hat[r] = a * tau_hat[r] + (1.0 - a) * tau_g_ref_previous[r]
        residual = tau_g_m[r] - tau_hat[r]
        block_sum[r] += residual
        if not warm:
            continue
        z = (residual - offset[r]) * inv_sigma / scale[r]
        flagged = flags[r, column]
        over = False
        for j in range(k):
            m = shifts[j]
            value = _positive_part(statistic[r, j] + m * (z * signs[j] - 0.5 * m))
            if flagged:
                value = 0.0
            statistic[r, j] = value
            run[r, j] = run[r, j] + 1.0 if value > 0.0 else 0.0
            if value >= h:
                over = True
        raised = over and not flagged
        if raised:
            best = 0  # np.argmax: the first largest, or the first NaN
            largest = statistic[r, 0]
            if largest == largest:
                for j in range(1, k):
                    value = statistic[r, j]
                    if value != value:
                        best = j
                        break
                    if value > largest:
                        largest = value
                        best = j
            length = run[r, best] if run[r, best] >= 1.0 else 1.0  # np.maximum(run, 1.0); run is never NaN
            m = shifts[best]
            mean[r] = signs[best] * (statistic[r, best] / (m * length) + 0.5 * m)
            count[r] = length
            clear_statistic[r] = 0.0
            for j in range(k):
                statistic[r, j] = 0.0
                run[r, j] = 0.0
        # the clearing CUSUM (``_converter_clearing``)
        count[r] += 1.0 if flagged else 0.0
        weight = _at_least(1.0 / _at_least(count[r], 1.0), memory_weight) if flagged else 0.0
        mean[r] += weight * (z - mean[r])
        m = _at_least(abs(mean[r]), clear_floor)
        llr = m * (0.5 * m - (-z if mean[r] < 0.0 else z))
        held = False
        if flagged:
            value = _positive_part(clear_statistic[r] + llr)
            clear_statistic[r] = value
            held = value >= clear_h
        else:
            clear_statistic[r] = 0.0
        flags[r, column] = raised or (flagged and not held)
