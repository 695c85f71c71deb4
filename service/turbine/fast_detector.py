"""Compiled twin of the speed FDI's tick (``service.turbine.fdi.SpeedSensorFDI.step``, ``wwcore.backend``) in one
call: the frozen readings' repeat test, the calibration offsets, the generator-speed arbiter's histories and learnt
covariance (``arbitration.GeneratorArbiter.observe``), the window tests with the adaptive thresholds' learning and,
on a tick where nothing is inconsistent, frozen, flagged or pending (almost every tick), the rotor-speed bias
CUSUMs (``bias_test``). It answers whether Python is needed on this tick: where it is, ``SpeedSensorFDI.step``'s
lines after the kernel run as they are (the isolation, the clearing, a bias flag raised).

The kernels it calls perform the numpy reference's operations in its order, so the results equal the reference's
bit for bit (``tests/test_fast_detector.py``, ``tests/test_fast_backend.py``). The arbiter's prediction, the
histories' product with the quadratic fit's weights, is numba's product, which calls the BLAS routine numpy's does
(the same numbers: the tests compare them).
"""

from __future__ import annotations

import numpy as np

from service.turbine.fast import any_equal, rotor_bias, window_test, window_test_learn
from service.turbine.fast_arbitration import arbiter_learn, arbiter_push
from wwcore.jit import kernel
from wwcore.kept import Kept


@kernel
def arbiter_observe(y, learn, arbiter, learns):
    """``GeneratorArbiter.observe``'s kernels: ``arbiter_push`` of y (n, 4), then where ``learns`` (the histories
    hold a whole fit and its L errors) the prediction p = m[:, −L−W:−L] @ wᵀ and ``arbiter_learn`` on the rows of
    ``learn``; ``arbiter`` = (histories (the means and parities as the planes of one (2, n, span) array), onset,
    wᵀ (W, L), rate, covariance, fit (n, W): the histories' slice copied). Whether any row's ℓ_J is still growing."""
    histories, onset, weights_t, rate, covariance, fit = arbiter
    means, parities = histories[0], histories[1]
    growing = arbiter_push(y, means, parities, onset)
    if learns:
        width, ahead = weights_t.shape
        start = means.shape[1] - ahead - width
        for r in range(means.shape[0]):
            for c in range(width):
                fit[r, c] = means[r, start + c]
        arbiter_learn(means, fit @ weights_t, learn, rate, covariance)
    return growing


@kernel
def detector_tick(y_raw, raw, x_hat, previous, tick, flags, offset, window, learning, arbiter, bias, outputs):
    """``SpeedSensorFDI.step``'s kernels of one tick, in its order:

    * the frozen readings' repeat test: whether any reading of ``y_raw`` (n, 4) equals ``previous``'s (None: not
      tested here, ``FrozenReadings.push`` tests it);
    * y = y_raw − the calibration offsets (``offset``: the calibration's ``HealthySpread.state``, its plane 5;
      None: none) into ``outputs[0]``;
    * ``arbiter_observe`` of y, learning on the rows with nothing flagged or pending (``flags``: flagged
      and deadline, the planes of one (2, n) array);
    * ``window_test`` of ``raw`` (n, m), or ``window_test_learn`` with ``learning`` = (rank, gear ratio, the χ²
      spread's and the calibration's (min_weight, s_max², state)); None: nothing learnt) into ``outputs[1:3]`` =
      (χ²/ŝ², ratio);
    * where ``tick`` = (slot, the arbiter learns, a healthy tick may be finished here: after the warm-up, nothing
      flagged or pending) says so and nothing is repeated or exceeded: ``rotor_bias`` against x̂ with ``bias`` =
      (predictor of each flagged mask, column, scale, test, state, learning) (None: no bias test), its sensors named
      into ``outputs[3]``.

    ``window`` = (the χ² spread's ``HealthySpread.state``, of which ŝ² (plane 2), ring, window sum, h_detect,
    h_window, the all-sensor observer's column). Returns (finished: the tick needs no Python beyond a raised bias
    flag, repeated, exceeded, the arbiter's ℓ_J growing, a bias raised)."""
    slot, learns, healthy = tick
    flagged, deadline = flags[0], flags[1]
    y, chi2_stat, ratio, over = outputs
    n = y_raw.shape[0]
    tested, repeated = False, False
    if previous is not None:  # (each ``is None`` test on an argument is settled when numba compiles it)
        tested, repeated = True, any_equal(y_raw, previous)
    if offset is None:
        y[:, :] = y_raw
    else:
        offset = offset[5]
        for r in range(n):
            for c in range(4):
                y[r, c] = y_raw[r, c] - offset[r, c]
    learn = np.empty(n, dtype=np.bool_)
    for r in range(n):
        learn[r] = flagged[r] == 0 and deadline[r] < 0
    growing = arbiter_observe(y, learn, arbiter, learns)
    spread_state, history, window_sum, h_detect, h_window, column = window
    scale2 = spread_state[2]
    if learning is None:
        exceeded = window_test(raw, scale2, history, slot, window_sum, h_detect, h_window, column, chi2_stat, ratio)
    else:
        rank, gear_ratio, spread, calibration = learning
        exceeded = window_test_learn(
            raw, scale2, history, slot, window_sum, h_detect, h_window, column, chi2_stat, ratio,
            (flagged, deadline, rank, y_raw, gear_ratio, spread, calibration),
        )  # fmt: skip
    finished = healthy and tested and not repeated and not exceeded
    raised = False
    if bias is not None:  # noqa: SIM102 (numba settles ``bias is None`` alone, not within an ``and``)
        if finished:
            predictor_of_mask, columns, scale, test, state, spread_learning = bias
            raised = rotor_bias(
                y, x_hat, flagged, deadline, predictor_of_mask, columns, scale, test, state, spread_learning, over
            )
    return finished, repeated, exceeded, growing, raised


@kernel
def detector_tick_kept(y_raw, raw, x_hat, previous, tick, kept, ratio):
    """``detector_tick`` with its arguments kept from tick to tick as one ``wwcore.kept.Kept`` (``kept.args`` =
    (flags, offset, window, learning, arbiter, bias, y, χ²/ŝ², over): ``detector_arguments``' ``"packed"``) and the
    fresh ``ratio``: one struct to unbox for the kept arrays."""
    flags, offset, window, learning, arbiter, bias, y, chi2_stat, over = kept.args
    return detector_tick(
        y_raw, raw, x_hat, previous, tick, flags, offset, window, learning, arbiter, bias, (y, chi2_stat, ratio, over)
    )


PACKED = ("flags", "offset", "window", "learning", "arbiter", "bias", "y", "chi2_stat", "over")
"""``detector_arguments``' names in ``detector_tick_kept``'s ``kept.args``, in order."""


def detector_arguments(fdi) -> dict:
    """``detector_tick``'s arguments of a ``SpeedSensorFDI`` kept from tick to tick (its arrays are updated in
    place, never replaced): flags, offset, window, learning, arbiter, bias, and the outputs read only within the tick
    (the calibrated readings, χ²/ŝ², the bias test's sensors; the ratio leaves the tick and stays new); ``"packed"``:
    the nine as ``detector_tick_kept``'s one ``Kept``."""
    n, m = fdi._window_sum.shape
    spread, calibration, arbiter = fdi.spread, fdi.calibration, fdi.arbiter
    learning = None
    if spread.enabled:
        learning = (
            fdi._rank,
            fdi._gear_ratio,
            (spread.min_weight, spread.max_scale2, spread.state),
            (calibration.min_weight, calibration.max_scale2, calibration.state),
        )
    bias = None
    if fdi.bias is not None:
        b, s = fdi.bias, fdi.bias.spread
        bias = (
            fdi._bias_predictor,
            b.column,
            b.scale,
            (b.parity_shifts, b.h),
            (b.sums, b.predictor),
            (s.enabled, s.min_weight, s.max_scale2, s.state),
        )
    kept = {
        "flags": fdi._flags,
        "offset": calibration.state if calibration.enabled else None,
        "window": (spread.state, fdi._history, fdi._window_sum, fdi.h_detect, fdi.h_window, fdi._all_healthy),
        "learning": learning,
        "arbiter": arbiter.compiled_arguments(),
        "bias": bias,
        "y": np.empty((n, 4)),
        "chi2_stat": np.empty((n, m)),
        "over": np.empty((n, 2), dtype=bool),
    }
    kept["packed"] = Kept(tuple(kept[name] for name in PACKED))
    return kept
