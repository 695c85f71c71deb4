"""The hydrostatic turbine's scorecard, one set of functions for ``windwarden eval`` (``evaluation.hydro``) and the
live run folder (``windwarden.kinds.hydro``): the detection figures, the reconstruction figures of f̂_a,filt, and
the scorecard's fields in their order."""

from __future__ import annotations

from typing import Any

import numpy as np

from windwarden.evaluation.scoring import DetectionScore, score_detection, windows_from_faults
from windwarden.evaluation.scoring_policy import HYDRO as SCORING
from wwcore.events import Event
from wwcore.hydro_params import FAULT_TARGETS
from wwcore.scenario import Scenario

SETTLE_BAND = 0.05  # settled when |f̂_filt − f| ≤ 5 % of |f|
ERROR_SKIP_S = 1.0  # reconstruction error measured from 1 s after a fault starts
WARMUP_S = SCORING.warmup_s  # s, left out of the fault-free statistics as of every detection figure


def detection(scenario: Scenario, events: list[Event], runs: int, faulty: bool = True) -> DetectionScore:
    """The scoring policy's figures for one twin's events (the fault-free twin: no fault windows)."""
    windows = windows_from_faults(scenario.faults, scenario.duration_s) if faulty else []
    return score_detection(events, windows, runs=runs, duration_s=scenario.duration_s, policy=SCORING)


def reconstruction_metrics(traces: dict[str, np.ndarray], scenario: Scenario, dt: float) -> list[dict[str, Any]]:
    """Per fault: mean |f̂_filt − f|/|f| over [start + 1 s, end) and the time to stay within 5 % of |f|."""
    out = []
    for fault in scenario.faults:
        j = FAULT_TARGETS.index(fault.target)
        end = scenario.duration_s if fault.end_s is None else min(fault.end_s, scenario.duration_s)
        k0, k1 = round(fault.start_s / dt), round(end / dt)
        ks = round((fault.start_s + ERROR_SKIP_S) / dt)
        size = abs(float(fault.value or 0.0))
        err = np.abs(traces["f_filt"][:, :, j] - traces["f_true"][:, :, j]).astype(float)  # (ticks, runs)
        error_pct = 100.0 * err[ks:k1].mean(axis=0) / size if k1 > ks else np.full(err.shape[1], np.nan)
        outside = err[k0:k1] > SETTLE_BAND * size
        # last tick outside the band (+1 tick) after the start: when the error stays within 5 %
        last = np.where(outside.any(axis=0), outside.shape[0] - np.argmax(outside[::-1], axis=0), 0)
        settle = last * dt
        out.append(
            {
                "fault": fault.label,
                "target": fault.target,
                "size": fault.value,
                "error_pct": float(np.mean(error_pct)),
                "error_pct_max": float(np.max(error_pct)),
                "settle_s": float(np.mean(settle)),
                "settle_s_max": float(np.max(settle)),
                "settled_pct": float(100.0 * np.mean(~outside[-1])),
            }
        )
    return out


def scorecard(
    scenario: Scenario,
    *,
    runs: int,
    seed: int,
    observer: str,
    detector: str,
    compensation: bool,
    score: DetectionScore,
    metrics: dict[str, Any],
) -> dict[str, Any]:
    """The hydrostatic scorecard (``docs/scorecards.md``)."""
    return {
        "scenario": scenario.name,
        "runs": runs,
        "seed": seed,
        "duration_s": scenario.duration_s,
        "observer": observer,
        "detector": detector,
        "compensation": compensation,
        **score.card_fields(),
        "metrics": metrics,
    }
