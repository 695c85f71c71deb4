"""From an observer's state estimate to the rotor-effective wind speed, and the estimates sent to the controller.

1. Aerodynamic torque from the rotor equation (21) of seed 000 solved for τ_r, with the observer's estimates::

       τ̂_r = J_r dΩ̂/dt + K_dt θ̂_Δ + (B_dt + B_r) ω̂_r − (B_dt/N_g) ω̂_g

   The rotor acceleration is taken from Ω̂ = ω̂_g/N_g where the observer uses a generator-speed sensor: below
   the 4.5 Hz torsion mode the shaft is rigid (the low-frequency part of θ̇_Δ = ω_r − ω_g/N_g is ~1e-4 rad/s),
   and the generator encoder is ~50× less noisy than the rotor-speed sensors once referred to the rotor side.
   Observers without one (observer 5) use Ω̂ = ω̂_r.
2. τ̂_r, ω̂_r and the pitch are low-pass filtered by the same second-order Butterworth filter (cutoff
   ``wind_cutoff_hz``), so all three carry the same delay, then
3. v̂ solves τ̂_r = ½ρπR³ C_q(ω̂_r R / v, β̂) v² (``wwcore.aero.wind_from_torque``), started from the previous
   estimate; the anemometer only provides the start value at the first tick.

The pitch is the collective reference passed through the nominal actuator model, so pitch-sensor faults do
not reach the wind estimate. The published speed estimates pass through a second-order Butterworth filter
(``speed_cutoff_hz``) that removes the torsion mode, which is unobservable once the unknown input is decoupled
in observers without a generator-speed sensor; there ω̂_g = N_g ω̂_r.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import butter, cont2discrete, lfilter_zi

from service.turbine.bank import BankDesign
from wwcore import aero
from wwcore.turbine_params import TurbineParams


class Biquad:
    """Second-order IIR filter (transposed direct form II) applied column-wise to (n, m) arrays."""

    def __init__(self, cutoff_hz: float, dt: float):
        b, a = butter(2, cutoff_hz, fs=1.0 / dt)
        self.b, self.a = b, a
        self.s1: np.ndarray | None = None
        self.s2: np.ndarray | None = None

    def start(self, x0: np.ndarray) -> None:
        """Set the state to the steady state of a constant input x0."""
        zi = lfilter_zi(self.b, self.a)
        self.s1, self.s2 = zi[0] * x0, zi[1] * x0

    def __call__(self, x: np.ndarray) -> np.ndarray:
        b, a = self.b, self.a
        y = b[0] * x + self.s1
        self.s1 = b[1] * x - a[1] * y + self.s2
        self.s2 = b[2] * x - a[2] * y
        return y


class PitchModel:
    """The nominal pitch actuator ω_n²/(s² + 2ζω_n s + ω_n²), discretised (zoh), driven by β_ref."""

    def __init__(self, p: TurbineParams, n: int):
        wn, zeta = p.pitch.omega_n, p.pitch.zeta
        A = np.array([[0.0, 1.0], [-(wn**2), -2.0 * zeta * wn]])
        B = np.array([[0.0], [wn**2]])
        Ad, Bd, *_ = cont2discrete((A, B, np.eye(2), np.zeros((2, 1))), p.dt, method="zoh")
        self.Ad, self.Bd = Ad, Bd.ravel()
        self.x = np.zeros((n, 2))

    def start(self, beta: np.ndarray) -> None:
        self.x[:, 0], self.x[:, 1] = beta, 0.0

    def step(self, beta_ref_prev: np.ndarray) -> np.ndarray:
        self.x = self.x @ self.Ad.T + beta_ref_prev[:, None] * self.Bd
        return self.x[:, 0]


class WindRecovery:
    """Torque, wind and filtered speeds for every observer of the bank, every tick (columns = observers)."""

    def __init__(self, p: TurbineParams, bank: BankDesign, n: int, wind_cutoff_hz: float, speed_cutoff_hz: float):
        self.p = p
        self.n = n
        n_obs = len(bank.names)
        width = bank.F_blk.shape[0]
        self.now_map = np.zeros((width, n_obs))  # τ̂_raw[n] = x̂[n] @ now_map + x̂[n−1] @ prev_map
        self.prev_map = np.zeros((width, n_obs))
        self.omega_r_map = np.zeros((width, n_obs))
        self.omega_g_map = np.zeros((width, n_obs))
        for j, o in enumerate(bank.observers):
            i0 = bank.offsets[j]
            uses_generator = any(s.startswith("omega_g") for s in o.sensors)
            accel_col, accel_gain = (i0 + 1, p.J_r / (p.N_g * p.dt)) if uses_generator else (i0, p.J_r / p.dt)
            self.now_map[accel_col, j] += accel_gain
            self.prev_map[accel_col, j] -= accel_gain
            self.now_map[i0 + 2, j] += p.K_dt
            self.now_map[i0 + 0, j] += p.B_dt + p.B_r
            self.now_map[i0 + 1, j] -= p.B_dt / p.N_g
            self.omega_r_map[i0, j] = 1.0
            if uses_generator:
                self.omega_g_map[i0 + 1, j] = 1.0
            else:
                self.omega_g_map[i0, j] = p.N_g
        self.torque_filter = Biquad(wind_cutoff_hz, p.dt)  # columns: τ (n_obs), ω_r (n_obs), β (1)
        self.speed_filter = Biquad(speed_cutoff_hz, p.dt)  # columns: ω_r (n_obs), ω_g (n_obs)
        self.pitch = PitchModel(p, n)
        self.n_obs = n_obs
        self._x_prev: np.ndarray | None = None
        self.torque = np.zeros((n, n_obs))
        self.omega_r = np.zeros((n, n_obs))
        self.omega_g = np.zeros((n, n_obs))
        self.pitch_filtered = np.zeros(n)
        self._filtered_torque = np.zeros((n, n_obs))
        self._filtered_omega_r = np.zeros((n, n_obs))

    def start(self, x_hat: np.ndarray, beta0: np.ndarray, tau_aero0: np.ndarray) -> None:
        self.pitch.start(beta0)
        omega_r = x_hat @ self.omega_r_map
        torque_in = np.hstack([np.repeat(tau_aero0[:, None], self.n_obs, axis=1), omega_r, beta0[:, None]])
        self.torque_filter.start(torque_in)
        self.speed_filter.start(np.hstack([omega_r, x_hat @ self.omega_g_map]))
        self._x_prev = x_hat

    def step(self, x_hat: np.ndarray, beta_ref_prev: np.ndarray) -> None:
        """Update torque, speed and pitch estimates of every observer from the bank's x̂[n]."""
        raw_torque = x_hat @ self.now_map + self._x_prev @ self.prev_map
        raw_omega_r = x_hat @ self.omega_r_map
        beta = self.pitch.step(beta_ref_prev)
        filtered = self.torque_filter(np.hstack([raw_torque, raw_omega_r, beta[:, None]]))
        m = self.n_obs
        self._filtered_torque = filtered[:, :m]
        self._filtered_omega_r = filtered[:, m : 2 * m]
        self.pitch_filtered = filtered[:, 2 * m]
        speeds = self.speed_filter(np.hstack([raw_omega_r, x_hat @ self.omega_g_map]))
        self.omega_r, self.omega_g = speeds[:, :m], speeds[:, m:]
        self._x_prev = x_hat

    def wind(self, columns: np.ndarray, v_guess: np.ndarray) -> np.ndarray:
        """Wind speed of observer ``columns[i]`` (shape (m, n)) for every row: (m, n) m/s, one inversion call."""
        rows = np.broadcast_to(np.arange(self.n), columns.shape)
        return aero.wind_from_torque(
            self._filtered_torque[rows, columns],
            self._filtered_omega_r[rows, columns],
            np.broadcast_to(self.pitch_filtered, columns.shape),
            v_guess,
            self.p,
            iterations=3,  # warm-started from the previous estimate, 10 Hz apart
        )
