"""Compiled twin of ``wwcore.thrust.thrust_coefficient`` (``wwcore.backend``): the same operations in the same order.

C_T = h⁻¹(K C_p(λ, β)/C_p,max) with C_p from ``wwcore.aero.power_coefficient``. The element-wise arithmetic between
numpy's transcendental functions is three kernels; numpy's own calls stay between them: ``arcsinh``, ``sin``,
``exp`` and ``log1p`` of the pitch features, the 6 × 6 product g = Mᵀ f (BLAS) and the ``exp`` of C_q, so every number
is the reference's bit for bit (numpy's SIMD ``exp``, ``arcsinh`` and ``log1p`` differ from a compiled loop's libm in
the last bit; a loop would sum the product's six terms in another order). Nine calls (and four allocations) instead
of about forty.
``interp`` is ``np.interp``'s arithmetic for one float, shared with ``service.farm.fast``; ``interp_binned`` the same
on h⁻¹'s grid, its bisection started from h's bin.
"""

from __future__ import annotations

import numpy as np

from wwcore.aero import _B0, _B1, _M_T, _X_REF, PITCH_MAX_DEG, PITCH_MIN_DEG, SHAPE, TSR_MAX, TSR_MIN
from wwcore.jit import kernel
from wwcore.thrust import _CT_GRID, _H_GRID, H_MAX, THRUST_LOADING_K, model_cp_max
from wwcore.units import DEG

_BETA_H, _BETA_K, _W_K = SHAPE[2:5]
_INV_BETA_H, _INV_W_K, _KNEE = 1.0 / _BETA_H, 1.0 / _W_K, _BETA_K / _W_K
# h⁻¹'s grid in uniform bins of h (``interp_binned``): 4 096 bins over its 4 001 points, a bin's bisection a few steps
_H_PER_BIN = 4096 / _H_GRID[-1]
_H_BIN_FIRST = np.searchsorted(_H_GRID, np.arange(4097) / _H_PER_BIN, side="right") - 1


@kernel
def interp(x, xp, fp):
    """np.interp of one float on increasing ``xp`` (held at the ends; nan stays nan), numpy's arithmetic."""
    m = xp.size
    if x != x:
        return x
    if x < xp[0]:
        return fp[0]
    if x >= xp[m - 1]:
        return fp[m - 1]
    return _interp_inside(x, xp, fp, 0, m - 1)


@kernel
def interp_binned(x, xp, fp, first, per_bin):
    """``interp`` on strictly increasing ``xp`` from xp[0] = 0 with ``first`` (bins + 1,) the last index with xp[i] ≤
    b / ``per_bin`` for each bin edge b: x's bin bounds the bisection, which finds the same interval as over the whole
    grid (the only one with xp[lo] ≤ x < xp[lo + 1]), so the same arithmetic in a few steps instead of log₂ m."""
    m = xp.size
    if not xp[0] <= x < xp[m - 1]:  # nan, or held at an end
        return interp(x, xp, fp)
    b = min(int(x * per_bin), first.size - 2)
    lo, hi = first[b], min(first[b + 1] + 1, m - 1)
    while xp[lo] > x:  # the bin's edge rounded past x: the interval is further down (xp[0] ≤ x ends it)
        lo -= 1
    while xp[hi] <= x:  # or further up (x < xp[m − 1] ends it)
        hi += 1
    return _interp_inside(x, xp, fp, lo, hi)


@kernel
def _interp_inside(x, xp, fp, lo, hi):
    """np.interp's arithmetic for xp[lo] ≤ x < xp[hi]: the interval by bisection, then its line."""
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if xp[mid] <= x:
            lo = mid
        else:
            hi = mid
    if xp[lo] == x:
        return fp[lo]
    slope = (fp[lo + 1] - fp[lo]) / (xp[lo + 1] - xp[lo])
    value = slope * (x - xp[lo]) + fp[lo]
    if value != value:  # numpy tries the other end, then a flat segment's value
        value = slope * (x - xp[lo + 1]) + fp[lo + 1]
        if value != value and fp[lo] == fp[lo + 1]:
            value = fp[lo]
    return value


@kernel
def np_maximum(a, b):
    """np.maximum of two floats as numpy's SIMD loop gives it: nan if either is nan, ``b`` where they are equal
    (signed zeros)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a > b else b


@kernel
def np_minimum(a, b):
    """np.minimum of two floats as numpy's SIMD loop gives it: nan if either is nan, ``b`` where they are equal
    (signed zeros)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a < b else b


@kernel
def thrust_front(tsr, pitch_deg, lam, upper, f, knee, u, x):
    """``aero.power_coefficient``'s clips (λ into ``lam``, min(λ, 13) into ``upper``) and the arguments of the pitch
    features' transcendental functions: β/β_h into f[1], β·DEG into f[3], β/w_k − β_k/w_k into ``knee``; u = 1/λ
    and x = u − x_ref. All (m,) but f (6, m)."""
    for i in range(tsr.size):
        up = np_minimum(tsr[i], TSR_MAX)
        upper[i] = up
        lam[i] = np_maximum(up, TSR_MIN)
        beta = np_minimum(np_maximum(pitch_deg[i], PITCH_MIN_DEG), PITCH_MAX_DEG)
        f[0, i] = 1.0
        f[1, i] = beta * _INV_BETA_H
        f[3, i] = beta * DEG
        knee[i] = beta * _INV_W_K - _KNEE
        u[i] = 1.0 / lam[i]
        x[i] = u[i] - _X_REF


@kernel
def thrust_middle(f, x, exponent):
    """The features' squares h² and sin² β into f[2], f[4]; −b x with b = b0 − b1 h into ``exponent``."""
    for i in range(x.size):
        h, s = f[1, i], f[3, i]
        f[2, i] = h * h
        f[4, i] = s * s
        exponent[i] = -(_B0 - _B1 * h) * x[i]


@kernel
def thrust_back(lam, upper, u, x, e, g, cp_max, out):
    """C_q = Q E + g3 + λ (g4 + λ g5), C_p = min(λ, 13) C_q, h = clip(K C_p/C_p,max, 0, 16/27), C_T = h⁻¹(h) by
    np.interp's arithmetic on the reference's grid, into ``out``."""
    for i in range(lam.size):
        q = (g[0, i] * x[i] + g[1, i]) * u[i] + g[5, i]
        cq = q * e[i] + g[2, i] + lam[i] * (g[3, i] + lam[i] * g[4, i])
        cp = upper[i] * cq
        h = np_minimum(np_maximum(THRUST_LOADING_K * cp / cp_max, 0.0), H_MAX)
        out[i] = interp_binned(h, _H_GRID, _CT_GRID, _H_BIN_FIRST, _H_PER_BIN)


def thrust_coefficient(tsr: np.ndarray, pitch_deg: np.ndarray) -> np.ndarray:
    """``thrust.thrust_coefficient`` of float64 arrays of one shape: C_T (–), bit for bit the reference's."""
    shape = np.shape(tsr)
    tsr = np.ascontiguousarray(tsr, dtype=float).reshape(-1)
    m = tsr.size
    lam, upper, knee, u, x, exponent, e = np.empty((7, m))
    out = np.empty(m)
    f, g = np.empty((2, 6, m))
    thrust_front(tsr, np.ascontiguousarray(pitch_deg, dtype=float).reshape(-1), lam, upper, f, knee, u, x)
    np.arcsinh(f[1], out=f[1])  # h = asinh(β/β_h)
    np.sin(f[3], out=f[3])
    np.log1p(np.exp(knee, out=knee), out=f[5])  # σ = ln(1 + e^((β − β_k)/w_k))
    thrust_middle(f, x, exponent)
    np.matmul(_M_T, f, out=g)
    np.exp(exponent, out=e)
    thrust_back(lam, upper, u, x, e, g, model_cp_max(), out)
    return out.reshape(shape)
