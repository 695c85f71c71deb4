"""The weight of one healthy sample in an online estimate: the plain mean first, then an exponential memory.

Both the turbine's adaptive thresholds (``service.turbine.adaptive``) and the farm detector's learnt levels
(``service.farm.baseline``) update an estimate m by m ← m + w (x − m) with

    w = max(1/c, Δt/T) where the sample is learnt from, 0 elsewhere,

c the number of samples learnt from so far (this one included) and T the estimate's time constant: the running
mean of the first T/Δt samples, then an exponentially weighted mean of time constant T.
"""

from __future__ import annotations

import numpy as np


def learning_weight(count: np.ndarray, live: np.ndarray, floor: float) -> np.ndarray:
    """w = max(1/count, ``floor``) where ``live``, 0 elsewhere (``floor`` = Δt/T; count < 1 counts as 1)."""
    return np.where(live, np.maximum(1.0 / np.maximum(count, 1.0), floor), 0.0)
