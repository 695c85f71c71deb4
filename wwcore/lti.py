"""The few linear-systems tools the step code needs, kept off ``scipy.signal`` (whose import costs ~0.7 s, and
a supervisor restarted mid-run must be back within 2 s). ``tests/test_lti.py`` checks each against scipy.signal.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm


def zoh(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation of (…, n, n), (…, n, m): expm([[A, B], [0, 0]] dt) = [[Φ, Γ], [0, I]]."""
    n, m = A.shape[-1], B.shape[-1]
    M = np.zeros((*A.shape[:-2], n + m, n + m))
    M[..., :n, :n] = A * dt
    M[..., :n, n:] = B * dt
    E = expm(M)
    return E[..., :n, :n], E[..., :n, n:]


def butter2_lowpass(cutoff_hz: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of the second-order Butterworth low-pass, bilinear transform with the cutoff prewarped."""
    k = math.tan(math.pi * cutoff_hz * dt)
    norm = 1.0 / (1.0 + math.sqrt(2.0) * k + k * k)
    b0 = k * k * norm
    a1 = 2.0 * (k * k - 1.0) * norm
    a2 = (1.0 - math.sqrt(2.0) * k + k * k) * norm
    return np.array([b0, 2.0 * b0, b0]), np.array([1.0, a1, a2])


def biquad_steady_state(b: np.ndarray, a: np.ndarray) -> np.ndarray:
    """States (s1, s2) of a transposed-direct-form-II section at rest under a unit constant input.

    With y = H(1): s2 = b2 − a2 y, s1 = b1 − a1 y + s2 (the same as ``scipy.signal.lfilter_zi``).
    """
    gain = b.sum() / a.sum()
    s2 = b[2] - a[2] * gain
    return np.array([b[1] - a[1] * gain + s2, s2])


def second_order_tf(phi: np.ndarray, gamma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(num, den) in z of y = x₁ for the 2-state x[k+1] = Φ x[k] + Γ u[k]: C adj(zI − Φ) Γ / det(zI − Φ)."""
    (p11, p12), (p21, p22) = phi
    g1, g2 = np.ravel(gamma)
    den = np.array([1.0, -(p11 + p22), p11 * p22 - p12 * p21])
    num = np.array([0.0, g1, p12 * g2 - p22 * g1])
    return num, den
