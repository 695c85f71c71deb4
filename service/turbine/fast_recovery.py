"""Compiled twin of the wind recovery's per-tick arithmetic (``service.turbine.wind_recovery``, ``wwcore.backend``):
the recovery's operands stacked, its map product, the pitch model, its filters, the estimator's common tick and the
wind's warm inversion of chosen observers' columns. ``service.turbine.fast`` exports them with the supervisor's other
kernels; each performs the numpy reference's operations in its order (``tests/test_fast_backend.py``,
``tests/test_estimator_healthy_tick.py``).
"""

from __future__ import annotations

import numpy as np

from wwcore.aero_fast import maximum, wind_from_torque_flat
from wwcore.blas_fast import gemm_product
from wwcore.jit import kernel


# -- stacking (the wind recovery's operands) ------------------------------------------------------------------------
@kernel
def stack(left, middle, right, out):
    """out = [left | middle | right] row by row; ``middle`` (n,) may be empty (n, 0)-free: pass a (n, 0) array."""
    a, b = left.shape[1], middle.shape[1]
    for r in range(left.shape[0]):
        for c in range(a):
            out[r, c] = left[r, c]
        for c in range(b):
            out[r, a + c] = middle[r, c]
        for c in range(right.shape[1]):
            out[r, a + b + c] = right[r, c]


# -- wind recovery (``service.turbine.wind_recovery.WindRecovery.step``, every pitch sensor healthy) ------------------
@kernel
def recovery_filter(raw, pitch_m1, pitch_m2, healthy, modelled, b0, a1, a2, s1, s2, filtered):
    """The biquads of every column of [raw, β̄], states in place: y = b0 x + s1, s1 ← (2 b0 x + s2) − a1 y,
    s2 ← b0 x − a2 y (``Biquad.__call__``). β̄ is the mean over the blades of both sensors' mean, or with
    ``healthy`` = (healthy_m1, healthy_m2) given (n, 3 each) of the healthy sensors' mean, the pitch model's
    ``modelled`` where neither is (``WindRecovery.step``)."""
    m = raw.shape[1]
    blade = np.empty(3)
    for r in range(raw.shape[0]):
        for b in range(3):
            if healthy is None:
                blade[b] = (pitch_m1[r, b] + pitch_m2[r, b]) / 2.0
            else:
                h1 = 1.0 if healthy[0][r, b] else 0.0
                h2 = 1.0 if healthy[1][r, b] else 0.0
                weight = h1 + h2
                if weight > 0:
                    blade[b] = (h1 * pitch_m1[r, b] + h2 * pitch_m2[r, b]) / maximum(weight, 1.0)
                else:
                    blade[b] = modelled[r]
        for c in range(m + 1):
            x = raw[r, c] if c < m else ((blade[0] + blade[1]) + blade[2]) / 3.0
            bx = b0[c] * x
            y = bx + s1[r, c]
            twice = bx + bx
            twice += s2[r, c]
            s1[r, c] = twice - a1[c] * y
            s2[r, c] = bx - a2[c] * y
            filtered[r, c] = y


@kernel
def recovery_tick(raw, pitch_m1, pitch_m2, healthy, pitch, reference, coef, biquads, filtered):
    """``pitch_model`` of ``pitch`` = (β, β̇) and the reference, in place, then ``recovery_filter`` with the new β as
    the modelled pitch (``WindRecovery.step``); ``biquads`` = (b0, a1, a2, s1, s2)."""
    beta, rate = pitch
    pitch_model(beta, rate, reference, coef, beta, rate)
    b0, a1, a2, s1, s2 = biquads
    recovery_filter(raw, pitch_m1, pitch_m2, healthy, beta, b0, a1, a2, s1, s2, filtered)


@kernel
def recovery_healthy_tick(faulty, x_hat, x_prev, sensors, reference, zone, pitch_columns, selected, kept):
    """``WindRecovery.step_healthy``: nothing done and False where any of ``faulty`` (the estimator's distrusted
    targets) is set; else True after [x̂[n], x̂[n−1]] (``x_hat``, ``x_prev``) stacked into ``stacked`` and mapped
    into ``raw`` (``product`` = (stacked, map, nonzeros or None, raw): ``map_product``), ``recovery_tick`` with
    every pitch sensor healthy on the readings [β_i,m1 | β_i,m2] gathered from ``sensors`` (columns
    ``pitch_columns``), ``gather_speeds`` of ``selected`` into ``speeds`` = (rotor start, generator start, ω̂_r,
    ω̂_g) and ``region2_speed`` of the controller's ``zone`` (``UIOBankEstimator.step``'s common tick). ``kept`` is
    a ``wwcore.kept.Kept`` of (product, pitch, coef, biquads, filtered, speeds, encoder state),
    ``WindRecovery._healthy_kept``: written in place."""
    for r in range(faulty.shape[0]):
        for c in range(faulty.shape[1]):
            if faulty[r, c]:
                return False
    product, pitch, coef, biquads, filtered, speeds, encoder_state = kept.args
    stacked, matrix, sparse, raw = product
    width = x_hat.shape[1]
    n = sensors.shape[0]
    for r in range(n):
        for c in range(width):
            stacked[r, c] = x_hat[r, c]
            stacked[r, width + c] = x_prev[r, c]
    map_product(stacked, matrix, sparse, raw)
    pitch_m1, pitch_m2 = np.empty((n, 3)), np.empty((n, 3))
    for r in range(n):
        for b in range(3):
            pitch_m1[r, b] = sensors[r, pitch_columns[b]]
            pitch_m2[r, b] = sensors[r, pitch_columns[3 + b]]
    recovery_tick(raw, pitch_m1, pitch_m2, None, pitch, reference, coef, biquads, filtered)
    rotor_start, generator_start, omega_r, omega_g = speeds
    gather_speeds(filtered, rotor_start, generator_start, selected, omega_r, omega_g)
    region2_speed(x_hat, selected, zone, encoder_state, omega_g)
    return True


@kernel
def column_winds(filtered, torque_start, rotor_start, columns, guess, radius, gain, iterations):
    """``WindRecovery.wind``'s warm inversion in one call: v (m, n) of observer ``columns`` (m, n) of each row from
    its filtered τ̂_r, ω̂_r (the columns from ``torque_start``, ``rotor_start``) and β̄ (the last column), from
    ``guess`` (m, n), by ``aero_fast.wind_from_torque_flat`` on the entries in ``columns``' order (the gathers and
    ``aero_fast.wind_from_torque``'s operations, with ``radius`` R and ``gain`` ½ρπR³)."""
    m, n = columns.shape
    size = m * n
    tau, rw, v, beta = np.empty(size), np.empty(size), np.empty(size), np.empty(size)
    pitch = filtered.shape[1] - 1
    for i in range(m):
        for r in range(n):
            k = i * n + r
            j = columns[i, r]
            tau[k] = filtered[r, torque_start + j]
            rw[k] = filtered[r, rotor_start + j] * radius
            beta[k] = filtered[r, pitch]
            v[k] = guess[i, r]
    wind_from_torque_flat(tau, rw, v, beta, gain, iterations)
    return v.reshape((m, n))


@kernel
def map_product(stacked, matrix, sparse, raw):
    """raw = stacked @ matrix: ``gemm_product`` over the matrix's nonzeros ``sparse`` (``blas_fast.nonzeros``), or
    with None BLAS's product (numba's calls the routine numpy's ``@`` does, with its numbers:
    ``tests/test_fast_kernels.py``)."""
    if sparse is None:
        np.dot(stacked, matrix, raw)
    else:
        gemm_product(stacked, matrix, sparse, raw)


@kernel
def region2_speed(x_hat, selected, zone, encoder_state, omega_g):
    """``WindRecovery.region2_generator_speed`` in place: ω̂_g ← x̂[r, encoder_state[selected]] on the rows in
    region 2 (``zone`` 0) whose selected observer (≥ 0) has a generator-speed state (≥ 0); a copy of a value."""
    for r in range(selected.size):
        j = selected[r]
        if zone[r] == 0 and j >= 0:
            state = encoder_state[j]
            if state >= 0:
                omega_g[r] = x_hat[r, state]


@kernel
def pitch_model(beta, rate, reference, coef, new_beta, new_rate):
    """[β, β̇] ← [a β + b β̇ + g0 β_ref, c β + d β̇ + g1 β_ref] (``wind_recovery.PitchModel.step``); ``new_beta``,
    ``new_rate`` may be ``beta``, ``rate`` (in place)."""
    a, b, c, d, g0, g1 = coef[0], coef[1], coef[2], coef[3], coef[4], coef[5]
    for r in range(beta.size):
        old_beta, old_rate = beta[r], rate[r]
        new_beta[r] = a * old_beta + b * old_rate + g0 * reference[r]
        new_rate[r] = c * old_beta + d * old_rate + g1 * reference[r]


@kernel
def gather_speeds(filtered, rotor_start, generator_start, selected, omega_r, omega_g):
    """ω̂_r, ω̂_g of each row's observer (observer 0 where none is selected) from the filtered columns."""
    for r in range(selected.size):
        j = max(selected[r], 0)
        omega_r[r] = filtered[r, rotor_start + j]
        omega_g[r] = filtered[r, generator_start + j]
