"""Batch evaluation of the hydrostatic turbine (seed 003): reconstruction, detection and compensation figures.

Per Monte Carlo run (per-run random streams from ``SeedSequence(seed, spawn_key=(0, run))``) four twins share
wind and measurement noise:

* ``compensated``: the scenario's faults, the observer's correction applied (eq. 36);
* ``uncompensated``: the same faults, no correction (the observer still reconstructs and detects);
* ``fault_free``: no faults, no correction, the reference the deviations are measured against;
* ``calibration``: no faults, correction as selected, on *other* streams (``spawn_key=(1, run)``): the
  fault-free statistics the detection thresholds come from (``service.hydro.detector``).

Detection does not feed back into the loop, so the evaluator runs the supervisor's own detector class over the
recorded reconstructions once the calibrated thresholds are known; the events are those the supervisor would
emit with those thresholds. Detection figures come from ``scoring.score_detection``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from plant_sim.hydro import HydroTurbineBatch
from service.hydro.detector import DetectionSettings, OffsetDetector, threshold_from_quiet
from service.hydro.supervisor import HydroSupervisor
from windwarden.evaluation.kinds import EvalOptions, Evaluation
from windwarden.evaluation.parallel import run_chunks
from windwarden.evaluation.scoring import score_detection, windows_from_faults
from windwarden.evaluation.scoring_policy import HYDRO as SCORING
from wwcore.events import Event
from wwcore.hydro_params import FAULT_TARGETS, NOMINAL
from wwcore.scenario import Scenario

VARIANTS = ("compensated", "uncompensated", "fault_free", "calibration")
TRACES = ("f_filt", "f_hat", "f_true", "omega_r", "omega_g", "P_g", "x_p", "x_M", "u_p", "u_M", "dp", "dp_hat")
SETTLE_BAND = 0.05  # settled when |f̂_filt − f| ≤ 5 % of |f|
ERROR_SKIP_S = 1.0  # reconstruction error measured from 1 s after a fault starts
OVERSPEED_MARGIN = 0.05  # rotor overspeed: ω_r above its fault-free twin by 5 % of the rated rotor speed
CHUNK = 10  # runs per process: 20 runs use both cores


def _seeds(seed: int, stream: int, run_ids: list[int]) -> list[np.random.SeedSequence]:
    return [np.random.SeedSequence(seed, spawn_key=(stream, run)) for run in run_ids]


def simulate(
    scenario: Scenario,
    run_ids: list[int],
    seed: int,
    observer: str,
    compensation: bool,
    hook: Callable[[float], None] | None = None,
) -> dict[str, dict[str, np.ndarray]]:
    """The four twins of the runs ``run_ids`` in one batch of 4 × len(run_ids) turbines (numpy's per-call
    overhead is shared); traces (ticks, runs, …) per variant."""
    n = len(run_ids)
    seeds = _seeds(seed, 0, run_ids) * 3 + _seeds(seed, 1, run_ids)
    fault_mask = np.repeat([True, True, False, False], n)
    comp = np.repeat([True, False, False, compensation], n)
    plant = HydroTurbineBatch(
        scenario.plant, scenario.wind, list(scenario.faults), seeds, run_ids * 4, NOMINAL, fault_mask=fault_mask
    )
    sup = HydroSupervisor(
        n=4 * n,
        run_ids=run_ids * 4,
        params=plant.nominal,
        observer=observer,
        observer_params=scenario.supervisor.params,
        compensation=comp,
    )
    ticks = round(scenario.duration_s / plant.dt)
    shapes = {"f_filt": 2, "f_hat": 2, "f_true": 2}
    rec = {name: np.zeros((ticks, 4 * n, shapes.get(name, 1)), dtype=np.float32) for name in TRACES}
    refs = None
    report_every = 100
    for k in range(ticks):
        frame = plant.measure()
        plant.control(refs)
        refs = sup.step(frame)
        truth = plant.truth()
        x = truth["x"]
        rec["f_filt"][k] = refs.correction
        rec["f_hat"][k] = refs.f_hat
        rec["f_true"][k] = truth["f"]  # the offset acting over [t_k, t_k+1)
        rec["omega_r"][k, :, 0] = x[:, 0]
        rec["omega_g"][k, :, 0] = x[:, 1]
        rec["P_g"][k, :, 0] = truth["P_g"]
        rec["x_p"][k, :, 0] = x[:, 4]
        rec["x_M"][k, :, 0] = x[:, 5]
        rec["u_p"][k, :, 0] = plant.u_sent[:, 0]
        rec["u_M"][k, :, 0] = plant.u_sent[:, 1]
        rec["dp"][k, :, 0] = x[:, 2]
        rec["dp_hat"][k, :, 0] = refs.x_hat[:, 2]
        plant.advance()
        plant.drain_events()  # fault windows come from the scenario
        sup.drain_events()  # default-threshold events; re-derived after calibration
        if hook is not None and (k + 1) % report_every == 0:
            hook(report_every * plant.dt)
    flat = {key: v[..., 0] if v.shape[-1] == 1 else v for key, v in rec.items()}
    return {variant: {key: v[:, i * n : (i + 1) * n] for key, v in flat.items()} for i, variant in enumerate(VARIANTS)}


def _worker(
    run_ids: list[int], hook: Callable[[float], None], scenario: Scenario, seed: int, observer: str, comp: bool
) -> dict[str, Any]:
    # the hook counts run-seconds of one run; the batch advances all four twins at once
    out: dict[str, Any] = simulate(scenario, run_ids, seed, observer, comp, lambda s: hook(len(VARIANTS) * s))
    out["run_ids"] = run_ids
    return out


def _merge(parts: list[dict[str, Any]]) -> dict[str, Any]:
    """Chunks back in run order: traces (ticks, runs, …)."""
    order = np.argsort(np.concatenate([p["run_ids"] for p in parts]))
    merged: dict[str, Any] = {}
    for variant in VARIANTS:
        merged[variant] = {name: np.concatenate([p[variant][name] for p in parts], axis=1)[:, order] for name in TRACES}
    return merged


def detect(f_filt: np.ndarray, dt: float, settings: DetectionSettings) -> list[Event]:
    """The supervisor's detector over recorded reconstructions f_filt (ticks, runs, 2)."""
    runs = f_filt.shape[1]
    det = OffsetDetector(runs, list(range(runs)), settings)
    for k in range(f_filt.shape[0]):
        det.step(k * dt, f_filt[k])
    return det.drain()


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


def _rms_dev(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = a.astype(float) - b.astype(float)
    return np.sqrt(np.mean(d * d, axis=0))


def deviation_metrics(m: dict[str, Any]) -> dict[str, Any]:
    """ω_g and P_g RMS deviations from the fault-free twin (whole run, mean over runs), overspeed figures."""
    ff = m["fault_free"]
    out: dict[str, Any] = {}
    for key, name in (("omega_g_dev_rms", "omega_g"), ("power_dev_rms", "P_g")):
        comp = float(np.mean(_rms_dev(m["compensated"][name], ff[name])))
        unc = float(np.mean(_rms_dev(m["uncompensated"][name], ff[name])))
        out[key] = {"compensated": comp, "uncompensated": unc, "ratio": comp / unc if unc > 0 else None}
    limit = OVERSPEED_MARGIN * NOMINAL.omega_r_rated
    over: dict[str, Any] = {"margin_rad_s": limit}
    for variant in ("compensated", "uncompensated"):
        excess = (m[variant]["omega_r"].astype(float) - ff["omega_r"]).max(axis=0)
        over[variant] = {
            "runs_pct": float(100.0 * np.mean(excess > limit)),
            "max_excess_rad_s": float(excess.max()),
            "omega_r_max_rad_s": float(m[variant]["omega_r"].max()),
            "omega_g_max_rad_s": float(m[variant]["omega_g"].max()),
            "dp_max_pa": float(m[variant]["dp"].max()),
        }
    over["fault_free"] = {"omega_r_max_rad_s": float(ff["omega_r"].max()), "dp_max_pa": float(ff["dp"].max())}
    out["rotor_overspeed"] = over
    return out


def evaluate(scenario: Scenario, runs: int, seed: int, options: EvalOptions) -> Evaluation:
    """Scorecard and plots of a hydrostatic scenario over ``runs`` Monte Carlo runs."""
    observer = options.estimator or scenario.supervisor.estimator or "ts-smo"
    main = "compensated" if options.compensation else "uncompensated"
    parts = run_chunks(
        _worker,
        runs,
        scenario.duration_s * len(VARIANTS),
        args=(scenario, seed, observer, options.compensation),
        chunk=CHUNK,
        workers=options.workers,
        label=f"{scenario.name} ({len(VARIANTS)} twins)",
        show_progress=options.progress,
    )
    m = _merge(parts)
    dt = NOMINAL.dt
    base = DetectionSettings()
    warm = round(base.warmup_s / dt)
    quiet = np.abs(m["calibration"]["f_filt"][warm:]).max(axis=(0, 1))
    settings = replace(base, threshold=threshold_from_quiet(quiet))
    events = detect(m[main]["f_filt"], dt, settings)
    windows = windows_from_faults(scenario.faults, scenario.duration_s)
    detection = score_detection(events, windows, runs=runs, duration_s=scenario.duration_s, policy=SCORING)
    ff_events = detect(m["fault_free"]["f_filt"], dt, settings)
    ff = score_detection(ff_events, [], runs=runs, duration_s=scenario.duration_s, policy=SCORING)
    metrics: dict[str, Any] = {"reconstruction": reconstruction_metrics(m[main], scenario, dt)}
    metrics.update(deviation_metrics(m))
    metrics["detection"] = {
        "thresholds": dict(zip(FAULT_TARGETS, settings.threshold, strict=True)),
        "calibration_max_abs_f_filt": dict(zip(FAULT_TARGETS, map(float, quiet), strict=True)),
        "false_alarms": detection.false_alarms,
        "fault_free_twin_false_alarms_per_1000s": ff.false_alarms_per_1000s,
        "rule": f"|f̂_filt| > θ for {base.on_samples} samples; release below {base.off_ratio:g} θ for "
        f"{base.off_samples} samples; θ = max(1.5 · max|f̂_filt| over the calibration twin, 0.01)",
    }
    scorecard = {
        "scenario": scenario.name,
        "runs": runs,
        "seed": seed,
        "duration_s": scenario.duration_s,
        "observer": observer,
        "compensation": options.compensation,
        **detection.card_fields(),
        "metrics": metrics,
    }

    def plot(folder: Path) -> list[Path]:
        from windwarden.evaluation.hydro_plots import write_plots

        return write_plots(folder, scenario, m, dt)

    return Evaluation(scorecard=scorecard, plot=plot)
