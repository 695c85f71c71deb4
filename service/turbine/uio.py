"""One unknown input observer in the discrete form of seed 000, eqs. (11)–(20) (Chen & Patton 1999).

Observer (eqs. (11)–(12))::

    z[n] = F_j z[n−1] + T_j B_d u[n−1] + K_j y_j[n−1]
    x̂[n] = z[n] + H_j y_j[n]

Design (eqs. (13)–(20)), with the paper's typesetting slips corrected (each noted where it is implemented):

    H_j  = E_d (C_j E_d)⁺                               (13)  ⁺: (C_j E_d) is p×1, so the left pseudo-inverse
    A¹_j = A_d − H_j C_j A_d                             (14)  printed as A_d H_j C_j A_d
    T_j  = I − H_j C_j                                   (15)
    K¹_j[n] = A¹_j P_j[n−1] C_jᵀ (C_j P_j[n−1] C_jᵀ + R_j)⁻¹     (16)  printed without the inverse
    F_j[n]  = A¹_j − K¹_j[n] C_j                          (17)
    P_j[n]  = A¹_j P_j[n−1] A¹_jᵀ − K¹_j[n] C_j P_j[n−1] A¹_jᵀ + T_j Q T_jᵀ + H_j R_j H_jᵀ   (18)–(19) merged:
              printed as P^p = P − K¹CP(A¹)ᵀ, P = A¹P^p(A¹)ᵀ + …, which does not type-check; this is the
              Riccati recursion they abbreviate
    K_j[n]  = F_j[n] H_j + K¹_j[n]                        (20)
    P_j[0]  = 0

Existence: rank(C_j E_d) = rank(E_d) and (C_j, A¹_j) detectable. Detectable is read with a margin: a mode that
no output sees must decay faster than ``SLOWEST_ERROR_S`` (5 s, |λ| < e^(−Ts/5 s) = 0.998), because an observer
whose error lingers for tens of seconds is of no use to a supervisor that switches observers within tens of
milliseconds. Two observers of seed 000 fail:

* observer 4 (no rotor-speed sensor): C E = 0 in continuous time, and in discrete time the zero-order hold puts
  a sampling zero near −3.7 outside the unit circle, so (C_j, A¹_j) is not detectable at all;
* observer 5 (no generator-speed sensor): with the rotor-speed channel consumed by the decoupling, the
  generator side of the 4.5 Hz torsion mode is unobservable and damped only by friction (|λ| = 0.9994, a 17 s
  time constant); its estimate of ω_g would carry a resonant error of several rad/s.

Where it fails, observer 5 is a steady-state Kalman filter of the design model augmented with the unknown input
as a random-walk state (``kind == "kalman"``), and observer 4 the drive train as one rigid body
(``design_rigid``, ``kind == "rigid"``), both written in the same (F, T, K, H) form so the bank runs them like the
others.

Residual (decoupled from d): r_j[n] = y_j[n] − C_j x̂[n] = (I − C_j H_j) y_j[n] − C_j z[n]. With ε = T x − z,
ε[n+1] = F ε[n] + T ξ[n] − K η[n] and r = C ε + (I − C H) η, so its stationary covariance is closed-form:
Σ_ε = F Σ_ε Fᵀ + T Q Tᵀ + K R Kᵀ (discrete Lyapunov), S = C Σ_ε Cᵀ + (I − C H) R (I − C H)ᵀ.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_discrete_are

from service.turbine.design_model import DesignModel
from wwcore.quantiles import chi2_isf

RANK_TOL = 1e-9
SLOWEST_ERROR_S = 5.0  # an observer whose error decays slower than this counts as not detectable (see below)
CONVERGENCE_TOL = 1e-10
LAGS = 8  # residual autocovariance lags kept (windowed tests look back at most this many ticks)
MAX_TRANSIENT = 20_000


class UIOExistenceError(ValueError):
    """The UIO existence conditions fail for a sensor subset (and no fallback was allowed)."""


@dataclass(frozen=True)
class ObserverDesign:
    """Matrices of one observer of the bank. Steady-state gains plus the transient from P[0] = 0."""

    sensors: tuple[str, ...]
    kind: str  # "uio", "kalman" (augmented with the unknown input) or "rigid" (``design_rigid``)
    n_states: int  # 4 for a UIO and the rigid drive train, 5 for the augmented Kalman filter
    C: np.ndarray  # (p, n_states)
    H: np.ndarray  # (n_states, p)
    T: np.ndarray  # (n_states, n_states)
    TB: np.ndarray  # (n_states, 1) T_j B_d
    F: np.ndarray  # steady-state F_j
    K: np.ndarray  # steady-state K_j
    F_transient: np.ndarray  # (N, n, n) F_j[n] for n = 1 … N (N = 0 for the Kalman filter)
    K_transient: np.ndarray  # (N, n, p)
    residual_cov: np.ndarray  # (p, p) S_j
    state_error_cov: np.ndarray  # (n, n) Σ_x = Σ_ε + H R Hᵀ
    whitening: np.ndarray  # (rank, p): w = W r has identity covariance
    autocov: np.ndarray  # (LAGS, rank, rank): E[w[n+k] w[n]ᵀ] of the whitened residual, k = 0 … LAGS−1
    note: str = ""
    R: np.ndarray | None = None  # (p, p) measurement noise covariance of the sensors the design assumed
    Q: np.ndarray | None = None  # process noise covariance of the design (n_states × n_states)

    @property
    def rank(self) -> int:
        return self.whitening.shape[0]


def detectable(A: np.ndarray, C: np.ndarray, margin: float = 1e-9) -> bool:
    """PBH test: every eigenvalue of A with |λ| ≥ 1 − margin is observable through C."""
    n = A.shape[0]
    for lam in np.linalg.eigvals(A):
        if abs(lam) >= 1.0 - margin:
            pbh = np.vstack([lam * np.eye(n) - A, C.astype(complex)])
            if np.linalg.matrix_rank(pbh, tol=1e-8 * max(1.0, np.abs(pbh).max())) < n:
                return False
    return True


def existence_problem(model: DesignModel, sensors: tuple[str, ...]) -> str | None:
    """Why the UIO of eqs. (11)–(20) does not exist for ``sensors``; None when it does."""
    C = model.C(sensors)
    CE = C @ model.E_d
    scale = np.linalg.norm(C) * np.linalg.norm(model.E_d)
    if np.linalg.matrix_rank(CE, tol=RANK_TOL * scale) != np.linalg.matrix_rank(model.E_d):
        return "rank(C E_d) < rank(E_d)"
    H = model.E_d @ np.linalg.pinv(CE)  # any left inverse gives the same A¹ null structure
    A1 = model.A_d - H @ C @ model.A_d
    margin = -np.expm1(-model.dt / SLOWEST_ERROR_S)
    if not detectable(A1, C, margin):
        modes = _unobservable_modes(A1, C, margin)
        return f"(C, A¹) not detectable: unobservable mode(s) at z = {modes} (|z| ≥ {1 - margin:.4f})"
    return None


def _unobservable_modes(A: np.ndarray, C: np.ndarray, margin: float) -> str:
    n = A.shape[0]
    bad = []
    for lam in np.linalg.eigvals(A):
        pbh = np.vstack([lam * np.eye(n) - A, C.astype(complex)])
        if abs(lam) >= 1.0 - margin and np.linalg.matrix_rank(pbh, tol=1e-8 * max(1.0, np.abs(pbh).max())) < n:
            bad.append(f"{lam.real:.4g}{lam.imag:+.3g}j")
    return ", ".join(bad)


def weighted_left_inverse_gain(E_d: np.ndarray, C: np.ndarray, R: np.ndarray) -> np.ndarray:
    """H = E_d ((C E_d)ᵀ R⁻¹ C E_d)⁻¹ (C E_d)ᵀ R⁻¹: a left inverse of C E_d as eq. (13) needs (H C E_d = E_d).

    Eq. (13) writes (C E_d)⁻¹, which exists only for a square C E_d. Every left inverse decouples d; the
    R⁻¹-weighted one passes the least measurement noise into x̂ = z + H y (here it weighs a generator-speed
    sensor, which sees d through the shaft within one 10 ms step, against the noisier rotor-speed sensors).
    """
    CE = C @ E_d
    R_inv = np.linalg.inv(R)
    return E_d @ np.linalg.solve(CE.T @ R_inv @ CE, CE.T @ R_inv)


def _whitening(S: np.ndarray) -> np.ndarray:
    values, vectors = np.linalg.eigh(0.5 * (S + S.T))
    keep = values > 1e-9 * values.max()
    return (vectors[:, keep] / np.sqrt(values[keep])).T


def design_uio(model: DesignModel, sensors: tuple[str, ...], R: np.ndarray, Q: np.ndarray) -> ObserverDesign:
    """The UIO of eqs. (13)–(20) for one sensor subset; raises UIOExistenceError where it does not exist.

    R: (p, p) measurement noise covariance of the subset; Q: (4, 4) design process noise covariance.
    """
    problem = existence_problem(model, sensors)
    if problem is not None:
        raise UIOExistenceError(f"no UIO for sensors {sensors}: {problem}")
    C = model.C(sensors)
    n = 4
    H = weighted_left_inverse_gain(model.E_d, C, R)  # (13)
    T = np.eye(n) - H @ C  # (15)
    A1 = model.A_d - H @ C @ model.A_d  # (14)
    P = np.zeros((n, n))  # P_j[0] = 0
    process = T @ Q @ T.T + H @ R @ H.T
    F_seq, K_seq = [], []
    K_prev = None
    for _ in range(MAX_TRANSIENT):
        K1 = A1 @ P @ C.T @ np.linalg.inv(C @ P @ C.T + R)  # (16)
        F = A1 - K1 @ C  # (17)
        P = A1 @ P @ A1.T - K1 @ C @ P @ A1.T + process  # (18)–(19)
        P = 0.5 * (P + P.T)
        K = F @ H + K1  # (20)
        F_seq.append(F)
        K_seq.append(K)
        if K_prev is not None and np.abs(K - K_prev).max() <= CONVERGENCE_TOL * (1.0 + np.abs(K).max()):
            break
        K_prev = K
    else:
        raise UIOExistenceError(f"gain recursion for {sensors} did not converge in {MAX_TRANSIENT} steps")
    if np.abs(np.linalg.eigvals(F)).max() >= 1.0:
        raise UIOExistenceError(f"observer for {sensors} is unstable (spectral radius of F ≥ 1)")
    return _finish(sensors, "uio", C, H, T, T @ model.B_d, F, K, np.array(F_seq), np.array(K_seq), R, Q)


def design_augmented_kalman(
    model: DesignModel, sensors: tuple[str, ...], R: np.ndarray, Q: np.ndarray, q_unknown: float, note: str
) -> ObserverDesign:
    """Steady-state Kalman filter with the unknown input as a random-walk state, in UIO form.

    x_a = [x; d], x_a[n+1] = [[A_d, E_d], [0, 1]] x_a[n] + [B_d; 0] u[n] + w, Var(Δd) = q_unknown (N m)² per
    step. Filtered estimate x̂[n] = z[n] + L y[n] with z[n] = (I − L C) x̂[n|n−1], which is the observer form
    above with H = L, T = I − L C, F = T A_a, K = F L.
    """
    n = 5
    A = np.block([[model.A_d, model.E_d], [np.zeros((1, 4)), np.ones((1, 1))]])
    B = np.vstack([model.B_d, [[0.0]]])
    C = np.hstack([model.C(sensors), np.zeros((len(sensors), 1))])
    Qa = np.zeros((n, n))
    Qa[:4, :4] = Q
    Qa[4, 4] = q_unknown
    P = solve_discrete_are(A.T, C.T, Qa, R)  # a priori covariance
    L = P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
    T = np.eye(n) - L @ C
    F = T @ A
    K = F @ L
    empty = np.zeros((0, n, n)), np.zeros((0, n, len(sensors)))
    return _finish(sensors, "kalman", C, L, T, T @ B, F, K, *empty, R, Qa, note=note)


def design_rigid(
    model: DesignModel, sensors: tuple[str, ...], R: np.ndarray, gear_ratio: float, note: str
) -> ObserverDesign:
    """The drive train as one rigid body below its torsion mode, in the observer form (F, T, K, H).

    Every sensor of the set measures the same speed once referred to the generator side (a rotor-speed sensor
    times N_g), so x̂ = z + H y takes their inverse-variance weighted mean as ω̂_g and ω̂_g/N_g as ω̂_r; θ̂_Δ is
    not estimated (0); z carries only the converter torque, τ̂_g[n] = a τ̂_g[n−1] + (1 − a) τ_g,r[n−1] (the
    design model's exact first-order converter, a = e^(−α_gc Ts)), so F = diag(0, 0, 0, a) and K = 0. No model of
    the aerodynamic torque is involved: ``wind_recovery`` takes τ_r from the two shaft equations summed,
    τ_r = (J_r/N_g + N_g J_g/η) dω_g/dt + (N_g/η)(τ_g + B_g ω_g) + B_r ω_g/N_g, whose error is the torsion's
    own motion (4.5 Hz, removed by the 0.3 Hz wind filter). The residual (I − C H) y is the sensors' parity:
    white with covariance (I − C H) R (I − C H)ᵀ whatever the wind (rank p − 1; none for one sensor).
    """
    C = model.C(sensors)
    refer = np.where(C[:, 0] > 0, gear_ratio, 1.0)  # a rotor-speed reading times N_g is a generator speed
    inverse = 1.0 / (np.diag(R) * refer**2)
    weights = inverse / inverse.sum()
    H = np.zeros((4, len(sensors)))
    H[1] = weights * refer
    H[0] = H[1] / gear_ratio
    T = np.eye(4) - H @ C
    a = float(model.A_d[3, 3])
    F = np.diag([0.0, 0.0, 0.0, a])
    TB = np.array([[0.0], [0.0], [0.0], [1.0 - a]])
    K = np.zeros((4, len(sensors)))
    I_CH = np.eye(len(sensors)) - C @ H
    S = I_CH @ R @ I_CH.T
    W = _whitening(S) if np.abs(S).max() > 0.0 else np.zeros((0, len(sensors)))
    lags = np.zeros((LAGS, W.shape[0], W.shape[0]))
    lags[0] = np.eye(W.shape[0])
    return ObserverDesign(
        sensors=sensors,
        kind="rigid",
        n_states=4,
        C=C,
        H=H,
        T=T,
        TB=TB,
        F=F,
        K=K,
        F_transient=np.zeros((0, 4, 4)),
        K_transient=np.zeros((0, 4, len(sensors))),
        residual_cov=S,
        state_error_cov=H @ R @ H.T,
        whitening=W,
        autocov=lags,
        note=note,
        R=R,
        Q=np.zeros((4, 4)),
    )


def stationary_covariance(F: np.ndarray, W: np.ndarray, iterations: int = 64) -> np.ndarray:
    """Σ = F Σ Fᵀ + W for a stable F, by Smith's doubling Σ = Σ_k F^(2^k)-sums.

    Used instead of ``scipy.linalg.solve_discrete_lyapunov`` because the states here span twelve orders of
    magnitude (θ_Δ ~ 1e-3 rad, the Kalman filter's torque ~ 1e6 N m), which makes the Kronecker-product solve
    ill-conditioned; doubling only multiplies matrices and converges for any spectral radius below one.
    """
    sigma, power = W.copy(), F.copy()
    for _ in range(iterations):
        sigma = sigma + power @ sigma @ power.T
        power = power @ power
        if not np.any(power):
            break
    check = F @ sigma @ F.T + W - sigma
    if np.abs(check).max() > 1e-8 * np.abs(sigma).max():
        raise UIOExistenceError("observer error covariance did not converge (spectral radius of F too close to 1)")
    return 0.5 * (sigma + sigma.T)


def _finish(sensors, kind, C, H, T, TB, F, K, F_seq, K_seq, R, Q, note: str = "") -> ObserverDesign:
    sigma_eps = stationary_covariance(F, T @ Q @ T.T + K @ R @ K.T)
    I_CH = np.eye(C.shape[0]) - C @ H
    S = C @ sigma_eps @ C.T + I_CH @ R @ I_CH.T
    W = _whitening(S)
    # cov(r[n+k], r[n]) = C F^k Σ_ε Cᵀ − C F^(k−1) K R (I − C H)ᵀ for k ≥ 1 (ε[n+k] carries −K η[n] forward)
    lags = [W @ S @ W.T]
    Fk = np.eye(F.shape[0])
    for _ in range(1, LAGS):
        lag = C @ (F @ Fk) @ sigma_eps @ C.T - C @ Fk @ K @ R @ I_CH.T
        lags.append(W @ lag @ W.T)
        Fk = F @ Fk
    return ObserverDesign(
        sensors=sensors,
        kind=kind,
        n_states=C.shape[1],
        C=C,
        H=H,
        T=T,
        TB=TB,
        F=F,
        K=K,
        F_transient=F_seq,
        K_transient=K_seq,
        residual_cov=0.5 * (S + S.T),
        state_error_cov=sigma_eps + H @ R @ H.T,
        whitening=W,
        autocov=np.array(lags),
        note=note,
        R=R,
        Q=Q,
    )


def window_threshold(autocov: np.ndarray, window: int, alpha: float) -> float:
    """Upper α-quantile of Σ_{i<window} ‖w[n−i]‖² for a whitened residual with autocovariance ``autocov``.

    E = window·rank; Var = Σ_i Σ_j 2 tr(R_{|i−j|} R_{|i−j|}ᵀ) (Gaussian quadratic forms); the sum is taken as
    c·χ²_ν with c = Var/(2E), ν = 2E²/Var (Satterthwaite), which is exact for a white residual.
    """
    rank = autocov.shape[1]
    mean = window * rank
    lag_power = [2.0 * float(np.trace(autocov[k] @ autocov[k].T)) for k in range(window)]
    var = sum(lag_power[abs(i - j)] for i in range(window) for j in range(window))
    c, nu = var / (2.0 * mean), 2.0 * mean**2 / var
    return float(c * chi2_isf(alpha, nu))
