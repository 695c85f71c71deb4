"""The pitch-actuator test (benchmark faults 6–7): a generalised likelihood ratio between a blade whose actuator
is within its tolerance and a blade whose actuator has lost bandwidth.

**Residual.** With the benchmark's pitch loop, actuator i is driven by β_ref + n̄_i (n̄_i the mean noise of blade
i's two pitch sensors, σ_β²/2), so blade i's pair mean is m̄_i = G_i β_ref + (1 + G_i) n̄_i. The cross-blade
residual e_i = m̄_i − ½(m̄_j + m̄_k) cancels whatever the three actuators share (a common-mode mismatch: oil
temperature, supply pressure), and with blade i's actuator G_θ and the other two G::

    w_i = (1 + G)⁻¹ e_i = s_θ + v_i,   s_θ = (1 + G)⁻¹ (G_θ − G) β_ref,   v_i white, σ_w² = ¾ σ_β²      (1)

(the noise path (1 + G_θ)/(1 + G) colours v_i by at most 1.4 % of its variance for the faults below; the other
two blades see −½ s_θ). G is the design actuator ω_n²/(s² + 2ζω_n s + ω_n²) under zero-order hold, driven by the
reference of the frame (issued at tick k−1, so G has a direct term in the frame's reference). The signature s_θ
is known for every candidate θ = (ω_n, ζ): it is the reference filtered by a fixed sixth-order system.

**Log-likelihood** of candidate θ for blade i over a window of N ticks (white Gaussian v of variance σ_w², the
adaptive noise scale ŝ² of ``adaptive`` included)::

    L_i(θ) = (Σ_k w_i[k] s_θ[k] − ½ Σ_k s_θ[k]²) / σ_w²                                               (2)

**Composite hypotheses.** H_0 (healthy): θ ∈ T, the actuator tolerance (``TOLERANCE``: ω_n and ζ over the ranges
a real actuator spans without fault, those of the model-mismatch scenarios, design point included); H_1 (fault):
θ ∈ F (``FAULTS``: hydraulic actuators that lost bandwidth, ω_n 2–7.5 rad/s, ζ 0.3–1.2: pressure drop, air in the
oil, pump wear). The statistic is the GLR::

    Λ_i = max_{θ∈F} L_i(θ) − max_{θ∈T} L_i(θ)                                                          (3)

**False-alarm bound** (closed form). If blade i's actuator is θ_0 ∈ T, then max_T L ≥ L(θ_0) and, for each θ ∈ F,
L(θ) − L(θ_0) ~ N(−d²/2, d²) with d² = Σ(s_θ − s_θ0)²/σ_w²; P(L(θ) − L(θ_0) > h) = Q(h/d + d/2) ≤ Q(√(2h)) for
every d (the worst case d = √(2h)). A union over the |F| candidates and the three blades gives the threshold
for a per-decision budget α::

    P(max_i Λ_i > h) ≤ 3 |F| Q(√(2h)),   h = ½ [Q⁻¹(α / (3|F|))]²                                    (4)

whatever the excitation: with the pitch at rest every s_θ is 0 and Λ is 0, and an actuator anywhere in the
tolerance is, by construction, never evidence of a fault. The bound holds for θ_0 on the grid of T; between
grid points the misfit of the nearest one is small against h (the grid's spacing: a few % of d² at the edge).

**Offset.** The pair means carry the sensors' calibration biases, so w_i carries a constant b_i (within twice
the pitch sensors' tolerance). The signatures are not orthogonal to a constant: on a pitch ramp of rate ρ a
slower actuator lags, and its signature is the constant −½ Δτ ρ (Δτ = 2ζ_θ/ω_θ − 2ζ/ω_n the lag difference, ½ the
whitener's DC gain), which a bias mimics: b = 0.1 deg against the −0.01 deg of a 7.5-rad/s actuator on a
0.4 deg/s ramp is worth ≈ 16 in L over 5 s, the threshold. The offset is therefore a nuisance parameter of every
hypothesis, maximised out of (2): with w̃, s̃ the window-centred residual and signature,

    L_i(θ) = (Σ_k w̃_i s̃_θ − ½ Σ_k s̃_θ²) / σ_w²,  Σ w̃ s̃ = Σ w s − Σw Σs / N,  Σ s̃² = Σ s² − (Σs)² / N        (5)

and (4) holds unchanged with the centred signatures (the centring is a projection of white noise).

**Clearing** follows the same evidence the other way: the flag of blade i drops when the window favours the
tolerance over every fault, max_T L − max_F L ≥ h_c, h_c = ½ [Q⁻¹(α_c/|T|)]² from the false-clear budget α_c per
decision (a fault θ_f that persists clears the flag with P ≤ |T| Q(√(2h_c)), by (4) with the roles swapped).
With the pitch at rest both sides are 0, so the flag stays: an actuator shows its dynamics only while the pitch
moves, and a flag clears only on a window that could have shown the fault and did not.

The full window straddles a fault's end for its whole length (5 s), and its older part still speaks for the fault,
so ``ComponentFDI`` also weighs shorter windows ending at the decision (``actuator_clear_windows``, 1 and 2 s):
once the pitch moves after the fault has ended, a window that holds only that motion clears the flag without
waiting for the old evidence to leave the full window. Each window obeys the bound above, so over the K windows
P(a persisting fault clears) ≤ K |T| Q(√(2h_c)) per decision and h_c = ½ [Q⁻¹(α_c/(K|T|))]² (15.0 for the full
window and two shorter ones, against 14.0 for one). A window clears only if no shorter window favours a fault by the
raise threshold (newer evidence first; on a ramp the actuator is no fixed θ inside the full window). After a flag
clears, its blade may not raise again until the raise window holds no evidence from before the clearing.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import tf2ss

from wwcore.lti import zoh
from wwcore.quantiles import norm_isf
from wwcore.scenario.mismatch import LIMITS as _MISMATCH_LIMITS
from wwcore.turbine_params import BENCHMARK, TurbineParams


def _grid(omega: np.ndarray, zeta: np.ndarray) -> np.ndarray:
    return np.array([(w, z) for w in omega for z in zeta])


_OMEGA_TOL = _MISMATCH_LIMITS["pitch_omega_n_rads"]
_ZETA_TOL = _MISMATCH_LIMITS["pitch_zeta"]
TOLERANCE = np.concatenate(
    [
        _grid(np.linspace(_OMEGA_TOL.lo, _OMEGA_TOL.hi, 5), np.linspace(_ZETA_TOL.lo, _ZETA_TOL.hi, 3)),
        [(BENCHMARK.pitch.omega_n, BENCHMARK.pitch.zeta)],
    ]
)
"""(ω_n rad/s, ζ) of actuators taken as healthy: the model-mismatch range of the pitch actuators (8.3–13.9 rad/s,
0.45–0.8; docs/turbine.md, "Model mismatch"), 5 × 3 points, and the design point (11.11, 0.6) last."""
FAULTS = _grid(np.geomspace(2.0, 7.5, 6), np.array([0.3, 0.6, 0.9, 1.2]))
"""(ω_n rad/s, ζ) of actuators taken as faulty: hydraulic actuators that lost bandwidth (2–7.5 rad/s, 0.18–0.68 of
the design's, geometric; ζ 0.3–1.2), 6 × 4 points; the benchmark's three faulty actuators (5.73/0.45, 3.42/0.9,
7.27/0.75) lie inside the range, none on the grid."""


def _actuator_ss(p: TurbineParams, omega_n: float, zeta: float) -> tuple[np.ndarray, ...]:
    """(A, B, C, D) of β[k] = G β_ref,frame[k]: x[k+1] = Φ x[k] + Γ r[k], β[k] = c Φ x[k] + c Γ r[k] (the frame's
    reference r[k] was issued at k−1 and drives the actuator over (k−1, k])."""
    phi, gamma = zoh(
        np.array([[0.0, 1.0], [-(omega_n**2), -2.0 * zeta * omega_n]]), np.array([[0.0], [omega_n**2]]), p.dt
    )
    return phi, gamma[:, 0], phi[0], float(gamma[0, 0])


def signature_system(p: TurbineParams, whiten_b: np.ndarray, whiten_a: np.ndarray, candidates: np.ndarray):
    """(A (K, 6, 6), B (K, 6), C (K, 6), D (K,)) of s_θ = (1 + G)⁻¹ (G_θ − G) r for each candidate θ (eq. 1):
    states [x_θ, x_G, x_w], the whitener (b, a) in controllable canonical form."""
    a_w, b_w, c_w, d_w = tf2ss(whiten_b, whiten_a)
    b_w, c_w, d_w = b_w[:, 0], c_w[0], float(d_w[0, 0])
    a0, b0, c0, d0 = _actuator_ss(p, p.pitch.omega_n, p.pitch.zeta)
    k = len(candidates)
    A, B, C, D = np.zeros((k, 6, 6)), np.zeros((k, 6)), np.zeros((k, 6)), np.zeros(k)
    for j, (omega_n, zeta) in enumerate(candidates):
        a1, b1, c1, d1 = _actuator_ss(p, omega_n, zeta)
        # u = c1 x_θ − c0 x_G + (d1 − d0) r, the difference of the two actuators' outputs
        u_x = np.concatenate([c1, -c0])
        A[j, :2, :2], A[j, 2:4, 2:4], A[j, 4:, 4:] = a1, a0, a_w
        A[j, 4:, :4] = np.outer(b_w, u_x)
        B[j, :2], B[j, 2:4], B[j, 4:] = b1, b0, b_w * (d1 - d0)
        C[j, :4], C[j, 4:] = d_w * u_x, c_w
        D[j] = d_w * (d1 - d0)
    return A, B, C, D


def glr_threshold(alpha: float, tests: int) -> float:
    """h = ½ [Q⁻¹(α / tests)]²: P(Λ > h) ≤ tests · Q(√(2h)) = α (eq. 4)."""
    return 0.5 * float(norm_isf(alpha / tests)) ** 2


class SignatureBank:
    """s_θ[k] for every candidate θ and turbine, from the frames' pitch references (eq. 1)."""

    def __init__(self, p: TurbineParams, whiten_b: np.ndarray, whiten_a: np.ndarray, n: int):
        self.candidates = np.concatenate([FAULTS, TOLERANCE])
        self.n_faults = len(FAULTS)
        A, B, C, D = signature_system(p, whiten_b, whiten_a, self.candidates)
        self._At = np.ascontiguousarray(np.transpose(A, (0, 2, 1)))
        self._B, self._C, self._D = B, C, D
        # the state a constant reference holds: (I − A)⁻¹ B per candidate (the signature is 0 there)
        self._steady = np.linalg.solve(np.eye(6)[None] - A, B[..., None])[..., 0]
        self.x: np.ndarray | None = None  # (n, K, 6)
        self.n = n

    def block(self, reference: np.ndarray) -> np.ndarray:
        """s (ticks, n, K) for the references (ticks, n) of a block of frames, states carried over."""
        if self.x is None:
            self.x = reference[0][:, None, None] * self._steady[None]
        s = np.empty((len(reference), self.n, len(self.candidates)))
        x = self.x
        for k, r in enumerate(reference):
            s[k] = np.einsum("nkj,kj->nk", x, self._C) + r[:, None] * self._D
            x = np.matmul(x[:, :, None, :], self._At[None])[:, :, 0, :] + r[:, None, None] * self._B
        self.x = x
        return s

    def block_sums(
        self, reference: np.ndarray, w: np.ndarray, kernel, order: int = 0
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``block`` of the references (ticks, n) with the sums a pitch-actuator test takes of it, given the whitened
        residual w (ticks, n, 3): Σ_k w s_θ (n, 3, K), Σ_k s_θ² (n, K) and [Σ_k w | Σ_k s_θ] (n, 3 + K), by a compiled
        ``kernel`` (``service.turbine.fast_actuator.signature_block``: numpy's operations in numpy's order; its state
        products by the reproduced BLAS arithmetic of ``order`` (``fast_actuator.numpy_matmul_order``), by BLAS
        calls with 0)."""
        if self.x is None:
            self.x = reference[0][:, None, None] * self._steady[None]
        k = len(self.candidates)
        correlation, energy, sums = np.empty((self.n, 3, k)), np.empty((self.n, k)), np.empty((self.n, 3 + k))
        kernel(reference, self.x, self._At, self._B, self._C, self._D, w, correlation, energy, sums, order)
        return correlation, energy, sums


def glr(
    correlation: np.ndarray,
    energy: np.ndarray,
    variance: np.ndarray,
    n_faults: int,
    sums: tuple[np.ndarray, np.ndarray, int] | None = None,
) -> np.ndarray:
    """Λ (n, 3) of eq. 3 from Σ w_i s_θ (n, 3, K), Σ s_θ² (n, K) and σ_w² (n, 3); the first ``n_faults`` of the K
    candidates are F, the others T (``SignatureBank.candidates``). With ``sums`` = (Σ w_i (n, 3), Σ s_θ (n, K), N)
    the window's constant offset of w is a nuisance parameter maximised out (eq. 5): both sums are centred."""
    if sums is not None:
        sum_w, sum_s, count = sums
        correlation = correlation - sum_w[:, :, None] * sum_s[:, None, :] / count
        energy = energy - sum_s * sum_s / count
    likelihood = (correlation - 0.5 * energy[:, None, :]) / variance[:, :, None]  # L_i(θ), eq. 2
    return likelihood[:, :, :n_faults].max(axis=2) - likelihood[:, :, n_faults:].max(axis=2)
