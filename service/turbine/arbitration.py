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
**The fault's first tick.** The sum above needs many ticks because its third opinion is noisy (σ₃ ≈ 0.8 rad/s at a
third of rated torque, 16 σ_g), yet a generator-speed sensor's offset or gain fault shows at its first tick as a
jump of one reading that the other does not make. The pair mean m moves by half the jump, and m one tick ahead is
predictable from its own past: p[k] = Σ_i w_i m[k−i], i = 1 … ``JUMP_HISTORY`` (the least-squares quadratic
through the last 8 means, extrapolated one tick). That prediction is a third opinion of its own, free of both
sensors' readings at tick k, with variance σ_p² = v_e − σ_g²/2, where v_e is the variance of e = m − p on rows
with nothing flagged or being isolated (learnt with time constant ``JUMP_MEMORY_S``, never below the white-noise
value (σ_g²/2)(1 + Σw_i²), started at ``JUMP_START_SCALE`` times it). So at the onset tick k

    ℓ_J = δ[k] (m[k] − p[k]) / s_J²,   s_J² = σ_p² + σ_g² = v_e + σ_g²/2,

the same log-likelihood ratio with the prediction as ω₃: an offset b gives b²/(2 s_J²) in that one tick (8σ_g
≈ 0.4 rad/s: about 13 at 9 m/s, where v_e ≈ 0.0036 rad²/s², and 10 near rated, where the torsion mode makes
v_e ≈ 0.0053; h = 6.9). The onset is taken, when an isolation starts, as the parity's change point among the last
``JUMP_LOOKBACK`` ticks (the window test may detect a few ticks late): the split of δ's last W + J ticks into
before and after with the largest standardised difference of means. δ carries η_g1 − η_g2 and e carries
η_g1 + η_g2, which are independent for sensors of equal noise, so choosing the tick by the parity does not bias
ℓ_J. Only that tick's ℓ_J is used, once, added to both sums when the isolation starts: a
prediction made after the onset extrapolates the jump itself and would point the wrong way. A slow drift makes no
jump, and ℓ_J is then small and the sums decide as before. Rows with a generator-speed sensor flagged take no ℓ_J
(the parity then carries the flagged sensor's fault).
"""

from __future__ import annotations

import math

import numpy as np

from service.turbine.bank import POWER_SPEED, BankDesign
from wwcore.quantiles import norm_isf

JUMP_HISTORY = 8  # W: ticks of the pair mean the onset prediction is fitted to
JUMP_LOOKBACK = 8  # J: ticks before an isolation's start searched for the fault's onset
JUMP_MEMORY_S = 5.0  # time constant of the learnt variance of the pair mean's prediction error, s
JUMP_START_SCALE = 4.0  # that variance before anything is learnt, × its white-noise value


def jump_weights(history: int = JUMP_HISTORY) -> np.ndarray:
    """w (history,): p[k] = w @ m[k−history … k−1], the least-squares quadratic through the last ``history``
    values extrapolated one tick (oldest first)."""
    t = np.arange(-history, 0, dtype=float)
    V = np.vander(t, 3)
    return np.array([0.0, 0.0, 1.0]) @ np.linalg.pinv(V)


def _variance_of(R: np.ndarray, i: int) -> float:
    return float(R[i, i])


class GeneratorArbiter:
    """The running log-likelihood ratio ``total`` (n,): > 0 favours ω_g,m1 faulty, < 0 ω_g,m2."""

    def __init__(self, bank: BankDesign, n: int, alpha: float, dt: float = 0.01):
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
        # variance of e = m − p on white sensor noise alone (σ_g²/2 (1 + Σw²)): the floor of the learnt one
        self.jump_floor = 0.5 * self.generator_variance * (1.0 + float(self.weights @ self.weights))
        self.jump_variance = np.full(n, JUMP_START_SCALE * self.jump_floor)  # v_e, rad²/s²
        self._jump_rate = dt / JUMP_MEMORY_S
        span = JUMP_HISTORY + JUMP_LOOKBACK
        self._means = np.zeros((n, span))  # the pair mean of the last ``span`` ticks, oldest first
        self._parities = np.zeros((n, span))  # δ of the same ticks
        self._seen = 0  # ticks observed (the histories are full once it reaches ``span``)
        self.jump = np.zeros(n)  # ℓ_J added at the last reset of each row (0: none)
        self.parity = np.zeros(n)  # Σ (y_r1 − y_r2) since the isolation started, rad/s
        self.count = np.zeros(n)  # ticks summed

    def reset(self, rows: np.ndarray, jump: np.ndarray | None = None) -> None:
        """Start the sums of ``rows`` ((n,) bool) afresh, from ℓ_J of the fault's onset on the rows of ``jump``
        ((n,) bool; None: none) once the histories are full (module docstring)."""
        self.total[rows] = 0.0
        self.total_power[rows] = 0.0
        self.parity[rows] = 0.0
        self.count[rows] = 0.0
        self.jump[rows] = 0.0
        if jump is None or self._seen < self._means.shape[1]:
            return
        take = np.flatnonzero(rows & jump)
        if len(take) == 0:
            return
        self.jump[take] = ell = self.onset_ratio(take)
        self.total[take] += ell
        self.total_power[take] += ell

    def onset_ratio(self, rows: np.ndarray) -> np.ndarray:
        """ℓ_J of ``rows`` (indices): at the tick of the parity's largest step among the last J, δ (m − p) / s_J²."""
        W, J = JUMP_HISTORY, JUMP_LOOKBACK
        means, parities = self._means[rows], self._parities[rows]
        # the parity's change point among the last J ticks: the split into "before" (≥ W ticks) and "from the
        # onset on" with the largest standardised difference of means, √(a b / (a + b)) |mean_after − mean_before|
        span = W + J
        before = np.arange(W, span)  # ticks before each candidate onset (candidate i: tick W + i of the history)
        after = span - before
        cumulative = np.cumsum(parities, axis=1)
        total = cumulative[:, -1:]
        head = cumulative[:, before - 1]
        score = np.sqrt(before * after / span) * np.abs((total - head) / after - head / before)
        onset = score.argmax(axis=1)  # 0 … J − 1: the onset is tick W + onset of the histories
        index = onset[:, None] + np.arange(W + 1)  # the W means before the onset, and the onset's
        window = np.take_along_axis(means, index, axis=1)
        error = window[:, W] - window[:, :W] @ self.weights
        delta = parities[np.arange(len(rows)), W + onset]
        return delta * error / (self.jump_variance[rows] + 0.5 * self.generator_variance)

    def observe(self, y: np.ndarray, learn: np.ndarray) -> None:
        """Push this tick's pair mean and parity (y (n, 4) calibrated speed readings) into the histories, and
        learn v_e on the rows of ``learn`` ((n,) bool: nothing flagged or being isolated)."""
        middle = 0.5 * (y[:, 2] + y[:, 3])
        if self._seen >= JUMP_HISTORY:
            error = middle - self._means[:, -JUMP_HISTORY:] @ self.weights
            update = self._jump_rate * (error * error - self.jump_variance)
            self.jump_variance += np.where(learn, update, 0.0)
            np.maximum(self.jump_variance, self.jump_floor, out=self.jump_variance)
        self._means[:, :-1] = self._means[:, 1:]
        self._means[:, -1] = middle
        self._parities[:, :-1] = self._parities[:, 1:]
        self._parities[:, -1] = y[:, 2] - y[:, 3]
        self._seen += 1

    @property
    def rotor_disagree(self) -> np.ndarray:
        """(n,) bool: the rotor-speed sensors' summed difference is beyond the isolation level (module docstring)."""
        return np.abs(self.parity) > self.parity_level * self.parity_sigma * np.sqrt(np.maximum(self.count, 1.0))

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
