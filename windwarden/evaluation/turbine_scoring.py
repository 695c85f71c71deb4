"""The single turbine's scorecard, one set of functions for ``windwarden eval`` (``evaluation.turbine``) and the
live run folder (``windwarden.kinds.turbine``): the metric window of each tick, the detection figures, the wind RMSE
table and the scorecard's fields in their order."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from windwarden.evaluation.scoring import DetectionScore, score_detection, windows_from_faults
from windwarden.evaluation.scoring_policy import TURBINE as SCORING
from wwcore.events import Event
from wwcore.scenario import FaultSpec, Scenario

WARMUP_S = SCORING.warmup_s  # left out of every figure (scoring_policy says why)
GRACE_S = SCORING.grace_s  # after a fault ends, its flags may still be up for this long (scoring_policy)
WIND_KEYS = ("fte", "nfte", "anemometer")
"""The wind estimates of ``metrics.wind_rmse``: fault-tolerant, non-fault-tolerant (observer 1), the anemometer."""


def window_of_tick(scenario: Scenario, n_steps: int, dt: float) -> tuple[np.ndarray, list[str]]:
    """Metric window of each tick: 0 fault-free, i ≥ 1 inside the i-th fault window, −1 left out (warm-up, and
    the ``GRACE_S`` after a fault ends, while the supervisor switches back); and the windows' labels."""
    t = np.arange(n_steps) * dt
    windows = windows_from_faults(scenario.faults, scenario.duration_s)
    which = np.zeros(n_steps, dtype=int)
    for i, w in enumerate(windows, start=1):
        which[(t >= w.end_s) & (t < w.end_s + GRACE_S) & (which == 0)] = -1
        which[(t >= w.start_s) & (t < w.end_s)] = i
    which[t < WARMUP_S] = -1
    return which, ["fault_free"] + [w.name for w in windows]


def detection(events: list[Event], faults: Sequence[FaultSpec], duration_s: float, runs: int) -> DetectionScore:
    """The detection figures of ``runs`` runs' events against the fault windows (``scoring.score_detection``)."""
    windows = windows_from_faults(faults, duration_s)
    return score_detection(events, windows, runs=runs, duration_s=duration_s, policy=SCORING)


def wind_rmse(
    labels: Sequence[str],
    sq: Mapping[str, Sequence[float]],
    counts: Sequence[float],
    window_keys: Sequence[str] = WIND_KEYS,
    fault_free_keys: Sequence[str] = WIND_KEYS,
) -> dict[str, dict[str, float]]:
    """√(Σ squared error / samples) per metric window with samples; the fault windows have ``window_keys`` (the
    fault-free twins' ``fte_fault_free`` and the clean runs' ``fte_clean`` too, when there are twins), the
    fault-free time ``fault_free_keys`` (``WIND_KEYS``, and ``fte_clean`` with twins)."""
    return {
        label: {key: float(np.sqrt(sq[key][i] / counts[i])) for key in (window_keys if i > 0 else fault_free_keys)}
        for i, label in enumerate(labels)
        if counts[i] > 0
    }


def scorecard(
    scenario: Scenario,
    *,
    runs: int,
    seed: int,
    detector: str,
    estimator: str,
    score: DetectionScore,
    wind: dict[str, dict[str, float]],
    twin: dict[str, Any] | None = None,
    clean: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The turbine scorecard (``docs/scorecards.md``); ``twin`` and ``clean``: the fault-free twins' and the clean
    runs' false alarms, if any ran."""
    return {
        "scenario": scenario.name,
        "runs": runs,
        "seed": seed,
        "duration_s": scenario.duration_s,
        "detector": detector,
        "estimator": estimator,
        **score.card_fields(),
        **({"false_alarms_twin": twin} if twin is not None else {}),
        **({"false_alarms_clean": clean} if clean is not None else {}),
        "metrics": {"wind_rmse": wind},
    }
