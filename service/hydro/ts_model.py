"""The Takagi–Sugeno form of the hydrostatic turbine, eqs. (6)–(15).

The nonlinear model (4) is rewritten as ẋ = A(z) x + B u with the three premise nonlinearities of eq. (6)

    f_1 = T_r(λ, β)/ω_g,   f_2 = x̃_p,   f_3 = x̃_M,

each written as a convex combination of its bounds over the operating envelope (9)–(11), which gives 2³ = 8
vertex models A_i (14)–(15) weighted by the memberships h_i = w_1k w_2k w_3k (13). Inside the envelope
Σ h_i(z) A_i x + B u equals eq. (4) exactly (sector nonlinearity); ``tests/hydro/test_ts_model.py`` checks it.

Vertex order: i = 4 (k_1 − 1) + 2 (k_2 − 1) + (k_3 − 1), with k_j = 1 taking the upper bound f̄_j (w_j1) and
k_j = 2 the lower bound f_j (w_j2), as in (9)–(10).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from wwcore.hydro_model import aero_torque
from wwcore.hydro_params import HydroParams

N_PREMISES = 3
N_VERTICES = 2**N_PREMISES
OUTPUT_STATES = (0, 1, 3, 4, 5)  # y = C x: ω_r, ω_g, T_g, x̃_p, x̃_M; Δp (index 2) is not measured
VERTEX_CORNERS = np.array(list(itertools.product((1, 2), repeat=N_PREMISES)))  # (8, 3) k_j of each vertex


@dataclass(frozen=True)
class PremiseBounds:
    """f_j ∈ [lo_j, hi_j] over the operating envelope (the f̲_j, f̄_j of eq. (9))."""

    lo: np.ndarray  # (3,)
    hi: np.ndarray  # (3,)

    def clip(self, z: np.ndarray) -> np.ndarray:
        return np.clip(z, self.lo, self.hi)

    def inside(self, z: np.ndarray) -> np.ndarray:
        """(n,) True where every premise lies within its bounds (where the TS model is exact)."""
        return np.all((z >= self.lo) & (z <= self.hi), axis=-1)


def premises(x: np.ndarray, T_r: np.ndarray) -> np.ndarray:
    """z = [f_1, f_2, f_3] of eq. (6) for states x (n, 6) and rotor torque T_r (n,): (n, 3)."""
    return np.column_stack([T_r / x[:, 1], x[:, 4], x[:, 5]])


def premise_bounds(p: HydroParams, grid: int = 121) -> PremiseBounds:
    """Bounds of eq. (9) over the envelope ``p.envelope`` (β = 0, partial load).

    f_1 = T_r/ω_g: T_r is gridded over (ω_r, v) in the envelope, then divided by both ω_g bounds (T_r/ω_g is
    monotone in ω_g for either sign of T_r, so the extremes sit at the ω_g bounds). f_2, f_3 are the strokes.
    """
    env = p.envelope
    w_r, v = np.meshgrid(np.linspace(env.omega_r_min, env.omega_r_max, grid), np.linspace(env.v_min, env.v_max, grid))
    T_r = aero_torque(w_r.ravel(), v.ravel(), p)
    ratios = np.concatenate([T_r / env.omega_g_min, T_r / env.omega_g_max])
    lo = np.array([ratios.min(), env.x_p_min, env.x_M_min])
    hi = np.array([ratios.max(), env.x_p_max, env.x_M_max])
    return PremiseBounds(lo=lo, hi=hi)


def memberships(z: np.ndarray, bounds: PremiseBounds) -> np.ndarray:
    """h_i(z) of eqs. (10)–(13) for premises z (n, 3): (n, 8), each row ≥ 0 and summing to 1.

    Premises outside the envelope are clipped to it first (the TS model is then no longer exact there).
    """
    z = bounds.clip(z)
    # (10) w_j1 = (f_j − f̲_j)/(f̄_j − f̲_j),  w_j2 = (f̄_j − f_j)/(f̄_j − f̲_j)
    w1 = (z - bounds.lo) / (bounds.hi - bounds.lo)
    w = np.stack([w1, 1.0 - w1], axis=-1)  # (n, 3, 2): w[:, j, k−1]
    # (13) h_i = w_1k · w_2k · w_3k over the 8 corners
    h = np.ones((z.shape[0], N_VERTICES))
    for j in range(N_PREMISES):
        h *= w[:, j, VERTEX_CORNERS[:, j] - 1]
    return h


@dataclass(frozen=True)
class TSModel:
    """Vertex matrices of eq. (14): ẋ = Σ h_i(z) A_i x + B u, y = C x; F the actuator-fault matrix of (21)."""

    A: np.ndarray  # (8, 6, 6)
    B: np.ndarray  # (6, 3), columns [u_p, u_M, T_g,d]
    C: np.ndarray  # (5, 6)
    F: np.ndarray  # (6, 2): F = B restricted to the u_p and u_M columns (Section 4.3)
    bounds: PremiseBounds

    def vertex_premises(self) -> np.ndarray:
        """(8, 3) the premise values at each vertex (f̄_j for k_j = 1, f̲_j for k_j = 2)."""
        return np.where(VERTEX_CORNERS == 1, self.bounds.hi, self.bounds.lo)

    def derivative(self, x: np.ndarray, u: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Σ h_i(z) A_i x + B u for x (n, 6), u (n, 3), z (n, 3)."""
        A = np.einsum("nk,kij->nij", memberships(z, self.bounds), self.A)
        return np.einsum("nij,nj->ni", A, x) + u @ self.B.T


def system_matrix(f: np.ndarray, p: HydroParams) -> np.ndarray:
    """A(z) of eq. (7) with the entries (8) evaluated at premise values f = [f_1, f_2, f_3]."""
    A = np.zeros((6, 6))
    A[0, 1] = f[0] / p.J_r  # a12 = f_1/J_r
    A[0, 2] = -p.V_p * f[1] / p.J_r  # a13 = −Ṽ_p f_2/J_r
    A[1, 2] = p.V_M * f[2] / p.J_g  # a23 = Ṽ_M f_3/J_g
    A[1, 3] = -1.0 / p.J_g
    A[2, 0] = p.V_p * f[1] / p.C_H  # a31 = Ṽ_p f_2/C_H
    A[2, 1] = -p.V_M * f[2] / p.C_H  # a32 = −Ṽ_M f_3/C_H
    A[2, 2] = -p.k_leak / p.C_H
    A[3, 3] = -1.0 / p.tau_g
    A[4, 4] = -1.0 / p.tau_p
    A[5, 5] = -1.0 / p.tau_M
    return A


def build_ts_model(p: HydroParams, bounds: PremiseBounds | None = None) -> TSModel:
    """The 8 vertex models (14)–(15) of the parameter set ``p`` over its envelope."""
    bounds = premise_bounds(p) if bounds is None else bounds
    corners = np.where(VERTEX_CORNERS == 1, bounds.hi, bounds.lo)
    A = np.stack([system_matrix(f, p) for f in corners])
    B = np.zeros((6, 3))
    B[4, 0] = 1.0 / p.tau_p
    B[5, 1] = 1.0 / p.tau_M
    B[3, 2] = 1.0 / p.tau_g
    C = np.zeros((5, 6))
    C[np.arange(5), OUTPUT_STATES] = 1.0
    return TSModel(A=A, B=B, C=C, F=B[:, :2].copy(), bounds=bounds)
