"""Plots of a turbine evaluation, after seed 000's Figs. 2–7 (run 0 of the batch)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from windwarden.evaluation.scoring import FaultWindow
from wwcore.scenario import Scenario

MARGIN_S = 50.0


def plot_turbine(scenario: Scenario, trace: dict[str, np.ndarray], windows: list[FaultWindow], out: Path) -> list[Path]:
    if not trace:
        return []
    written = [_overview(scenario, trace, out / "fig2_wind_fte_vs_true.png")]
    for i, w in enumerate(windows, start=1):
        written.append(_window(trace, w, out / f"fault{i}_{_slug(w.target)}.png"))
    return written


def _slug(text: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in text)


def _overview(scenario: Scenario, trace: dict[str, np.ndarray], path: Path) -> Path:
    fig, ax = plt.subplots(figsize=(11, 4))
    ax.plot(trace["t"], trace["wind"], lw=0.6, label="true rotor-effective wind")
    ax.plot(trace["t"], trace["fte"], lw=0.6, label="FTE")
    if np.isfinite(trace.get("fte_clean", [np.nan])).any():
        ax.plot(trace["t"], trace["fte_clean"], lw=0.6, alpha=0.7, label="FTE of the clean run (no fault)")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("wind speed [m/s]")
    ax.set_title(f"{scenario.name}: fault-tolerant wind speed estimate vs true wind (cf. seed 000 Fig. 2)")
    ax.legend(loc="upper right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def _window(trace: dict[str, np.ndarray], w: FaultWindow, path: Path) -> Path:
    t = trace["t"]
    sel = (t >= w.start_s - MARGIN_S) & (t <= w.end_s + MARGIN_S)
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    top.plot(t[sel], trace["wind"][sel], lw=0.7, label="true")
    top.plot(t[sel], trace["fte"][sel], lw=0.7, label="FTE")
    top.plot(t[sel], trace["nfte"][sel], lw=0.7, alpha=0.7, label="NFTE (observer 1)")
    if w.target == "v_hub_m":
        top.plot(t[sel], trace["anemometer"][sel], lw=0.4, alpha=0.5, label="anemometer")
    top.axvspan(w.start_s, w.end_s, color="red", alpha=0.08, label="fault")
    top.set_ylabel("wind [m/s]")
    top.legend(loc="upper right", fontsize=8)
    top.set_title(f"{w.name} ({w.target}), cf. seed 000 Figs. 3–7")
    bottom.plot(t[sel], trace["fte"][sel] - trace["nfte"][sel], lw=0.7, color="k")
    bottom.axvspan(w.start_s, w.end_s, color="red", alpha=0.08)
    bottom.set_ylabel("FTE − NFTE [m/s]")
    bottom.set_xlabel("time [s]")
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
