"""The correction while an offset is flagged: the mean of the reconstruction (35) since the flag, once it is the
better estimate, kept within σ of the filtered one (option ``hold_offset``; docs/hydro.md §4).

The faults are offsets: constant from onset to end (eq. 38). A filter (37)/(37') must trade noise for lag at
every instant, because it cannot know whether f_a has changed; once the detector has flagged actuator j, the
offset is known to be there and to be constant, and the least-squares estimate of a constant from the samples
since the flag is their mean:

    f̄_j[N] = (1/N) Σ_{k=1..N} f̂_a,j[k]                    (N samples since the flag, f̂_a of (35) or (35'))

f̂_a carries the stroke reading's noise ν differentiated (its model is the lag τ_p: f̂_a ≈ x̃ + τ_p dx̃/dt − u),
and the mean of a derivative telescopes: f̄ ≈ mean(x̃ − u) + τ_p (x̃_N − x̃_0)/(N dt). With white ν of variance
σ_ν² per sample its variance is therefore about

    σ²(f̄[N]) ≈ σ_ν² (1/N + 2 (τ_p/(N dt))²),               σ_ν = (a/√3) at the rated stroke

which falls as 1/N² at first and as 1/N later, while the filter's σ_j = (a/√3)‖h_j‖₂ stays. The held estimate
is used from the first N at which its predicted σ is no larger than the filter's; both scale with the sensors'
accuracy a, so that N depends on the observer and its filter only (``hold_samples``, computed exactly from the
observer's measured noise response h_a of f̂_a: σ(f̄[N]) = (a/√3)‖h_a ∗ 1_N/N‖₂).

**Never further than σ from the filter.** The mean is right only while the offset is constant; a drifting one (a
ramp in or out) leaves it behind by up to θ_j before the change test below fires. The correction is therefore the
mean clamped to f̂_filt ± σ_j (σ_j the filter's predicted noise at the design accuracy): it can be worse than the
filter by σ_j at most, whatever the fault does, and on a constant offset, where f̂_filt − f ~ N(0, σ_j) and the
mean is almost exact, the clamp costs E[(|f̂_filt − f| − σ_j)⁺] = 2 σ_j (φ(1) − Q(1)) = 0.17 σ_j, a fifth of the
filter's own mean error 0.8 σ_j.

**A change ends the segment.** The detector's threshold θ_j bounds how far the filtered f̂_filt strays from its
mean by noise alone at the design false-alarm rate (``service.hydro.detector``). While the mean is held, a sample
of f̂_filt further than θ_j from it means the offset has changed (a second fault on the same actuator, a ramp, the
fault's end): the mean restarts from that sample, and until it is the better estimate again the correction is
f̂_filt, as before the flag. No persistence is asked for: a restart by noise costs only N samples of the filter's
noise, whereas every sample the stale mean is held after a change is a sample of wrong correction (a persistence
of the detector's 5 samples held the full offset 0.05 s past each fault's end). When the flag falls, the
correction is f̂_filt.
"""

from __future__ import annotations

import numpy as np

from service.hydro.noise import NoiseResponse

MAX_HOLD_SAMPLES = 10_000  # a mean that never beats the filter within 100 s is not used


def mean_response_l2(h_a: np.ndarray, samples: int) -> np.ndarray:
    """‖h_a ∗ 1_N/N‖₂ per actuator (2,): the noise gain of the mean of N consecutive f̂_a (h_a: samples, readings,
    actuators)."""
    if samples < 1:
        raise ValueError(f"the mean needs at least one sample, got {samples}")
    c = np.cumsum(np.concatenate([h_a, np.zeros((samples, *h_a.shape[1:]))]), axis=0)
    window = c.copy()
    window[samples:] -= c[:-samples]  # Σ over the N samples ending at i
    return np.sqrt((window**2).sum(axis=(0, 1))) / samples


def hold_samples(response: NoiseResponse) -> np.ndarray:
    """The smallest N per actuator (2,) with σ(f̄[N]) ≤ σ(f̂_filt), from the observer's noise responses."""
    if response.h_a is None:
        raise ValueError("the noise response has no h_a (the unfiltered reconstruction's); the mean cannot be designed")
    target = response.l2
    out = np.full(2, MAX_HOLD_SAMPLES, dtype=int)
    pending = np.ones(2, dtype=bool)
    for samples in range(1, MAX_HOLD_SAMPLES + 1):
        ok = pending & (mean_response_l2(response.h_a, samples) <= target)
        out[ok] = samples
        pending &= ~ok
        if not pending.any():
            break
    return out


class OffsetHold:
    """Per turbine and actuator: the mean of f̂_a since the flag clamped to f̂_filt ± σ, or f̂_filt (module docstring)."""

    def __init__(self, n: int, theta: np.ndarray, samples: np.ndarray, sigma: np.ndarray):
        theta, samples, sigma = (
            np.asarray(theta, dtype=float),
            np.asarray(samples, dtype=int),
            np.asarray(sigma, dtype=float),
        )
        if any(v.shape != (2,) or (v <= 0).any() for v in (theta, samples, sigma)):
            raise ValueError(
                f"θ, the samples of the mean and σ(f̂_filt) need two positive values each: {theta}, {samples}, {sigma}"
            )
        self.n = n
        self.theta = theta
        self.samples = samples
        self.sigma = sigma  # the predicted σ of f̂_filt: how far the correction may leave it
        self.count = np.zeros((n, 2), dtype=int)  # samples in the current segment
        self.total = np.zeros((n, 2))  # Σ f̂_a over the segment
        self.held = np.zeros((n, 2), dtype=bool)  # the correction is the mean

    def step(self, flags: np.ndarray, f_hat: np.ndarray, f_filt: np.ndarray) -> np.ndarray:
        """The correction (n, 2) for this sample, from the detector's flags and the observer's f̂_a and f̂_filt."""
        flags = np.asarray(flags, dtype=bool)
        for name, value in (("flags", flags), ("f_hat", f_hat), ("f_filt", f_filt)):
            if np.shape(value) != (self.n, 2):
                raise ValueError(f"{name} must have the shape {(self.n, 2)}, got {np.shape(value)}")
        count = np.where(flags, self.count + 1, 0)
        total = np.where(flags, self.total + f_hat, 0.0)
        mean = total / np.maximum(count, 1)
        held = flags & (count >= self.samples)
        changed = held & (np.abs(f_filt - mean) > self.theta)
        # the offset changed: a new segment starts with this sample, the filter corrects until the mean is better
        count = np.where(changed, 1, count)
        total = np.where(changed, f_hat, total)
        held &= ~changed
        self.count, self.total, self.held = count, total, held
        # the mean, but never further from f̂_filt than f̂_filt's own σ (the bound on the regret, module docstring)
        return np.where(held, f_filt + np.clip(mean - f_filt, -self.sigma, self.sigma), f_filt)
