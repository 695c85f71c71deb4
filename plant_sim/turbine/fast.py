"""Compiled twin of the turbine plant's tick (``wwcore.backend``): ``TurbineBatch`` and ``BenchmarkController``
call these with ``backend="numba"`` and the numpy code otherwise.

Each kernel performs the numpy reference's operations in its order, row by row, so its results equal the
reference's bit for bit (``tests/test_fast_backend.py``); the matrix products stay BLAS's, but for one row's exact
step, whose ``gemv`` ``control_inputs`` reproduces where ``wwcore.blas_fast`` finds it numpy's on this machine. They
cover the common tick: a nominal plant (no ``[mismatch]`` surface shift) and no sensor fault active; the plant falls
back to the numpy code for the rest.
"""

from __future__ import annotations

import math

import numpy as np

from wwcore.aero import _M_T, TSR_MAX
from wwcore.aero_fast import cq_inside, features, maximum, minimum
from wwcore.blas_fast import vector_matrix, vector_matrix_is_numpys  # noqa: F401 (the plant's set-up)
from wwcore.jit import kernel
from wwcore.kept import Kept  # noqa: F401 (the plant's kept arguments, ``TurbineBatch._measure_arguments``)

TWO_PI = 2.0 * math.pi
M_T = _M_T  # (6, 6): Mᵀ of the aerodynamic fit, g = Mᵀ f (``measure``'s argument)


# -- wind (``plant_sim.wind.WindField.sample``) -------------------------------------------------------------------
@kernel
def blade_winds(azimuth, table, slope, per_rad, offsets, base, u3, blades, rotor):
    """F(ψ_i) by linear interpolation in the table, w = v_m + u_0 + u_3 cos 3ψ; blades = w F, rotor = mean."""
    for r in range(azimuth.size):
        psi = azimuth[r]
        turned = (psi % TWO_PI) * per_rad
        w = base[r] + u3[r] * math.cos(3.0 * psi)
        for b in range(3):
            x = turned + offsets[b]
            i = int(x)
            blades[r, b] = w * (table[i] + slope[i] * (x - i))
        rotor[r] = ((blades[r, 0] + blades[r, 1]) + blades[r, 2]) * (1.0 / 3.0)


# -- aerodynamic torque (``TurbineDynamics.blade_torques``, nominal plant) --------------------------------------------
@kernel
def _blade_features(omega_r, radius, wind, pitch, tsr, lam, f):
    """tsr = ω_r (R / v) per blade, λ its clip, and the pitch features of β (n, 3, already offset)."""
    n = omega_r.size
    for r in range(n):
        for b in range(3):
            i = 3 * r + b
            tsr[i] = omega_r[r] * (radius / wind[r, b])
            lam[i] = tsr[i]
    features(lam, pitch.ravel(), f)


@kernel
def _blade_torques(tsr, lam, f, g, wind, gain, torque, tau_aero):
    cq = np.empty(lam.size)
    cq_inside(lam, f, g, cq)
    for r in range(tau_aero.size):
        for b in range(3):
            i = 3 * r + b
            c = cq[i] * (TSR_MAX / maximum(tsr[i], TSR_MAX))
            v = wind[r, b]
            torque[r, b] = gain[r] * (c * (v * v))
        tau_aero[r] = (torque[r, 0] + torque[r, 1]) + torque[r, 2]


def blade_torques(
    omega_r: np.ndarray, pitch: np.ndarray, wind: np.ndarray, gain: np.ndarray, radius: float
) -> tuple[np.ndarray, np.ndarray]:
    """(τ_r,i (n, 3), τ_r = Σ_i τ_r,i (n,)) in N m; pitch (n, 3) deg with its offsets, gain (n,) factor ρπR³/6."""
    n = len(omega_r)
    tsr, lam, f = np.empty(3 * n), np.empty(3 * n), np.empty((6, 3 * n))
    _blade_features(omega_r, radius, wind, pitch, tsr, lam, f)
    torque, tau_aero = np.empty((n, 3)), np.empty(n)
    _blade_torques(tsr, lam, f, _M_T @ f, wind, gain, torque, tau_aero)
    return torque, tau_aero


# -- sensors (``TurbineBatch.measure``, no sensor fault) ----------------------------------------------------------
@kernel
def readings(x, hub, power_gain, pick, noise, bias, beta_m1, beta_m2, quantities, y, pitch_error):
    """[ω_r, ω_g, v_hub, β_1..3, τ_g, P_g] (P_g = η_gc f_P ω_g τ_g), y = q[pick] + (noise + bias), and the pitch
    error ½(β_i,m1 + β_i,m2) − β_i that reaches the actuators."""
    for r in range(x.shape[0]):
        quantities[r, 0] = x[r, 0]
        quantities[r, 1] = x[r, 1]
        quantities[r, 2] = hub[r]
        quantities[r, 3] = x[r, 5]
        quantities[r, 4] = x[r, 7]
        quantities[r, 5] = x[r, 9]
        quantities[r, 6] = x[r, 3]
        quantities[r, 7] = power_gain[r] * x[r, 1] * x[r, 3]
        for s in range(pick.size):
            y[r, s] = quantities[r, pick[s]] + (noise[r, s] + bias[s])
        for b in range(3):
            pitch_error[r, b] = 0.5 * (y[r, beta_m1[b]] + y[r, beta_m2[b]]) - x[r, 5 + 2 * b]


# -- the whole measurement (``TurbineBatch.measure`` with its own ``WindField``, nominal plant) ----------------------
@kernel
def measure(x, j, i, kept, y):
    """``measure``'s common tick in one call: the blades' wind (``blade_winds``), the blade torques
    (``blade_torques``: the pitch with its offsets, the gain ρπR³/6 f_aero, Mᵀ f by BLAS as numpy's product) and the
    readings without sensor faults (``readings``, P_g's gain η_gc f_P), each kernel's operations in its order.

    ``j``: the tick's row of the wind chunk, ``i`` its column of the noise block. ``kept`` = (wind, aero, sensors,
    outputs), the arguments ``TurbineBatch._measure_arguments`` keeps between ticks: ``wind`` = (the table and its
    slope (2, m), per_rad, offsets, the chunk's v_m + u_0, u_3 and v_hub (ticks, n)); ``aero`` = (Mᵀ, ρπR³/6,
    f_aero (n,), pitch offsets (n, 3), R); ``sensors`` = (η_gc, f_P (n,), the columns (pick, β_m1, β_m2), the noise
    block (rows, ticks, sensors), the tick's noise (n, sensors; twin rows repeat their run's row), bias);
    ``outputs`` = (the blades' wind, torques and pitch errors (3, n, 3), the rotor's wind and τ_r (2, n), the
    quantities (n, 8))."""
    wind, aero, sensors, outputs = kept
    tables, per_rad, offsets, base, u3, hub = wind
    m_t, blade_gain, aero_factor, pitch_offset, radius = aero
    eta_gc, power_factor, columns, draws, noise, bias = sensors
    per_blade, per_row, quantities = outputs
    blades, torque, pitch_error = per_blade[0], per_blade[1], per_blade[2]
    rotor, tau_aero = per_row[0], per_row[1]
    pick, beta_m1, beta_m2 = columns[: bias.size], columns[bias.size : bias.size + 3], columns[bias.size + 3 :]
    n = x.shape[0]
    rows = draws.shape[0]
    azimuth, omega_r, gain, power_gain = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    pitch = np.empty((n, 3))
    for r in range(n):
        azimuth[r] = x[r, 4]
        omega_r[r] = x[r, 0]
        gain[r] = blade_gain * aero_factor[r]
        power_gain[r] = eta_gc * power_factor[r]
        for b in range(3):
            pitch[r, b] = x[r, 5 + 2 * b] + pitch_offset[r, b]
        for s in range(noise.shape[1]):
            noise[r, s] = draws[r % rows, i, s]
    blade_winds(azimuth, tables[0], tables[1], per_rad, offsets, base[j], u3[j], blades, rotor)
    tsr, lam, f = np.empty(3 * n), np.empty(3 * n), np.empty((6, 3 * n))
    _blade_features(omega_r, radius, blades, pitch, tsr, lam, f)
    _blade_torques(tsr, lam, f, m_t @ f, blades, gain, torque, tau_aero)
    readings(x, hub[j], power_gain, pick, noise, bias, beta_m1, beta_m2, quantities, y, pitch_error)


@kernel
def measure_kept(x, j, i, kept, y):
    """``measure`` with its kept argument tuple as one ``wwcore.kept.Kept`` (``kept.args``, built by
    ``TurbineBatch._measure_arguments``): one struct to unbox instead of its 18 arrays."""
    measure(x, j, i, kept.args, y)


# -- controller (``BenchmarkController.step``) ------------------------------------------------------------------
@kernel
def control(omega_g_m, estimated, omega_g_est, p_g_m, power_ref, zone, integrator, beta_ref, tau_g_ref, consts):
    """Zone logic, the region-3 PI (saturated integrator and output) and the two torque laws, in place, on the
    generator speed ω_g = ``omega_g_est`` where ``estimated`` (the supervisor's fresh, valid estimate), else the
    sensor's ``omega_g_m`` (``np.where``'s choice: the value itself)."""
    omega_nom, omega_delta, dt, lo, hi, k_p, k_i, eta_gc, k_opt = consts
    for r in range(omega_g_m.size):
        w = omega_g_est[r] if estimated[r] else omega_g_m[r]
        # the previous zone held: region 3 stays above Ω_nom − Ω_Δ, is entered at P_r or Ω_nom
        stay, enter = w >= omega_nom - omega_delta, (p_g_m[r] >= power_ref[r]) or (w >= omega_nom)
        region3 = stay if zone[r] != 0 else enter
        zone[r] = 1 if region3 else 0
        error = w - omega_nom
        integrator[r] = minimum(maximum(integrator[r] + dt * error, lo), hi)
        beta_pi = minimum(maximum(k_p * error + k_i * integrator[r], lo), hi)
        beta_ref[r] = beta_pi if region3 else 0.0
        tau_g_ref[r] = power_ref[r] / (eta_gc * maximum(w, 1.0)) if region3 else k_opt * w * w


@kernel
def control_inputs(y, columns, estimated, omega_g_est, power_ref, zone, integrator, beta_ref, tau_g_ref, consts, step,
                   product):  # fmt: skip
    """``control`` on the readings ``y``'s generator-speed and power columns (``columns``), the estimate ``omega_g_est``
    where ``estimated`` (None: no fresh estimate, the sensor's reading), then, where ``step`` = (fill, x, τ_r, Δτ,
    β_f (n, 3), z) asks (``fill``), the exact step's inputs z from the new commands (``step_inputs``): the plant's
    ``control`` and the first half of its ``advance`` in one call. With ``product`` = (the shared step matrix, x'),
    not None, also its second half for one row: x' = z @ shared with numpy's BLAS arithmetic
    (``wwcore.blas_fast.vector_matrix``)."""
    omega_g_m, p_g_m = y[:, columns[0]], y[:, columns[1]]
    if omega_g_est is None:
        control(omega_g_m, estimated, omega_g_m, p_g_m, power_ref, zone, integrator, beta_ref, tau_g_ref, consts)
    else:
        control(omega_g_m, estimated, omega_g_est, p_g_m, power_ref, zone, integrator, beta_ref, tau_g_ref, consts)
    fill, x, tau_r, torque_offset, pitch_error, z = step
    if fill:
        step_inputs(x, tau_r, tau_g_ref, torque_offset, beta_ref, pitch_error, z)
    if product is not None:
        shared, x_next = product
        vector_matrix(z[0], shared, x_next[0])


@kernel
def control_inputs_kept(y, estimated, omega_g_est, power_ref, kept, fill, x, x_next):
    """``control_inputs`` with the arguments kept from tick to tick as one ``wwcore.kept.Kept``: ``kept.args`` =
    (the readings' columns, the controller's zone, integrator, β_ref, τ_g,r and constants, ``measure``'s two output
    blocks (β_f = per_blade[2], τ_r = per_row[1]), Δτ, z, the shared step matrix or None), built by
    ``TurbineBatch._measure_arguments``; ``fill``, the state ``x`` and one row's next state ``x_next`` (None: no
    product in the call) are the tick's."""
    columns, zone, integrator, beta_ref, tau_g_ref, consts, per_blade, per_row, torque_offset, z, shared = kept.args
    step = (fill, x, per_row[1], torque_offset, per_blade[2], z)
    if x_next is None:
        control_inputs(y, columns, estimated, omega_g_est, power_ref, zone, integrator, beta_ref, tau_g_ref, consts,
                       step, None)  # fmt: skip
    else:
        control_inputs(y, columns, estimated, omega_g_est, power_ref, zone, integrator, beta_ref, tau_g_ref, consts,
                       step, (shared, x_next))  # fmt: skip


# -- step (``DiscreteStep.step``, every row alike) -----------------------------------------------------------
@kernel
def step_inputs(x, tau_r, tau_g_ref, torque_offset, beta_ref, pitch_error, z):
    """z = [x, τ_r, τ_g,r + Δτ, β_ref + β_f,1..3], the left operand of the shared step matrix."""
    n_states = x.shape[1]
    for r in range(x.shape[0]):
        for c in range(n_states):
            z[r, c] = x[r, c]
        z[r, n_states] = tau_r[r]
        z[r, n_states + 1] = tau_g_ref[r] + torque_offset[r]
        for b in range(3):
            z[r, n_states + 2 + b] = beta_ref[r] + pitch_error[r, b]


@kernel
def faulty_readings(q, pick, noise, bias, beta_m1, beta_m2, x, faults, t, drift, y, pitch_error):
    """y = ((q[pick] + bias) + noise f_σ) g + o, plus the drift r (t − t_0) when ``drift``, then the fixed and the
    stuck values where set (``TurbineBatch.measure`` with a sensor fault), and the pitch error of these readings.
    ``faults`` = (noise scale, gain, offset, drift rate, drift start, fixed, fixed value, stuck, stuck value),
    each (n, sensors)."""
    noise_scale, gain, offset, drift_rate, drift_start, fixed, fixed_value, stuck, stuck_value = faults
    for r in range(q.shape[0]):
        for s in range(pick.size):
            v = ((q[r, pick[s]] + bias[s]) + noise[r, s] * noise_scale[r, s]) * gain[r, s] + offset[r, s]
            if drift:
                v += drift_rate[r, s] * (t - drift_start[r, s])
            if fixed[r, s]:
                v = fixed_value[r, s]
            if stuck[r, s]:
                v = stuck_value[r, s]
            y[r, s] = v
        for b in range(3):
            pitch_error[r, b] = 0.5 * (y[r, beta_m1[b]] + y[r, beta_m2[b]]) - x[r, 5 + 2 * b]
