"""Upper-tail quantiles for thresholds, from scipy.special (scipy.stats costs ~0.7 s to import)."""

from __future__ import annotations

import numpy as np
from scipy.special import chdtri, ndtri


def chi2_isf(alpha: float | np.ndarray, dof: float | np.ndarray) -> np.ndarray:
    """x with P(χ²_dof > x) = alpha (scipy.stats.chi2.isf)."""
    return chdtri(dof, alpha)


def norm_isf(alpha: float | np.ndarray) -> np.ndarray:
    """z with P(N(0, 1) > z) = alpha (scipy.stats.norm.isf)."""
    return -ndtri(alpha)
