"""Plots of a farm evaluation (run 0 of the batch, and run means for the damage), after seed 001's Figs. 2–4.

* ``fig2_farm_power.png``: farm power vs demand, dispatch and PI on the fault-free farm (Fig. 2), with a zoom
  (Fig. 3) — from the ``--compare`` runs; without them, the evaluated run's farm power vs demand;
* ``turbine_power_vs_reference.png``: each turbine's power and its reference (run 0; on a farm of more than
  ``farm_scoring.MAX_SHOWN`` turbines, the faulty ones and then the first ones up to that many);
* ``fig4_damage.png``: drive-train damage number over time, without and with accommodation, mean over runs, for
  the turbines hit by drive-train faults (Fig. 4), the fault-free twin being 1 by construction; below it the Miner
  ratio of the farm's nine drive trains and of the turbines without a drive-train fault;
* ``detector_statistics.png``: per turbine and fault type, the test statistic over its threshold (run 0);
* ``faults_injected_vs_detected.png``: fault windows and the detector's flags per turbine (run 0).
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from plant_sim.farm.damage import WOHLER_M
from windwarden.evaluation.farm import DAMAGE_BIN_S, Variant
from windwarden.evaluation.farm_scoring import WARMUP_S, shown_turbines
from wwcore.scenario import Scenario
from wwcore.scenario.farm import FARM_FAULT_TYPES, farm_fault_name

MAX_LEGEND = 12  # turbines named in a legend at most
COLORS = {"debris": "tab:orange", "pitch_misalignment": "tab:purple", "drivetrain": "tab:red"}


def write_plots(out: Path, scenario: Scenario, main: Variant, comp: dict) -> list[Path]:
    written = []
    if main.trace:
        written.append(_farm_power(out / "fig2_farm_power.png", scenario, main, comp))
        written.append(_turbines(out / "turbine_power_vs_reference.png", scenario, main))
        written.append(_statistics(out / "detector_statistics.png", scenario, main))
        written.append(_timeline(out / "faults_injected_vs_detected.png", scenario, main))
    if "no_accommodation" in comp and main.twin_damage is not None:
        written.append(_damage(out / "fig4_damage.png", scenario, main, comp["no_accommodation"]))
    return written


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def _farm_power(path: Path, scenario: Scenario, main: Variant, comp: dict) -> Path:
    fig, (ax, zoom) = plt.subplots(2, 1, figsize=(11, 7))
    pairs = [("dispatch", comp.get("fault_free")), ("PI", comp.get("fault_free_pi"))]
    shown = [(name, v) for name, v in pairs if v is not None and v.trace]
    if not shown:
        shown = [(main.controller, main)]
    t0 = None
    for name, v in shown:
        tr = v.trace
        ax.plot(tr["t"], tr["power"][:, 0] / 1e6, lw=0.6, label=f"farm power, {name}")
        t0 = tr
    ax.plot(t0["t"], t0["demand"][:, 0] / 1e6, "k--", lw=0.8, label="demand")
    ax.set_ylabel("power [MW]")
    ax.set_title(f"{scenario.name}: farm power vs demand (cf. seed 001 Figs. 2–3)")
    ax.legend(loc="upper right", fontsize=8)
    mid = len(t0["t"]) // 2
    sel = slice(mid, min(mid + 1200, len(t0["t"])))  # a 120 s zoom
    for name, v in shown:
        zoom.plot(v.trace["t"][sel], v.trace["power"][sel, 0] / 1e6, lw=0.8, label=name)
    zoom.plot(t0["t"][sel], t0["demand"][sel, 0] / 1e6, "k--", lw=0.8, label="demand")
    zoom.set_xlabel("time [s]")
    zoom.set_ylabel("power [MW]")
    zoom.legend(loc="upper right", fontsize=8)
    for a in (ax, zoom):
        a.grid(alpha=0.3)
    return _save(fig, path)


def _turbines(path: Path, scenario: Scenario, v: Variant) -> Path:
    tr = v.trace
    shown = shown_turbines(scenario)
    columns = math.ceil(math.sqrt(len(shown)))
    rows = math.ceil(len(shown) / columns)
    fig, axes = plt.subplots(rows, columns, figsize=(13, 8), sharex=True, sharey=True, squeeze=False)
    for ax in axes.flat[len(shown) :]:
        ax.set_visible(False)
    for i, t in enumerate(shown):
        ax = axes.flat[i]
        ax.plot(tr["t"], tr["power_t"][:, t] / 1e6, lw=0.4, label="power")
        ax.plot(tr["t"], tr["ref_t"][:, t] / 1e6, lw=0.7, label="reference")
        ax.set_title(f"turbine {t + 1}", fontsize=9)
        ax.grid(alpha=0.3)
    axes.flat[0].legend(fontsize=7)
    fig.suptitle(f"{scenario.name}: power per turbine vs its reference (run 0, {v.controller})")
    return _save(fig, path)


def _statistics(path: Path, scenario: Scenario, v: Variant) -> Path:
    tr = v.trace
    fig, axes = plt.subplots(len(FARM_FAULT_TYPES), 1, figsize=(11, 8), sharex=True)
    n = scenario.plant.n_turbines
    for j, (ax, name) in enumerate(zip(axes, FARM_FAULT_TYPES, strict=True)):
        with np.errstate(invalid="ignore", divide="ignore"):
            margin = tr["stat"][:, :n, j] / tr["thr"][:, :n, j]
        for t in range(n):
            ax.plot(tr["t"], margin[:, t], lw=0.5, label=f"wt{t + 1}" if n <= MAX_LEGEND else None)
        ax.axhline(1.0, color="k", lw=0.8, ls="--")
        for w in scenario.faults:
            if _type(w) == name:
                ax.axvspan(w.start_s, w.end_s or scenario.duration_s, color=COLORS[name], alpha=0.15)
        ax.set_ylabel(f"{name}\nstatistic / threshold")
        ax.set_yscale("symlog", linthresh=1.0)
        ax.grid(alpha=0.3)
    if n <= MAX_LEGEND:
        axes[0].legend(ncol=9, fontsize=7, loc="upper left")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(f"{scenario.name}: detector `{v.detector}` statistics vs thresholds (run 0)")
    return _save(fig, path)


def _type(fault) -> str:
    return farm_fault_name(fault)


def _timeline(path: Path, scenario: Scenario, v: Variant) -> Path:
    tr = v.trace
    n = scenario.plant.n_turbines
    fig, ax = plt.subplots(figsize=(11, 4))
    for w in scenario.faults:
        name = _type(w)
        ax.broken_barh(
            [(w.start_s, (w.end_s or scenario.duration_s) - w.start_s)],
            (w.turbine - 0.4, 0.35),
            color=COLORS.get(name, "grey"),
            alpha=0.5,
        )
    for j, name in enumerate(FARM_FAULT_TYPES):
        flags = tr["flags"][:, :n, j]
        for t in range(n):
            on = flags[:, t].astype(bool)
            if on.any():
                ax.fill_between(tr["t"], t + 1.05, t + 1.4, where=on, color=COLORS[name], step="post", label=None)
    handles = [plt.Rectangle((0, 0), 1, 1, color=c, alpha=0.6) for c in COLORS.values()]
    ax.legend(handles, list(COLORS), loc="upper right", fontsize=8)
    ax.set_yticks(range(1, n + 1, max(1, n // 20)))
    ax.set_ylabel("turbine (lower bar injected, upper detected)")
    ax.set_xlabel("time [s]")
    ax.set_title(f"{scenario.name}: faults injected vs detected by `{v.detector}` (run 0)")
    ax.grid(alpha=0.3)
    return _save(fig, path)


def _damage(path: Path, scenario: Scenario, with_acc: Variant, without: Variant) -> Path:

    turbines = sorted({w.turbine for w in scenario.faults if _type(w) == "drivetrain"})
    fig, (ax, ax_farm) = plt.subplots(2, 1, figsize=(10, 7.5), sharex=True)
    t_end = (np.arange(with_acc.damage.shape[2]) + 1) * DAMAGE_BIN_S
    scored = t_end > WARMUP_S
    t_end = t_end[scored]
    n = scenario.plant.n_turbines
    healthy = [t for t in range(n) if t + 1 not in turbines]

    def number(v: Variant, rows: list[int], power: float) -> np.ndarray:
        """(mean Σ n S⁴ up to t / the twin's)^power over the runs, summed over ``rows``."""
        cum = np.cumsum(v.damage[:, rows][:, :, scored].sum(axis=1), axis=1)
        cum_ff = np.cumsum(v.twin_damage[:, rows][:, :, scored].sum(axis=1), axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            return (cum.mean(axis=0) / cum_ff.mean(axis=0)) ** power

    for label, v, style in (("no accommodation", without, "tab:red"), ("with accommodation", with_acc, "k")):
        if turbines:
            ax.plot(t_end, number(v, [t - 1 for t in turbines], 1.0 / WOHLER_M), color=style, label=label)
        ax_farm.plot(t_end, number(v, list(range(n)), 1.0), color=style, label=f"farm, {label}")
        ax_farm.plot(t_end, number(v, healthy, 1.0), color=style, ls=":", label=f"the other {len(healthy)}, {label}")
    for a in (ax, ax_farm):
        a.axhline(1.0, color="tab:blue", ls="--", label="fault free")
        for w in scenario.faults:
            if _type(w) == "drivetrain":
                a.axvspan(w.start_s, w.end_s or scenario.duration_s, color="tab:red", alpha=0.08)
        a.legend(loc="upper left", fontsize=8)
        a.grid(alpha=0.3)
    ax.set_ylabel("damage number (DEL up to t / fault-free)")
    ax.set_title(f"{scenario.name}: drive-train damage, turbines {turbines} (cf. seed 001 Fig. 4)")
    ax_farm.set_xlabel("time [s]")
    ax_farm.set_ylabel("Miner ratio (Σ n S⁴ up to t / fault-free)")
    ax_farm.set_title(
        f"the farm's {n} drive trains, and the turbines without a drive-train fault ({len(healthy)}), mean over runs"
    )
    return _save(fig, path)
