"""Compiled twin of ``wwcore.aero``'s C_q evaluation (``wwcore.backend``): the same operations in the same order.

C_q(λ, β) = Q E + g3 + g4 λ + g5 λ² with g = Mᵀ f(β) (``aero._cq_inside``). The two element-wise halves are
kernels; the 6 × 6 product g = Mᵀ f between them stays numpy's (BLAS), so that every number equals the reference
bit for bit: a compiled loop would sum the six products in another order, or without BLAS's fused multiply-adds.
"""

from __future__ import annotations

import math

import numpy as np

from wwcore.aero import _B0, _B1, _M_T, _X_REF, PITCH_MAX_DEG, PITCH_MIN_DEG, SHAPE, TSR_MAX, TSR_MIN
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
def features(lam, beta, f):
    """λ (m,) → clipped in place to [1, 13]; β (m,) deg → f (6, m) = [1, h, h², sin β, sin² β, σ] of clipped β."""
    for i in range(lam.size):
        lam[i] = maximum(minimum(lam[i], TSR_MAX), TSR_MIN)
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
