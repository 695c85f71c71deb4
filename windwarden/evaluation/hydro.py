"""Batch evaluation of the hydrostatic turbine (seed 003): reconstruction, detection and compensation figures.

Per Monte Carlo run (per-run random streams from ``SeedSequence(seed, spawn_key=(0, run))``) three twins share
wind and measurement noise:

* ``compensated``: the scenario's faults, the observer's correction applied (eq. 36);
* ``uncompensated``: the same faults, no correction (the observer still reconstructs and detects);
* ``fault_free``: no faults, no correction, the reference the deviations are measured against.

All three run one ``HydroSupervisor``, the one the live system runs, with the scenario's options: its
thresholds are the design values of ``service.hydro.detector`` (fixed before any run, from the sensors'
accuracy and the design false-alarm rate, no data). The detection figures score the supervisor's own
DETECTION / RECOVERY events of the main twin (compensated, or uncompensated with ``--no-compensation``); the
fault-free twin's events give a second false-alarm count. Scoring goes through ``hydro_scoring`` alone
(``scoring.score_detection`` with the hydrostatic ``ScoringPolicy``), as the live run folder's does.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

import numpy as np

from plant_sim.hydro import HydroTurbineBatch
from service.hydro.detector import DetectionSettings
from service.hydro.supervisor import HydroSupervisor
from windwarden.evaluation.hydro_scoring import WARMUP_S, detection, reconstruction_metrics, scorecard
from windwarden.evaluation.kinds import EvalOptions, Evaluation
from windwarden.evaluation.parallel import run_chunks
from wwcore.events import Event
from wwcore.hydro_params import FAULT_TARGETS, NOMINAL
from wwcore.scenario import Scenario
from wwcore.stepping import run_ticks

VARIANTS = ("compensated", "uncompensated", "fault_free")
TRACES = ("f_filt", "f_hat", "f_true", "omega_r", "omega_g", "P_g", "x_p", "x_M", "u_p", "u_M", "dp", "dp_hat")
OVERSPEED_MARGIN = 0.05  # rotor overspeed: ω_r above its fault-free twin by 5 % of the rated rotor speed
CHUNK = 10  # runs per process: 20 runs use both cores


def _seeds(seed: int, stream: int, run_ids: list[int]) -> list[np.random.SeedSequence]:
    return [np.random.SeedSequence(seed, spawn_key=(stream, run)) for run in run_ids]


def simulate(
    scenario: Scenario,
    run_ids: list[int],
    seed: int,
    observer: str | None = None,
    detector: str | None = None,
    hook: Callable[[float], None] | None = None,
) -> dict[str, Any]:
    """The three twins of the runs ``run_ids`` in one batch of 3 × len(run_ids) turbines (numpy's per-call
    overhead is shared): traces (ticks, runs, …) per variant, and the supervisor's events per variant
    (``run`` = the Monte Carlo run). ``observer``, ``detector``: registered names (None: the scenario's)."""
    n = len(run_ids)
    seeds = _seeds(seed, 0, run_ids) * len(VARIANTS)
    fault_mask = np.repeat([True, True, False], n)
    comp = np.repeat([True, False, False], n)
    plant = HydroTurbineBatch(
        scenario.plant, scenario.wind, list(scenario.faults), seeds, run_ids * 3, NOMINAL, fault_mask=fault_mask
    )
    sup = HydroSupervisor(
        n=3 * n,
        run_ids=list(range(3 * n)),  # the batch row; mapped back to (variant, run) below
        params=plant.nominal,
        observer=observer or scenario.supervisor.estimator,
        detector=detector or scenario.supervisor.detector,
        options=scenario.supervisor.params,
        compensation=comp,
    )
    ticks = round(scenario.duration_s / plant.dt)
    shapes = {"f_filt": 2, "f_hat": 2, "f_true": 2}
    rec = {name: np.zeros((ticks, 3 * n, shapes.get(name, 1)), dtype=np.float32) for name in TRACES}
    events: list[Event] = []
    report_every = 100

    def record(k: int, frame, refs) -> None:
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

    def report(k: int) -> None:
        plant.drain_events()  # fault windows come from the scenario
        events.extend(sup.drain_events())
        if hook is not None and (k + 1) % report_every == 0:
            hook(report_every * plant.dt)

    run_ticks(plant, sup, range(ticks), stepped=record, advanced=report)
    flat = {key: v[..., 0] if v.shape[-1] == 1 else v for key, v in rec.items()}
    out: dict[str, Any] = {
        variant: {key: v[:, i * n : (i + 1) * n] for key, v in flat.items()} for i, variant in enumerate(VARIANTS)
    }
    out["events"] = {
        variant: [replace(e, run=run_ids[e.run % n]) for e in events if e.run // n == i]
        for i, variant in enumerate(VARIANTS)
    }
    return out


def _worker(
    run_ids: list[int],
    hook: Callable[[float], None],
    scenario: Scenario,
    seed: int,
    names: dict[str, str | None],
) -> dict[str, Any]:
    # the hook counts run-seconds of one run; the batch advances all three twins at once
    out: dict[str, Any] = simulate(scenario, run_ids, seed, **names, hook=lambda s: hook(len(VARIANTS) * s))
    out["run_ids"] = run_ids
    return out


def _merge(parts: list[dict[str, Any]]) -> dict[str, Any]:
    """Chunks back in run order: traces (ticks, runs, …), events in time order per variant."""
    order = np.argsort(np.concatenate([p["run_ids"] for p in parts]))
    merged: dict[str, Any] = {}
    for variant in VARIANTS:
        merged[variant] = {name: np.concatenate([p[variant][name] for p in parts], axis=1)[:, order] for name in TRACES}
    merged["events"] = {
        variant: sorted((e for p in parts for e in p["events"][variant]), key=lambda e: (e.run, e.t))
        for variant in VARIANTS
    }
    return merged


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


def detection_metrics(supervisor: HydroSupervisor, m: dict[str, Any]) -> dict[str, Any]:
    """The detector's design (thresholds, predicted fault-free σ of f̂_filt) beside what the fault-free twin shows:
    its largest |f̂_filt| after the warm-up, and that as a share of θ (the margin the design left)."""
    out: dict[str, Any] = {"detector": supervisor.detector_name}
    warm = round(WARMUP_S / NOMINAL.dt)
    free = m["fault_free"]["f_filt"][warm:].astype(float)
    quiet = np.abs(free).max(axis=(0, 1))
    out["fault_free_max_abs_f_filt"] = dict(zip(FAULT_TARGETS, map(float, quiet), strict=True))
    out["fault_free_std_f_filt"] = dict(zip(FAULT_TARGETS, map(float, free.std(axis=(0, 1))), strict=True))
    theta = supervisor.thresholds
    if theta is not None:
        out["thresholds"] = dict(zip(FAULT_TARGETS, map(float, theta), strict=True))
        out["fault_free_max_over_threshold"] = dict(zip(FAULT_TARGETS, map(float, quiet / theta), strict=True))
    sigma = getattr(supervisor.detector, "sigma", None)
    if sigma is not None:
        out["predicted_sigma_f_filt"] = dict(zip(FAULT_TARGETS, map(float, sigma), strict=True))
    settings = getattr(supervisor.detector, "s", None)
    if isinstance(settings, DetectionSettings):
        out["design"] = asdict(settings)
        out["rule"] = (
            f"|f̂_filt| > θ for {settings.on_samples} samples; release below {settings.off_ratio:g} θ for "
            f"{settings.off_samples} samples; θ = max(σ̂ Q⁻¹(R dt/4000 s), min_offset) with σ̂ predicted from "
            f"the sensors' ±{settings.sensor_noise_pct:g} % and R = {settings.false_alarms_per_1000s:g}/1000 s "
            "(service.hydro.detector)"
        )
    return out


def evaluate(scenario: Scenario, runs: int, seed: int, options: EvalOptions) -> Evaluation:
    """Scorecard and plots of a hydrostatic scenario over ``runs`` Monte Carlo runs."""
    names = {
        "observer": options.estimator or scenario.supervisor.estimator,
        "detector": options.detector or scenario.supervisor.detector,
    }
    # the supervisor of the runs, built once first: bad names and options are refused before anything runs
    probe = HydroSupervisor(
        n=1, observer=names["observer"], detector=names["detector"], options=scenario.supervisor.params
    )
    main = "compensated" if options.compensation else "uncompensated"
    parts = run_chunks(
        _worker,
        runs,
        scenario.duration_s * len(VARIANTS),
        options,
        args=(scenario, seed, names),
        max_chunk=CHUNK,
        label=f"{scenario.name} ({len(VARIANTS)} twins)",
    )
    m = _merge(parts)
    dt = NOMINAL.dt
    score = detection(scenario, m["events"][main], runs, faulty=True)
    fault_free = detection(scenario, m["events"]["fault_free"], runs, faulty=False)
    metrics: dict[str, Any] = {"reconstruction": reconstruction_metrics(m[main], scenario, dt)}
    metrics.update(deviation_metrics(m))
    metrics["detection"] = detection_metrics(probe, m)
    metrics["detection"].update(
        {
            "false_alarms": score.false_alarms,
            "fault_free_twin_false_alarms": fault_free.false_alarms,
            "fault_free_twin_false_alarms_per_1000s": fault_free.false_alarms_per_1000s,
        }
    )
    card = scorecard(
        scenario,
        runs=runs,
        seed=seed,
        observer=probe.observer_name,
        detector=probe.detector_name,
        compensation=options.compensation,
        score=score,
        metrics=metrics,
    )

    def plot(folder: Path) -> list[Path]:
        from windwarden.evaluation.hydro_plots import write_plots

        return write_plots(folder, scenario, m, dt)

    return Evaluation(scorecard=card, plot=plot)
