"""A persistent bias on one rotor-speed sensor: Page's CUSUM on its exclusion residual, beside the window tests.

The bank's window tests (``fdi``) see a rotor-speed bias only as the UIOs' states drift from it over a few ticks,
and a UIO takes much of a small bias for aerodynamic torque: a gain error g on ω_r,m is a bias g·ω_r, 1–2 σ for
g = 3 % (σ_r = 0.0251 rad/s, ω_r = 0.9–1.8 rad/s), which those tests find late, or not at all below rated.
The generator-speed sensors see the same shaft through the gearbox, 50 times less noisy once referred to the
rotor side: the Kalman filter on them alone (observer 5 of the bank, ``bank.estimate_observers``) predicts what a
healthy rotor-speed sensor reads, and its prediction never uses either rotor-speed sensor. The exclusion residual
of rotor-speed sensor s (``clearing``),

    e_s[n] = (y_s[n] − x̂_5,ω_r[n]) / σ_e,s,

is N(0, 1) over many ticks while s is healthy (σ_e,s from the residual's long-run variance) and N(μ, 1) under a
bias of μ σ_e. Page's two-sided CUSUM for a shift of ±m (``bias_shift``)::

    S⁺ = max(0, S⁺ + m (e − m/2)),   S⁻ = max(0, S⁻ + m (−e − m/2))

is the log-likelihood ratio of N(±m, 1) against N(0, 1), so its mean run length before a false alarm is at least
e^h ticks (Lorden): h = ln(4/α), α = rate·Ts/1000 from the false-alarm budget shared by the four one-sided tests of
a row (h = 17.5 for 0.01 per 1000 s at 100 Hz). A bias μ > m/2 is detected after about h / (m (μ − m/2)) ticks:
with m = 1.5, 0.31 s for μ = 1.1, 0.09 s for μ = 2; a bias below m/2 never is.

**Hysteresis.** A flag dropped by the clearing (``clearing``: its CUSUM clears a fault smaller than μ_floor/2,
0.5 σ with the default floor of 1) is not raised again by this test for a fault under m/2 = 0.75 σ, and a flag this
test raised is not dropped by the clearing for a fault above 0.5 σ: between the two a fault's flag stays as it is,
raised or not, instead of flapping.

**One sensor.** A shift of both rotor-speed sensors' residuals alike is not a rotor-speed sensor fault but a wrong
prediction (a generator-speed fault, which the window tests find first, or a model error); a sensor is flagged only
while the other's statistic of the same sign stays below h/2.

**Beside a generator-speed flag.** The test runs on rows where no rotor-speed sensor is flagged and no isolation
is under way. Where a generator-speed sensor is flagged, the prediction comes from the observer that leaves it out
with both rotor-speed sensors (the Kalman filter on the other generator-speed sensor alone, σ_e ≈ σ_r as well), so
the rotor-speed half of a double fault is flagged beside the generator-speed half instead of moving the flags
between explanations; a row whose predictor changes starts from zero.
"""

from __future__ import annotations

import math

import numpy as np

ROTOR = (0, 1)  # columns of the rotor-speed sensors in SPEED_SENSORS order
TESTS_PER_ROW = 4  # two sensors, two signs: they share the row's false-alarm budget


class RotorBiasTest:
    """S⁺ and S⁻ (n, 2) of the two rotor-speed sensors of n turbines (module docstring).

    ``column`` (m, 2): where observer j's predicted rotor speed sits in the bank's stacked x̂ for each rotor-speed
    sensor; ``scale`` (m, 2): 1/σ_e,s of that prediction (rad/s⁻¹; NaN where j uses the sensor); ``dt`` (s);
    ``rate_per_1000s``: the false-alarm budget; ``shift``: m, in σ_e.
    """

    def __init__(self, n: int, column: np.ndarray, scale: np.ndarray, dt: float, rate_per_1000s: float, shift: float):
        if shift <= 0.0:
            raise ValueError(f"the shift must be positive, not {shift}")
        self.column = np.atleast_2d(np.asarray(column, dtype=np.int64))
        self.scale = np.atleast_2d(np.asarray(scale, dtype=float))
        if self.column.shape != self.scale.shape or self.scale.shape[1] != len(ROTOR):
            raise ValueError(f"column and scale must both be (m, 2), not {self.column.shape} and {self.scale.shape}")
        self.shift = float(shift)
        self.h = math.log(TESTS_PER_ROW * 1000.0 / (rate_per_1000s * dt))
        self.up = np.zeros((n, len(ROTOR)))
        self.down = np.zeros((n, len(ROTOR)))
        self.predictor = np.full(n, -1, dtype=np.int64)  # the observer each row's statistics were summed against

    def usable(self, j: int) -> bool:
        """Whether observer j predicts both rotor-speed sensors without using them."""
        return bool(np.isfinite(self.scale[j]).all() and (self.scale[j] > 0.0).all())

    def step(
        self, y: np.ndarray, x_hat: np.ndarray, predictor: np.ndarray, noise: np.ndarray | None = None
    ) -> np.ndarray:
        """Advance the statistics of every row against its ``predictor`` (n,) observer (−1: the row is not tested
        and its statistics start from zero; a row whose predictor changes starts from zero too). y (n, 4) the
        calibrated speed readings (rad/s), x_hat the bank's stacked x̂, noise (n,) the rows' healthy noise scale
        (``adaptive``; None: 1). Returns (n, 2) bool: the rotor-speed sensor whose bias is detected, at most one
        per row."""
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
        if noise is not None:
            e = e / noise[:, None]
        m = self.shift
        quiet = active[:, None]
        np.copyto(self.up, np.where(quiet, np.maximum(0.0, self.up + m * (e - 0.5 * m)), 0.0))
        np.copyto(self.down, np.where(quiet, np.maximum(0.0, self.down + m * (-e - 0.5 * m)), 0.0))
        half = 0.5 * self.h
        over = ((self.up >= self.h) & (self.up[:, ::-1] < half)) | ((self.down >= self.h) & (self.down[:, ::-1] < half))
        both = over.all(axis=1)
        if both.any():  # both sensors, opposite signs, on one tick: the larger statistic names the sensor
            larger = np.maximum(self.up, self.down)[both]
            over[both] = larger == larger.max(axis=1, keepdims=True)
            over[both, 1] &= ~over[both, 0]
        return over

    def reset(self, rows: np.ndarray) -> None:
        """Forget the statistics of ``rows`` (n,) bool."""
        self.up[rows] = 0.0
        self.down[rows] = 0.0
