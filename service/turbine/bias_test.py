"""A persistent bias on one rotor-speed sensor: Page's CUSUMs (a bank of shifts) on the two rotor-speed sensors'
parity, beside the window tests.

The bank's window tests (``fdi``) see a rotor-speed bias only as the UIOs' states drift from it over a few ticks,
and a UIO takes much of a small bias for aerodynamic torque: a gain error g on ω_r,m is a bias g·ω_r, 1–2 σ for
g = 3 % (σ_r = 0.0251 rad/s, ω_r = 0.9–1.8 rad/s), which those tests find late, or not at all below rated.
The generator-speed sensors see the same shaft through the gearbox: the Kalman filter on them alone (observer 5
of the bank, ``bank.estimate_observers``) predicts what a healthy rotor-speed sensor reads, and its prediction
never uses either rotor-speed sensor. The exclusion residual of rotor-speed sensor s (``clearing``) is

    e_s[n] = (y_s[n] − x̂_5,ω_r[n]) / σ_e,s = η_s[n]/σ_e,s − ε[n]/σ_e,s,

the sensor's own noise η_s (white, σ_r) less the prediction error ε, which is the *same* for both sensors.

**What the healthy residual is** (measured: docs/turbine.md, "A persistent rotor-speed bias"). Over 8 runs of
360 s at each of ten mean winds from 4 to 25 m/s (Kaimal turbulence 12 %), on the design plant e_s is white
N(0, 1) at 4–10 m/s and 16–25 m/s (autocorrelation at lags 1–20 below 0.005 in size from 4 to 8 and from 16 m/s
up, below 0.05 at 10 m/s; variance 0.99–1.06), but not near rated: at 11.5 and 13 m/s its variance is 2.7–3.2
and its autocorrelation oscillates with the drive train's torsion mode (ρ₁ = 0.44 and 0.27, ρ₁₀ = −0.40 and
−0.25). All of that excess is common to the two sensors: Cov(e_1, e_2) = 1.67 and 2.18 there (below 0.07
elsewhere), while the parity (e_1 − e_2)/√2 has variance 0.996–1.002 and autocorrelation below 0.005 in size at
every wind. The generator-side prediction is worse than the design model says where the controller hands over
between torque and pitch and excites the lightly damped mode (0.19 % in the design model); on the
``ftwse-2012-mismatch`` plant, whose drive train is damped at 1 %, e_s is white at every wind (variance 0.96–1.04,
Cov(e_1, e_2) ≤ 0.005, the parity's variance 0.990–0.999). The earlier CUSUM on e_s, whose threshold assumed it
white N(0, 1), raised its false alarms near rated (3.9 per 1000 s on ``turbine-fault-free``).

**The test.** A bias b = μ σ_e on sensor 1 moves the parity

    d[n] = (e_1[n] − e_2[n]) / (√2 ŝ[n])

by +μ/√2 (on sensor 2 by −μ/√2), and the common prediction error cancels in it exactly, at every wind and with
any colour: d is the difference of two independent white sensor noises, N(0, σ_r²/σ_e²) ≤ N(0, 1) on the design
noise. ŝ² (``adaptive.HealthySpread``, over ``adapt_time_s``) is the healthy mean of d² while the row is tested
and the statistics are below h, clipped to [1, ``max_noise_scale``²]: sensors noisier than their data sheet scale
d back to unit variance, and since d carries no model error the estimate does not depend on the wind. Page's
two-sided CUSUMs for a bank of K shifts ±m_d,k, m_d,k = m_k/√2 with m_k = m·2^k (k = 0 … K − 1; m =
``bias_shift``, the smallest bias designed for, in σ_e of one sensor's bias; K = ``bias_bank``)::

    S⁺_k = max(0, S⁺_k + m_d,k (d − m_d,k/2)),   S⁻_k = max(0, S⁻_k + m_d,k (−d − m_d,k/2))

each the log-likelihood ratio of N(±m_d,k, 1) against N(0, 1) on a white residual, so each one-sided test's mean
run length before a false alarm is at least e^h ticks (Lorden): h = ln(2K/α), α = rate·Ts/1000 from the
false-alarm budget shared by the 2K one-sided tests of a row (h = 17.9 for K = 3 at 0.01 per 1000 s and 100 Hz;
16.8 for the single CUSUM). A bias of μ σ_e is detected after about min_k h / (m_d,k (μ/√2 − m_d,k/2)) =
min_k 2h / (m_k (μ − m_k/2)) ticks; a bias below m/2 = 0.75 σ_e never is.

*Why a bank.* The delay of the optimal test for a known bias μ (Lorden's bound, h₀ / KL per tick with the
parity's KL = μ²/4 and h₀ = ln(2/α)) is 4h₀/μ² ticks. One CUSUM tuned to m = 1.5 meets it at μ = m and wastes time
on larger biases: 2h₀/(m(μ − m/2)) is 1.33 × the bound at μ = 3, 1.96 × at μ = 5 (a rotor-speed gain of 5–10 % at
rated speed is 3.4–6.8 σ_e). With shifts an octave apart the best of the bank is within max x²/(2x − 1) = 1.125
(x = μ/m_k = 1.5, where two neighbours tie) of the bound times h/h₀ from μ = m to 1.5 m_K: 1.2 × the bound at
worst for K = 3, against the single CUSUM's 2.0 at μ = 5; at the bank's bottom the larger h costs a little,
2h/(m(μ − m/2)) at μ = 1.1 is 68 ticks instead of 64. The parity gives up half of the single residual's
information per tick (its delay is twice the test on one residual's at the same limit) for a false-alarm bound
that holds on the residual as it is.

**Which sensor.** S⁺ rises for sensor 1 reading high or sensor 2 reading low; S⁻ for the reverse. The sum
e_1 + e_2 tells them apart: a bias μ on sensor 1 moves it by +μ, on sensor 2 by −μ. Over the ticks since the
statistic left zero (its run), A = Σ (e_1 + e_2); at a raise the largest statistic of the bank decides (of the
sign raised, or of both where both are), and S⁺ names sensor 1 if its A > 0 and sensor 2 otherwise, S⁻ sensor 1
if its A < 0. The common prediction error enters A twice (2 Σ ε/σ_e), so near rated
a small bias can be named wrongly; the window tests and the clearing then see the flagged sensor consistent and
the other not.

**Hysteresis.** A flag dropped by the clearing (``clearing``: its CUSUM clears a fault smaller than μ_floor/2,
0.5 σ with the default floor of 1) is not raised again by this test for a fault under m/2 = 0.75 σ_e, and a flag
this test raised is not dropped by the clearing for a fault above 0.5 σ_e: between the two a fault's flag stays as
it is, raised or not, instead of flapping.

**Common shifts.** A shift of both rotor-speed sensors' residuals alike (a generator-speed fault, which moves the
prediction, or a model error) does not move d: it is not a rotor-speed sensor fault and is never flagged here.

**Beside a generator-speed flag.** The test runs on rows where no rotor-speed sensor is flagged and no isolation
is under way. Where a generator-speed sensor is flagged, the prediction for the isolation sum comes from the
observer that leaves it out with both rotor-speed sensors (the Kalman filter on the other generator-speed sensor
alone), so the rotor-speed half of a double fault is flagged beside the generator-speed half; a row whose
predictor changes starts from zero.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from service.turbine.adaptive import HealthySpread
from wwcore.planes import Planes, planes

ROTOR = (0, 1)  # columns of the rotor-speed sensors in SPEED_SENSORS order
SIGNS = 2  # the parity's two signs: with the bank's shifts, they share the row's false-alarm budget


class RotorBiasTest(Planes):
    """S⁺ and S⁻ (n, K) of the rotor-speed parity of n turbines for the bank's K shifts, and the isolation sums A⁺,
    A⁻ over each statistic's run (module docstring).

    ``column`` (m, 2): where observer j's predicted rotor speed sits in the bank's stacked x̂ for each rotor-speed
    sensor; ``scale`` (m, 2): 1/σ_e,s of that prediction (rad/s⁻¹; NaN where j uses the sensor); ``dt`` (s);
    ``rate_per_1000s``: the false-alarm budget; ``shift``: m, the smallest bias designed for in σ_e of one sensor;
    ``bank``: K, the shifts m·2^k (k < K; 1: the single CUSUM);
    ``adapt_time_s``, ``max_noise_scale``: the parity's healthy spread ŝ (``adaptive``; adapt_time_s = 0: ŝ = 1).
    ``fast``: ``service.turbine.fast`` (``wwcore.backend``) or None; with it, ``step_flags`` is one kernel
    (``rotor_bias``, the same operations).
    """

    PLANES: ClassVar[dict[str, tuple]] = {"sums": ("up", "down", "run_up", "run_down")}

    def __init__(
        self,
        n: int,
        column: np.ndarray,
        scale: np.ndarray,
        dt: float,
        rate_per_1000s: float,
        shift: float,
        adapt_time_s: float = 0.0,
        max_noise_scale: float = 1.0,
        fast=None,
        bank: int = 1,
    ):
        if bank < 1:
            raise ValueError(f"the bank must hold at least one shift, not {bank}")
        if shift <= 0.0:
            raise ValueError(f"the shift must be positive, not {shift}")
        if rate_per_1000s <= 0.0:
            raise ValueError(f"the false-alarm rate must be positive, not {rate_per_1000s}")
        self.column = np.atleast_2d(np.asarray(column, dtype=np.int64))
        self.scale = np.atleast_2d(np.asarray(scale, dtype=float))
        if self.column.shape != self.scale.shape or self.scale.shape[1] != len(ROTOR):
            raise ValueError(f"column and scale must both be (m, 2), not {self.column.shape} and {self.scale.shape}")
        self.shift = float(shift)
        self.shifts = self.shift * 2.0 ** np.arange(bank)  # m_k, in σ_e of one sensor
        self.parity_shifts = self.shifts / math.sqrt(2.0)  # m_d,k: the parity's mean under a bias of m_k on one sensor
        self.parity_shift = float(self.parity_shifts[0])
        self.h = math.log(SIGNS * bank * 1000.0 / (rate_per_1000s * dt))
        # S⁺, S⁻ and A⁺, A⁻ (Σ (e_1 + e_2) over the current run of each S⁺, S⁻), (n, K) each: the planes of one
        # block (``wwcore.planes``), which the compiled step takes
        self.sums = np.zeros((len(self.PLANES["sums"]), n, bank))
        self.__dict__.update(planes(self.sums, self.PLANES["sums"]))
        self.spread = HealthySpread((n,), dt, adapt_time_s, max_noise_scale)
        self.predictor = np.full(n, -1, dtype=np.int64)  # the observer each row's statistics were summed against
        self._fast = fast

    def usable(self, j: int) -> bool:
        """Whether observer j predicts both rotor-speed sensors without using them."""
        return bool(np.isfinite(self.scale[j]).all() and (self.scale[j] > 0.0).all())

    def step_flags(
        self, y: np.ndarray, x_hat: np.ndarray, flagged: np.ndarray, deadline: np.ndarray, predictor_of_mask: np.ndarray
    ) -> np.ndarray | None:
        """``step`` against the predictor ``predictor_of_mask`` (2⁴,) gives each row's ``flagged`` bitmask (n,), −1
        (not tested) where an isolation is pending (``deadline`` ≥ 0). Returns ``step``'s (n, 2) bool, or None when
        no bias is detected on any row."""
        if self._fast is None:
            over = self.step(y, x_hat, np.where(deadline < 0, predictor_of_mask[flagged], -1))
            return over if over.any() else None
        s = self.spread
        over = np.empty((len(flagged), len(ROTOR)), dtype=bool)
        raised = self._fast.rotor_bias(
            y,
            x_hat,
            flagged,
            deadline,
            predictor_of_mask,
            self.column,
            self.scale,
            (self.parity_shifts, self.h),
            (self.sums, self.predictor),
            (s.enabled, s.min_weight, s.max_scale2, s.state),
            over,
        )
        return over if raised else None

    def step(self, y: np.ndarray, x_hat: np.ndarray, predictor: np.ndarray) -> np.ndarray:
        """Advance the statistics of every row against its ``predictor`` (n,) observer (−1: the row is not tested
        and its statistics start from zero; a row whose predictor changes starts from zero too). y (n, 4) the
        calibrated speed readings (rad/s), x_hat the bank's stacked x̂. Returns (n, 2) bool: the rotor-speed sensor
        whose bias is detected, at most one per row."""
        changed = predictor != self.predictor
        self.predictor = predictor.copy()
        active = predictor >= 0
        if changed.any():
            self.reset(changed)
        over = np.zeros((len(predictor), len(ROTOR)), dtype=bool)
        if not active.any():
            return over
        j = np.where(active, predictor, 0)
        scale = np.where(active[:, None], self.scale[j], 0.0)
        predicted = np.take_along_axis(x_hat, self.column[j], axis=1)
        e = (y[:, list(ROTOR)] - predicted) * scale
        raw = (e[:, 0] - e[:, 1]) / math.sqrt(2.0)
        d = raw / self.spread.scale
        total = e[:, 0] + e[:, 1]
        m = self.parity_shifts
        tested = active[:, None]
        up = np.where(tested, np.maximum(0.0, self.up + m * (d[:, None] - 0.5 * m)), 0.0)
        down = np.where(tested, np.maximum(0.0, self.down + m * (-d[:, None] - 0.5 * m)), 0.0)
        self.run_up = np.where(up > 0.0, self.run_up + total[:, None], 0.0)
        self.run_down = np.where(down > 0.0, self.run_down + total[:, None], 0.0)
        self.up, self.down = up, down
        raised_up, raised_down = (up >= self.h).any(axis=1), (down >= self.h).any(axis=1)
        self.spread.update(raw**2, active & ~raised_up & ~raised_down)
        if not (raised_up.any() or raised_down.any()):
            return over
        # of each sign the largest statistic of the bank (the shift nearest the bias), and of the two signs, which
        # cannot both be right on one tick, the larger: its run's sum names the sensor
        rows = np.arange(len(predictor))
        best_up, best_down = up.argmax(axis=1), down.argmax(axis=1)
        top_up, top_down = up[rows, best_up], down[rows, best_down]
        use_up = raised_up & (~raised_down | (top_up >= top_down))
        use_down = raised_down & ~use_up
        first = (use_up & (self.run_up[rows, best_up] > 0.0)) | (use_down & (self.run_down[rows, best_down] < 0.0))
        over[:, 0] = first
        over[:, 1] = (use_up | use_down) & ~first
        return over

    def reset(self, rows: np.ndarray) -> None:
        """Forget the statistics of ``rows`` (n,) bool (the healthy spread ŝ is kept: it is the sensors')."""
        self.up[rows] = 0.0
        self.down[rows] = 0.0
        self.run_up[rows] = 0.0
        self.run_down[rows] = 0.0
