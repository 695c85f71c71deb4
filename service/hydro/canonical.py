"""Existence conditions and the canonical form of the sliding mode observer (Section 4.1; Edwards & Spurgeon 1998).

For each vertex (A_i, F, C) the observer needs (Condition 2) q = rank(CF) = rank(F) and p > q, and
(Condition 3) every invariant zero of (A_i, F, C) in the open left half-plane. ``check_existence`` tests both
numerically and raises ``ObserverDesignError`` naming the vertex and the violated condition.

``canonical_form`` computes T_i = T_L,i T_b,i T_c by an algorithm (no hand-typed matrices):

1. T_c = [N_cᵀ; C] with N_c an orthonormal basis of ker C, so that C T_c⁻¹ = [0 I_p] (eq. 28);
2. T_b = [[I, −F̄_1 F̄_2⁺], [0, I_p]] removes the fault from the unmeasured block: T_b T_c F = [0; F̄_2];
3. T_L = [[I, L], [0, I_p]] with L = L_0 N_Fᵀ, N_F an orthonormal basis of the outputs the fault does not
   reach (N_Fᵀ F̄_2 = 0, so T_L keeps F_1 = 0). L_0 places the poles of A_11 + L A_21 (the unmeasured-state
   error dynamics, eq. (29)) with ``scipy.signal.place_poles``; the part of (A_11, N_Fᵀ A_21) that cannot be
   moved carries exactly the invariant zeros, hence Condition 3.

In these coordinates the faults act only on the outputs: 𝓕_i = T_i F = [0; 𝓕_2,i] (eq. 22).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import null_space, orth
from scipy.signal import place_poles


class ObserverDesignError(ValueError):
    """A parameter set for which the sliding mode observer does not exist (Conditions 2–3 of Section 4.1)."""


@dataclass(frozen=True)
class CanonicalForm:
    """One vertex in the coordinates of eq. (22): x_can = T x = [x_1; y]."""

    T: np.ndarray  # (n, n)
    T_inv: np.ndarray  # (n, n)
    A11: np.ndarray  # (n−p, n−p)
    A12: np.ndarray  # (n−p, p)
    A21: np.ndarray  # (p, n−p)
    A22: np.ndarray  # (p, p)
    F2: np.ndarray  # (p, q)
    L: np.ndarray  # (n−p, p)


def _rank(M: np.ndarray, rtol: float = 1e-9) -> int:
    if M.size == 0:
        return 0
    s = np.linalg.svd(M, compute_uv=False)
    return int(np.sum(s > rtol * max(s[0], 1e-300)))


def _output_coordinates(F: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """T_b T_c and its inverse (steps 1–2)."""
    n, p = F.shape[0], C.shape[0]
    N_c = null_space(C)  # (n, n−p) orthonormal, C N_c = 0
    T_c = np.vstack([N_c.T, C])
    F_bar = T_c @ F
    F1, F2 = F_bar[: n - p], F_bar[n - p :]
    T_b = np.eye(n)
    T_b[: n - p, n - p :] = -F1 @ np.linalg.pinv(F2)
    T = T_b @ T_c
    return T, np.linalg.inv(T)


def _unmoved_split(A: np.ndarray, F: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A_11, A_211 = N_Fᵀ A_21, N_F) in the coordinates of steps 1–2."""
    n, p = F.shape[0], C.shape[0]
    T, T_inv = _output_coordinates(F, C)
    Ab = T @ A @ T_inv
    F2 = (T @ F)[n - p :]
    N_F = null_space(F2.T)  # (p, p−q): output directions the fault does not reach
    return Ab[: n - p, : n - p], N_F.T @ Ab[n - p :, : n - p], N_F


def invariant_zeros(A: np.ndarray, F: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Invariant zeros of (A, F, C) for rank(CF) = rank(F) = q < p.

    They are the unobservable modes of (A_11, A_211) (Edwards & Spurgeon 1998, Prop. 6.3): the eigenvalues of
    A_11 restricted to the unobservable subspace ker [A_211; A_211 A_11; …].
    """
    A11, A211, _ = _unmoved_split(A, F, C)
    m = A11.shape[0]
    if m == 0:
        return np.zeros(0, dtype=complex)
    if A211.shape[0] == 0:
        return np.linalg.eigvals(A11)
    obs = np.vstack([A211 @ np.linalg.matrix_power(A11, k) for k in range(m)])
    scale = np.abs(obs).max(axis=1, keepdims=True)
    N_o = null_space(obs / np.where(scale > 0, scale, 1.0), rcond=1e-9)
    if N_o.shape[1] == 0:
        return np.zeros(0, dtype=complex)
    return np.linalg.eigvals(N_o.T @ A11 @ N_o)


def check_existence(A_vertices: np.ndarray, F: np.ndarray, C: np.ndarray) -> None:
    """Conditions 2 and 3 for every vertex; raise ``ObserverDesignError`` with the first violation."""
    q = F.shape[1]
    p = C.shape[0]
    if _rank(C) != p:
        raise ObserverDesignError(f"C must have full row rank p = {p}; rank(C) = {_rank(C)}")
    rank_F, rank_CF = _rank(F), _rank(C @ F)
    if not (rank_CF == rank_F == q):
        raise ObserverDesignError(
            f"Condition 2 violated: rank(CF) = {rank_CF}, rank(F) = {rank_F}, q = {q} (need all equal): "
            "some fault does not show in the outputs"
        )
    if not p > q:
        raise ObserverDesignError(f"Condition 2 violated: p = {p} outputs must exceed q = {q} faults")
    for i, A in enumerate(A_vertices):
        zeros = invariant_zeros(A, F, C)
        bad = zeros[zeros.real >= -1e-12]
        if bad.size:
            raise ObserverDesignError(
                f"Condition 3 violated at vertex {i + 1}: invariant zero(s) {np.round(bad, 6).tolist()} of "
                "(A_i, F, C) not in the open left half-plane; the fault reconstruction would drift"
            )


def canonical_form(A: np.ndarray, F: np.ndarray, C: np.ndarray, x1_poles: np.ndarray | None) -> CanonicalForm:
    """T_i = T_L T_b T_c for one vertex and the blocks of eq. (22).

    ``x1_poles``: desired eigenvalues of A_11 + L A_21 (the unmeasured-state error, eq. (29)); None keeps L = 0
    (then A_11 itself must be Hurwitz). Only the observable part of (A_11, N_Fᵀ A_21) is moved.
    """
    n, p = F.shape[0], C.shape[0]
    T_bc, _ = _output_coordinates(F, C)
    A11, A211, N_F = _unmoved_split(A, F, C)
    m = n - p
    L = np.zeros((m, p))
    if x1_poles is not None and A211.shape[0] > 0:
        basis = orth(A211.T)  # directions of x_1 that A_211 sees
        if basis.shape[1] == m:
            # dual pole placement: eig(A_11ᵀ − A_211ᵀ K) = poles, L_0 = −Kᵀ
            B_r = orth(A211)  # (p−q, r) reduce the injection channels to their range
            K = place_poles(A11.T, (B_r.T @ A211).T, np.asarray(x1_poles, dtype=float)).gain_matrix
            L = (-K.T @ B_r.T) @ N_F.T
    T_L = np.eye(n)
    T_L[:m, m:] = L
    T = T_L @ T_bc
    T_inv = np.linalg.inv(T)
    Ac = T @ A @ T_inv
    Fc = T @ F
    if np.abs(Fc[:m]).max(initial=0.0) > 1e-9 * max(np.abs(Fc).max(), 1.0):
        raise ObserverDesignError("canonical form failed: the fault still acts on the unmeasured states")
    return CanonicalForm(
        T=T, T_inv=T_inv, A11=Ac[:m, :m], A12=Ac[:m, m:], A21=Ac[m:, :m], A22=Ac[m:, m:], F2=Fc[m:], L=L
    )
