"""A regression fingerprint of a simulation that survives the machine it runs on.

A SHA-256 of a run's raw floats pins its numbers to the last bit, and the last bit is the machine's: numpy
computes ``exp``, ``log`` and the trigonometric functions with the widest SIMD the CPU has (AVX-512 or AVX2), and
those kernels round differently, so a run's digest changes from one CPU to the next while no number moved by more
than a few ulps. ``NumericFingerprint`` keeps, per named channel and per column (the last axis of what is fed to
it: a state, a turbine), two sums over every update: Σ|x| and Σ r x with fixed pseudo-random weights r ∈ [1, 2)
(a change of any one value, or a swap of two, moves it). ``mismatches`` compares each column within ``rtol`` of
its own Σ|x|, so a small quantity is not hidden behind a large one. A change of the code's arithmetic beyond
rounding moves a column by far more than 1e-9 of its scale; a change of the CPU's rounding by ~1e-15 (grown by a
closed loop over a short run to ~1e-12 at most).

The expected values live in ``tests/data/numeric_fingerprints.json``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

RTOL = 1e-9
STORE = Path(__file__).parent / "data" / "numeric_fingerprints.json"


class NumericFingerprint:
    def __init__(self) -> None:
        self._rng = np.random.default_rng(0x5EED)
        self.channels: dict[str, list[np.ndarray]] = {}  # name → [Σ|x|, Σ r x], each (columns,)

    def update(self, name: str, values) -> None:
        x = np.asarray(values, dtype=float)
        x = x.reshape(-1, x.shape[-1]) if x.ndim else x.reshape(1, 1)
        if not np.isfinite(x).all():
            raise AssertionError(f"{name}: a fingerprinted value is not finite")
        r = 1.0 + self._rng.random(x.shape)
        sums = self.channels.setdefault(name, [np.zeros(x.shape[1]), np.zeros(x.shape[1])])
        sums[0] += np.abs(x).sum(axis=0)
        sums[1] += (r * x).sum(axis=0)

    def values(self) -> dict[str, list[list[float]]]:
        return {name: [a.tolist(), w.tolist()] for name, (a, w) in self.channels.items()}


def expected(key: str) -> dict[str, list[list[float]]]:
    return json.loads(STORE.read_text())[key]


def mismatches(got: dict, want: dict, rtol: float = RTOL) -> list[str]:
    """The channels and columns of ``got`` that differ from ``want`` beyond ``rtol`` of the column's Σ|x|."""
    if sorted(got) != sorted(want):
        return [f"channels {sorted(got)} != {sorted(want)}"]
    out = []
    for name in want:
        (ga, gw), (wa, ww) = (np.asarray(v) for v in got[name]), (np.asarray(v) for v in want[name])
        if ga.shape != wa.shape:
            out.append(f"{name}: {ga.shape[0]} columns, expected {wa.shape[0]}")
            continue
        scale = np.maximum(wa, 1e-300)
        bad = (np.abs(ga - wa) > rtol * scale) | (np.abs(gw - ww) > 2.0 * rtol * scale)
        out += [f"{name}[{j}]: Σ|x| {ga[j]!r} vs {wa[j]!r}, Σrx {gw[j]!r} vs {ww[j]!r}" for j in np.flatnonzero(bad)]
    return out
