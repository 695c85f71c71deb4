"""Compiled twin of the generator-speed arbiter's per-tick history (``service.turbine.arbitration.GeneratorArbiter
.observe``, ``wwcore.backend``): the pair mean's and parity's histories and the learnt covariance of the onset
prediction's errors, row by row.

The kernels perform the numpy reference's floating-point operations in its order, so their results equal the
reference's bit for bit (``tests/test_fast_backend.py``). The prediction itself, the histories' product with the
quadratic fit's weights, stays numpy's (BLAS): a compiled loop would sum in another order.
"""

from __future__ import annotations

from wwcore.jit import kernel


@kernel
def arbiter_push(y, means, parities, onset):
    """Shift the histories (n, span) one tick to the left and append the pair mean ½(y_g1 + y_g2) and parity
    y_g1 − y_g2 of y (n, 4); whether any row's ℓ_J is still growing (onset ≥ 0)."""
    span = means.shape[1]
    growing = False
    for r in range(y.shape[0]):
        for c in range(span - 1):
            means[r, c] = means[r, c + 1]
            parities[r, c] = parities[r, c + 1]
        means[r, span - 1] = 0.5 * (y[r, 2] + y[r, 3])
        parities[r, span - 1] = y[r, 2] - y[r, 3]
        if onset[r] >= 0:
            growing = True
    return growing


@kernel
def arbiter_learn(means, predicted, learn, rate, covariance):
    """On the rows of ``learn`` (n,) bool: C ← C + rate (e eᵀ − C), e = means[:, −L:] − predicted (n, L), the
    errors of the fit that ended L ticks ago."""
    ticks = predicted.shape[1]
    start = means.shape[1] - ticks
    for r in range(means.shape[0]):
        if not learn[r]:
            continue
        for i in range(ticks):
            error_i = means[r, start + i] - predicted[r, i]
            for j in range(ticks):
                error_j = means[r, start + j] - predicted[r, j]
                covariance[r, i, j] += rate * (error_i * error_j - covariance[r, i, j])
