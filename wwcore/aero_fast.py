"""Compiled twin of ``wwcore.aero``'s C_q evaluation (``wwcore.backend``): the same operations in the same order.

C_q(λ, β) = Q E + g3 + g4 λ + g5 λ² with g = Mᵀ f(β) (``aero._cq_inside``). The two element-wise halves are
kernels; the 6 × 6 product g = Mᵀ f between them stays numpy's (BLAS), so that the arithmetic is the reference's
operation for operation: a compiled loop would sum the six products in another order, or without BLAS's fused
multiply-adds. The kernels' ``asinh``, ``exp`` and ``log1p`` are the C library's; numpy's equal them on an AVX2 CPU,
but where numpy runs its AVX-512 SIMD versions (arrays of three or more elements) they differ in the last place on
some entries (on this AMD Zen 5 machine: h = asinh(β/β_h) on 226 of 1 000 random pitch angles, C_q on 216, and the
wind's inversion, whose Newton steps carry that on, up to 1 400 units in the last place, about 3·10⁻¹³ relative),
so the numbers equal the reference within the tests' 1e-12 of each quantity's scale, not always to the last bit
(``docs/cluster.md``).
"""

from __future__ import annotations

import math

import numpy as np

from wwcore.aero import (
    _AWAY_STEP,
    _B0,
    _B1,
    _M_T,
    _MAX_STEP,
    _MIN_SLOPE,
    _STALL_TSR,
    _X_REF,
    PITCH_MAX_DEG,
    PITCH_MIN_DEG,
    SHAPE,
    TSR_MAX,
    TSR_MIN,
    WIND_MAX,
    WIND_MIN,
)
from wwcore.jit import kernel
from wwcore.units import DEG

_BETA_H, _BETA_K, _W_K = SHAPE[2:5]
_INV_BETA_H, _INV_W_K, _KNEE = 1.0 / _BETA_H, 1.0 / _W_K, _BETA_K / _W_K


@kernel
def minimum(a, b):
    """np.minimum of two floats (nan if either is nan)."""
    return a if a <= b or a != a else b


@kernel
def maximum(a, b):
    """np.maximum of two floats (nan if either is nan)."""
    return a if a >= b or a != a else b


@kernel
def pitch_features(beta, f):
    """β (m,) deg → f (6, m) = [1, h, h², sin β, sin² β, σ] of β clipped to the table (``aero.pitch_features``)."""
    for i in range(beta.size):
        b = minimum(maximum(beta[i], PITCH_MIN_DEG), PITCH_MAX_DEG)
        h = math.asinh(b * _INV_BETA_H)
        s = math.sin(b * DEG)
        f[0, i] = 1.0
        f[1, i] = h
        f[2, i] = h * h
        f[3, i] = s
        f[4, i] = s * s
        f[5, i] = math.log1p(math.exp(b * _INV_W_K - _KNEE))


@kernel
def features(lam, beta, f):
    """λ (m,) clipped in place to [1, 13], and the pitch features of β (m,) into f (6, m)."""
    for i in range(lam.size):
        lam[i] = maximum(minimum(lam[i], TSR_MAX), TSR_MIN)
    pitch_features(beta, f)


@kernel
def cq_inside(lam, f, g, out):
    """C_q at clipped λ (m,) from the features f and g = Mᵀ f (6, m) each; into ``out`` (m,)."""
    for i in range(lam.size):
        u = 1.0 / lam[i]
        x = u - _X_REF
        b = _B0 - _B1 * f[1, i]
        e = math.exp(-b * x)
        q = (g[0, i] * x + g[1, i]) * u + g[5, i]
        out[i] = q * e + g[2, i] + lam[i] * (g[3, i] + lam[i] * g[4, i])


def torque_coefficient(tsr: np.ndarray, pitch_deg: np.ndarray) -> np.ndarray:
    """``aero.torque_coefficient`` for arrays of one shape (float64): C_q (–), bit for bit the reference's."""
    tsr = np.ascontiguousarray(tsr, dtype=float)
    lam = tsr.ravel().copy()
    f = np.empty((6, lam.size))
    features(lam, np.ascontiguousarray(pitch_deg, dtype=float).ravel(), f)
    cq = np.empty(lam.size)
    cq_inside(lam, f, _M_T @ f, cq)
    return (cq * (TSR_MAX / np.maximum(tsr.ravel(), TSR_MAX))).reshape(tsr.shape)


@kernel
def _newton(tau_aero, rw, v, f, g, gain, iterations):
    """``aero.wind_from_torque``'s safeguarded Newton steps on v (m,) in place, g = Mᵀ f(β) of the clipped pitch
    (constant over the iterations); C_q and ∂C_q/∂λ as ``aero.torque_coefficient_and_slope``."""
    for i in range(v.size):
        v[i] = minimum(maximum(v[i], WIND_MIN), WIND_MAX)
    for _ in range(iterations):
        for i in range(v.size):
            tsr = rw[i] / v[i]
            lam = maximum(minimum(tsr, TSR_MAX), TSR_MIN)
            u = 1.0 / lam
            x = u - _X_REF
            b = _B0 - _B1 * f[1, i]
            e = math.exp(-b * x)
            q = (g[0, i] * x + g[1, i]) * u + g[5, i]
            cq = q * e + g[2, i] + lam * (g[3, i] + lam * g[4, i])
            slope = e * u * u * (b * q - g[0, i] * u - (g[0, i] * x + g[1, i])) + g[3, i] + 2.0 * lam * g[4, i]
            if tsr > TSR_MAX:
                cq = cq * TSR_MAX / maximum(tsr, TSR_MAX)
                slope = -cq / maximum(tsr, TSR_MAX)
            if tsr < TSR_MIN:
                slope = 0.0
            s = 2.0 * cq - tsr * slope
            residual = gain * cq * v[i] * v[i] - tau_aero[i]
            if s > _MIN_SLOPE:
                step = residual / (gain * v[i] * v[i] * s)
            else:
                down = tsr < _STALL_TSR and (residual > 0.0 or s < -_MIN_SLOPE)
                step = _AWAY_STEP if down else -_AWAY_STEP
            step = minimum(maximum(step, -_MAX_STEP), _MAX_STEP)
            v[i] = minimum(maximum(v[i] * (1.0 - step), WIND_MIN), WIND_MAX)


@kernel
def wind_from_torque_flat(tau_aero, rw, v, beta, gain, iterations):
    """``wind_from_torque``'s arithmetic on flat arrays (m,) inside a kernel: the pitch features of β, g = Mᵀ f by
    numba's product (which calls the BLAS routine numpy's ``@`` does, with its numbers: ``tests/test_fast_kernels.py``)
    and ``_newton`` on v in place; ``rw`` = ω_r R."""
    f = np.empty((6, beta.size))
    pitch_features(beta, f)
    _newton(tau_aero, rw, v, f, _M_T @ f, gain, iterations)


def wind_from_torque(
    tau_aero: np.ndarray,
    omega_r: np.ndarray,
    pitch_deg: np.ndarray,
    v_guess: np.ndarray,
    params,
    iterations: int = 8,
) -> np.ndarray:
    """``aero.wind_from_torque`` (m/s), the same numbers: the pitch features and g = Mᵀ f once (they depend on
    the pitch only), the iterations in one kernel."""
    tau_aero, omega_r, pitch_deg, v_guess = np.broadcast_arrays(
        *(np.asarray(a, dtype=float) for a in (tau_aero, omega_r, pitch_deg, v_guess))
    )
    shape = tau_aero.shape
    f = np.empty((6, tau_aero.size))
    pitch_features(np.ascontiguousarray(pitch_deg).ravel(), f)
    rw = np.ascontiguousarray(omega_r).ravel() * params.radius
    v = np.array(v_guess, dtype=float).ravel()
    _newton(np.ascontiguousarray(tau_aero).ravel(), rw, v, f, _M_T @ f, params.aero_torque_gain, iterations)
    return v.reshape(shape)
