"""Dynamics of the benchmark turbine (PARAMETERS.md a.2) for a batch of n turbines, and their discretisation.

State columns of ``x`` (shape (n, N_STATES)):

====  ========  ===========================================  ======
col   symbol    meaning                                      unit
====  ========  ===========================================  ======
0     ω_r       rotor speed (low-speed shaft)                rad/s
1     ω_g       generator speed (high-speed shaft)           rad/s
2     θ_Δ       drive-train torsion angle                    rad
3     τ_g       generator/converter torque                   N m
4     ψ         rotor azimuth of blade 1                     rad
5,7,9 β_i       pitch angle of blade i (actuator output)     deg
6,8,10 β̇_i      pitch rate of blade i                        deg/s
====  ========  ===========================================  ======

Drive train (two-mass model, a.2) and converter::

    J_r ω̇_r = τ_r − K_dt θ_Δ − (B_dt + B_r) ω_r + (B_dt/N_g) ω_g
    J_g ω̇_g = η_dt K_dt/N_g θ_Δ + η_dt B_dt/N_g ω_r − (η_dt B_dt/N_g² + B_g) ω_g − τ_g
    θ̇_Δ     = ω_r − ω_g/N_g
    τ̇_g     = α_gc (τ_g,r + Δτ − τ_g),       ψ̇ = ω_r

Pitch actuator i: β̈_i = ω_n,i² (β_ref,i − β_i) − 2ζ_i ω_n,i β̇_i.
Aerodynamics per blade: τ_r,i = (ρπR³/6) C_q(λ_i, β_i + δβ_i) v_i², λ_i = ω_r R / v_i, τ_r = Σ τ_r,i; a plant
that differs from the design model scales this by s ρ/ρ_0 and moves C_p by Δλ (``plant_sim.turbine.mismatch``).

Given the aerodynamic torque, everything above is linear. The plant therefore integrates exactly: the linear
part is discretised with a zero-order hold on its inputs (τ_r, τ_g,r + Δτ, β_ref,i) by the matrix exponential,
so the 4.5 Hz torsion mode is neither damped nor excited numerically, and τ_r is evaluated once per tick at the
tick's state and wind and held over the step, like the controller outputs and the wind sample.
"""

from __future__ import annotations

import numpy as np

from wwcore import aero
from wwcore.lti import zoh
from wwcore.turbine_params import TurbineParams

OMEGA_R, OMEGA_G, THETA, TAU_G, AZIMUTH = 0, 1, 2, 3, 4
PITCH = np.array([5, 7, 9])
PITCH_RATE = PITCH + 1
N_MECH = 5  # ω_r, ω_g, θ_Δ, τ_g, ψ
N_STATES = 11


def mechanical_matrices(
    p: TurbineParams, eta: np.ndarray, stiffness: np.ndarray, damping: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Continuous A (n, 5, 5) and B (n, 5, 2) of [ω_r, ω_g, θ_Δ, τ_g, ψ] with inputs [τ_r, τ_g,r + Δτ]."""
    n = len(eta)
    K, Bd, N = p.K_dt * stiffness, p.B_dt * damping, p.N_g
    A = np.zeros((n, N_MECH, N_MECH))
    A[:, 0, 0] = -(Bd + p.B_r) / p.J_r
    A[:, 0, 1] = Bd / (N * p.J_r)
    A[:, 0, 2] = -K / p.J_r
    A[:, 1, 0] = eta * Bd / (N * p.J_g)
    A[:, 1, 1] = -(eta * Bd / N**2 + p.B_g) / p.J_g
    A[:, 1, 2] = eta * K / (N * p.J_g)
    A[:, 1, 3] = -1.0 / p.J_g
    A[:, 2, 0] = 1.0
    A[:, 2, 1] = -1.0 / N
    A[:, 3, 3] = -p.alpha_gc
    A[:, 4, 0] = 1.0
    B = np.zeros((n, N_MECH, 2))
    B[:, 0, 0] = 1.0 / p.J_r
    B[:, 3, 1] = p.alpha_gc
    return A, B


def pitch_matrices(a0: np.ndarray, a1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Continuous A (…, 2, 2), B (…, 2, 1) of [β, β̇] with input β_ref; a0 = ω_n², a1 = 2ζω_n."""
    A = np.zeros((*a0.shape, 2, 2))
    A[..., 0, 1] = 1.0
    A[..., 1, 0] = -a0
    A[..., 1, 1] = -a1
    B = np.zeros((*a0.shape, 2, 1))
    B[..., 1, 0] = a0
    return A, B


def plant_torque_coefficient(tsr: np.ndarray, pitch_deg: np.ndarray, tsr_shift: np.ndarray) -> np.ndarray:
    """C_p(λ − Δλ, β)/λ (–): a plant's C_q before its scale s (``plant_sim.turbine.mismatch``), held below
    λ_e = 1 + |Δλ|.

    ``tsr`` (–) and ``pitch_deg`` (deg) broadcast with ``tsr_shift`` (–). With Δλ = 0 this is C_q(λ, β).
    """
    lam = np.maximum(tsr, 1.0 + np.abs(tsr_shift))
    return aero.power_coefficient(lam - tsr_shift, pitch_deg) / lam


def plant_power_coefficient(
    tsr: np.ndarray, pitch_deg: np.ndarray, cp_scale: np.ndarray, tsr_shift: np.ndarray
) -> np.ndarray:
    """C_p,plant(λ, β) = s C_p(λ − Δλ, β) (–) for λ ≥ 1 + |Δλ| (``plant_sim.turbine.mismatch``)."""
    return cp_scale * aero.power_coefficient(tsr - tsr_shift, pitch_deg)


def torsion_mode(p: TurbineParams, stiffness_factor: float, damping_factor: float) -> tuple[float, float]:
    """(damping ratio ζ (–), damped frequency (Hz)) of the drive train's torsion mode: the oscillatory eigenvalue
    pair of the [ω_r, ω_g, θ_Δ] block of ``mechanical_matrices`` with K_dt and B_dt scaled by the factors."""
    a, _ = mechanical_matrices(p, np.array([p.eta_dt]), np.array([stiffness_factor]), np.array([damping_factor]))
    poles = np.linalg.eigvals(a[0, :3, :3])
    mode = poles[np.argmax(np.abs(poles.imag))]
    return float(-mode.real / abs(mode)), float(abs(mode.imag) / (2.0 * np.pi))


class TurbineDynamics:
    """Aerodynamic torque and the continuous-time derivative (the latter for tests and reference)."""

    def __init__(self, params: TurbineParams):
        self.p = params
        self.blade_gain = params.rho * np.pi * params.radius**3 / 6.0  # ρπR³/6, per blade

    def aero_torque(
        self,
        omega_r: np.ndarray,
        pitch: np.ndarray,
        wind: np.ndarray,
        factor: np.ndarray,
        tsr_shift: np.ndarray | None = None,
    ) -> np.ndarray:
        """τ_r = Σ_i (ρπR³/6) C_q(λ_i, β_i) v_i² in N m; pitch (n,3) in deg, wind (n,3) in m/s."""
        return self.blade_torques(omega_r, pitch, wind, factor, tsr_shift).sum(axis=1)

    def blade_torques(
        self,
        omega_r: np.ndarray,
        pitch: np.ndarray,
        wind: np.ndarray,
        factor: np.ndarray,
        tsr_shift: np.ndarray | None = None,
    ) -> np.ndarray:
        """τ_r,i = factor (ρπR³/6) C_q(λ_i, β_i) v_i² of each blade, (n, 3) in N m (``aero_torque`` is their sum).

        ``factor`` (n,) multiplies the gain (the plant's s ρ/ρ_0); ``tsr_shift`` (n,) Δλ, when given, evaluates the
        plant's surface C_p(λ − Δλ, β)/λ instead of the design's C_q (``plant_sim.turbine.mismatch``).
        """
        tsr = omega_r[:, None] * (self.p.radius / wind)
        if tsr_shift is None:
            cq = aero.torque_coefficient(tsr, pitch)
        else:
            cq = plant_torque_coefficient(tsr, pitch, np.asarray(tsr_shift, dtype=float)[:, None])
        return (self.blade_gain * np.asarray(factor, dtype=float))[..., None] * (cq * (wind * wind))

    def derivative(self, x, tau_g_ref, pitch_ref, wind, faults) -> np.ndarray:
        """ẋ for the continuous model with the aerodynamic torque re-evaluated at x (reference implementation)."""
        p = self.p
        out = np.zeros_like(x)
        omega_r, omega_g, theta, tau_g = x[:, OMEGA_R], x[:, OMEGA_G], x[:, THETA], x[:, TAU_G]
        shift = faults.healthy.tsr_shift if faults.healthy.shifted else None
        tau_r = self.aero_torque(omega_r, x[:, PITCH] + faults.pitch_offset, wind, faults.aero_factor, shift)
        k_dt, b_dt = p.K_dt * faults.stiffness_factor, p.B_dt * faults.damping_factor
        shaft = k_dt * theta + b_dt * (omega_r - omega_g / p.N_g)
        out[:, OMEGA_R] = (tau_r - shaft - p.B_r * omega_r) / p.J_r
        out[:, OMEGA_G] = (faults.eta_dt * shaft / p.N_g - p.B_g * omega_g - tau_g) / p.J_g
        out[:, THETA] = omega_r - omega_g / p.N_g
        out[:, TAU_G] = p.alpha_gc * (tau_g_ref + faults.torque_offset - tau_g)
        out[:, AZIMUTH] = omega_r
        out[:, PITCH] = x[:, PITCH_RATE]
        out[:, PITCH_RATE] = faults.pitch_a0 * (pitch_ref - x[:, PITCH]) - faults.pitch_a1 * x[:, PITCH_RATE]
        return out


def _distinct(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(distinct rows of ``keys``, index of each row's distinct key): keys[i] == distinct[which[i]]."""
    distinct, which = np.unique(keys, axis=0, return_inverse=True)
    return distinct, which.ravel()


class DiscreteStep:
    """x[k+1] = Φ x[k] + Γ u[k] per row, rebuilt for rows whose parameters change (faults).

    Inputs u held over the step: τ_r (rotor side, N m), τ_g,cmd (converter command, N m), β_ref,i (deg) and,
    optionally, an external torque τ_ext on the generator side (N m, high-speed shaft, accelerating), which the
    farm's drive-train fault uses for its internal torque pair (``plant_sim.turbine.plant``).
    """

    def __init__(self, params: TurbineParams, n: int):
        self.p = params
        self.n = n
        self.phi_m = np.zeros((n, N_MECH, N_MECH))
        self.gamma_m = np.zeros((n, N_MECH, 2))
        self.gamma_ext = np.zeros((n, N_MECH))  # response to τ_ext held over the step
        self.phi_p = np.zeros((n, 3, 2, 2))
        self.gamma_p = np.zeros((n, 3, 2))
        self._key_m: np.ndarray | None = None
        self._key_p: np.ndarray | None = None
        self.shared: np.ndarray | None = None  # (16, 11) when every row is alike: x' = inputs @ shared
        self.inputs = np.empty((n, N_STATES + 5))  # [x, τ_r, τ_g,cmd, β_ref,1..3], the shared path's input

    def update(self, faults) -> None:
        """Recompute Φ, Γ for the rows whose drive-train or pitch parameters differ from last time."""
        key_m = np.column_stack([faults.eta_dt, faults.stiffness_factor, faults.damping_factor])
        rows = np.arange(self.n) if self._key_m is None else np.flatnonzero((key_m != self._key_m).any(axis=1))
        if len(rows):
            # The matrix exponential dominates (about 10 ms per matrix), and rows mostly share parameters: each
            # distinct key is discretised once. ``expm`` treats every matrix of a batch on its own, so this is
            # bit for bit what discretising every row gives.
            keys, which = _distinct(key_m[rows])
            A, B = mechanical_matrices(self.p, keys[:, 0], keys[:, 1], keys[:, 2])
            b_ext = np.zeros((len(keys), N_MECH, 1))
            b_ext[:, OMEGA_G, 0] = 1.0 / self.p.J_g  # J_g ω̇_g = … + τ_ext
            phi, gamma = zoh(A, np.concatenate([B, b_ext], axis=2), self.p.dt)
            phi, gamma = phi[which], gamma[which]
            self.phi_m[rows], self.gamma_m[rows], self.gamma_ext[rows] = phi, gamma[..., :2], gamma[..., 2]
        self._key_m = key_m
        key_p = np.concatenate([faults.pitch_a0, faults.pitch_a1], axis=1)
        rows = np.arange(self.n) if self._key_p is None else np.flatnonzero((key_p != self._key_p).any(axis=1))
        if len(rows):
            # one (a0, a1) pair per row and blade; distinct pairs discretised once, as above
            pairs = np.stack([faults.pitch_a0[rows], faults.pitch_a1[rows]], axis=-1).reshape(-1, 2)
            keys, which = _distinct(pairs)
            A, B = pitch_matrices(keys[:, 0], keys[:, 1])
            phi, gamma = zoh(A, B, self.p.dt)
            self.phi_p[rows] = phi[which].reshape(len(rows), 3, 2, 2)
            self.gamma_p[rows] = gamma[which, :, 0].reshape(len(rows), 3, 2)
        self._key_p = key_p
        alike = (key_m == key_m[0]).all() and (key_p == key_p[0]).all()
        if alike:
            # One (16, 11) matrix for the whole batch: [x, τ_r, τ_g,cmd, β_ref,1..3] → x'. The drive train and
            # converter block, and per blade [β, β̇, β_ref] → [β, β̇]' (block diagonal), in one matrix product.
            m = np.zeros((N_STATES + 5, N_STATES))
            m[:N_MECH, :N_MECH] = self.phi_m[0].T
            m[N_STATES : N_STATES + 2, :N_MECH] = self.gamma_m[0].T
            for b in range(3):
                cols = slice(N_MECH + 2 * b, N_MECH + 2 * b + 2)
                m[cols, cols] = self.phi_p[0, b].T
                m[N_STATES + 2 + b, cols] = self.gamma_p[0, b]
            self.shared = m
        else:
            self.shared = None

    def step(
        self,
        x: np.ndarray,
        tau_r: np.ndarray,
        tau_g_cmd: np.ndarray,
        pitch_ref: np.ndarray,
        tau_ext: np.ndarray | None = None,
    ) -> np.ndarray:
        if self.shared is not None:
            z = self.inputs
            z[:, :N_STATES] = x
            z[:, N_STATES] = tau_r
            z[:, N_STATES + 1] = tau_g_cmd
            z[:, N_STATES + 2 :] = pitch_ref
            out = z @ self.shared
        else:
            out = np.empty_like(x)
            mech = x[:, :N_MECH]
            out[:, :N_MECH] = np.einsum("nij,nj->ni", self.phi_m, mech) + (
                self.gamma_m[:, :, 0] * tau_r[:, None] + self.gamma_m[:, :, 1] * tau_g_cmd[:, None]
            )
            pitch = x[:, N_MECH:].reshape(self.n, 3, 2)
            new_pitch = np.einsum("nbij,nbj->nbi", self.phi_p, pitch) + self.gamma_p * pitch_ref[:, :, None]
            out[:, N_MECH:] = new_pitch.reshape(self.n, 6)
        if tau_ext is not None:
            out[:, :N_MECH] += self.gamma_ext * tau_ext[:, None]
        return out
