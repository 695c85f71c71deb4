"""Which generator-speed sensor is faulty, when the observers' residuals cannot tell.

A small fault on one generator-speed sensor (an offset of a few σ, a slow drift in its first seconds) makes the
two generator-speed sensors disagree, and every observer that uses the faulty one inconsistent with the other,
but the observers that use one of them and the rotor-speed sensors (3-g1, 3-g2) are both consistent: the
rotor-speed sensors are 50 times noisier once referred to the generator side, and a UIO takes a step of a
generator-speed reading for an aerodynamic torque impulse. Guessing is costly: the estimate would then rest on
the faulty sensor alone.

A third opinion settles it over time: ω₃, the inverse-variance weighted mean of N_g ω_r,m1, N_g ω_r,m2 and the
power-speed channel P_g,m/(η_gc τ_g,m) (``interfaces.power_speed``), with variance σ₃². With s² = σ₃² + σ_g²,
the log-likelihood ratio of "ω_g,m1 is faulty" against "ω_g,m2 is faulty" at one tick is

    ℓ = [(y_g1 − ω₃)² − (y_g2 − ω₃)²] / (2 s²) = δ (m − ω₃) / s²,   δ = y_g1 − y_g2,  m = (y_g1 + y_g2)/2,

summed from the moment the isolation started; the sign of the sum names the faulty sensor once its magnitude
reaches h = ln(1/α_iso), the isolation's own level (Wald: a wrong choice has probability ≈ e^(−h)). For an
offset b it grows by b²/(2 s²) per tick: a 5σ offset (0.25 rad/s) is settled in about 1 s at a third of rated
torque (σ₃ ≈ 0.8 rad/s), a drift faster as it grows. A rotor-speed sensor that is flagged or suspected is left
out of ω₃; below ``POWER_SPEED_MIN_TORQUE`` the power-speed channel is N_g × the rotor-speed mean and adds
nothing, so it is left out too.

**A rotor-speed fault beside it.** A double fault puts a rotor-speed fault beside the generator-speed one, and a
rotor-speed sensor that nobody suspects yet moves ω₃: a gain of 4 % on ω_r,m1 moves N_g ω_r,m1 by about 2 % of
ω_g, ten times a 8σ generator-speed offset, and the sum then names the healthy generator-speed sensor. The two
rotor-speed sensors measure the same shaft, so their difference d = y_r1 − y_r2 is N(0, σ_r1² + σ_r2²) while
both are healthy, whatever the wind. Its sum since the isolation started, z = |Σd| / (σ_d √k) over k ticks, tests
that; once z exceeds the isolation's two-sided level Φ⁻¹(1 − α_iso/2) (3.3 at α_iso = 1e-3) the sum ℓ taken
with the power-speed channel alone (``total_power``, accumulated beside ``total`` from the start) decides, and
where that channel is not usable nothing is decided by the third opinion (the isolation's ``arbitration_s``
runs out instead). The pair is compared whether or not one of them is suspected, and left uncompared only once one
is flagged: the first explanation of a double fault may suspect the healthy rotor-speed sensor, which would leave
the faulty one alone in ω₃ and the pair never compared (a random-scenario window, ω_r,m2 gain 0.913 beside an
8.5σ offset on ω_g,m1 at 15 m/s: ω_r,m1 suspected first, ω_g,m2 flagged on the rotor-speed opinion; docs/turbine.md).
Beside the pair's difference, each rotor-speed sensor's reading less each generator-speed sensor's through the gear is
summed over the same ticks (``encoder_gap``): the sums ``rotor_pair`` tests against one encoder.

**The fault's first ticks.** The sum above needs many ticks because its third opinion is noisy (σ₃ ≈ 0.8 rad/s at
a third of rated torque, 16 σ_g), yet a generator-speed sensor's offset or gain fault shows at its first tick as a
jump of one reading that the other does not make. The pair mean m moves by half the jump, and m a few ticks ahead
is predictable from its own past: p_i[k] = w_i · m[k−W … k−1], the least-squares quadratic through the last
W = ``JUMP_HISTORY`` means extrapolated i + 1 ticks (i = 0 … L − 1, L = ``JUMP_TICKS``). Those predictions are a
third opinion free of both sensors' readings from tick k on. The errors e_i = m[k+i] − p_i[k] of one fit have a
covariance Cov(e) that the drive train's torsion and the turbulence make larger than the white-noise
(σ_g²/2)(I + w wᵀ), most near rated; it is learnt on rows with nothing flagged or being isolated (time constant
``JUMP_MEMORY_S``, started at ``JUMP_START_SCALE`` times the white-noise value). With δ and m over the ticks from the
onset on, the log-likelihood ratio of "ω_g,m1 faulty" against "ω_g,m2 faulty" is, as for ℓ above with the
prediction as ω₃,

    ℓ_J = ½ (r₁ᵀ C⁻¹ r₁ − r₂ᵀ C⁻¹ r₂) = δᵀ C⁻¹ (m − p),   r_s = y_s − p,   C = Cov(e) + σ_g²/2 I

(C is the covariance of the healthy sensor's y − p: Cov(e) less the pair mean's own σ_g²/2 I, plus σ_g² I). For
one tick, an offset b gives b²/(2 C₁₁): 8σ_g ≈ 0.4 rad/s gives about 13 at 9 m/s and 10 near rated, h = 6.9;
over L ticks (b²/2) 1ᵀC⁻¹1. ℓ_J is added to both sums when the isolation starts, over the ticks from the onset seen
so far, and replaced on each of the next ticks until it spans L. δ carries η_g1 − η_g2 and e carries η_g1 + η_g2,
which are independent for sensors of equal noise.

The onset is placed, when an isolation starts, ``JUMP_GUARD`` tick before the parity's change point among the
last ``JUMP_LOOKBACK`` ticks (the window test may detect a few ticks late; the change point is the split of δ's
last W + J ticks into before and after with the largest standardised difference of means; choosing it from δ
alone does not bias ℓ_J). A change point placed late puts fault ticks into the fit, whose extrapolation then
overshoots the jump and points the wrong way (a 6σ_g offset detected 4 ticks late: 9 wrong decisions in 4000 at
the change point itself, 1 with the guard); placed early, a healthy tick enters the comparison and only dilutes it.
A slow drift makes no jump, ℓ_J is then small and the sums decide as before. Rows with a generator-speed sensor
flagged take no ℓ_J (the parity then carries the flagged sensor's fault).
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from service.turbine.bank import POWER_SPEED, BankDesign
from wwcore.backend import fast_module
from wwcore.planes import Planes, planes
from wwcore.quantiles import norm_isf

JUMP_HISTORY = 8  # W: ticks of the pair mean the onset prediction is fitted to
JUMP_LOOKBACK = 8  # J: ticks before an isolation's start searched for the fault's onset
JUMP_TICKS = 4  # L: ticks from the onset on compared with the prediction (≤ J)
JUMP_GUARD = 1  # ticks the onset is placed before the parity's change point
JUMP_MEMORY_S = 5.0  # time constant of the learnt covariance of the pair mean's prediction errors, s
JUMP_START_SCALE = 4.0  # that covariance before anything is learnt, × its white-noise value


def jump_weights(history: int = JUMP_HISTORY, ahead: int = JUMP_TICKS) -> np.ndarray:
    """w (ahead, history): p_i[k] = w[i] @ m[k−history … k−1] (oldest first), the least-squares quadratic through
    the last ``history`` values extrapolated i + 1 ticks ahead."""
    t = np.arange(-history, 0, dtype=float)
    fit = np.linalg.pinv(np.vander(t, 3))
    return np.array([[i * i, i, 1.0] for i in range(ahead)]) @ fit


def _variance_of(R: np.ndarray, i: int) -> float:
    return float(R[i, i])


class GeneratorArbiter(Planes):
    """The running log-likelihood ratio ``total`` (n,): > 0 favours ω_g,m1 faulty, < 0 ω_g,m2."""

    PLANES: ClassVar[dict[str, tuple]] = {"_histories": ("_means", "_parities")}

    def __init__(self, bank: BankDesign, n: int, alpha: float, dt: float = 0.01, fast=None):
        self._fast_arbitration = fast_module("service.turbine.fast_arbitration") if fast is not None else None
        gear_ratio = bank.gear_ratio
        self.h = math.log(1.0 / alpha)
        all_sensors = bank.observers[bank.index(frozenset())]
        variance = dict(zip(all_sensors.sensors, np.diag(all_sensors.R), strict=True))
        self.rotor_variance = float(variance["omega_r_m1"]) * gear_ratio**2  # referred to the generator side
        self.generator_variance = float(variance["omega_g_m1"])
        # σ² of the power-speed channel of each 5-pe design, in ``interfaces.power_speed_band`` order
        self.power_variance = np.array(
            [_variance_of(bank.observers[j].R, bank.observers[j].sensors.index(POWER_SPEED)) for j in bank.power_speed]
        )
        self.gear_ratio = gear_ratio
        self.parity_sigma = math.sqrt(float(variance["omega_r_m1"]) + float(variance["omega_r_m2"]))  # σ_d, rad/s
        self.parity_level = float(norm_isf(0.5 * alpha))  # z above which the rotor-speed sensors disagree
        self.total = np.zeros(n)
        self.total_power = np.zeros(n)  # ℓ summed with the power-speed channel as the only third opinion
        self.weights = jump_weights()
        # covariance of e = m − p (the L prediction errors from one fit) on white sensor noise alone, σ_g²/2 (I + w wᵀ)
        self.jump_floor = 0.5 * self.generator_variance * (np.eye(JUMP_TICKS) + self.weights @ self.weights.T)
        self.jump_covariance = np.tile(JUMP_START_SCALE * self.jump_floor, (n, 1, 1))  # learnt, rad²/s²
        self._jump_rate = dt / JUMP_MEMORY_S
        span = JUMP_HISTORY + JUMP_LOOKBACK
        # the pair mean of the last ``span`` ticks, oldest first, and δ of the same ticks: the planes of one block
        # (``wwcore.planes``), which the compiled tick takes
        self._histories = np.zeros((len(self.PLANES["_histories"]), n, span))
        self.__dict__.update(planes(self._histories, self.PLANES["_histories"]))
        self._seen = 0  # ticks observed (the histories are full once it reaches ``span``)
        self.jump = np.zeros(n)  # ℓ_J in the sums of each row (0: none)
        self._onset = np.full(n, -1, dtype=np.int64)  # tick (count of ``observe``) of the onset while ℓ_J grows
        self.parity = np.zeros(n)  # Σ (y_r1 − y_r2) since the isolation started, rad/s
        self.count = np.zeros(n)  # ticks summed
        # Σ (y_rs − y_gk/N_g) over the same ticks, [row, s, k]: each rotor-speed sensor against each generator-speed
        # sensor through the gear (the one-encoder rigid observers 4-g1, 4-g2), rad/s
        self.encoder_gap = np.zeros((n, 2, 2))
        self.encoder_sigma = math.sqrt(float(variance["omega_r_m1"]) + self.generator_variance / gear_ratio**2)

    def reset(self, rows: np.ndarray, jump: np.ndarray | None = None) -> None:
        """Start the sums of ``rows`` ((n,) bool) afresh, from ℓ_J of the fault's onset on the rows of ``jump``
        ((n,) bool; None: none) once the histories are full (module docstring)."""
        self.total[rows] = 0.0
        self.total_power[rows] = 0.0
        self.parity[rows] = 0.0
        self.count[rows] = 0.0
        self.encoder_gap[rows] = 0.0
        self.jump[rows] = 0.0
        self._onset[rows] = -1
        if jump is None or self._seen < self._means.shape[1]:
            return
        take = np.flatnonzero(rows & jump)
        if len(take) == 0:
            return
        # a change point placed late would put fault ticks into the prediction's fit, which then extrapolates the
        # jump and points the wrong way; placed early, a healthy tick enters the comparison and only dilutes it
        onset = np.maximum(self._change_point(take) - JUMP_GUARD, 0)
        self._onset[take] = self._seen - JUMP_LOOKBACK + onset
        self._grow_jump(take)

    def _change_point(self, rows: np.ndarray) -> np.ndarray:
        """The parity's change point among the last J ticks of ``rows`` (0 … J − 1, oldest first): the split of its
        last W + J ticks into "before" (≥ W ticks) and "from the onset on" with the largest standardised
        difference of means, √(a b / (a + b)) |mean_after − mean_before|."""
        span = JUMP_HISTORY + JUMP_LOOKBACK
        before = np.arange(JUMP_HISTORY, span)
        after = span - before
        cumulative = np.cumsum(self._parities[rows], axis=1)
        total, head = cumulative[:, -1:], cumulative[:, before - 1]
        score = np.sqrt(before * after / span) * np.abs((total - head) / after - head / before)
        return score.argmax(axis=1)

    def _grow_jump(self, rows: np.ndarray) -> None:
        """Replace ℓ_J of ``rows`` (indices, onset known) by ℓ_J over the ticks from the onset seen so far (≤ L):
        ℓ_J = δᵀ C⁻¹ (m − p), C = Cov(e) + σ_g²/2 I over those ticks (module docstring)."""
        W, span = JUMP_HISTORY, JUMP_HISTORY + JUMP_LOOKBACK
        half_noise = 0.5 * self.generator_variance
        for row in rows:
            start = int(self._onset[row]) - (self._seen - span)  # the onset's column in the histories
            k = min(JUMP_TICKS, span - start)
            means = self._means[row]
            error = means[start : start + k] - self.weights[:k] @ means[start - W : start]
            delta = self._parities[row, start : start + k]
            C = self.jump_covariance[row, :k, :k] + half_noise * np.eye(k)
            ell = float(delta @ np.linalg.solve(C, error))
            self.total[row] += ell - self.jump[row]
            self.total_power[row] += ell - self.jump[row]
            self.jump[row] = ell
            if k == JUMP_TICKS:
                self._onset[row] = -1

    def observe(self, y: np.ndarray, learn: np.ndarray) -> None:
        """Push this tick's pair mean and parity (y (n, 4) calibrated speed readings) into the histories, learn
        Cov(e) on the rows of ``learn`` ((n,) bool: nothing flagged or being isolated) from the L errors of the fit
        that ended L ticks ago, and grow ℓ_J where its onset is recent."""
        W, L = JUMP_HISTORY, JUMP_TICKS
        if self._fast_arbitration is not None:  # the lines below by two kernels around numpy's product
            growing = self._fast_arbitration.arbiter_push(y, self._means, self._parities, self._onset)
            self._seen += 1
            if self._seen >= W + L:
                predicted = self._means[:, -L - W : -L] @ self.weights.T
                fast = self._fast_arbitration
                fast.arbiter_learn(self._means, predicted, learn, self._jump_rate, self.jump_covariance)
            if growing:
                self._grow_jump(np.flatnonzero(self._onset >= 0))
            return
        self._means[:, :-1] = self._means[:, 1:]
        self._means[:, -1] = 0.5 * (y[:, 2] + y[:, 3])
        self._parities[:, :-1] = self._parities[:, 1:]
        self._parities[:, -1] = y[:, 2] - y[:, 3]
        self._seen += 1
        if self._seen >= W + L:
            error = self._means[:, -L:] - self._means[:, -L - W : -L] @ self.weights.T
            rows = np.flatnonzero(learn)
            if len(rows):
                outer = error[rows, :, None] * error[rows, None, :]
                self.jump_covariance[rows] += self._jump_rate * (outer - self.jump_covariance[rows])
        growing = np.flatnonzero(self._onset >= 0)
        if len(growing):
            self._grow_jump(growing)

    def compiled_arguments(self) -> tuple:
        """``observe``'s kernel arguments for a caller that runs them in its own kernel
        (``fast_detector.arbiter_observe``): the histories (one block), the onsets, wᵀ, the learning rate, Cov(e)
        (updated in place, never replaced) and an (n, W) buffer for the fit's slice of the histories."""
        n = self._means.shape[0]
        return (
            self._histories, self._onset, self.weights.T, self._jump_rate, self.jump_covariance,
            np.empty((n, JUMP_HISTORY)),
        )  # fmt: skip

    def observed(self, growing: bool) -> bool:
        """``observe``'s lines after its kernels, where a caller ran them (``compiled_arguments``): the tick
        counted, ℓ_J grown where it is ``growing``. Returns whether the next tick's kernels learn Cov(e) (the
        histories then hold a whole fit and its L errors)."""
        self._seen += 1
        if growing:
            self._grow_jump(np.flatnonzero(self._onset >= 0))
        return self._seen + 1 >= JUMP_HISTORY + JUMP_TICKS

    @property
    def rotor_z(self) -> np.ndarray:
        """(n,) |Σ(y_r1 − y_r2)| / (σ_d √k): the rotor-speed sensors' summed difference in its standard deviations,
        N(0, 1) in magnitude while both are healthy (0 before anything is summed)."""
        return np.abs(self.parity) / (self.parity_sigma * np.sqrt(np.maximum(self.count, 1.0)))

    def rotor_log_ratio(self, shift: float, rows=slice(None), spread: float = 1.0) -> np.ndarray:
        """Λ = shift·|Σd| − k·shift²/2 of ``rows`` (all: (n,); one row index: a scalar), d = (y_r1 − y_r2)/(σ_d ŝ)
        over the k ticks summed, ŝ = ``spread``: the log-likelihood ratio of "one rotor-speed sensor is biased by
        ±shift σ_d ŝ of their difference" (the sign that fits) against "both are healthy" (0 before anything is
        summed)."""
        return shift * np.abs(self.parity[rows]) / (self.parity_sigma * spread) - 0.5 * shift**2 * self.count[rows]

    def rotor_sensor_log_ratios(self, shift: float, row: int, encoder: int, spread: float = 1.0) -> np.ndarray:
        """Λ_s = shift·|Σe_s| − k·shift²/2 for s = ω_r,m1, ω_r,m2 (2,) on ``row``, e_s = (y_rs − y_g/N_g)/(σ_e ŝ)
        over the k ticks summed, y_g the generator-speed sensor ``encoder`` (0: ω_g,m1, 1: ω_g,m2), σ_e² = σ_r² +
        σ_g²/N_g², ŝ = ``spread``: the log-likelihood ratio of "rotor-speed sensor s is biased by ±shift σ_e" (the
        sign that fits) against "both are healthy", on residuals that do not share the other rotor-speed sensor's
        noise (``rotor_pair``; docs/turbine.md, "Against one encoder")."""
        z = np.abs(self.encoder_gap[row, :, encoder]) / (self.encoder_sigma * spread)
        return shift * z - 0.5 * shift**2 * self.count[row]

    @property
    def rotor_disagree(self) -> np.ndarray:
        """(n,) bool: the rotor-speed sensors' summed difference is beyond the isolation level (module docstring)."""
        return self.rotor_z > self.parity_level

    @property
    def log_ratio(self) -> np.ndarray:
        """(n,) the sum that decides: ``total_power`` where the rotor-speed sensors disagree, ``total`` elsewhere."""
        return np.where(self.rotor_disagree, self.total_power, self.total)

    def step(
        self,
        y: np.ndarray,
        power_speed: np.ndarray | None,
        band: np.ndarray | None,
        rotor_trusted: np.ndarray,
        power_trusted: np.ndarray,
        rotor_paired: np.ndarray | None = None,
    ) -> None:
        """Add this tick's ℓ. y (n, 4) speed readings; power_speed (n,) the power-speed channel (None: not used);
        band (n,) its 5-pe design (σ); rotor_trusted (n, 2) and power_trusted (n,) which opinions to use;
        rotor_paired (n,) the rows whose two rotor-speed readings are compared (None: where both are trusted).

        The comparison does not depend on which rotor-speed sensor is suspected: a suspicion may name the healthy
        one (the first explanation of a double fault is often the wrong rotor-speed sensor), and the other, faulty,
        would then be the only rotor-speed opinion in ω₃, unchecked. Compared, the pair's disagreement hands the
        decision to the power-speed channel whichever of the two is at fault."""
        both_rotor = rotor_trusted.all(axis=1) if rotor_paired is None else rotor_paired
        self.parity += np.where(both_rotor, y[:, 0] - y[:, 1], 0.0)
        self.count += both_rotor
        gap = y[:, :2, None] - y[:, None, 2:4] / self.gear_ratio
        self.encoder_gap += np.where(both_rotor[:, None, None], gap, 0.0)
        weight_r = rotor_trusted / self.rotor_variance
        numerator = (weight_r * y[:, :2]).sum(axis=1) * self.gear_ratio
        weight = weight_r.sum(axis=1)
        power_numerator, power_weight = np.zeros_like(weight), np.zeros_like(weight)
        if power_speed is not None and len(self.power_variance):
            power_weight = power_trusted / self.power_variance[band]
            power_numerator = power_weight * power_speed
        delta = y[:, 2] - y[:, 3]
        middle = 0.5 * (y[:, 2] + y[:, 3])
        self.total += self._ell(numerator + power_numerator, weight + power_weight, delta, middle)
        self.total_power += self._ell(power_numerator, power_weight, delta, middle)

    def _ell(self, numerator: np.ndarray, weight: np.ndarray, delta: np.ndarray, middle: np.ndarray) -> np.ndarray:
        """ℓ = δ (m − ω₃) / s² with ω₃ = numerator / weight; 0 where there is no third opinion (weight 0)."""
        usable = weight > 0.0
        third = numerator / np.where(usable, weight, 1.0)
        s2 = 1.0 / np.where(usable, weight, 1.0) + self.generator_variance
        return np.where(usable, delta * (middle - third) / s2, 0.0)

    def decided(self) -> np.ndarray:
        return np.abs(self.log_ratio) >= self.h
