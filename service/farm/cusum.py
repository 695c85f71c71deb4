r"""CUSUM tests and decision rules of the farm detectors, vectorised over any number of statistics.

**The paper's test** (seed 001, eqs. (6)–(7), (9)–(10), (15)–(16)): for a Gaussian residual r with in-control mean
μ_0, out-of-control mean μ_1 and variance σ²,

.. math::

    S[j] = \sum_{k=1}^{j} \frac{μ_1[k] - μ_0}{σ^2}\Bigl(r[k] - \frac{μ_0 + μ_1[k]}{2}\Bigr),\qquad
    g[k] = S[k] - \min_{1 \le j \le k} S[j]

(the minimum includes k itself, so g[1] = 0 and g ≥ 0). The decision rule (17) as we read it (decision D-17 in
``docs/farm.md``): the paper lists "1 if g ≥ h_1" and "0 if g ≤ h_1" and then a third case that only makes sense as
a hysteresis, so a flag rises when g ≥ h_1 and, once up, falls only when g has dropped h_0 below its maximum since
the flag rose:

.. code-block:: text

    f[k] = 1                 if f[k−1] = 0 and g[k] ≥ h_1
    f[k] = 0                 if f[k−1] = 1 and max_{j ≤ k} g[j] − g[k] ≥ h_0
    f[k] = f[k−1]            otherwise

and when f falls, S, its minimum and the maximum of g are reset ("reset when f changes from 1 to 0").

**The log-likelihood-ratio CUSUM** of the analytic-redundancy detector: the same increments s_k are the log-
likelihood ratio of N(μ_1, σ²) against N(μ_0, σ²), so g_k = max(0, g_{k−1} + s_k) is Page's CUSUM, whose mean time
between false alarms is at least e^h samples (Lorden 1971). That bound is how its thresholds follow from a false-
alarm budget (``threshold_for``). Once a flag is up, the reverse CUSUM q_k = max(0, q_{k−1} − s_k) decides that the
fault has gone (q ≥ h_end); g restarts from 0.
"""

from __future__ import annotations

import math

import numpy as np


def llr_increment(r: np.ndarray, mu0: np.ndarray | float, mu1: np.ndarray | float, var: np.ndarray | float):
    """s = (μ_1 − μ_0)/σ² · (r − (μ_0 + μ_1)/2): the eq. (7) increment, the LLR of a Gaussian mean shift."""
    return (mu1 - mu0) / var * (r - 0.5 * (mu0 + mu1))


def threshold_for(mean_samples_between_false_alarms: float) -> float:
    """h = ln(ARL_0): Page's CUSUM of log-likelihood ratios then alarms falsely at most once per ARL_0 samples."""
    return math.log(mean_samples_between_false_alarms)


class PaperCusum:
    """g of eq. (6) with the decision rule (17), for statistics of any shape."""

    def __init__(self, shape: tuple[int, ...], h1: float, h0: float):
        self.h1, self.h0 = h1, h0
        self.S = np.zeros(shape)
        self.S_min = np.full(shape, np.inf)
        self.g = np.zeros(shape)
        self.g_max = np.full(shape, -np.inf)
        self.flag = np.zeros(shape, dtype=bool)

    def step(self, increment: np.ndarray, active: np.ndarray | None = None) -> np.ndarray:
        """Add one increment per statistic; statistics not ``active`` are held at zero and never flag."""
        if active is not None:
            increment = np.where(active, increment, 0.0)
        self.S = self.S + increment
        self.S_min = np.minimum(self.S_min, self.S)
        self.g = self.S - self.S_min
        self.g_max = np.maximum(self.g_max, self.g)
        rise = ~self.flag & (self.g >= self.h1)
        fall = self.flag & (self.g_max - self.g >= self.h0)
        if active is not None:
            rise &= active
            fall |= self.flag & ~active
        self.flag = (self.flag | rise) & ~fall
        if fall.any():  # "the maximum, minimum, and the running sum are all reset"
            self.S = np.where(fall, 0.0, self.S)
            self.S_min = np.where(fall, np.inf, self.S_min)
            self.g_max = np.where(fall, -np.inf, self.g_max)
        if active is not None:
            self.S = np.where(active, self.S, 0.0)
            self.S_min = np.where(active, self.S_min, np.inf)
            self.g = np.where(active, self.g, 0.0)
        return self.flag


class PageCusum:
    """Page's CUSUM of LLR increments with a reverse CUSUM for the fault's end (module docstring)."""

    def __init__(self, shape: tuple[int, ...], h: float | np.ndarray, h_end: float | np.ndarray):
        self.h, self.h_end = h, h_end
        self.g = np.zeros(shape)
        self.q = np.zeros(shape)
        self.flag = np.zeros(shape, dtype=bool)

    def step(self, llr: np.ndarray) -> np.ndarray:
        self.g = np.maximum(self.g + llr, 0.0)
        self.q = np.where(self.flag, np.maximum(self.q - llr, 0.0), 0.0)
        rise = ~self.flag & (self.g >= self.h)
        fall = self.flag & (self.q >= self.h_end)
        self.flag = (self.flag | rise) & ~fall
        self.g = np.where(fall, 0.0, self.g)
        self.q = np.where(fall, 0.0, self.q)
        return self.flag
