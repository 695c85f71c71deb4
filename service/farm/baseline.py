r"""Each turbine's own healthy level and spread of a residual, learnt online: what makes the ``analytic`` detector
robust to a plant that differs from its design model (``docs/farm.md`` §1.7, ``docs/decisions.md``).

A real turbine's residuals are not those of the design model. A pitch encoder calibrated 0.1 deg off moves
z_2 = β̄_i − ½ Σ_{j≠i} β̄_j by a constant as large as 0.4 deg at the edge of its tolerance (the benchmark's plant also
turns the mean encoder error into a real misalignment of that size); a power transducer within its accuracy class
moves z_1 by up to 24 kW against a debris fault of 27–150 kW; sensors noisier than the data sheet widen every
residual. None of these is a fault: each is there from the first sample and stays. A fault is an *onset*: a change
of the residual's level, of the size the fault model gives, at some moment of the run. So each residual r_k
(any shape, one value per statistic) is judged against its own learnt level m_k and its own learnt spread:

**Level** (units of r). A running mean over the first ``n_learn`` samples, then an exponentially weighted mean
with time constant T_m (``level_time_s``):

.. math::  m_k = m_{k-1} + w_k (r_k - m_{k-1}),\qquad w_k = \max(1/k,\ Δt/T_m)

**Spread** (a ratio, –). The residual's design standard deviation σ_d,k (from the published sensor noise; it may
change with the operating point) gives the normalised deviation u_k = (r_k − m_k)/σ_d,k. Its long-run variance
(the spectral density at zero frequency, which governs a CUSUM's random walk) is estimated by batch means over
blocks of B samples (``BLOCK_SAMPLES``, 1 s): ū_b the mean of block b, B ū_b² an unbiased estimate of it for blocks
longer than the residual's correlation time. The estimate ρ_b = ρ_{b−1} + v_b (B ū_b² − ρ_{b−1}),
v_b = max(1/b, BΔt/T_s) (T_s = ``spread_time_s``), is bounded below by the design's 1 and above by
``max_ratio`` (the largest noise scale a healthy plant may have, squared):

.. math::  σ^2_{\mathrm{eff},k} = \min\bigl(\max(ρ_b, 1),\ ρ_{\max}\bigr)\, σ^2_{d,k}\,ρ_{d}

with ρ_d the design's own long-run over one-sample ratio folded into σ_d (the caller passes the long-run design
standard deviation). For white noise of standard deviation σ the estimate converges to (σ/σ_d)².

**Frozen** where ``frozen`` is true (the caller's flag is up, or its CUSUM has climbed half-way to its threshold):
a fault never teaches the detector its own level. A slow drift of the residual (time scale ≫ T_m) is learnt as
health; the paper's faults are abrupt.
"""

from __future__ import annotations

import math

import numpy as np

from service.learning import learning_weight
from wwcore.scenario.farm import FARM_DT_S

BLOCK_SAMPLES = 10  # samples per batch mean of the spread estimate (1 s at 10 Hz)


class LearntLevel:
    """Level m and spread ratio ρ of residuals of ``shape`` (n,) or (n, m) (module docstring); ``fast``: the
    compiled twin ``service.farm.fast`` or None."""

    def __init__(
        self,
        shape: tuple[int, ...],
        *,
        level_time_s: float,
        spread_time_s: float,
        max_ratio: float,
        block: int = BLOCK_SAMPLES,
        dt: float = FARM_DT_S,
        fast=None,
    ):
        if level_time_s <= 0.0 or spread_time_s <= 0.0 or max_ratio < 1.0 or block < 1:
            raise ValueError("time constants must be > 0 s, max_ratio ≥ 1 and blocks ≥ 1 sample")
        if len(shape) not in (1, 2):
            raise ValueError(f"learnt levels are of one or two dimensions (turbines, residuals), not {shape}")
        self.block = block
        self.max_ratio = max_ratio
        self.alpha_level = dt / level_time_s
        self.alpha_block = min(1.0, block * dt / spread_time_s)
        self.level = np.zeros(shape)
        self.samples = np.zeros(shape)  # samples learnt from
        self.raw_ratio = np.ones(shape)  # ρ before its bounds
        self.blocks = np.zeros(shape)  # whole blocks learnt from
        self._block_sum = np.zeros(shape)
        self._block_n = np.zeros(shape, dtype=np.int64)
        # ``service.farm.fast`` (``wwcore.backend``) or None; with it, ``update`` is one kernel on (n, m) views of
        # the state, updated in place (views taken at each call: a copied object keeps its own)
        self._fast = fast
        self._rows = (shape[0], shape[1] if len(shape) == 2 else 1)

    @property
    def ratio(self) -> np.ndarray:
        """ρ bounded to [1, max_ratio]: the learnt long-run variance over the design's."""
        return np.clip(self.raw_ratio, 1.0, self.max_ratio)

    def update(self, r: np.ndarray, design_std: np.ndarray | float, frozen: np.ndarray | bool = False) -> None:
        """Learn from residuals ``r`` whose design standard deviation is ``design_std``, except where ``frozen``.

        A frozen statistic also drops its unfinished block, so a block never spans a flag."""
        if self._fast is not None:  # the lines below by one kernel (``service.farm.fast.learn_level``)
            shape, f = self.level.shape, self._fast
            rows = (f.as_rows(r, shape), f.as_rows(design_std, shape).astype(float), f.as_rows(frozen, shape))
            arrays = (self.samples, self.level, self.raw_ratio, self.blocks, self._block_sum, self._block_n)
            state = tuple(a.reshape(self._rows) for a in arrays)
            f.learn_level(*rows, self.alpha_level, self.alpha_block, self.block, state)
            return
        live = ~np.broadcast_to(np.asarray(frozen, dtype=bool), self.level.shape)
        self.samples = self.samples + live
        w = learning_weight(self.samples, live, self.alpha_level)
        self.level = self.level + w * (r - self.level)
        u = (r - self.level) / design_std
        self._block_sum = np.where(live, self._block_sum + u, 0.0)
        self._block_n = np.where(live, self._block_n + 1, 0)
        full = self._block_n >= self.block
        if full.any():
            self.blocks = self.blocks + full
            mean = self._block_sum / self.block
            v = learning_weight(self.blocks, full, self.alpha_block)
            self.raw_ratio = self.raw_ratio + v * (self.block * mean * mean - self.raw_ratio)
            self._block_sum = np.where(full, 0.0, self._block_sum)
            self._block_n = np.where(full, 0, self._block_n)


class LearntRayleighScale:
    r"""The I/Q standard deviation s of a lock-in amplitude A learnt from its healthy samples.

    Without a tone, A = 2√(I² + Q²) with I, Q ~ N(0, s²) (the whitened amplitude of ``service.farm.signals``), so
    u = A²/(8 s²) ~ Exp(1) and E[A²] = 8 s². The estimate is the running (then exponentially weighted, time constant
    T_s) mean m of A²/8 over the samples learnt from. The caller withholds the samples whose A has climbed to a share
    k of the threshold h = 2s√(2 ln 1/p) (so a fault's onset never teaches the scale): that truncates u at
    c = k² ln(1/p), and the mean of the kept samples is s² g(c) with

    .. math::  g(c) = E[u \mid u < c] = 1 - \frac{c\,e^{-c}}{1 - e^{-c}}

    (0.925 for k = ½ and the 3 × 3's p = 1.1·10⁻⁷: s² learnt 7.5 % low, which makes a Rayleigh threshold exceeded
    3× as often as designed at that p). So s² = m/g(c) (``truncation`` = c; ``None`` for no truncation), and
    s_eff = clip(s, s_d, √ρ_max s_d) with s_d the design value; frozen where ``frozen``. A steady 3P tone of the
    turbine's own (a rotor that was always so) raises E[A²] and so the threshold, which is conservative: the Rice
    distribution of A with a tone is narrower than a Rayleigh of the same E[A²].
    """

    def __init__(
        self,
        n: int,
        design_s: float,
        *,
        spread_time_s: float,
        max_ratio: float,
        truncation: float | None = None,
        dt: float = FARM_DT_S,
    ):
        if truncation is not None and truncation <= 0.0:
            raise ValueError("the truncation of A²/(8s²) must be > 0")
        self.design_s = design_s
        self.max_ratio = max_ratio
        self.alpha = dt / spread_time_s
        self.kept_share = 1.0 if truncation is None else truncated_exponential_mean(truncation)
        self.mean_square = np.full(n, design_s * design_s * self.kept_share)  # (A²/8) of the kept samples, –²
        self.samples = np.zeros(n)

    @property
    def scale(self) -> np.ndarray:
        s = np.sqrt(self.mean_square / self.kept_share)
        return np.clip(s, self.design_s, self.design_s * np.sqrt(self.max_ratio))

    def update(self, amplitude: np.ndarray, frozen: np.ndarray | bool = False) -> None:
        live = ~np.broadcast_to(np.asarray(frozen, dtype=bool), self.mean_square.shape)
        self.samples = self.samples + live
        w = learning_weight(self.samples, live, self.alpha)
        self.mean_square = self.mean_square + w * (amplitude * amplitude / 8.0 - self.mean_square)


def truncated_exponential_mean(c: float) -> float:
    """g(c) = E[u | u < c] for u ~ Exp(1) (``LearntRayleighScale``)."""
    return 1.0 - c * math.exp(-c) / -math.expm1(-c)


class LearntRateGain:
    r"""The gain k of a residual on a regressor x (a rate), r ≈ k x, by exponentially weighted least squares.

    .. math::  S_{xx,k} = λ S_{xx,k-1} + x_k^2,\quad S_{xr,k} = λ S_{xr,k-1} + x_k r_k,\quad
               \hat k = \frac{S_{xr}}{S_{xx} + P_0},\qquad λ = 1 - Δt/T

    P_0 (``prior``, x² × samples) pulls k̂ towards 0 until the regressor has moved: k̂ is learnt only from samples
    where x is large enough to show it. Frozen where ``frozen``. Used for the pitch residual's part that follows the
    blades' rate through actuators of slightly different lag (``service.farm.analytic``): a constant
    misalignment is uncorrelated with the rate, so it stays in the residual while the lag differences leave it.
    """

    def __init__(self, shape: tuple[int, ...], *, time_s: float, prior: float, dt: float = FARM_DT_S):
        if time_s <= 0.0 or prior <= 0.0:
            raise ValueError("the time constant and the prior weight must be > 0")
        self.forget = 1.0 - dt / time_s
        self.prior = prior
        self.sxx = np.zeros(shape)
        self.sxr = np.zeros(shape)

    @property
    def gain(self) -> np.ndarray:
        return self.sxr / (self.sxx + self.prior)

    def update(self, r: np.ndarray, x: np.ndarray, frozen: np.ndarray | bool = False) -> None:
        live = ~np.broadcast_to(np.asarray(frozen, dtype=bool), self.sxx.shape)
        self.sxx = np.where(live, self.forget * self.sxx + x * x, self.sxx)
        self.sxr = np.where(live, self.forget * self.sxr + x * r, self.sxr)
