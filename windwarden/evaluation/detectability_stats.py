"""Where a detectability curve reaches 50 % and 95 %, and how sure the runs make us (``detectability.sweep``).

* ``fit_probit``: P(s) = Φ((ln s − μ)/σ) fitted to counts k of n at sizes s by maximum likelihood;
* ``threshold_sizes``: the fitted sizes at 50 % and 95 % with a 95 % interval from refitting on layouts
  resampled with replacement (layouts, not runs, are the independent draws of fault time and wind), and where the
  measured curve first reaches each level (``crossing``: the bracketing grid sizes, interpolated in ln s);
* ``clopper_pearson``: the exact binomial 95 % interval of one measured k of n (40 of 40 means ≥ 91.2 %).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy import optimize, special, stats

LEVELS = (0.5, 0.95)
BOOTSTRAP = 400  # layout resamples for the intervals of the fitted sizes


def clopper_pearson(k: int, n: int) -> tuple[float, float]:
    """95 % interval of a proportion from k of n (exact binomial)."""
    if n == 0:
        return 0.0, 1.0
    ci = stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="exact")
    return float(ci.low), float(ci.high)


def fit_probit(sizes: np.ndarray, k: np.ndarray, n: np.ndarray) -> tuple[float, float] | None:
    """(μ, σ) of P(s) = Φ((ln s − μ)/σ) by maximum likelihood on counts k of n at sizes; None without both
    detected and missed windows (no curve is identified). σ is kept in [0.005, 20] (a step between two grid
    sizes has no finite maximum)."""
    if k.sum() == 0 or k.sum() == n.sum():
        return None
    x = np.log(sizes)

    def nll(theta: np.ndarray) -> tuple[float, np.ndarray]:
        sigma = math.exp(theta[1])
        z = (x - theta[0]) / sigma
        log_p, log_q = special.log_ndtr(z), special.log_ndtr(-z)
        log_phi = -0.5 * z * z - 0.5 * math.log(2.0 * math.pi)
        # d/dz of k log Φ(z) + (n − k) log Φ(−z)
        dz = k * np.exp(log_phi - log_p) - (n - k) * np.exp(log_phi - log_q)
        grad = np.array([np.sum(dz) / sigma, np.sum(dz * z)])
        return -float(np.sum(k * log_p + (n - k) * log_q)), grad

    p = k / np.maximum(n, 1)
    start = float(x[np.argmin(np.abs(p - 0.5))])
    best = None
    for log_sigma in (-1.0, 0.5):
        res = optimize.minimize(
            nll,
            np.array([start, log_sigma]),
            jac=True,
            method="L-BFGS-B",
            bounds=[(x.min() - 5.0, x.max() + 5.0), (math.log(0.005), math.log(20.0))],
        )
        if best is None or res.fun < best.fun:
            best = res
    assert best is not None
    return float(best.x[0]), float(math.exp(best.x[1]))


def probit_size(fit: tuple[float, float], level: float) -> float:
    mu, sigma = fit
    return math.exp(mu + sigma * stats.norm.ppf(level))


def crossing(sizes: Sequence[float], pct: Sequence[float | None], level: float) -> dict[str, Any]:
    """Where the measured curve first reaches ``level``: the bracketing grid sizes and the size interpolated
    linearly in ln s between them; 'below' if the smallest size already does, 'above' if no size does."""
    target = 100.0 * level
    for i, p in enumerate(pct):
        if p is not None and p >= target:
            if i == 0:
                return {"status": "below", "bracket": [None, sizes[0]], "size": None}
            lo, hi = pct[i - 1] or 0.0, p
            f = (target - lo) / (hi - lo) if hi > lo else 1.0
            size = math.exp(math.log(sizes[i - 1]) + f * (math.log(sizes[i]) - math.log(sizes[i - 1])))
            return {"status": "inside", "bracket": [sizes[i - 1], sizes[i]], "size": size}
    return {"status": "above", "bracket": [sizes[-1], None], "size": None}


def threshold_sizes(
    records: Sequence[dict[str, Any]], sizes: Sequence[float], what: str, seed: int, bootstrap: int = BOOTSTRAP
) -> dict[str, Any]:
    """The sizes at which ``what`` (detected | isolated) reaches 50 % and 95 %: fitted (probit, module docstring)
    with a layout-bootstrap 95 % interval, and the measured crossing."""
    sizes_arr = np.asarray(sizes, dtype=float)
    by_layout = sorted({r["layout"] for r in records})
    k_l = np.zeros((len(by_layout), len(sizes)))
    n_l = np.zeros_like(k_l)
    for r in records:
        i, j = by_layout.index(r["layout"]), sizes.index(r["size"])
        k_l[i, j] += r[what]
        n_l[i, j] += r["runs"]
    k, n = k_l.sum(axis=0), n_l.sum(axis=0)
    pct = [100.0 * a / b if b else None for a, b in zip(k, n, strict=True)]
    fit = fit_probit(sizes_arr, k, n)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0xB007]))
    boots: list[tuple[float, float] | str] = []
    for _ in range(bootstrap if fit is not None and len(by_layout) > 1 else 0):
        pick = rng.integers(len(by_layout), size=len(by_layout))
        kb, nb = k_l[pick].sum(axis=0), n_l[pick].sum(axis=0)
        # a resample that detects every window (or none) puts the level below (above) the grid
        boots.append(fit_probit(sizes_arr, kb, nb) or ("below" if kb.sum() == nb.sum() else "above"))
    edge = {"below": sizes_arr[0] / 10.0, "above": sizes_arr[-1] * 10.0}
    out: dict[str, Any] = {"fit": None if fit is None else {"mu": fit[0], "sigma": fit[1]}}
    for level in LEVELS:
        entry: dict[str, Any] = {"measured": crossing(sizes, pct, level)}
        if fit is not None:
            value = probit_size(fit, level)
            entry["fitted"] = value
            entry["within_grid"] = bool(sizes_arr[0] <= value <= sizes_arr[-1])
            draws = [edge[b] if isinstance(b, str) else probit_size(b, level) for b in boots]
            if draws:
                entry["ci95"] = [float(np.percentile(draws, 2.5)), float(np.percentile(draws, 97.5))]
        out[f"p{round(level * 100)}"] = entry
    return out
