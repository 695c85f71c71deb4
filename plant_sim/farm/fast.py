"""Compiled twin of the farm plant's per-tick arithmetic (``wwcore.backend``): the turbines' wind on the row means
(``FarmWindField.sample``) and the farm controller's zone logic, PI, drive-train damper and torque laws
(``FarmTurbineController.step``). The same operations in the reference's order, so the same numbers bit for bit
(``tests/test_fast_backend.py``); the mean over the blades stays numpy's product, and the controller's hold, fade
and 3P cancellation stay numpy code around the kernel.
"""

from __future__ import annotations

import math

from wwcore.aero_fast import maximum, minimum
from wwcore.jit import kernel

TWO_PI = 2.0 * math.pi


@kernel
def blade_winds(azimuth, table, slope, per_rad, offsets, fields, gain, drift, blades, hub_out, mean_out):
    """Each blade's wind w F(ψ_i), w = (v_b + Δ) + u_3 cos 3ψ on the row mean's offset Δ = Δ_0 + δ m; the hub's and
    the mean's winds plus Δ. ``fields`` = (base, hub, u_3, v_m) of the tick; ``gain`` the turbulence gains (None:
    1); ``drift`` = (Δ_0, δ, m)."""
    base_t, hub_t, u3_t, vm_t = fields
    offset_now, offset_step, m = drift
    for r in range(azimuth.size):
        psi = azimuth[r]
        offset = offset_now[r] + offset_step[r] * m
        base, hub, u3, vm = base_t[r], hub_t[r], u3_t[r], vm_t[r]
        if gain is not None:
            g = gain[r]
            base, hub, u3 = vm + g * (base - vm), vm + g * (hub - vm), g * u3
        w = (base + offset) + u3 * math.cos(3.0 * psi)
        turned = (psi % TWO_PI) * per_rad
        for b in range(3):
            x = turned + offsets[b]
            i = int(x)
            blades[r, b] = w * (table[i] + slope[i] * (x - i))
        hub_out[r] = hub + offset
        mean_out[r] = vm + offset


@kernel
def control(omega_g, omega_g_m, p_g_m, state, references, consts):
    """Zone logic on the speed set point with hysteresis, the saturated PI, the drive-train damper (band-pass in
    transposed direct form II, state in place) and the torque laws; ``state`` = (zone, integrator, beta_ref, damper
    state (2, n), damper out, base torque out), ``references`` = (P_r, ω_set, hysteresis, hold)."""
    zone, integrator, beta_ref, z, damper, base = state
    power_ref, setpoint, hysteresis, hold = references
    dt, lo, hi, k_p, k_i, eta_gc, k_opt, b0, b2, a1, a2 = consts
    for r in range(omega_g.size):
        w = omega_g[r]
        enter = (w >= setpoint[r]) or ((p_g_m[r] >= power_ref[r]) and not hold[r])
        stay = w >= setpoint[r] - hysteresis[r]
        region3 = enter if zone[r] == 0 else stay
        zone[r] = 1 if region3 else 0
        error = w - setpoint[r]
        integrator[r] = minimum(maximum(integrator[r] + dt * error, lo), hi)
        beta_pi = minimum(maximum(k_p * error + k_i * integrator[r], lo), hi)
        beta_ref[r] = beta_pi if region3 else 0.0
        wm = omega_g_m[r]
        d = b0 * wm + z[0, r]
        z[0, r] = z[1, r] - a1 * d
        z[1, r] = b2 * wm - a2 * d
        damper[r] = d
        base[r] = power_ref[r] / (eta_gc * maximum(w, 1.0)) if region3 else k_opt * w * w
