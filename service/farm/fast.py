"""Compiled twin of the farm supervisor's per-sample arithmetic (``wwcore.backend``): the analytic detector's learnt
levels and spread ratios (``service.farm.baseline.LearntLevel.update``). The same operations in the reference's
order, so the same numbers bit for bit (``tests/test_fast_backend_farm.py``); the lock-in, the CUSUMs and the decisions
stay numpy code around it, and the available power's wind inversion is ``wwcore.aero_fast``'s.
"""

from __future__ import annotations

import numpy as np

from wwcore.aero_fast import maximum
from wwcore.jit import kernel


@kernel
def learn_level(r, design_std, frozen, alpha_level, alpha_block, block, state):
    """``LearntLevel.update`` on (n, m) arrays, in place: where not ``frozen`` (each of ``r``, ``design_std`` and
    ``frozen`` (n, m), or of one row or one column to broadcast), count the sample, m += w (r − m) with
    w = max(1/count, ``alpha_level``), add u = (r − m)/σ_d to the block; where a block of ``block`` samples is full,
    ρ += v (block ū² − ρ) with v = max(1/blocks, ``alpha_block``), and the block restarts. ``state`` = (samples,
    level, raw_ratio, blocks, block_sum, block_n)."""
    samples, level, raw_ratio, blocks, block_sum, block_n = state
    n, m = level.shape
    any_full = False
    for i in range(n):
        for j in range(m):
            live = not frozen[min(i, frozen.shape[0] - 1), min(j, frozen.shape[1] - 1)]
            count = samples[i, j] + (1.0 if live else 0.0)
            samples[i, j] = count
            w = maximum(1.0 / maximum(count, 1.0), alpha_level) if live else 0.0
            x = r[min(i, r.shape[0] - 1), min(j, r.shape[1] - 1)]
            new_level = level[i, j] + w * (x - level[i, j])
            level[i, j] = new_level
            u = (x - new_level) / design_std[min(i, design_std.shape[0] - 1), min(j, design_std.shape[1] - 1)]
            block_sum[i, j] = block_sum[i, j] + u if live else 0.0
            block_n[i, j] = block_n[i, j] + 1 if live else 0
            if block_n[i, j] >= block:
                any_full = True
    if not any_full:
        return
    for i in range(n):
        for j in range(m):
            full = block_n[i, j] >= block
            count = blocks[i, j] + (1.0 if full else 0.0)
            blocks[i, j] = count
            mean = block_sum[i, j] / block
            v = maximum(1.0 / maximum(count, 1.0), alpha_block) if full else 0.0
            raw_ratio[i, j] = raw_ratio[i, j] + v * (block * mean * mean - raw_ratio[i, j])
            if full:
                block_sum[i, j] = 0.0
                block_n[i, j] = 0


def as_rows(a, shape: tuple[int, ...]) -> np.ndarray:
    """``a`` (a scalar, or an array broadcastable to ``shape``) as a 2-D array that ``learn_level`` broadcasts:
    (n, m) for ``shape`` (n, m), (n, 1) for ``shape`` (n,); a scalar (1, 1)."""
    a = np.asarray(a)
    if a.ndim == 0:
        return a.reshape(1, 1)
    return a.reshape(a.shape[0], 1) if len(shape) == 1 else a
