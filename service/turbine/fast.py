"""Compiled twin of the turbine supervisor's per-tick arithmetic (``wwcore.backend``): the observer bank's inputs
and χ² statistics, the wind recovery's filters, the FDI's window tests and the pitch-sensor parity.

Each kernel performs the numpy reference's operations in its order, row by row, so its results equal the
reference's bit for bit (``tests/test_fast_backend.py``). The matrix products (the bank's two, the recovery's
map) stay numpy's (BLAS): a compiled loop would sum in another order. Decisions (isolation, clearing, events)
stay in Python: they run on the rare ticks where something is suspected.
"""

from __future__ import annotations

from wwcore.aero_fast import maximum
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
def _square(out, r, width, column, n_res):
    if column == n_res:
        return 0.0
    w = out[r, width + column]
    return w * w


# -- wind recovery (``service.turbine.wind_recovery.WindRecovery.step``, every pitch sensor healthy) ------------------
@kernel
def recovery_filter(raw, pitch_m1, pitch_m2, b0, a1, a2, s1, s2, filtered):
    """The biquads of every column of [raw, β̄] (β̄ the mean over the blades of both sensors' mean), states in
    place: y = b0 x + s1, s1 ← (2 b0 x + s2) − a1 y, s2 ← b0 x − a2 y (``Biquad.__call__``)."""
    m = raw.shape[1]
    for r in range(raw.shape[0]):
        p0 = (pitch_m1[r, 0] + pitch_m2[r, 0]) / 2.0
        p1 = (pitch_m1[r, 1] + pitch_m2[r, 1]) / 2.0
        p2 = (pitch_m1[r, 2] + pitch_m2[r, 2]) / 2.0
        for c in range(m + 1):
            x = raw[r, c] if c < m else ((p0 + p1) + p2) / 3.0
            bx = b0[c] * x
            y = bx + s1[r, c]
            twice = bx + bx
            twice += s2[r, c]
            s1[r, c] = twice - a1[c] * y
            s2[r, c] = bx - a2[c] * y
            filtered[r, c] = y


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
def any_equal(a, b):
    """Whether any element of ``a`` equals ``b``'s (``FrozenReadings.push``'s repeated reading)."""
    for r in range(a.shape[0]):
        for c in range(a.shape[1]):
            if a[r, c] == b[r, c]:
                return True
    return False


# -- pitch-sensor parity (``service.turbine.component_fdi.ComponentFDI._pitch_sensors``) ---------------------------
@kernel
def parity(beta, scale, ring, slot, total, window_scale, z_single, par, window):
    """parity = (β_m1 − β_m2) scale, its running window sum (ring slot ``slot`` replaced), window = Σ × scale;
    True when any |parity| or |window| exceeds ``z_single``."""
    suspicious = False
    for r in range(beta.shape[0]):
        for b in range(3):
            x = (beta[r, b] - beta[r, 3 + b]) * scale
            par[r, b] = x
            total[r, b] += x - ring[slot, r, b]
            ring[slot, r, b] = x
            w = total[r, b] * window_scale
            window[r, b] = w
            if maximum(abs(x), abs(w)) > z_single:
                suspicious = True
    return suspicious
