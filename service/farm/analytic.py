r"""The better farm detector, ``analytic``: residuals from each turbine's own measurements, no neighbour needed.

The paper compares a turbine with its row, so it is blind where a turbine stands alone (wind case 2) and its
residuals carry the turbulence difference between two rotors. Each of the three faults, however, breaks a
relation *inside* one turbine whose only uncertainty is sensor noise of known size (PARAMETERS.md a.3, under the
scenario's noise convention); so each residual below has a known distribution without the fault, and its alarm
threshold follows from the false-alarm budget alone (no tuning on faulty runs). All residuals use the turbines'
10 Hz SCADA means (mean of 10 readings; where a quantity has two sensors, of both).

**Fault 1, debris** (the output falls to 0.97 of the generator's power at unchanged speed and torque):

.. math::  z_1 = η_{gc}\,\bar ω_g\,\bar τ_g - \bar P_g,\qquad
           σ_1^2 = \frac{σ_P^2}{10} + (η_{gc}\bar τ_g)^2\frac{σ_{ω_g}^2}{20} + (η_{gc}\bar ω_g)^2\frac{σ_τ^2}{10}

Fault-free z_1 ~ N(0, σ_1²); with the fault z_1 = (1 − 0.97) η_gc ω̄_g τ̄_g =: μ_1. Page's CUSUM of the LLR
increments (μ_1/σ_1²)(z_1 − μ_1/2) (the increments of the paper's eq. (7)).

**Fault 2, pitch misalignment** (blade i held δ = 0.3 deg off the collective command): per blade,

.. math::  z_{2,i} = \bar β_i - \tfrac12\sum_{j \ne i} \bar β_j

with β̄_i the mean of blade i's two encoders. The collective command, the controller's compensation and the
wind cancel; what is left is sensor noise, including the part that reaches the true pitch through the
actuator (PARAMETERS.md a.2: the mean encoder error is added to the actuator's reference). Its variance σ_2² is
computed from the published actuator and noise parameters (``pitch_residual_variance``). Two one-sided CUSUMs
per blade, design shift ±δ.

**Fault 3, drive train** (a 3P transmission error: the generator swings against the rotor at the planet-pass
frequency): the torsion-rate residual

.. math::  z_3 = \bar ω_g - N_g\,\bar ω_r,\qquad σ_3^2 = \frac{σ_{ω_g}^2}{20} + N_g^2 \frac{σ_{ω_r}^2}{20}

is free of the wind (the rotor and the generator turn together below the 4.5 Hz torsion mode) and of the
controller. Its whitened 3P lock-in amplitude Ã (``signals.LockIn3P``, τ = 1.5 s: the quadratic form of the
demodulated I, Q in their exact covariance, which the 2·3P image of one low-pass makes unequal and correlated) is
Rayleigh-distributed without the fault (Ã/(2s) with s from σ_3), so the alarm is Ã ≥ h_3 with P(Ã > h_3) = p_3.
The plain amplitude A = 2|I + jQ| (``whiten_lockin = false``) has a heavier (Hoyt) tail: 2.5–6.5 × p_3.

**Thresholds from the budget.** The budget is per *farm*: B false alarms per 1000 s of farm operation per fault
type (``false_alarms_per_1000s``, default 0.01: ten times below the target 0.1, for the model's imperfections),
shared by the farm's N turbines (N from the site) and their m one-sided tests each (m = 1, 6, 1). Each test may
alarm once per ARL_0 = 10⁴ · N m / B samples. Page's CUSUM of LLRs has ARL_0 ≥ e^h (Lorden), so
h = ln ARL_0 = ln(10⁴ m / B) + ln N: the thresholds grow with the logarithm of the farm's size (faults 1, 2 at
B = 0.01: h = 16.0, 17.8 for N = 9; 18.2, 20.0 for N = 80; 13.8, 15.6 for N = 1), and so do the detection delays,
by Δh over the CUSUM's drift per sample (ln(80/9) = 2.2 more for Horns Rev 1 than for the 3 × 3). For fault 3 the
exceedance probability per sample is p_3 = B/(10⁴ · N), a bound on the crossing rate (h_3 = 2s √(2 ln 1/p_3),
growing with √(ln N)).
The end of a fault is decided by the reverse CUSUM (faults 1, 2; same h) or by A < h_3/2 for 3 s (fault 3).
No test runs during the first ``warmup_s`` (filters settling, levels learnt).

**A plant that differs from the design model** (``learn_levels``, on by default; ``service.farm.baseline``). Each
turbine's residuals are judged against its own healthy level and spread, learnt online from the first sample
(``docs/farm.md`` §1.7 says what each mismatch does without this):

* z_1 and z_2 enter the CUSUMs as z − m, m the turbine's learnt level (W; deg per blade). A calibration bias of
  the power, torque or pitch sensors, or the within-tolerance misalignment a pitch bias causes through the
  actuator's loop, is there from the start and stays; the paper's faults are onsets of their design size.
* The pitch residual also follows the blades' rate where one rotor's actuators differ in lag τ = 2ζ/ω_n:
  z_2,i ≈ −(τ_i − ½ Σ_{j≠i} τ_j) β̇ with β̇ (deg/s) the rate of the collective (blade-mean) pitch over one sample.
  Its gain k_i (s) is learnt by least squares (``LearntRateGain``) and k_i β̇ taken out; what is left is covered
  by widening the test's variance by (τ_u β̇_max)², τ_u = ``pitch_lag_tolerance_s`` (0.01 s) and β̇_max the larger
  of the last two samples' |β̇|. In a demand step the blades move at up to 20–70 deg/s, where lags differing by
  0.01 s (per-blade ω_n within ±0.5 rad/s) put 0.5–0.8 deg into z_2 for a second; a misalignment stays when the
  blades stop.
* The variance is ρ σ², ρ ∈ [1, ``max_noise_scale``²] the learnt ratio of the residual's long-run variance to the
  design's (sensors noisier than the data sheet). Fault 3's h_3 is computed per turbine from its learnt I/Q scale
  s ∈ [s_3, ``max_noise_scale`` s_3]; as the scale learns only from Ã < h_3/2, its mean is corrected for that
  truncation (``baseline.LearntRayleighScale``: s² 7.5 % low otherwise).
* Levels and rate gains learn with time constant ``level_time_s``, spreads with ``spread_time_s``; all are frozen
  while the turbine's flag of that type is up or its statistic (CUSUM g, or A) is above h/2, so a fault never
  teaches the detector its own level. The thresholds h stay those of the budget: only the noise model under them
  is learnt. The price: a fault present from the first sample, or one that grows over many minutes, is learnt as
  the turbine's health (as a calibration bias of the same size would be).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from scipy.signal import cont2discrete

from service.farm.baseline import LearntLevel, LearntRateGain, LearntRayleighScale
from service.farm.cusum import PageCusum, llr_increment, threshold_for
from service.farm.interfaces import (
    BETA,
    N_TYPES,
    OMEGA_G,
    OMEGA_R,
    P_G,
    TAU_G,
    FarmContext,
    FarmDiagnosis,
    FarmSample,
)
from service.farm.signals import LockIn3P, lockin_iq_std, rayleigh_threshold
from wwcore.channels import SENSOR_INDEX
from wwcore.scenario.farm import FARM_DT_S
from wwcore.turbine_params import TurbineParams

DEBRIS_FACTOR = 0.97  # design fault 1: output × 0.97 (PARAMETERS.md b)
MISALIGNMENT_DEG = 0.3  # design fault 2 (PARAMETERS.md b)
LOCKIN_TAU_S = 1.5  # s, 3P lock-in low-pass
RELEASE_S = 3.0  # s, fault 3 ends after A < h_3/2 for this long
TESTS_PER_TURBINE = (1, 6, 1)
LEVEL_TIME_S = 600.0  # s, time constant of the learnt levels after the learning period [PROPOSED]
SPREAD_TIME_S = 600.0  # s, time constant of the learnt spreads [PROPOSED]
MAX_NOISE_SCALE = 3.0  # –, the largest sensor noise over the design σ learnt as health (the mismatch range's top)
WARMUP_S = 10.0  # s, no decisions before this: filters settle, levels and spreads are first learnt
SUSPICION = 0.5  # –, a statistic above this share of its threshold stops its level and spread learning
PITCH_LAG_TOLERANCE_S = 0.01  # s, lag left unexplained between one rotor's pitch actuators [PROPOSED]
RATE_PRIOR = 100.0  # (deg/s)² samples: the pitch-rate gain is learnt once the blades have moved that much
LOCKIN_SETTLE_S = 10.0  # s, the lock-in's high-pass settles (its time constant) before its scale is learnt
SAMPLES_PER_1000S = round(1000.0 / FARM_DT_S)


@lru_cache(maxsize=8)
def pitch_residual_variance(params: TurbineParams, sigma_beta: float, samples: int = 10) -> float:
    """Variance (deg²) of z_2 = β̄_i − ½ Σ_{j≠i} β̄_j without faults, from the actuator and the encoder noise.

    Per blade, the mean encoder error e_k (variance σ²/2, white at Ts) is read with the pitch and added to the
    actuator's reference (PARAMETERS.md a.2), so the measured mean is y_k = e_k + Σ_{m≥1} h_m e_{k−m}, h the
    zero-order-hold impulse response of ω_n²/(s² + 2ζω_n s + ω_n²). The variance of one block mean of y is
    (σ²/2) Σ_k c_k², c = (1/10)·ones(10) * (δ + h); its long-run variance (what the CUSUM sums) is
    (σ²/2)(Σ_k δ_k + h_k)²/10. We return the larger; the blades are independent, so var z_2 = (1 + 1/2) var ȳ.
    """
    wn, zeta, dt = params.pitch.omega_n, params.pitch.zeta, params.dt
    a = np.array([[0.0, 1.0], [-(wn**2), -2.0 * zeta * wn]])
    b = np.array([[0.0], [wn**2]])
    ad, bd, *_ = cont2discrete((a, b, np.eye(2), np.zeros((2, 1))), dt, method="zoh")
    length = 4000
    h = np.zeros(length)
    x = bd[:, 0].copy()  # state after one step of a unit reference pulse
    for k in range(1, length):
        h[k] = x[0]
        x = ad @ x
    impulse = h.copy()
    impulse[0] += 1.0  # y_k = e_k + (h * e)_k
    c = np.convolve(np.full(samples, 1.0 / samples), impulse)
    var_mean = 0.5 * sigma_beta**2 * float(np.sum(c * c))
    # Consecutive block means are correlated through the actuator (its 1.8 Hz bandwidth spans several samples),
    # and a CUSUM adds them up: what governs its random walk is the long-run variance, the spectral density at
    # zero frequency, (σ²/2)(Σ_k δ_k + h_k)²/10 per block mean (2.4 × the one-sample variance here).
    long_run = 0.5 * sigma_beta**2 * float(np.sum(impulse)) ** 2 / samples
    return 1.5 * max(var_mean, long_run)


class AnalyticDetector:
    """Per-turbine analytic-redundancy residuals with budget-derived thresholds (module docstring)."""

    def __init__(self, *, context: FarmContext, options: dict | None = None):
        options = options or {}
        self.context = context
        p = self.p = context.params
        n = self.n = context.n
        sig = context.sensor_sigma
        self.var_p = sig[P_G] ** 2 / 10.0
        self.var_w = sig[OMEGA_G[0]] ** 2 / 20.0
        self.var_t = sig[TAU_G] ** 2 / 10.0
        self.var_r = sig[OMEGA_R[0]] ** 2 / 20.0
        beta_sigma = float(sig[SENSOR_INDEX["beta_1_m1"]])
        self.var_2 = pitch_residual_variance(p, beta_sigma)
        self.var_3 = self.var_w + p.N_g**2 * self.var_r
        budget = float(options.get("false_alarms_per_1000s", 0.01))
        self.budget = budget
        per_farm = context.turbines  # the budget is the farm's, shared by its turbines
        arl = [SAMPLES_PER_1000S * per_farm * m / budget for m in TESTS_PER_TURBINE]
        self.h1, self.h2 = threshold_for(arl[0]), threshold_for(arl[1])
        self.p3 = budget / (SAMPLES_PER_1000S * per_farm)
        self.s3 = float(lockin_iq_std(math.sqrt(self.var_3), LOCKIN_TAU_S))
        self.h3 = float(rayleigh_threshold(self.s3, self.p3))
        self.h3_now = np.full(n, self.h3)  # per turbine, from its learnt I/Q scale (the design's without learning)
        self.warmup = round(float(options.get("warmup_s", WARMUP_S)) / FARM_DT_S)
        self.learn = bool(options.get("learn_levels", True))
        level_s = float(options.get("level_time_s", LEVEL_TIME_S))
        spread_s = float(options.get("spread_time_s", SPREAD_TIME_S))
        max_ratio = float(options.get("max_noise_scale", MAX_NOISE_SCALE)) ** 2
        learnt = {"level_time_s": level_s, "spread_time_s": spread_s, "max_ratio": max_ratio}
        self.level1 = LearntLevel((n,), **learnt, fast=context.fast)
        self.level2 = LearntLevel((n, 3), **learnt, fast=context.fast)
        withheld = SUSPICION**2 * math.log(1.0 / self.p3)  # u = A²/(8s²) above which A is not learnt from
        self.scale3 = LearntRayleighScale(n, self.s3, spread_time_s=spread_s, max_ratio=max_ratio, truncation=withheld)
        self.whiten = bool(options.get("whiten_lockin", True))
        self.rate_gain = LearntRateGain((n, 3), time_s=level_s, prior=RATE_PRIOR)
        self.lag_tolerance = float(options.get("pitch_lag_tolerance_s", PITCH_LAG_TOLERANCE_S))
        self.last_pitch: np.ndarray | None = None
        self.last_rate = np.zeros(n)
        self.cusum1 = PageCusum((n,), self.h1, self.h1)
        self.cusum2 = PageCusum((n, 6), self.h2, self.h2)
        self.lockin = LockIn3P(n, LOCKIN_TAU_S, fast=context.fast)
        self.flag3 = np.zeros(n, dtype=bool)
        self.quiet3 = np.zeros(n)  # s that A has been below h_3/2 while flagged
        self.samples = 0
        self.residuals = np.zeros((n, N_TYPES))
        # ``service.farm.fast`` (``FarmContext.fast``) or None: with it, the residuals before the lock-in, the
        # learning and the decisions are one kernel each (the same numbers); the learnt quantities', the CUSUMs' and
        # fault 3's state is then updated in place
        self._fast = context.fast
        columns = (*OMEGA_G, *OMEGA_R, TAU_G, P_G)
        consts = (p.eta_gc, self.var_p, self.var_w, self.var_t, p.N_g, 1.0 - DEBRIS_FACTOR)
        self._fast_front = (np.array(columns, dtype=np.intp), np.ascontiguousarray(BETA, dtype=np.intp), consts)
        self._consts = (self.h1, self.h2, MISALIGNMENT_DEG, FARM_DT_S, RELEASE_S)
        rayleigh = float(np.sqrt(2.0 * math.log(1.0 / self.p3)))  # h_3 = 2 s √(2 ln 1/p_3), ``rayleigh_threshold``
        self._learn_consts = (self.h1, self.h2, SUSPICION, self.var_2, math.sqrt(self.var_2), self.lag_tolerance)
        self._learn_consts += (rayleigh,)
        self._s3_max = self.scale3.design_s * np.sqrt(self.scale3.max_ratio)  # ``LearntRayleighScale.scale``'s clip

    @staticmethod
    def _level_state(level: LearntLevel) -> tuple[np.ndarray, ...]:
        """A learnt level's state arrays, as ``service.farm.fast.learn_level`` takes them."""
        return (level.samples, level.level, level.raw_ratio, level.blocks, level._block_sum, level._block_n)

    def thresholds(self) -> dict[str, float]:
        return {"debris": self.h1, "pitch_misalignment": self.h2, "drivetrain": self.h3}

    def step(self, sample: FarmSample) -> FarmDiagnosis:
        p, n = self.p, self.n
        y = sample.scada
        if self._fast is not None:  # the lines below to the lock-in by one kernel (``analytic_residuals``)
            front = self._fast.analytic_residuals(np.ascontiguousarray(y, dtype=float), *self._fast_front)
            omega_g, z1, var1, mu1, blades, z2, worst2, z3, omega_r_of_g, collective = front
        else:
            omega_g = y[:, OMEGA_G].mean(axis=1)
            omega_r = y[:, OMEGA_R].mean(axis=1)
            tau_g = y[:, TAU_G]
            # fault 1: z1 = η ω̄_g τ̄_g − P̄_g
            p_gen = p.eta_gc * omega_g * tau_g
            z1 = p_gen - y[:, P_G]
            var1 = self.var_p + (p.eta_gc * tau_g) ** 2 * self.var_w + (p.eta_gc * omega_g) ** 2 * self.var_t
            mu1 = (1.0 - DEBRIS_FACTOR) * np.abs(p_gen)
            # fault 2: z2_i = β̄_i − ½ Σ_{j≠i} β̄_j
            blades = y[:, BETA].mean(axis=2)
            z2 = 1.5 * blades - 0.5 * blades.sum(axis=1, keepdims=True)
            worst2 = np.abs(z2).max(axis=1)
            # fault 3: z3 = ω̄_g − N ω̄_r, whose 3P amplitude the lock-in takes
            z3, omega_r_of_g = omega_g - p.N_g * omega_r, omega_g / p.N_g
            collective = blades.mean(axis=1)
        amplitude = self.lockin.step(z3, omega_r_of_g)
        if self.whiten:
            amplitude = self.lockin.whitened
        self.samples += 1
        self.residuals = residuals = np.empty((n, 3))  # the three columns, as ``np.column_stack`` would stack them
        residuals[:, 0], residuals[:, 1], residuals[:, 2] = z1, worst2, amplitude
        warming = self.samples <= self.warmup
        rate = (collective - (collective if self.last_pitch is None else self.last_pitch)) / FARM_DT_S  # deg/s
        self.last_pitch = collective
        noise_ratio = None  # (n, 3) the learnt noise ratios, from the kernel
        if self.learn and self._fast is not None:  # the branch below by one kernel (``analytic_learn``)
            c1, c2 = self.cusum1, self.cusum2
            tests = (c1.g, c1.flag, c2.g, c2.flag, self.flag3, np.ascontiguousarray(self.h3_now, dtype=float))
            levels = [
                (self._level_state(lv), lv.alpha_level, lv.alpha_block, lv.block, lv.max_ratio)
                for lv in (self.level1, self.level2)
            ]
            gain, s3 = self.rate_gain, self.scale3
            scale = (s3.samples, s3.mean_square, s3.alpha, s3.kept_share, s3.design_s, self._s3_max)
            settling = self.samples * FARM_DT_S <= LOCKIN_SETTLE_S
            z1, var1, z2, var2, self.h3_now, noise_ratio = self._fast.analytic_learn(
                (z1, var1, z2),
                rate,
                self.last_rate,
                amplitude,
                settling,
                tests,
                *levels,
                (gain.sxx, gain.sxr, gain.forget, gain.prior),
                scale,
                self._learn_consts,
            )
        elif self.learn:  # learn before judging: a sample that raises a flag is not learnt (flags of the last sample)
            g1, g2 = self.cusum1.g, self.cusum2.g.max(axis=1)
            self.level1.update(z1, np.sqrt(var1), self.cusum1.flag | (g1 >= SUSPICION * self.h1))
            frozen2 = (self.cusum2.flag.any(axis=1) | (g2 >= SUSPICION * self.h2))[:, None]
            self.rate_gain.update(z2 - self.level2.level, rate[:, None], frozen2)
            z2 = z2 - self.rate_gain.gain * rate[:, None]
            self.level2.update(z2, math.sqrt(self.var_2), frozen2)
            settling = self.samples * FARM_DT_S <= LOCKIN_SETTLE_S
            self.scale3.update(amplitude, self.flag3 | (amplitude >= SUSPICION * self.h3_now) | settling)
            z1 = z1 - self.level1.level
            z2 = z2 - self.level2.level
            var1 = var1 * self.level1.ratio
            fast = np.maximum(np.abs(rate), np.abs(self.last_rate))  # deg/s, this sample's and the last one's
            var2 = self.var_2 * self.level2.ratio + ((self.lag_tolerance * fast) ** 2)[:, None]
            self.h3_now = rayleigh_threshold(self.scale3.scale, self.p3)
        else:
            var2 = np.full((n, 3), self.var_2)
        self.last_rate = rate
        if warming:
            diagnosis = FarmDiagnosis(np.zeros((n, N_TYPES), dtype=bool), np.zeros((n, N_TYPES)), self._h(n))
            diagnosis.extra = {"amplitude_3p": amplitude}
            return diagnosis
        if self._fast is not None:  # the lines below to the diagnosis by one kernel (``analytic_decide``)
            c1, c2 = self.cusum1, self.cusum2
            state = ((c1.g, c1.q, c1.flag), (c2.g, c2.q, c2.flag), (self.flag3, self.quiet3))
            var2 = np.ascontiguousarray(var2, dtype=float)
            h3 = self.h3_now
            decided = self._fast.analytic_decide(z1, mu1, var1, z2, var2, amplitude, h3, *state, self._consts)
            diagnosis = FarmDiagnosis(*decided)
        else:
            z2 = np.concatenate([z2, -z2], axis=1)  # (n, 6): +δ and −δ on each blade
            var2 = np.concatenate([var2, var2], axis=1)
            f1 = self.cusum1.step(llr_increment(z1, 0.0, mu1, var1))
            f2 = self.cusum2.step(llr_increment(z2, 0.0, MISALIGNMENT_DEG, var2)).any(axis=1)
            h3 = self.h3_now
            rise = amplitude >= h3
            low = amplitude < 0.5 * h3
            self.quiet3 = np.where(self.flag3 & low, self.quiet3 + FARM_DT_S, 0.0)
            self.flag3 = (self.flag3 | rise) & ~(self.quiet3 >= RELEASE_S)
            self.quiet3 = np.where(self.flag3, self.quiet3, 0.0)
            diagnosis = FarmDiagnosis(
                np.column_stack([f1, f2, self.flag3]),
                np.column_stack([self.cusum1.g, self.cusum2.g.max(axis=1), amplitude]),
                self._h(n),
            )
        diagnosis.extra = {"amplitude_3p": amplitude}
        if noise_ratio is not None:
            diagnosis.extra["noise_ratio"] = noise_ratio
        elif self.learn:
            diagnosis.extra["noise_ratio"] = np.column_stack(
                [self.level1.ratio, self.level2.ratio.max(axis=1), (self.scale3.scale / self.s3) ** 2]
            )
        return diagnosis

    def _h(self, n: int) -> np.ndarray:
        return np.column_stack([np.full(n, self.h1), np.full(n, self.h2), np.broadcast_to(self.h3_now, (n,))])
