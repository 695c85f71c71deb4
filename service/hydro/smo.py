"""The Takagi–Sugeno sliding mode observer of Section 4 and the fault reconstruction, eqs. (23)–(37).

In the coordinates x of the model (24):

    dx̂/dt = Σ h_i(z) (A_i x̂ + B u − G_L,i e_y + G_n,i v),   e_y = C x̂ − y,
    G_L,i = T_i⁻¹ [𝒜_12,i; 𝒜_22,i − 𝒜ˢ_22],   G_n,i = T_i⁻¹ [0; I_p],
    v = −ρ P_2 e_y / (‖P_2 e_y‖ + δ)                                   (33), P_2 𝒜ˢ_22 + 𝒜ˢ_22ᵀ P_2 = −Q_2 (26)
    f̂_a = [Σ h_i 𝓕_2,i]⁺ v                                            (35)
    df̂_filt/dt = diag(1/τ) (f̂_a − f̂_filt)                               (37)

Two options (``layer_correction``, ``filter_order``; both off by default, the paper's equations), argued in
docs/hydro.md §4:

* (35') the equivalent injection of the boundary layer. In the canonical coordinates the output error obeys
  ė_y = 𝒜_21 e_1 + 𝒜ˢ_22 e_y + v − 𝓕_2 f_a (e = x̂ − x). (35) takes ė_y = e_y = 0 (ideal sliding); the smoothed
  injection (33) holds e_y at −𝓕_2 f_a/(ρλ_max(P_2)/δ + |𝒜ˢ_22|) instead, so (35) returns f_a scaled by
  ρλ_max(P_2)/δ / (ρλ_max(P_2)/δ + |𝒜ˢ_22|) = 0.984. With ė_y = 0 and e_1 = 0 but e_y ≠ 0 the injection that
  holds the layer is v_eq = 𝓕_2 f_a − 𝒜ˢ_22 e_y, and e_y is known, so::

      f̂_a = [Σ h_i 𝓕_2,i]⁺ (v + 𝒜ˢ_22 e_y)                                (35')

  which is exact in steady state whatever δ (ideal sliding, e_y = 0, makes it (35)).
* (37') two stages of (37) in series, a critically damped second-order filter::

      df̂_1/dt = (f̂_a − f̂_1)/τ,   df̂_filt/dt = (f̂_1 − f̂_filt)/τ                        (37')

  f̂_a carries the stroke reading's noise differentiated (its model is the lag τ_p: f̂ ≈ τ_p dx̃/dt + x̃ − u), which
  (37) passes with the flat high-frequency gain τ_p/τ; (37') rolls it off. Both filters leave a step's
  tracking deficit ∫(f − f̂_filt) dt = τ f for (37) and 2τ f for (37'), so (37') at τ/2 costs the compensation
  the same input deficit as (37) at τ.

Decisions where the paper is silent:

* Output scaling. ‖P_2 e_y‖ in (33) mixes rad/s, N m and strokes; with Q_2 = I in SI units the torque channel
  (N m) would own the whole injection. The observer therefore works on per-unit outputs y/y_N (ω_r,rated,
  ω_g,N, Ṽ_M Δp_N, 1, 1), which is a choice of T_c. ρ = 100 and δ = 0.002 are then per-unit/s and per-unit.
* Premise f_1 = T_r/ω_g needs the rotor torque, which no sensor gives (no wind measurement in y). The observer
  uses the quasi-static rotor balance T̂_r = Ṽ_p x̃_p Δp̂ with its own pressure estimate. The difference
  (J_r ω̇_r, ≤ 0.05 per-unit/s) is absorbed by the ω_r channel's injection and does not enter (35), whose
  𝓕_2 has no ω_r row.
* Sampling. Measurements arrive every dt = 10 ms; between samples the observer sees them linearly
  interpolated (first-order hold of y_{k−1} → y_k) and integrates with forward Euler at h = dt/N.
* Integration step. Inside the boundary layer (33) is a linear injection of gain ρ λ_max(P_2)/δ (= 1250 s⁻¹
  with the paper's settings) on top of 𝒜ˢ_22 (−20 s⁻¹): forward Euler reproduces the continuous boundary layer
  without numerical chattering only if h · (ρ λ_max(P_2)/δ + |λ(𝒜ˢ_22)|) ≤ 1, i.e. h ≤ 0.79 ms, so N = 13
  substeps per 10 ms sample. Equivalently the largest move of one step, ρh, stays within the layer's width
  δ/λ_max(P_2). ``required_substeps`` computes N from the settings.
* f̂_a reported per sample is the mean of (35) over the sample's substeps (the equivalent injection is the
  low-frequency part of v); the filter (37) integrates every substep.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Annotated

import numpy as np
from scipy.linalg import solve_continuous_lyapunov

from service.hydro.canonical import CanonicalForm, canonical_form, check_existence
from service.hydro.ts_model import OUTPUT_STATES, TSModel, build_ts_model, memberships
from wwcore.hydro_params import HydroParams
from wwcore.options import Bounds


@dataclass(frozen=True)
class SMOSettings:
    """Observer settings, the ``ts-smo`` options of ``[supervisor.params]``; defaults are the paper's eq. (39) and
    Section 4.3, ``Bounds`` the accepted ranges."""

    a22s: Annotated[float, Bounds(ge=-1000.0, lt=0.0, unit="1/s")] = -20.0  # 𝒜ˢ_22 = diag(a22s, …) (39)
    rho: Annotated[float, Bounds(gt=0.0, le=10_000.0, unit="per-unit/s")] = 100.0  # ρ (39)
    delta: Annotated[float, Bounds(gt=0.0, le=1.0, unit="per-unit")] = 0.002  # δ (39)
    tau_filter: Annotated[tuple[float, float], Bounds(gt=0.0, le=10.0, unit="s")] = (0.1, 0.1)  # τ_1, τ_2 of (37)
    # Q_2 = diag(q2) of (26) [PROPOSED: identity]
    q2: Annotated[tuple[float, float, float, float, float], Bounds(gt=0.0, le=1e6)] = (1.0, 1.0, 1.0, 1.0, 1.0)
    # eigenvalue of 𝒜_11 + L𝒜_21 (pressure error) [PROPOSED]; None: L = 0
    x1_pole: Annotated[float | None, Bounds(ge=-100.0, lt=0.0, unit="1/s")] = -2.0
    # None: the smallest N with h (ρλ_max(P_2)/δ + |a22s|) ≤ 1
    substeps: Annotated[int | None, Bounds(ge=1, le=1000)] = None
    # (35') f̂_a = 𝓕_2⁺ (v + 𝒜ˢ_22 e_y): the injection that holds ė_y = 0 inside the boundary layer; False: (35)
    layer_correction: bool = False
    # stages of (37) in series: 1 is the paper's filter, 2 a critically damped second-order filter
    filter_order: Annotated[int, Bounds(ge=1, le=2)] = 1


@dataclass
class Reconstruction:
    """One sample's output of the observer, arrays over the batch."""

    f_hat: np.ndarray  # (n, 2) eq. (35), mean over the sample
    f_filt: np.ndarray  # (n, 2) eq. (37) at the sample time
    x_hat: np.ndarray  # (n, 6)
    sliding: np.ndarray  # (n,) bool: ‖P_2 e_y‖ < δ at the sample (inside the boundary layer)
    e_y_norm: np.ndarray  # (n,) ‖P_2 e_y‖, per-unit


@dataclass
class ObserverDesign:
    """Everything computed offline: TS model, canonical forms, gains, P_2, the pseudo-inverse of (35)."""

    ts: TSModel
    forms: list[CanonicalForm]
    G_L: np.ndarray  # (8, 6, 5)
    G_n: np.ndarray  # (8, 6, 5)
    P2: np.ndarray  # (5, 5)
    F2_pinv: np.ndarray  # (2, 5)
    y_scale: np.ndarray  # (5,)
    substeps: int
    settings: SMOSettings = field(default_factory=SMOSettings)


def required_substeps(settings: SMOSettings, P2: np.ndarray, dt: float) -> int:
    """Smallest N with (dt/N) · (ρ λ_max(P_2)/δ + |a22s|) ≤ 1 (see the module docstring)."""
    gain = settings.rho * float(np.linalg.eigvalsh(P2).max()) / settings.delta + abs(settings.a22s)
    return max(1, math.ceil(dt * gain - 1e-9))


def design_observer(p: HydroParams, settings: SMOSettings | None = None) -> ObserverDesign:
    """Check the existence conditions, compute T_i, G_L,i, G_n,i, P_2 (26) and [𝓕_2]⁺ for every vertex."""
    settings = SMOSettings() if settings is None else settings
    ts = build_ts_model(p)
    y_scale = np.array([p.omega_r_rated, p.omega_g_N, p.rated_generator_torque, 1.0, 1.0])
    Cs = ts.C / y_scale[:, None]  # per-unit outputs
    check_existence(ts.A, ts.F, Cs)
    n_y = Cs.shape[0]
    x1_poles = None if settings.x1_pole is None else np.array([settings.x1_pole])
    forms = [canonical_form(A, ts.F, Cs, x1_poles) for A in ts.A]
    A22s = settings.a22s * np.eye(n_y)
    G_L = np.stack([f.T_inv @ np.vstack([f.A12, f.A22 - A22s]) for f in forms])
    G_n = np.stack([f.T_inv @ np.vstack([np.zeros((f.A11.shape[0], n_y)), np.eye(n_y)]) for f in forms])
    # (26) P_2 𝒜ˢ_22 + 𝒜ˢ_22ᵀ P_2 = −Q_2; scipy solves a X + X aᴴ = q, so a = 𝒜ˢ_22ᵀ, q = −Q_2
    P2 = solve_continuous_lyapunov(A22s.T, -np.diag(settings.q2))
    # (35) the pseudo-inverse of the convex combination of 𝓕_2,i; T_L keeps 𝓕_2 common to all vertices
    F2 = np.mean([f.F2 for f in forms], axis=0)
    if max(np.abs(f.F2 - F2).max() for f in forms) > 1e-9:
        raise ValueError("𝓕_2,i differ between vertices; (35) would need the blended pseudo-inverse per sample")
    substeps = settings.substeps or required_substeps(settings, P2, p.dt)
    return ObserverDesign(ts, forms, G_L, G_n, P2, np.linalg.pinv(F2), y_scale, substeps, settings)


class TSSlidingModeObserver:
    """The observer (24) with reconstruction (35) and filter (37) for a batch of n turbines."""

    def __init__(self, p: HydroParams, n: int, settings: SMOSettings | None = None):
        self.p = p
        self.n = n
        self.design = design_observer(p, settings)
        self.settings = self.design.settings
        self.dt = p.dt
        self.x_hat = np.zeros((n, 6))
        self.f_filt = np.zeros((n, 2))
        self._f_stage = np.zeros((n, 2))  # the first stage of a second-order (37)
        self._y_prev: np.ndarray | None = None
        d = self.design
        self._Cs = d.ts.C / d.y_scale[:, None]
        self._tau = np.asarray(self.settings.tau_filter, dtype=float)
        self._p2_diagonal = bool(np.allclose(d.P2, np.diag(np.diag(d.P2))))

    def initialise(self, y: np.ndarray) -> None:
        """x̂(0) from the first measurement; Δp̂ from the motor's torque balance Δp = T_g/(Ṽ_M x̃_M)."""
        self.x_hat[:, OUTPUT_STATES] = y
        self.x_hat[:, 2] = y[:, 2] / (self.p.V_M * np.maximum(y[:, 4], 0.05))
        self.f_filt[:] = 0.0
        self._f_stage[:] = 0.0
        self._y_prev = y / self.design.y_scale

    def premises(self, y: np.ndarray) -> np.ndarray:
        """z = [T̂_r/ω_g, x̃_p, x̃_M] from the measurements and the pressure estimate (T̂_r = Ṽ_p x̃_p Δp̂)."""
        T_r_hat = self.p.V_p * y[:, 3] * self.x_hat[:, 2]
        return np.column_stack([T_r_hat / np.maximum(y[:, 1], 1.0), y[:, 3], y[:, 4]])

    def step(self, y: np.ndarray, u: np.ndarray) -> Reconstruction:
        """Integrate over the last sample interval with the commands ``u`` (n, 3) that were applied during it
        and the measurements moving linearly from the previous sample to ``y`` (n, 5)."""
        if self._y_prev is None:
            self.initialise(y)
        d, s = self.design, self.settings
        y_s = y / d.y_scale
        y0, dy = self._y_prev, y_s - self._y_prev
        h_w = memberships(self.premises(y), d.ts.bounds)  # (n, 8), held over the sample
        A = np.einsum("nk,kij->nij", h_w, d.ts.A)
        G_L = np.einsum("nk,kij->nij", h_w, d.G_L)
        G_n = np.einsum("nk,kij->nij", h_w, d.G_n)
        # (24) rearranged: dx̂/dt = (A − G_L C) x̂ + G_L y + B u + G_n v
        M = A - G_L @ self._Cs
        drive0 = np.einsum("nij,nj->ni", G_L, y0) + u @ d.ts.B.T
        drive1 = np.einsum("nij,nj->ni", G_L, dy)
        N = d.substeps
        h = self.dt / N
        x, f_filt, f_stage = self.x_hat, self.f_filt, self._f_stage
        a22s = s.a22s if s.layer_correction else 0.0
        second_order = s.filter_order == 2
        f_sum = np.zeros((self.n, 2))
        rho, delta, F2pT = s.rho, s.delta, d.F2_pinv.T
        sel, inv_scale = list(OUTPUT_STATES), 1.0 / d.y_scale
        # P_2 is diagonal for a diagonal 𝒜ˢ_22 and Q_2; then P_2 e_y is an elementwise product
        p2 = np.diag(d.P2) if self._p2_diagonal else None
        alpha = h / self._tau
        for j in range(N):
            frac = j / N
            e_y = x[:, sel] * inv_scale - (y0 + frac * dy)
            Pe = e_y * p2 if p2 is not None else e_y @ d.P2
            # (33) v = −ρ P_2 e_y / (‖P_2 e_y‖ + δ)
            v = Pe * (-rho / (np.sqrt(np.einsum("ij,ij->i", Pe, Pe)) + delta))[:, None]
            # (24): dx̂/dt = (A − G_L C) x̂ + G_L y + B u + G_n v
            dx = np.matmul(M, x[:, :, None])[:, :, 0] + np.matmul(G_n, v[:, :, None])[:, :, 0]
            dx += drive0 + frac * drive1
            # (35) f̂_a = 𝓕_2⁺ v, or (35') 𝓕_2⁺ (v + 𝒜ˢ_22 e_y);  (37) df̂_filt/dt = (f̂_a − f̂_filt)/τ, or (37')
            f_hat = (v + a22s * e_y) @ F2pT
            if second_order:
                f_stage = f_stage + alpha * (f_hat - f_stage)
                f_filt = f_filt + alpha * (f_stage - f_filt)
            else:
                f_filt = f_filt + alpha * (f_hat - f_filt)
            f_sum += f_hat
            x = x + h * dx
        self.x_hat, self.f_filt, self._f_stage, self._y_prev = x, f_filt, f_stage, y_s
        e_norm = np.linalg.norm((x @ self._Cs.T - y_s) @ d.P2, axis=1)
        return Reconstruction(
            f_hat=f_sum / N, f_filt=f_filt.copy(), x_hat=x.copy(), sliding=e_norm < delta, e_y_norm=e_norm
        )
