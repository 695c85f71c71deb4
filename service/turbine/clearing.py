"""When a flagged speed sensor is healthy again: Page's CUSUM on its exclusion residual.

While sensor s is flagged, the observer j the estimate comes from (``bank.estimate_observers``: the Kalman
filter on the healthy generator-speed sensors, or 5-pe; none of them uses a flagged sensor) predicts what s
should read, C_s x̂_j. The *exclusion residual*

    e_s[n] = (y_s[n] − C_s x̂_j[n]) / σ_e,s

has mean 0 when s is healthy and, while the fault persists, the fault's size μ in units of σ_e (a bias, a
gain's share of the speed, the distance of a fixed value from the truth). x̂_j never uses s, so e_s returns to
zero mean on the tick the fault ends: there is no observer transient to wait for.

Two hypotheses: H1, the fault persists with the magnitude seen so far, e ~ N(μ̂, 1); H0, s is healthy,
e ~ N(0, 1). Page's CUSUM for the change from H1 to H0::

    S[n] = max(0, S[n−1] + ℓ[n]),   ℓ = ln p0(e)/p1(e) = m (m/2 − sgn(μ̂) e),   m = max(|μ̂|, μ_floor)

and the flag may clear when S ≥ h. μ̂ is the running mean of e since the flag was raised, exponentially
weighted over ``fault_memory_s`` once that much has passed (a gain fault follows the speed, a drift its growth;
an estimate that lags a growing fault only makes ℓ more negative). ℓ is a log-likelihood ratio, so while H1
holds the mean time before S reaches h is at least e^h ticks (Wald): h = ln(1/α) with α = rate·Ts/1000 from a
false-clear budget, by default the detection tests' 0.01 per 1000 s (h = 16.1), because a flag that drops while
its fault persists costs what a false alarm costs. Under H0 the statistic grows by m²/2 per tick on average: the
end of a fault of size m is recognised after about 2h/m² ticks (one tick for m ≥ 5.7; 0.1 s for m = 1.8), and
μ_floor bounds that for a flag whose magnitude estimate is near zero (a healthy sensor isolated by mistake, a
fixed value close to the truth): at most about 2h/μ_floor² ticks. A fault smaller than μ_floor/2 is cleared
even while it persists; the window tests rarely see one that small.

**A rotor-speed sensor beside a healthy partner.** Near rated the prediction x̂_j,ω_r of the generator-side
observers carries the drive train's torsion (the healthy e_s has variance 2.7–3.2 at 11.5–13 m/s, coloured at the
torsion mode, and all of that excess is common to the two rotor-speed sensors: ``bias_test``, docs/turbine.md), so
a CUSUM derived for a white e_s decides a persisting rotor-speed fault has gone whenever the ringing cancels it
for a half-period (a 5 % gain at 11.3 m/s: the flag dropped and raised again 12 times per 48-s window). Where one
rotor-speed sensor is flagged and the other is not, the flagged one is judged against its partner instead:

    e_s[n] = (y_s[n] − y_o[n]) / (√2 σ_r),

the difference of two independent white sensor noises (the common prediction error is not in it), N(0, 1) while s
is healthy (σ_r the rotor-speed sensors' design noise, the calibration offsets taken off ``y``) and N(b/(√2 σ_r), 1)
under a bias b. A bias μ σ_r is then μ/√2 in these units, so its floor is μ_floor/√2: the flag is still cleared
below the same μ_floor/2 σ_r and the hysteresis with ``bias_test`` (raised above ``bias_shift``/2 σ_e) is
unchanged; the end of a fault is recognised after 2h/(μ²/2) ticks instead of 2h/μ², twice as late. Where both
rotor-speed sensors are flagged, each is judged against the prediction as before.

σ_e,s: with ε the observer's error (``uio``), e_s σ_e = C_s (ε − H_j η_j) + η_s, so its autocovariance is
closed-form: γ(0) = C_s Σ_x C_sᵀ + σ_s², γ(k) = C_s (F^k Σ_ε + F^(k−1) K R Hᵀ) C_sᵀ for k ≥ 1. σ_e,s² is the
larger of γ(0) and the long-run variance Σ_k γ(k) = γ(0) + 2 C_s (F (I − F)⁻¹ Σ_ε + (I − F)⁻¹ K R Hᵀ) C_sᵀ, so
that over many ticks the CUSUM drifts and spreads as it would on a white residual.
"""

from __future__ import annotations

import math

import numpy as np

from service.turbine.bank import BankDesign
from service.turbine.design_model import SPEED_SENSOR_STATE
from service.turbine.uio import ObserverDesign
from wwcore.channels import SPEED_SENSORS

ROTOR = (0, 1)  # columns of the rotor-speed sensors in SPEED_SENSORS order


def exclusion_variance(o: ObserverDesign, state: int, sensor_variance: float) -> float:
    """σ_e² of y_s − x̂[state] for a sensor s that observer ``o`` does not use (module docstring)."""
    c = np.zeros(o.n_states)
    c[state] = 1.0
    H_R = o.H @ o.R
    sigma_eps = o.state_error_cov - H_R @ o.H.T
    gamma0 = float(c @ o.state_error_cov @ c) + sensor_variance
    resolvent = np.linalg.inv(np.eye(o.n_states) - o.F)
    tail = o.F @ resolvent @ sigma_eps + resolvent @ o.K @ H_R.T
    long_run = gamma0 + 2.0 * float(c @ tail @ c)
    return max(gamma0, long_run)


class FlagClearing:
    """The CUSUM of every (turbine, speed sensor); ``ready`` where a flagged sensor's statistic reached h."""

    def __init__(
        self,
        bank: BankDesign,
        n: int,
        dt: float,
        rate_per_1000s: float,
        floor: float,
        memory_s: float,
        predictor_of_mask: np.ndarray,
        fast=None,
    ):
        self._fast = fast  # ``service.turbine.fast`` (``wwcore.backend``) or None
        self.predictor_of_mask = predictor_of_mask  # (16,) observer predicting the flagged sensors, −1 none
        self.power_speed = np.array(bank.power_speed)
        self.h = math.log(1000.0 / (rate_per_1000s * dt))
        self.floor = floor
        self.partner_floor = floor / math.sqrt(2.0)  # μ_floor in the units of the partner residual
        self.min_weight = min(1.0, dt / memory_s)
        all_sensors = bank.observers[bank.index(frozenset())]
        variance = {s: float(all_sensors.R[i, i]) for i, s in enumerate(all_sensors.sensors)}
        rotor_variance = [variance[SPEED_SENSORS[i]] for i in ROTOR]
        if rotor_variance[0] != rotor_variance[1]:
            raise ValueError(f"the two rotor-speed sensors' design noise differs: {rotor_variance}")
        self.partner_scale = 1.0 / math.sqrt(2.0 * rotor_variance[0])  # 1/(√2 σ_r), rad/s⁻¹
        m = len(bank.observers)
        self.column = np.zeros((m, len(SPEED_SENSORS)), dtype=np.int64)  # of C_s x̂_j in the bank's x̂
        self.scale = np.full((m, len(SPEED_SENSORS)), np.nan)  # 1/σ_e,s; NaN where j uses s
        for j, o in enumerate(bank.observers):
            for i, s in enumerate(SPEED_SENSORS):
                if s in o.sensors:
                    continue
                state = SPEED_SENSOR_STATE[s]
                self.column[j, i] = bank.offsets[j] + state
                self.scale[j, i] = 1.0 / math.sqrt(exclusion_variance(o, state, variance[s]))
        self.mean = np.zeros((n, len(SPEED_SENSORS)))  # μ̂, in σ_e
        self.count = np.zeros((n, len(SPEED_SENSORS)))  # ticks since the flag was raised
        self.statistic = np.zeros((n, len(SPEED_SENSORS)))  # S
        self.residual = np.zeros((n, len(SPEED_SENSORS)))  # e of the last step (0 where not flagged)

    def start(self, raised: np.ndarray) -> None:
        """Forget everything about the (row, sensor) pairs whose flag was raised this tick ((n, 4) bool)."""
        self.mean[raised] = 0.0
        self.count[raised] = 0.0
        self.statistic[raised] = 0.0

    def step(
        self,
        y: np.ndarray,
        x_hat: np.ndarray,
        mask: np.ndarray,
        frozen: np.ndarray,
        torque_band: np.ndarray | None = None,
    ) -> np.ndarray:
        """Advance the CUSUM of every flagged sensor. y (n, 4) speed readings, x_hat the bank's stacked x̂, mask
        (n,) the bitmask of flagged sensors, frozen (n, 4) bool, torque_band (n,) the 5-pe design for the
        torque (``interfaces.power_speed_band``; None: the first). Returns (n, 4) bool: flagged sensors whose
        statistic has reached h (frozen ones never do; none where no observer predicts the flagged set)."""
        flagged = (mask[:, None] >> np.arange(len(SPEED_SENSORS))) & 1 == 1
        ready = np.zeros_like(flagged)
        predictor = self.predictor_of_mask[mask]
        if torque_band is not None and len(self.power_speed):
            predictor = np.where(predictor == self.power_speed[0], self.power_speed[torque_band], predictor)
        if self._fast is not None:  # the same per row and sensor, in place
            state = (self.count, self.mean, self.statistic, self.residual)
            partner = (self.partner_scale, self.partner_floor)
            args = (self.column, self.scale, self.min_weight, self.floor, partner, self.h, state, ready)
            self._fast.cusum(y, x_hat, mask, frozen, predictor, *args)
            return ready
        rows = np.flatnonzero((mask != 0) & (predictor >= 0))
        if len(rows) == 0:
            return ready
        sel = predictor[rows]
        predicted = np.take_along_axis(x_hat[rows], self.column[sel], axis=1)
        scale = self.scale[sel]
        active = flagged[rows] & np.isfinite(scale)
        e = np.where(active, (y[rows] - predicted) * np.where(active, scale, 0.0), 0.0)
        floor = np.full(e.shape, self.floor)
        r0, r1 = ROTOR
        alone = active[:, [r0, r1]] & ~flagged[rows][:, [r1, r0]]  # a flagged rotor-speed sensor, its partner not
        partner = np.column_stack([y[rows, r0] - y[rows, r1], y[rows, r1] - y[rows, r0]]) * self.partner_scale
        e[:, [r0, r1]] = np.where(alone, partner, e[:, [r0, r1]])
        floor[:, [r0, r1]] = np.where(alone, self.partner_floor, self.floor)
        count = self.count[rows] + active
        weight = np.where(active, np.maximum(1.0 / np.maximum(count, 1.0), self.min_weight), 0.0)
        mean = self.mean[rows] + weight * (e - self.mean[rows])
        m = np.maximum(np.abs(mean), floor)
        llr = m * (0.5 * m - np.where(mean < 0.0, -e, e))
        statistic = np.where(active & ~frozen[rows], np.maximum(0.0, self.statistic[rows] + llr), 0.0)
        self.count[rows], self.mean[rows], self.statistic[rows], self.residual[rows] = count, mean, statistic, e
        ready[rows] = active & (statistic >= self.h)
        return ready
