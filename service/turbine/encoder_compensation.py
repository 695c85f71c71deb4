"""Fault estimation and compensation of a flagged generator-speed encoder, for the wind estimate only.

While one generator-speed encoder is flagged and the other trusted, the wind estimate runs on the observer of the
healthy one (4-g1 or 4-g2), whose torque carries one encoder's noise instead of two encoders' mean (the one-encoder
floor, ``docs/turbine.md``). The flagged encoder still reads the shaft, only wrongly: for an offset, a drift or a
small gain, its readings less an estimate of the fault are a second, independent reading of ω_g at the frequencies
the wind's torque filter passes. This module estimates the fault against the healthy encoder; the estimator
(``UIOBankEstimator._compensate``) feeds the corrected pair to the flagged encoder's own one-encoder observer, which
the estimate does not use while the flag lasts, and inverts the wind from its torque once that is the quieter one.
The detector never sees it: it judges the raw readings, and the speeds sent to the controller are unchanged.

The fault model, on the difference d = y_f − y_h of the faulty and the healthy reading (rad/s; t the time since the
estimate started, in units of the forgetting time T)::

    d[n] = b + s t[n] + w[n],      w = e_f − e_h white, variance σ_f² + σ_h²                          (1)

an offset b and a drift s (rad/s per T), estimated by recursive least squares with forgetting factor
λ = 1 − Δt/T (weights λ^age). A gain g is followed as the slowly moving offset (g − 1) ω(t): the forgetting's window
T tracks ω's trend, and what it misses, (g − 1) × ω's motion faster than 1/T, moves the torque by (g − 1) of its
own share. A regression on the healthy reading (d on y_h) would estimate g itself, but y_h's own noise biases it by
−σ_h²/var(ω) (errors in variables): −1 % where ω moves by ±0.5 rad/s, the size of the gains themselves.

The corrected reading is ỹ_f[n] = y_f[n] − d̂[n], d̂ the prediction of (1) from the ticks before n. Its error is
e_f[n] less the prediction's error, which lies below the estimate's bandwidth: there ỹ_f repeats y_h, above it ỹ_f
is independent of y_h. The torque's noise is a differenced white noise through the wind filter, concentrated near
its cutoff f_c, so a T well above 1/(2π f_c) leaves the second encoder's contribution almost whole: with
T = ``FORGET_S`` = 10 s (0.016 Hz against 0.252 Hz) the corrected pair's stationary torque noise is 0.518 × the
healthy encoder's alone, against 0.5 for a healthy pair (``torque_noise_variances``). The linear drift in (1) keeps a
steady drift's prediction unbiased (an offset alone would lag it by s T, which the residual test below would
reject); T then bounds how fast the drift itself may change.

When the corrected pair is better than leaving the encoder out (``ticks_until_better``): both torques go through
the same filter (the one-encoder cutoff), so their lags are equal and the better one is the less noisy. Both are
linear in the encoders' white noise, so the variances are exact sums of squared coefficients: n ticks after the
estimate started, the corrected pair's against the healthy encoder's alone. Early on the prediction moves with each
tick's noise (it rests on n ticks), and that motion is torque noise; from ``min_ticks`` ticks (235 on the benchmark's
encoders, 2.35 s) the corrected pair is quieter for good.

The residual test: over each block of ticks between two inversions of the wind (``wind_every``), the innovations
r[n] = d[n] − d̂[n] of (1) are summed; under (1) the sum is normal with variance Σ (σ_f² + σ_h²)(1 + φᵀPφ). A sum
beyond its two-sided ``ALPHA`` quantile means the fault no longer fits (its size or kind changed): the estimate
restarts, and the corrected reading is left out until it has ``min_ticks`` ticks again. A flagged reading that
repeats exactly (a frozen sensor, a fixed value) carries nothing of the shaft and is never corrected while its flag
lasts.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.signal import lfilter
from scipy.stats import norm

from wwcore.lti import butter2_lowpass

FORGET_S = 10.0  # T of (1): the fault estimate's forgetting time, s
ALPHA = 1e-3  # the residual test's false-restart probability per block
N_PARAMS = 2  # b, s
DIFFUSE = 1e6  # the recursive least squares' starting P (in units of the innovations' variance): no prior
NOISE_BLOCK = 256  # noise samples whose coefficients ``torque_noise_variances`` holds at once (memory, not numbers)


@lru_cache(maxsize=8)
def torque_noise_variances(
    c_now: float,
    c_prev: float,
    weight_faulty: float,
    sigma_healthy: float,
    sigma_faulty: float,
    cutoff_pair_hz: float,
    cutoff_one_hz: float,
    dt: float,
    forget_s: float = FORGET_S,
) -> tuple[np.ndarray, float]:
    """The noise variance (N m)² of the corrected pair's filtered torque n = 0 … 2T/Δt − 1 ticks after the fault
    estimate started (inf for the first ``N_PARAMS``), and the healthy encoder's one-encoder observer's.

    Raw torque of a rigid observer: c_now ω̂[n] + c_prev ω̂[n−1] (the map's coefficients of ω̂_g), filtered by the
    second-order Butterworth at the column's cutoff (``cutoff_pair_hz``, ``cutoff_one_hz``). The corrected pair's
    ω̂[n] = (1 − w) y_h[n] + w ỹ_f[n] (``weight_faulty`` w: observer 4's inverse-variance weight of the flagged
    encoder), ỹ_f[n] = y_f[n] − a_nᵀ d[0..n−1] with a_n the weights of (1)'s prediction at n (``EncoderFaultEstimate
    .step``'s recursion from its diffuse start); before the start the column ran on the healthy encoder alone (the
    take-over, ``WindRecovery.transfer``). Noise variance at n: σ_h² ‖g_h,n‖² + σ_f² ‖g_f,n‖², g the coefficients of
    each encoder's noise sequence in the filtered torque. The one-encoder observer's: σ_h² Σ_k h_k², h the impulse
    response of its filter on c_now + c_prev z⁻¹."""
    forget = round(forget_s / dt)
    lam = 1.0 - 1.0 / forget
    horizon = 2 * forget
    history = int(np.ceil(10.0 / (2.0 * np.pi * min(cutoff_pair_hz, cutoff_one_hz) * dt)))
    # row n: the prediction's weights on d[0..n−1], by ``EncoderFaultEstimate.step``'s recursion on θ̂'s weights
    predict = np.zeros((horizon, horizon))
    theta = np.zeros((N_PARAMS, horizon))  # θ̂ = theta @ d
    P = DIFFUSE * np.eye(N_PARAMS)
    for n in range(horizon):
        phi = np.array([1.0, n / forget])
        if n >= N_PARAMS:
            predict[n, :n] = phi @ theta[:, :n]
        Pphi = P @ phi
        gain = Pphi / (lam + phi @ Pphi)
        theta[:, : n + 1] -= np.outer(gain, phi @ theta[:, : n + 1])
        theta[:, n] += gain
        P = (P - np.outer(gain, Pphi)) / lam
    size = history + horizon
    b, a = butter2_lowpass(cutoff_pair_hz, dt)
    variance = np.zeros(horizon)
    # ω̂'s coefficients (rows: ticks) on each noise sample (columns): e_h at every tick, e_f from the start; the
    # columns are independent noise samples, so their squared filtered coefficients are summed a block at a time
    for first in range(0, size + horizon, NOISE_BLOCK):
        columns = np.arange(first, min(first + NOISE_BLOCK, size + horizon))
        coefficients = np.zeros((size, len(columns)))
        healthy, faulty = columns < size, columns >= size
        before = healthy & (columns < history)
        coefficients[columns[before], np.flatnonzero(before)] = 1.0
        after = healthy & ~before
        k = columns[after] - history
        coefficients[history:, after] = weight_faulty * predict[:, k]  # −w a_nᵀ(e_f − e_h)
        coefficients[columns[after], np.flatnonzero(after)] = 1.0 - weight_faulty
        k = columns[faulty] - size
        coefficients[history:, faulty] = -weight_faulty * predict[:, k]
        coefficients[history + k, np.flatnonzero(faulty)] = weight_faulty
        sigma = np.where(healthy, sigma_healthy, sigma_faulty)
        raw = c_now * coefficients
        raw[1:] += c_prev * coefficients[:-1]
        filtered = lfilter(b, a, raw, axis=0)[history:]
        variance += np.sum((sigma * filtered) ** 2, axis=1)
    variance[:N_PARAMS] = np.inf
    b1, a1 = butter2_lowpass(cutoff_one_hz, dt)
    impulse = np.zeros(history + horizon)
    impulse[0], impulse[1] = c_now, c_prev
    one = sigma_healthy**2 * float(np.sum(lfilter(b1, a1, impulse) ** 2))
    variance.setflags(write=False)
    return variance, one


def ticks_until_better(*args, **kwargs) -> int:
    """The ticks since the fault estimate started from which the corrected pair's filtered torque is less noisy than
    the healthy encoder's alone at every later tick (``torque_noise_variances``' arguments); −1: not within 2 T."""
    variance, one = torque_noise_variances(*args, **kwargs)
    worse = np.flatnonzero(variance > one)
    if len(worse) and worse[-1] == len(variance) - 1:
        return -1
    return int(worse[-1] + 1) if len(worse) else 0


class EncoderFaultEstimate:
    """Per row, the fault (1) of one flagged generator-speed encoder against the other, by recursive least squares
    with forgetting, its one-step prediction d̂[n], and the residual test (module docstring).

    ``step`` is called every tick with the rows to estimate on and which encoder is flagged there; a row whose
    flagged encoder changed, or that was not estimated at the last tick, starts afresh."""

    def __init__(self, n: int, dt: float, sigma_d: float, min_ticks: int, forget_s: float = FORGET_S):
        self.n = n
        self.dt = dt
        self.sigma_d = sigma_d  # σ of w in (1), rad/s
        self.min_ticks = min_ticks  # −1: never use the corrected reading
        self.forget_ticks = round(forget_s / dt)
        self.lam = 1.0 - 1.0 / self.forget_ticks
        self.level = float(norm.isf(ALPHA / 2.0))
        self.encoder = np.full(n, -1, dtype=np.int64)  # the encoder estimated (0 or 1; −1: none)
        self.ticks = np.zeros(n, dtype=np.int64)  # readings taken since the start
        self.theta = np.zeros((n, N_PARAMS))  # b̂, ŝ of (1)
        self.P = np.zeros((n, N_PARAMS, N_PARAMS))
        self.frozen = np.zeros(n, dtype=bool)  # the flagged reading repeated since the start
        self.prediction = np.zeros(n)  # d̂[n] of this tick (from the ticks before it)
        self.ready = np.zeros(n, dtype=bool)  # ``step``'s rows whose corrected reading makes the quieter torque
        self._last = np.full(n, np.nan)  # the flagged reading of the last tick
        self._sum = np.zeros(n)  # the block's innovations, and their variance (units of σ_d²)
        self._variance = np.zeros(n)
        self.active = False  # whether any row is estimated

    def restart(self, rows: np.ndarray) -> None:
        """The estimate of ``rows`` starts again at their next reading."""
        self.ticks[rows] = 0
        self.theta[rows] = 0.0
        self.P[rows] = DIFFUSE * np.eye(N_PARAMS)
        self._sum[rows] = 0.0
        self._variance[rows] = 0.0

    def stop(self) -> None:
        """No row is estimated."""
        if self.active:
            self.encoder[:] = -1
            self.frozen[:] = False
            self.active = False

    def step(self, encoder: np.ndarray, faulty: np.ndarray, healthy: np.ndarray) -> np.ndarray:
        """Take this tick's readings: ``encoder`` (n,) the flagged encoder of each row (−1: none to estimate),
        ``faulty`` and ``healthy`` (n,) its reading and the other encoder's (rad/s). Returns the rows with a
        corrected reading ỹ_f = y_f − ``prediction`` this tick (bool, n): a prediction from ``N_PARAMS`` ticks or
        more, the reading never frozen since the start. ``ready`` (n,): those of them with ``min_ticks`` ticks or
        more (``ticks_until_better``), where the corrected reading makes the quieter torque. The prediction is made
        before the update."""
        new = (encoder >= 0) & (encoder != self.encoder)
        self.encoder = encoder.copy()
        self.frozen[new | (encoder < 0)] = False
        self.active = bool((encoder >= 0).any())
        if new.any():
            self.restart(np.flatnonzero(new))
        rows = np.flatnonzero(encoder >= 0)
        use = np.zeros(self.n, dtype=bool)
        self.ready = np.zeros(self.n, dtype=bool)
        if not len(rows):
            return use
        self.frozen[rows] |= faulty[rows] == self._last[rows]
        self._last = faulty.copy()
        phi = np.column_stack([np.ones(len(rows)), self.ticks[rows] / self.forget_ticks])  # (rows, 2)
        theta, P = self.theta[rows], self.P[rows]
        prediction = np.einsum("ij,ij->i", phi, theta)
        innovation = faulty[rows] - healthy[rows] - prediction
        Pphi = np.einsum("ijk,ik->ij", P, phi)
        spread = np.einsum("ij,ij->i", phi, Pphi)
        informed = self.ticks[rows] >= N_PARAMS  # the first N_PARAMS predictions rest on the diffuse start
        self._sum[rows] += np.where(informed, innovation, 0.0)
        self._variance[rows] += np.where(informed, 1.0 + spread, 0.0)
        gain = Pphi / (self.lam + spread)[:, None]
        self.theta[rows] = theta + gain * innovation[:, None]
        self.P[rows] = (P - gain[:, :, None] * Pphi[:, None, :]) / self.lam
        self.prediction[rows] = np.where(informed, prediction, 0.0)
        use[rows] = informed & ~self.frozen[rows]
        self.ready[rows] = use[rows] & (self.ticks[rows] >= self.min_ticks) & (self.min_ticks >= 0)
        self.ticks[rows] += 1
        return use

    def test(self) -> np.ndarray:
        """The residual test over the block since the last call (bool, n: the rows whose fault no longer fits
        (1)); those restart. Every row's block starts again."""
        misfit = np.zeros(self.n, dtype=bool)
        if not self.active:
            return misfit
        tested = self._variance > 0.0
        z = np.where(tested, self._sum / (self.sigma_d * np.sqrt(np.where(tested, self._variance, 1.0))), 0.0)
        misfit = np.abs(z) > self.level
        self._sum[:] = 0.0
        self._variance[:] = 0.0
        if misfit.any():
            self.restart(np.flatnonzero(misfit))
        return misfit

    def fault(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The offset b̂ at the last reading (rad/s) and the drift ŝ (rad/s per s) of each row, with their standard
        errors under (1): σ_d √P, exact without forgetting (λ → 1); with it, the weighted fit's approximately."""
        t = (self.ticks - 1) / self.forget_ticks
        offset = self.theta[:, 0] + self.theta[:, 1] * t
        drift = self.theta[:, 1] / (self.forget_ticks * self.dt)
        P = self.P * self.lam  # P before this tick's division: the fit's (ΦᵀΛΦ)⁻¹
        var_offset = P[:, 0, 0] + 2.0 * t * P[:, 0, 1] + t**2 * P[:, 1, 1]
        se_offset = self.sigma_d * np.sqrt(var_offset)
        se_drift = self.sigma_d * np.sqrt(P[:, 1, 1]) / (self.forget_ticks * self.dt)
        return offset, drift, se_offset, se_drift
