r"""Table 7's damage figures: the faulty turbine's and the farm's drive-train fatigue, against the fault-free twin.

D_t = Σ n_i S_i^m is the rainflow damage sum of turbine t's low-speed-shaft torque over a span
(``plant_sim.farm.damage``; m = 4), D'_t the same turbine's in the fault-free twin farm (same wind, noise and
supervisor, no faults). With one S–N curve for the farm's N identical drive trains, Miner's damage of turbine t is
D_t/K, so damage sums add across turbines. Per run and span:

* **damage number** of turbine t: (D_t / D'_t)^{1/m}, its DEL over the twin's (the paper's Table 7 figure);
* **Miner ratio** of turbine t: D_t / D'_t, its fatigue damage over the twin's;
* **farm Miner ratio**: Σ_t D_t / Σ_t D'_t over the N turbines: the farm's drive-train fatigue damage over the
  twin farm's, every turbine's damage counted at the same S–N curve. Its excess (ratio − 1) splits exactly into
  the faulty turbine's share (D_f − D'_f)/Σ_t D'_t and the other N − 1's, Σ_{t≠f} (D_t − D'_t)/Σ_t D'_t
  (``faulty_excess``, ``others_excess``): accommodation that moves damage onto the healthy turbines lowers the first
  and raises the second, and the farm's total shows whether it saved more than it moved;
* **others' Miner ratio**: Σ_{t≠f} D_t / Σ_{t≠f} D'_t, the N − 1 turbines without the window's fault.

Spans: the fault window [start, end) and the run (every bin after the warm-up). Each figure is computed per run
and averaged over the runs, and also **pooled** (``*_pooled``: the sums of all runs before the ratio, the runs'
total damage over their twins' total). A damage sum is dominated by its few largest cycles, so a run's ratio is
noisy and skewed (a run whose twin happened to miss a large cycle gives a large ratio), and the mean of ratios
lies above 1 for any change of trajectory, faulty or not; the pooled ratio weighs each run by its damage, as
fatigue life does. The main ones are also kept per run (the scorecard's ``per_run``, in run order) so that
two variants on the same seed and runs compare as paired differences (``windwarden compare``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from plant_sim.farm.damage import WOHLER_M
from wwcore.scenario.farm import FARM_FAULT_TYPES

if TYPE_CHECKING:
    from windwarden.evaluation.scoring import FaultWindow

NUMBER_WORDS = {8: "eight"}  # the others of the paper's nine, as its scorecards have always spelled them


def definition(turbines: int) -> str:
    """The scorecard's definition of the damage figures for a farm of ``turbines`` turbines."""
    others = NUMBER_WORDS.get(turbines - 1, str(turbines - 1))
    return (
        "D_t = rainflow damage sum Σ n S^4 of turbine t's low-speed-shaft torque over the span, D'_t the same "
        "turbine's in the fault-free twin farm. damage_number = (D_t/D'_t)^(1/4) (DEL ratio), miner_ratio = D_t/D'_t "
        f"of the faulty turbine; farm_miner_ratio = Σ_{turbines} D_t / Σ_{turbines} D'_t; others_miner_ratio the "
        f"same over the {others} turbines without the window's fault; faulty_excess = (D_f − D'_f)/Σ_{turbines} D'_t "
        f"and others_excess = Σ_(t≠f) (D_t − D'_t)/Σ_{turbines} D'_t add up to farm_miner_ratio − 1. Span: the fault "
        "window ('window') or the run after the warm-up ('run'). Per run, then the mean over runs (the scorecard's "
        "per_run keeps each run's value); *_pooled: the sums of all runs before the ratio (the runs' total damage "
        "over their twins' total). imbalance: |mean rotating-frame phasor Σ τ_r,i e^(j2π(i−1)/3)| over the window, "
        "N m"
    )


def _ratio(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0.0, num / np.where(den > 0.0, den, 1.0), np.where(num > 0.0, np.inf, 1.0))


def span_figures(damage: np.ndarray, twin: np.ndarray, faulty: int | None) -> dict[str, np.ndarray]:
    """Per-run figures of one span from damage sums ``damage``, ``twin`` (runs, N) and the faulty turbine's index
    (0-based; None: the farm only). Each value is an array over the runs."""
    farm, farm_twin = damage.sum(axis=1), twin.sum(axis=1)
    out = {"farm_miner_ratio": _ratio(farm, farm_twin)}
    out["farm_damage_number"] = out["farm_miner_ratio"] ** (1.0 / WOHLER_M)
    if faulty is not None:
        others = np.arange(damage.shape[1]) != faulty
        out["miner_ratio"] = _ratio(damage[:, faulty], twin[:, faulty])
        out["damage_number"] = out["miner_ratio"] ** (1.0 / WOHLER_M)
        out["others_miner_ratio"] = _ratio(damage[:, others].sum(axis=1), twin[:, others].sum(axis=1))
        out["faulty_excess"] = _ratio(damage[:, faulty] - twin[:, faulty], farm_twin)
        out["others_excess"] = _ratio((damage[:, others] - twin[:, others]).sum(axis=1), farm_twin)
    return out


def pooled(damage: np.ndarray, twin: np.ndarray, faulty: int | None) -> dict[str, float]:
    """The figures of ``span_figures`` with the sums of all runs pooled (Σ over runs before the ratio): the runs'
    total damage over their twins' total, which weighs each run by its damage rather than each run alike."""
    return {k: float(v[0]) for k, v in span_figures(damage.sum(axis=0)[None], twin.sum(axis=0)[None], faulty).items()}


def _means(
    figures: dict[str, np.ndarray], pool: dict[str, float], suffix: str, skip: tuple[str, ...] = ()
) -> dict[str, float]:
    """Each figure's mean over the runs (``<name>_<span>``) and pooled (``<name>_<span>_pooled``)."""
    out = {f"{name}_{suffix}": float(np.mean(v)) for name, v in figures.items() if name not in skip}
    return out | {f"{name}_{suffix}_pooled": v for name, v in pool.items() if name not in skip}


def turbine_numbers(damage: np.ndarray, twin: np.ndarray) -> dict[str, dict[str, float]]:
    """Each turbine's mean damage number and Miner ratio over a span, from sums (runs, N), and its pooled Miner
    ratio (Σ over runs before the ratio)."""
    miner = _ratio(damage, twin)
    pool = _ratio(damage.sum(axis=0), twin.sum(axis=0))
    return {
        f"wt{t + 1}": {
            "damage_number": float(np.mean(miner[:, t] ** (1.0 / WOHLER_M))),
            "miner_ratio": float(np.mean(miner[:, t])),
            "miner_ratio_pooled": float(pool[t]),
        }
        for t in range(damage.shape[1])
    }


PER_RUN_FIGURES = {  # the figures of a fault window kept per run, by span
    "window": ("damage_number", "miner_ratio", "farm_miner_ratio", "others_miner_ratio"),
    "run": ("damage_number", "miner_ratio", "others_miner_ratio"),
}


def _unique(names: list[str]) -> list[str]:
    """Fault names as keys: a repeated name gets its window's position appended."""
    return [n if names.count(n) == 1 else f"{n} #{i + 1}" for i, n in enumerate(names)]


def damage_metrics(
    damage: np.ndarray,
    twin_damage: np.ndarray | None,
    bin_s: float,
    warmup_s: float,
    windows: list[FaultWindow],
    targets: list[str],
    imbalance: np.ndarray,
    twin_imbalance: np.ndarray | None,
) -> tuple[dict[str, Any], dict[str, list[float]]]:
    """Table 7's damage figures from damage sums (runs, N, bins of ``bin_s``) and the twin's, per fault window
    (``targets``: their scorecard names) and over the run; ``imbalance`` (runs, N, windows) complex.

    Returns the means (``metrics.damage``) and the per-run values (``per_run``: "damage.<span or fault>.<figure>"
    → values in run order). Both empty without twins."""
    if twin_damage is None:
        return {}, {}
    starts = np.arange(damage.shape[2]) * bin_s
    scored = starts >= warmup_s  # the warm-up is left out, as everywhere
    if not scored.any():
        return {"note": f"the run is not longer than the {warmup_s:g} s warm-up"}, {}
    run_sums, run_twin = damage[:, :, scored].sum(axis=2), twin_damage[:, :, scored].sum(axis=2)
    per_run: dict[str, list[float]] = {}
    per_window, by_type = [], {name: [] for name in FARM_FAULT_TYPES}
    for i, (w, target, key) in enumerate(zip(windows, targets, _unique([w.name for w in windows]), strict=True)):
        t = w.turbine - 1
        inside = scored & (starts >= w.start_s) & (starts < w.end_s)
        win, win_twin = damage[:, :, inside].sum(axis=2), twin_damage[:, :, inside].sum(axis=2)
        spans = {"run": span_figures(run_sums, run_twin, t), "window": span_figures(win, win_twin, t)}
        entry: dict[str, Any] = {"fault": w.name, "target": target}
        farm_only = ("farm_miner_ratio", "farm_damage_number")  # over the run: the same for every window, below
        entry |= _means(spans["run"], pooled(run_sums, run_twin, t), "run", skip=farm_only)
        entry |= _means(spans["window"], pooled(win, win_twin, t), "window")
        entry["turbines_window"] = turbine_numbers(win, win_twin)
        for span, names in PER_RUN_FIGURES.items():
            per_run |= {f"damage.{key}.{name}_{span}": spans[span][name].tolist() for name in names}
        if w.target == "pitch_misalignment" and twin_imbalance is not None:
            imb, imb_ff = np.abs(imbalance[:, t, i]), np.abs(twin_imbalance[:, t, i])
            entry["imbalance_nm"] = float(np.mean(imb))
            entry["imbalance_fault_free_nm"] = float(np.mean(imb_ff))
            entry["imbalance_ratio"] = float(np.mean(imb) / max(np.mean(imb_ff), 1e-12))
            per_run[f"damage.{key}.imbalance_nm"] = imb.tolist()
        per_window.append(entry)
        if w.target in by_type:
            by_type[w.target].append(entry)
    keys = ["damage_number_run", "miner_ratio_run", "others_miner_ratio_run"]
    keys += [f"{name}_window" for name in ("damage_number", "miner_ratio", "farm_miner_ratio", "others_miner_ratio")]
    keys += [f"{key}_pooled" for key in keys if not key.startswith("damage_number")]
    summary = {}
    for name, entries in by_type.items():
        if entries:
            summary[name] = {key: float(np.mean([e[key] for e in entries])) for key in keys}
            if "imbalance_nm" in entries[0]:
                summary[name]["imbalance_nm"] = float(np.mean([e["imbalance_nm"] for e in entries]))
                summary[name]["imbalance_ratio"] = float(np.mean([e["imbalance_ratio"] for e in entries]))
    run = span_figures(run_sums, run_twin, None)
    per_run["damage.run.farm_miner_ratio"] = run["farm_miner_ratio"].tolist()
    per_run["damage.run.farm_damage_number"] = run["farm_damage_number"].tolist()
    miner = _ratio(run_sums, run_twin)
    for t in range(run_sums.shape[1]):
        per_run[f"damage.run.wt{t + 1}.damage_number"] = (miner[:, t] ** (1.0 / WOHLER_M)).tolist()
    metrics = {
        "definition": definition(run_sums.shape[1]),
        "by_type": summary,
        "farm_damage_number": float(np.mean(run["farm_damage_number"])),
        "farm_miner_ratio": float(np.mean(run["farm_miner_ratio"])),
        "farm_miner_ratio_pooled": pooled(run_sums, run_twin, None)["farm_miner_ratio"],
        "turbines_run": turbine_numbers(run_sums, run_twin),
        "per_fault": per_window,
    }
    return metrics, per_run
