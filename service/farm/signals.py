r"""Signal processing shared by the farm detectors and the dispatch: the 3P lock-in and the met-mast processing.

**3P lock-in amplitude.** The blade-passing (3P) content of a signal x at the rotor's own frequency: the phase
φ_k = φ_{k−1} + 3 ω̂_r Δt follows the rotor (ω̂_r = ω̄_g/N_g, the generator encoders being the precise speed
sensors), x is freed of its slow mean (first-order high-pass, ``hp_s``), demodulated and low-passed (first order,
time constant τ, a = e^{−Δt/τ}):

.. math::  I_k = \mathrm{LP}_τ\bigl(\tilde x_k \cos φ_k\bigr),\quad Q_k = \mathrm{LP}_τ\bigl(\tilde x_k \sin φ_k\bigr),
           \qquad A_k = 2\sqrt{I_k^2 + Q_k^2}

A sinusoid of amplitude a at 3P gives A → a. For white x of variance σ², Z = I + jQ = (1−a) Σ_m a^m x̃_{k−m}
e^{jφ_{k−m}} is a zero-mean Gaussian with E|Z|² = σ² V_k and E[Z²] = σ² W_k,

.. math::  V_k = a^2 V_{k-1} + (1-a)^2,\qquad W_k = a^2 W_{k-1} + (1-a)^2 e^{2jφ_k}

(V → (1−a)/(1+a) = 2s²/σ²). W is the demodulation's image at 2·3P that one first-order low-pass does not remove:
in steady rotation |W|/V = κ = (1−a²)/|1 − a² e^{2j·3ω_rΔt}|, 0.13 at rated speed (ω_r = 1.7 rad/s) and 0.26 at
the half speed of a derated turbine (τ = 1.5 s). I and Q then have variances σ²(V ± Re W)/2 and covariance
σ² Im W/2: they are not independent with equal variances, A/(2s) is not Rayleigh but Hoyt distributed, and its
tail is heavier: at the farm detector's per-sample probability 10⁻⁷ the Rayleigh threshold is exceeded 2.5× (rated
speed) to 6.5× (half speed) as often as designed.

**Whitened amplitude.** With ρ_k = W_k/V_k, the quadratic form of Z in the inverse of its covariance gives

.. math::  Ã_k = 2\sqrt{\frac{|Z_k|^2 - \mathrm{Re}(\bar ρ_k Z_k^2)}{1 - |ρ_k|^2}},
           \qquad Ã^2/(4 s^2) = [I\ Q]\, C_k^{-1} [I\ Q]^T \sim χ^2_2

exactly for Gaussian white x (any rotor-speed history), so Ã/(2s) is Rayleigh: P(Ã > h) = exp(−h²/(8s²))
(``rayleigh_threshold``); Ã = A where ρ = 0. A 3P tone of amplitude a puts its own image into Z as well; the
quadratic form removes most of it with the noise's: at half speed A swings between 0.85 a and 1.14 a at 2·3P, Ã
between 0.98 a and 1.04 a, both a on average. The whitening lowers the tone's peaks as it lowers the noise's tail.

**Met mast** (seed 001 eq. (3)). v̄ = H(s) v_mast with H(s) = 1/(s + 1), discretised exactly at 10 Hz; the wind
at row j is the mast reading d_j/v̄ earlier (``MastDelays``).
"""

from __future__ import annotations

import math

import numpy as np

from wwcore.scenario.farm import FARM_DT_S

HISTORY_S = 1500.0  # s of mast readings kept for the delays d/v̄
MIN_MEAN_WIND = 1.0  # m/s, floor of v̄ in d/v̄
MAX_IMPROPERNESS = 0.9  # –, |ρ| used at most: a rotor near standstill (or the first samples) has ρ → 1, where Q
# carries almost no noise and the quadratic form would turn any leftover into evidence (κ = 0.6 at ω_r = 0.3 rad/s)


def rayleigh_threshold(s: float | np.ndarray, p: float) -> float | np.ndarray:
    """h with P(A > h) = p for the lock-in amplitude A of white noise whose I/Q have standard deviation s."""
    return 2.0 * s * np.sqrt(2.0 * math.log(1.0 / p))


def lockin_iq_std(sigma: float | np.ndarray, tau_s: float, dt: float = FARM_DT_S) -> float | np.ndarray:
    """s: standard deviation of I and Q for white input of standard deviation σ (module docstring)."""
    a = math.exp(-dt / tau_s)
    return sigma * np.sqrt((1.0 - a) / (2.0 * (1.0 + a)))


class LockIn3P:
    """3P lock-in amplitude A and whitened amplitude Ã of n signals (module docstring)."""

    def __init__(self, n: int, tau_s: float, hp_s: float = 10.0, dt: float = FARM_DT_S, fast=None):
        self.dt = dt
        self.a = math.exp(-dt / tau_s)
        self.a_hp = math.exp(-dt / hp_s)
        self.phase = np.zeros(n)
        self.mean: np.ndarray | None = None
        self.i = np.zeros(n)
        self.q = np.zeros(n)
        self.amplitude = np.zeros(n)
        self.v = 0.0  # V_k: E|Z|² per unit input variance
        self._w = np.zeros(n, dtype=complex)  # W_k: E[Z²] per unit input variance (``w``)
        self.whitened = np.zeros(n)
        # ``service.farm.fast`` or None: with it, a step after the first is one kernel (``lockin_step``, the same
        # numbers); W is then kept as its real and imaginary parts (``w`` still gives it as a complex array)
        self._fast = fast
        self._w_parts: tuple[np.ndarray, np.ndarray] | None = (np.zeros(n), np.zeros(n)) if fast is not None else None

    @property
    def w(self) -> np.ndarray:
        """W_k (n,) complex: E[Z²] per unit input variance."""
        return self._w if self._w_parts is None else self._w_parts[0] + 1j * self._w_parts[1]

    @w.setter
    def w(self, value: np.ndarray) -> None:
        if self._w_parts is None:
            self._w = value
        else:
            self._w_parts = (value.real.copy(), value.imag.copy())

    def step(self, x: np.ndarray, omega_r: np.ndarray) -> np.ndarray:
        """Take x (n,) and the rotor speed ω_r (n,) rad/s of this sample; return the amplitude A (n,) (the whitened
        Ã is left in ``whitened``)."""
        if self.mean is None:
            self.mean = x.astype(float).copy()
        elif self._fast is not None:
            return self._fast_step(x, omega_r)
        self.mean = self.a_hp * self.mean + (1.0 - self.a_hp) * x
        self.phase = np.mod(self.phase + 3.0 * omega_r * self.dt, 2.0 * math.pi)
        xt = x - self.mean
        gain = 1.0 - self.a
        self.i = self.a * self.i + gain * xt * np.cos(self.phase)
        self.q = self.a * self.q + gain * xt * np.sin(self.phase)
        self.amplitude = 2.0 * np.sqrt(self.i * self.i + self.q * self.q)
        a2 = self.a * self.a
        self.v = a2 * self.v + gain * gain
        self.w = a2 * self.w + gain * gain * np.exp(2j * self.phase)
        rho = self.w / self.v
        size = np.abs(rho)
        rho = np.where(size > MAX_IMPROPERNESS, rho * (MAX_IMPROPERNESS / np.maximum(size, 1e-300)), rho)
        z = self.i + 1j * self.q
        form = (np.abs(z) ** 2 - (np.conj(rho) * z * z).real) / (1.0 - np.abs(rho) ** 2)
        self.whitened = 2.0 * np.sqrt(np.maximum(form, 0.0))
        return self.amplitude

    def _fast_step(self, x: np.ndarray, omega_r: np.ndarray) -> np.ndarray:
        """``step``'s lines by ``service.farm.fast.lockin_step``: the state in place, A and Ã new arrays."""
        gain = 1.0 - self.a
        a2 = self.a * self.a
        self.v = a2 * self.v + gain * gain
        consts = (self.a_hp, 1.0 - self.a_hp, self.dt, self.a, gain, a2, gain * gain, self.v, MAX_IMPROPERNESS)
        state = (self.mean, self.phase, self.i, self.q, *self._w_parts)
        n = len(self.phase)
        self.amplitude, self.whitened = np.empty(n), np.empty(n)
        x = np.ascontiguousarray(x, dtype=float)
        omega_r = np.ascontiguousarray(omega_r, dtype=float)
        self._fast.lockin_step(x, omega_r, state, consts, self.amplitude, self.whitened)
        return self.amplitude


class MastDelays:
    """Eq. (3): the mean wind v̄ = H(s) v_mast and the mast reading delayed by d/v̄, for ``farms`` farms."""

    def __init__(self, farms: int, dt: float = FARM_DT_S):
        self.dt = dt
        self.size = round(HISTORY_S / dt)
        self.history = np.zeros((farms, self.size))
        self.count = 0
        self.vbar: np.ndarray | None = None
        self._a = math.exp(-dt / 1.0)  # H(s) = 1/(s + 1): time constant 1 s

    def step(self, mast: np.ndarray) -> None:
        if self.vbar is None:
            self.vbar = mast.astype(float).copy()
            self.history[:] = mast[:, None]  # before the first reading: as the first reading
        self.vbar = self._a * self.vbar + (1.0 - self._a) * mast
        self.history[:, self.count % self.size] = mast
        self.count += 1

    def delayed(self, distances_m: np.ndarray) -> np.ndarray:
        """Mast readings d/v̄ ago for each farm and distance, (farms, k), m/s; ``distances_m`` (k,) the same for every
        farm or (farms, k) each farm's own."""
        vbar = np.maximum(self.vbar, MIN_MEAN_WIND)
        d = np.atleast_2d(distances_m)
        lag = np.minimum(np.rint(d / vbar[:, None] / self.dt).astype(np.intp), self.size - 1)
        slot = (self.count - 1 - lag) % self.size
        return self.history[np.arange(len(vbar))[:, None], slot]
