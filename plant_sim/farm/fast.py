"""Compiled twin of the farm plant's per-tick arithmetic (``wwcore.backend``): the turbines' wind on the row means
(``FarmWindField.sample``) and the farm controller's zone logic, PI, drive-train damper and torque laws
(``FarmTurbineController.step``), and the wakes' 10-Hz step at a fixed direction (``wake_step``, with the FLORIS
tables' combination ``wake_combine``, after the thrust coefficients of ``wwcore.thrust_fast``). The same operations
in the reference's order, so the same numbers bit for bit (``tests/test_fast_backend_farm.py``); the mean over the
blades stays numpy's product, and the controller's hold, fade and 3P cancellation stay numpy code around the kernel.

``sub_steps`` runs a farm sample's ten ticks (``FarmBatch.run_sample``) in one call: the kernels above and the
turbine's (``plant_sim.turbine.fast``) tick after tick, the followed reference's ramp computed ahead (``ramp``; it
does not depend on the plant). Its two matrix products per tick (the aerodynamic fit's 6 × 6 and the exact step's
16 × 11) are numba's ``np.dot``, which calls OpenBLAS's dgemm through SciPy rather than numpy's own OpenBLAS: equal
bit for bit on this machine (random operands of these shapes, and the tests tick by tick), the one place where a
product is not numpy's call (``docs/decisions.md`` N-7). Each writes into an array kept for the sample (the step's
into the state itself): the dgemm call of ``@`` without its allocation and copy (N-25).
"""

from __future__ import annotations

import math

import numpy as np

from plant_sim.turbine.fast import _blade_features, _blade_torques, readings, step_inputs
from wwcore.aero_fast import maximum, minimum
from wwcore.jit import fma, kernel
from wwcore.thrust_fast import thrust_coefficient  # noqa: F401 (the wakes' C_T, ``TableWakes.advance``)

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


@kernel
def chunk_at_ticks(last, fresh, q, frac, vm, out):
    """``WindField._chunk_at_ticks``'s arithmetic: the turbulence samples s_0 = ``last`` (u_p, u_0, u_3, each (n,)),
    s_1 … s_S = ``fresh`` (each (n, S)) at tick t's position q_t + f_t, s_q (1 − f) + s_(q+1) f, into ``out`` (4, T,
    n) = (v_m, v_m + u_p, v_m + u_0, u_3) of each tick (v_m = ``vm`` (T,))."""
    n = out.shape[2]
    for t in range(q.size):
        i, f = q[t], frac[t]
        g = 1.0 - f
        v = vm[t]
        for k in range(3):
            prev, chunk = last[k], fresh[k]
            for r in range(n):
                low = prev[r] if i == 0 else chunk[r, i - 1]
                value = low * g + chunk[r, i] * f
                out[k + 1, t, r] = value if k == 2 else v + value
        for r in range(n):
            out[0, t, r] = v


@kernel
def ramp(power_ref, target, step, ticks, out):
    """The followed reference of ``ticks`` ticks (``FarmTurbineController.step`` while ramping): each tick moves
    P_r towards the target by at most ``step`` W; ``out`` (ticks, n). Returns the ticks after which P_r still
    differs from the target somewhere (the controller's ``_ramping`` then stays set)."""
    moving = 0
    for i in range(ticks):
        differs = False
        for r in range(power_ref.size):
            previous = power_ref[r] if i == 0 else out[i - 1, r]
            now = previous + minimum(maximum(target[r] - previous, -step), step)
            out[i, r] = now
            differs = differs or now != target[r]
        if not differs:
            for later in range(i + 1, ticks):
                out[later] = out[i]
            return moving
        moving += 1
    return moving


@kernel
def phasor_power(lead_re, lead_im, rate, age, out):
    """Re{C e^{jω age}} (``FarmTurbineController._extra_power``) into ``out``: numpy's ``exp`` of the imaginary
    jω·age is (cos, sin) of ω·age, and the real part of its complex product with C = a + jb is fma(a, cos, −b sin)."""
    for r in range(out.size):
        turn = rate[r] * age
        out[r] = fma(lead_re[r], math.cos(turn), -(lead_im[r] * math.sin(turn)))


@kernel
def sub_steps(
    x,
    shared,
    wind,
    gain,
    aero,
    sensors,
    controller,
    references,
    pitch_add,
    trim,
    sums,
    last,
    frame,
    states,
    power,
    shaft,
    mesh,
    cancel,
    extra,
):
    """Ticks k … k + T − 1 of the farm plant inside one farm sample, its wakes moved on already: per tick the
    turbines' wind (``blade_winds``), blade torques (``plant_sim.turbine.fast.blade_torques``), readings with the
    tick's noise, the block sums of the SCADA means, the farm controller's laws (``control``) and the shared step
    (``step_inputs``, then x' = z · M), in the order of ``FarmBatch.measure`` / ``control`` / ``advance``.

    ``wind`` = (table, slope, per_rad, offsets, base, hub, u_3, v_m (each (ticks, n) of the chunk), Δ_0, δ, the
    first tick's row j in the chunk and its index m in the sample); ``gain`` the turbulence gains (None: 1);
    ``aero`` = (Mᵀ, gain ρπR³/6 f_aero, pitch offsets, R); ``sensors`` = (noise block (rows, chunk, sensors)
    σ-scaled, the first tick's index in it, η_gc f_P, pick, bias, β_m1, β_m2 indices, Δτ, ω_g,m1 and P_g,m
    indices); ``controller`` = (zone, integrator, β_ref, damper state, τ_g,r, constants of ``control``),
    updated in place; ``references`` = (P_r before the first tick, P_r (T, n), ω_set (T, n), Ω_Δ,set (T, n),
    hold) of each tick's control; ``pitch_add`` (a fault's pitch command offsets) and ``trim`` (the
    supervisor's pitch trims), each (n, 3) or None, are added to the pitch commands in that order.

    ``sums`` = (Σ readings, Σ P_r) of the block, added to in place; ``last`` = (blades, hub, mean, τ_r,i, τ_r,
    y, pitch error, quantities, ω_g read, damper torque) of the last tick and ``frame`` = (τ_g,r, β_ref, P_r,
    zone) its frame carries (the controller's before the tick's control). ``states`` (T, n, 11) receives x at
    each tick unless None, ``power`` (T, n) P_g = η_gc f_P ω_g τ_g, and ``shaft`` = (out (T, n), K_dt f_K, B_dt
    f_B, N_g), unless None, the shaft torque K (θ_Δ − e(ψ)) + B (ω_r − ω_g/N_g). ``x`` (in place) ends at tick
    k + T.

    The three the controller and the faults may add, each acting where its flag says (``TurbineBatch.advance``,
    ``FarmTurbineController.step``, ``_ripple``, ``_extra_power``, the same operations): ``mesh`` = (flags [mesh
    active, error active (updated)], e stage, e level (both in place), e_0, K_dt f_K, η_dt, Γ_ext (n, mechanical
    states), (Δt/T_onset, N_g, ½Δt)), the drive-train wear's torque pair; ``cancel`` = (flags [cancel 3P, asked,
    running (updated)], SOGI states (4, n), ω̄ mean, engagement, age (the last three in place), asked level, τ_ripple
    (out), (Δt, Δt/T_mean, 3/N_g, T_narrow, k_SOGI, k_track − k_SOGI, Δt/T_engage, −J_g, η_gc)), the 3P
    cancellation; ``extra`` = (flags [on], Re C, Im C, ω, (first tick k, Δt, t_0, η_gc), P_extra (out)), the power
    phasor Re{C e^{jω(t − t_0)}} (numpy's complex product, with fused multiply-adds)."""
    table, slope, per_rad, offsets, base, hub, u3, vm, offset_now, offset_step, first_j, first_m = wind
    m_t, blade_gain, pitch_offset, radius = aero
    draws, first_noise, power_gain, pick, bias, beta_m1, beta_m2, torque_offset, omega_col, power_col = sensors
    zone, integrator, beta_ref, bp_state, tau_g_ref, consts = controller
    ref_before, power_refs, setpoints, hysteresis, hold = references
    scada_sum, power_ref_sum = sums
    blades, hub_out, mean_out, torque, tau_aero, y, pitch_error, quantities, omega_g, damper = last
    frame_tau_g, frame_beta, frame_power_ref, frame_zone = frame
    mesh_flags, stage, level, error_target, stiffness_e, eta_dt, gamma_ext, mesh_consts = mesh
    onset_gain, n_g_mesh, half_dt = mesh_consts
    cancel_flags, ripple_state, ripple_mean, ripple_on, ripple_age, asked_level, ripple_torque, ripple_consts = cancel
    r_dt, mean_gain, w3_gain, narrow_s, sogi_gain, track_step, engage_rate, minus_j_g, eta_gc = ripple_consts
    extra_on, lead_re, lead_im, extra_rate, extra_consts, extra_power = extra
    extra_k0, extra_dt, extra_since, extra_eta_gc = extra_consts
    n, n_states = x.shape
    own = draws.shape[0]  # rows with their own noise stream; twin rows repeat their run's
    azimuth, omega_r, p_g_m = np.empty(n), np.empty(n), np.empty(n)
    pitch = np.empty((n, 3))
    tsr, lam, f = np.empty(3 * n), np.empty(3 * n), np.empty((6, 3 * n))
    g_aero = np.empty((6, 3 * n))
    noise = np.empty((n, pick.size))
    base_torque = np.empty(n)
    omega_raw, pair = np.empty(n), np.empty(n)
    z = np.empty((n, shared.shape[0]))
    n_mech = gamma_ext.shape[1]
    for i in range(power.shape[0]):
        j = first_j + i
        for r in range(n):
            if states is not None:
                for c in range(n_states):
                    states[i, r, c] = x[r, c]
            azimuth[r] = x[r, 4]
            omega_r[r] = x[r, 0]
            for b in range(3):
                pitch[r, b] = x[r, 5 + 2 * b] + pitch_offset[r, b]
            power[i, r] = power_gain[r] * x[r, 1] * x[r, 3]
        if shaft is not None:
            stiffness, damping, n_g = shaft[1], shaft[2], shaft[3]
            for r in range(n):
                twist = x[r, 2] - level[r] * math.cos(3.0 * x[r, 4]) if mesh_flags[1] else x[r, 2]
                shaft[0][i, r] = stiffness[r] * twist + damping[r] * (x[r, 0] - x[r, 1] / n_g)
        fields = (base[j], hub[j], u3[j], vm[j])
        blade_winds(
            azimuth,
            table,
            slope,
            per_rad,
            offsets,
            fields,
            gain,
            (offset_now, offset_step, first_m + i),
            blades,
            hub_out,
            mean_out,
        )
        _blade_features(omega_r, radius, blades, pitch, tsr, lam, f)
        np.dot(m_t, f, g_aero)
        _blade_torques(tsr, lam, f, g_aero, blades, blade_gain, torque, tau_aero)
        for r in range(n):
            for s in range(pick.size):
                noise[r, s] = draws[r % own, first_noise + i, s]
        readings(x, hub_out, power_gain, pick, noise, bias, beta_m1, beta_m2, quantities, y, pitch_error)
        now = ref_before if i == 0 else power_refs[i - 1]
        for r in range(n):
            for s in range(pick.size):
                scada_sum[r, s] += y[r, s]
            power_ref_sum[r] += now[r]
            frame_tau_g[r] = tau_g_ref[r]
            frame_beta[r] = beta_ref[r]
            frame_power_ref[r] = now[r]
            frame_zone[r] = zone[r]
            omega_raw[r] = y[r, omega_col]
            omega_g[r] = omega_raw[r]
            p_g_m[r] = y[r, power_col]
        cancelling = cancel_flags[0] != 0 and (cancel_flags[2] != 0 or cancel_flags[1] != 0)
        if cancelling:  # ``_ripple``: the 3P filter, its engagement and τ_ripple; the laws read ω_g,m without them
            if cancel_flags[2] == 0:  # started from the filter's steady state for a constant speed
                ripple_state[:, :] = 0.0
                for r in range(n):
                    ripple_mean[r] = omega_raw[r]
                cancel_flags[2] = 1
            running = False
            for r in range(n):
                w = omega_raw[r]
                ripple_mean[r] = ripple_mean[r] + (w - ripple_mean[r]) * mean_gain
                w3 = w3_gain * maximum(w, 1.0)
                narrowed = minimum(ripple_age[r] / narrow_s, 1.0)
                kw = (sogi_gain + track_step * narrowed) * w3
                v1 = ripple_state[0, r] + r_dt * (
                    kw * ((w - ripple_mean[r]) - ripple_state[0, r]) - w3 * ripple_state[1, r]
                )
                q1 = ripple_state[1, r] + r_dt * w3 * v1
                dv2 = kw * (v1 - ripple_state[2, r]) - w3 * ripple_state[3, r]
                v2 = ripple_state[2, r] + r_dt * dv2
                q2 = ripple_state[3, r] + r_dt * w3 * v2
                ripple_state[0, r], ripple_state[1, r], ripple_state[2, r], ripple_state[3, r] = v1, q1, v2, q2
                on = minimum(maximum(asked_level[r], ripple_on[r] - engage_rate), ripple_on[r] + engage_rate)
                ripple_on[r] = on
                ripple_age[r] = ripple_age[r] + r_dt if (on > 0.0 or asked_level[r] > 0.0) else 0.0
                ripple_torque[r] = minus_j_g * on * dv2
                running = running or on != 0.0
                omega_g[r] = w - on * v2
                p_g_m[r] = p_g_m[r] - (eta_gc * w) * ripple_torque[r]
            cancel_flags[2] = 1 if running else 0
        if extra_on[0]:  # ``_extra_power``: Re{C e^{jω age}}, taken at the tick's middle
            age = ((extra_k0 + i) + 0.5) * extra_dt - extra_since
            phasor_power(lead_re, lead_im, extra_rate, age, extra_power)
            for r in range(n):
                p_g_m[r] = p_g_m[r] - extra_power[r]
        state = (zone, integrator, beta_ref, bp_state, damper, base_torque)
        control(omega_g, omega_raw, p_g_m, state, (power_refs[i], setpoints[i], hysteresis[i], hold), consts)
        for r in range(n):
            tau_g_ref[r] = base_torque[r] + damper[r]
            if cancelling:
                tau_g_ref[r] = tau_g_ref[r] + ripple_torque[r]
            if extra_on[0]:
                tau_g_ref[r] = tau_g_ref[r] + extra_power[r] / (extra_eta_gc * maximum(omega_raw[r], 1.0))
        step_inputs(x, tau_aero, tau_g_ref, torque_offset, beta_ref, pitch_error, z)
        meshing = mesh_flags[0] != 0 or mesh_flags[1] != 0
        if meshing:  # drive-train wear: the torque pair K_dt e(ψ) at the step's mid-azimuth (``advance``)
            residue = False
            for r in range(n):
                stage[r] = stage[r] + (error_target[r] - stage[r]) * onset_gain
                level[r] = level[r] + (stage[r] - level[r]) * onset_gain
                residue = residue or (abs(level[r]) + abs(stage[r])) > 1e-9
                mid_step = x[r, 4] + half_dt * x[r, 0]
                pair[r] = stiffness_e[r] * level[r] * math.cos(3.0 * mid_step)
                z[r, n_states] = tau_aero[r] + pair[r]
            mesh_flags[1] = 1 if (mesh_flags[0] != 0 or residue) else 0
        if pitch_add is not None:
            for r in range(n):
                for b in range(3):
                    z[r, n_states + 2 + b] = z[r, n_states + 2 + b] + pitch_add[r, b]
        if trim is not None:
            for r in range(n):
                for b in range(3):
                    z[r, n_states + 2 + b] = z[r, n_states + 2 + b] + trim[r, b]
        np.dot(z, shared, x)
        if meshing:
            for r in range(n):
                tau_ext = -eta_dt[r] * pair[r] / n_g_mesh
                for c in range(n_mech):
                    x[r, c] = x[r, c] + gamma_ext[r, c] * tau_ext


@kernel
def wake_combine(entries, w, thrust, free, tables, speed, ti):
    """``WakeTables._combine`` for G farms in one table interval: each pair's C_T, the bilinear interpolation of τ and
    δ, their scatters (in the entries' order, as ``bincount`` adds them), the largest τ and the root of the sum of
    squares of δ over the upstream turbines (in their order). ``entries`` = (up, flat pair index, first-bin mask,
    table rows × M, table rows × M T) of ``WakeTables._bin``; ``w`` (G,) the weight of the second table direction;
    ``thrust`` (G, N, N) the C_T of i as its wake reaches j; ``free`` (G, N); ``tables`` = (τ flat, δ flat (float32),
    TI nodes, C_T max, 1/Δs, last thrust node's index, 1/ΔTI, TI_0²). Writes ``speed`` and ``ti``, each (G, N)."""
    up, flat, first, row_m, row_mt = entries
    added_ti, deficit, ti_grid, ct_max, inv_s_step, m_last, inv_ti_step, ambient_sq = tables
    g_farms, n = free.shape
    n_ti = ti_grid.size
    e_count = up.size
    added = np.empty((n, n))
    wake = np.empty((n, n))
    cell_m = np.empty(e_count, dtype=np.intp)
    cell_f = np.empty(e_count)
    added_flat, wake_flat = added.reshape(-1), wake.reshape(-1)
    for g in range(g_farms):
        low_weight = 1.0 - w[g]
        pairs = thrust[g].reshape(-1)
        added_flat[:] = 0.0
        wake_flat[:] = 0.0
        for e in range(e_count):
            weight = low_weight if first[e] else w[g]
            ct = pairs[flat[e]]
            x = (1.0 - math.sqrt(1.0 - minimum(maximum(ct, 0.0), ct_max))) * inv_s_step
            m = min(int(x), m_last)
            f = x - m
            lin = row_m[e] + m
            tau = added_ti[lin] + (added_ti[lin + 1] - added_ti[lin]) * f
            added_flat[flat[e]] += weight * tau
            cell_m[e] = m
            cell_f[e] = f
        for j in range(n):
            largest = added[0, j]
            for i in range(1, n):
                largest = maximum(largest, added[i, j])
            ti[g, j] = math.sqrt(ambient_sq + largest * largest)
        for e in range(e_count):
            weight = low_weight if first[e] else w[g]
            m, f = cell_m[e], cell_f[e]
            if n_ti == 1:
                lin = row_m[e] + m
                delta = deficit[lin] + (deficit[lin + 1] - deficit[lin]) * f
            else:
                y = minimum((ti[g, up[e]] - ti_grid[0]) * inv_ti_step, n_ti - 1.0)
                t = min(int(y), n_ti - 2)
                h = y - t
                base = row_mt[e] + m * n_ti + t
                low = deficit[base] + (deficit[base + 1] - deficit[base]) * h
                high = deficit[base + n_ti] + (deficit[base + n_ti + 1] - deficit[base + n_ti]) * h
                delta = low + (high - low) * f
            wake_flat[flat[e]] += weight * delta
        for j in range(n):
            square_sum = 0.0
            for i in range(n):
                square_sum += wake[i, j] * wake[i, j]
            speed[g, j] = free[g, j] * (1.0 - math.sqrt(square_sum))


@kernel
def wake_step(ct, nxt, a_ct, filtered, ring, mast, x, entries, w, tables, free, speed, ti):
    """``TableWakes.advance`` at a fixed wind direction after the thrust coefficients ``ct`` (F, N) of sample
    nxt − 1: the low-passed C_T (``filtered``, in place) into the ring buffer (float32, (F, N, H)), each turbine's
    delayed free stream (eq. (3), ``MastSeries.at``), each pair's C_T of when the wake now at j left i, and the
    combination (``wake_combine``). ``mast`` = (v̄ of sample nxt (F,) before its floor, mast winds v (runs, S),
    each farm's run, d_t (N,), v̄ floor, FARM_DT_S, HISTORY_S); ``x`` (N, N) x_ij ≥ 0. Writes ``free``, ``speed``
    and ``ti`` (F, N)."""
    mean_v, offset, mast_v, runs, distances, floor, dt, history_s = mast
    farms, n = ct.shape
    history = ring.shape[2]
    slot_now = (nxt - 1) % history
    one_minus = 1.0 - a_ct
    last = mast_v.shape[1] - 2
    t_now = nxt * dt
    pair_thrust = np.empty((farms, n, n))
    for g in range(farms):
        for t in range(n):
            filtered[g, t] = a_ct * filtered[g, t] + one_minus * ct[g, t]
            ring[g, t, slot_now] = filtered[g, t]
        run = runs[g]
        vbar = maximum(mean_v[run, offset + nxt], floor)
        for t in range(n):
            delay = minimum(distances[t] / vbar, history_s)
            position = (t_now - delay + history_s) / dt
            i = min(max(int(position), 0), last)
            frac = minimum(maximum(position - i, 0.0), 1.0)
            free[g, t] = mast_v[run, i] * (1.0 - frac) + mast_v[run, i + 1] * frac
        travel = vbar * dt
        for i in range(n):
            for j in range(n):
                lag = min(max(int(np.rint(x[i, j] / travel)), 1), history - 1)
                pair_thrust[g, i, j] = ring[g, i, (nxt - lag) % history]
    wake_combine(entries, w, pair_thrust, free, tables, speed, ti)
