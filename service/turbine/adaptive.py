"""Adaptive thresholds: each residual's healthy spread and offset, estimated online while the turbine is healthy.

Every residual test of the turbine supervisor is designed for the benchmark's sensor noise and the design model.
A real plant differs: its sensors are noisier or quieter than their data sheet (``noise_scale``), each channel
carries a calibration bias within its tolerance, and the drive train and pitch actuators are not exactly the
design's (docs/turbine.md, "Model mismatch"). A fixed threshold then sees the extra spread and the bias as a fault
and the false alarms come back at every tick of a long run. Following the adaptive-threshold idea of the FDI
literature (Ding, *Model-based fault diagnosis techniques*, 2nd ed., §10–12: a threshold that follows the
residual's healthy level instead of a worst-case bound), each test estimates, from its own residual while nothing
is flagged or suspected, the two quantities the design got wrong:

* **Spread.** For a statistic q whose design mean is 1 per sample (χ²/rank of a whitened residual, the squared
  z-score of a scalar one), the variance scale ŝ² is an exponentially weighted mean of q::

      ŝ²[k] = ŝ²[k−1] + w[k] (q[k] − ŝ²[k−1]),   w[k] = max(1/c[k], Δt/T_a) while healthy, 0 otherwise

  with c[k] the number of healthy samples so far (the plain mean at first, so the estimate is usable after the
  warm-up) and T_a the adaptation time (``adapt_time_s``, s; Δt the time between samples). The threshold used
  is h · clip(ŝ², 1, s_max²): never below the design's (the design σ is a floor, a quieter sensor keeps its
  design threshold) and at most ``max_noise_scale``² times it. For white Gaussian noise of σ = s σ_design the
  estimate converges to s², so the test keeps its design false-alarm rate (tests/test_turbine_adaptive.py).
* **Offset.** For a residual x that a calibration bias moves (a parity of two sensors, a measured-minus-predicted
  torque), the offset b̂ is the same weighted mean of x, clipped to the calibration tolerance ±b_max the
  channels are allowed (``wwcore.scenario.mismatch.SENSOR_BIAS_TOLERANCE``), and x − b̂ is tested. A fault is
  abrupt against T_a (a whole T_a of a constant fault would move b̂ by 1 − e⁻¹ of it, and the update stops
  at the first flag), and no offset beyond the tolerance can be absorbed, so a fault larger than twice the
  tolerance is still seen whatever the estimate.

"Healthy" is decided by the test's owner: no flag of the family up on the row, no isolation pending, and the
test's own statistic below its threshold (a sample that trips the test never feeds the estimate). A slow drift
that stays below the threshold is absorbed up to the two bounds; that is the price of any adaptive threshold,
and the bounds are where it stops.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from service.learning import learning_weight
from wwcore.planes import Planes, planes

# the planes of ``HealthySpread.state``, the arrays ``fast.learn_spread`` updates in place
SPREAD_PLANES = ("count", "estimate", "scale2", "scale", "mean", "offset", "limit")


class HealthySpread(Planes):
    """ŝ² (and optionally b̂) of one residual statistic per element of ``shape`` (module docstring).

    ``sample_s``: time between updates (s); ``adapt_time_s`` T_a (0: no adaptation, ŝ² = 1 and b̂ = 0 always);
    ``max_scale``: s_max, the largest noise scale accepted; ``offset_limit``: b_max in the residual's unit
    (None: no offset is estimated), a scalar or an array broadcast to ``shape``. ``fast``:
    ``service.turbine.fast`` (``wwcore.backend``) or None; with it, each update of a one- or two-dimensional
    ``shape`` is one kernel (``learn_spread``, the same operations).
    """

    PLANES: ClassVar[dict[str, tuple]] = {"state": SPREAD_PLANES}

    def __init__(
        self,
        shape: tuple[int, ...],
        sample_s: float,
        adapt_time_s: float,
        max_scale: float,
        offset_limit: float | np.ndarray | None = None,
        fast=None,
    ):
        self._fast = fast if len(shape) in (1, 2) else None
        self.enabled = adapt_time_s > 0.0
        self.min_weight = min(1.0, sample_s / adapt_time_s) if self.enabled else 0.0
        self.max_scale2 = float(max_scale) ** 2
        # one block (7, *shape), its planes by name (``SPREAD_PLANES``, ``wwcore.planes``): count; raw ŝ², unclipped;
        # clip(ŝ², 1, s_max²), the factor on the thresholds of variance; √scale2, the factor on the thresholds of
        # z-scores; raw b̂, unclipped; clip(b̂, −b_max, b_max); b_max (zero where no offset is learnt: never read)
        self.state = np.zeros((len(SPREAD_PLANES), *shape))
        self.state[1:4] = 1.0
        if offset_limit is not None:
            self.state[6] = offset_limit
        self.__dict__.update(planes(self.state, SPREAD_PLANES))
        self.offset_limit = self.limit if offset_limit is not None else None

    def update(self, q: np.ndarray | None, healthy: np.ndarray, x: np.ndarray | None = None) -> None:
        """One sample: q the statistic of design mean 1 (with the offset already removed; None: learn the offset
        only), healthy (bool, same shape, or (n, 1): one flag per row) where the sample may be learnt from, x the raw
        residual for the offset (needs ``offset_limit``)."""
        if not self.enabled:
            return
        if self._fast is not None:
            x = x if self.offset_limit is not None else None
            state = self.state
            if self.count.ndim == 1:  # as a column: (7, n, 1), a view
                state = state.reshape(*state.shape, 1)
                q, x = (None if a is None else a.reshape(-1, 1) for a in (q, x))
                healthy = healthy.reshape(-1, 1)
            self._fast.learn_spread(q, x, healthy, self.min_weight, self.max_scale2, state)
            return
        if not healthy.any():
            return
        self.count += healthy
        weight = learning_weight(self.count, healthy, self.min_weight)
        if q is not None:
            self.estimate += weight * (q - self.estimate)
            np.clip(self.estimate, 1.0, self.max_scale2, out=self.scale2)
            np.sqrt(self.scale2, out=self.scale)
        if x is not None and self.offset_limit is not None:
            self.mean += weight * (x - self.mean)
            np.clip(self.mean, -self.offset_limit, self.offset_limit, out=self.offset)

    def update_rows(self, q: np.ndarray | None, healthy: np.ndarray, x: np.ndarray | None = None) -> None:
        """``update`` with one healthy flag per row (n,) for every element of the row (a two-dimensional
        ``shape``)."""
        self.update(q, healthy[:, None], x)
