"""Plots of a hydrostatic evaluation in the manner of the paper's Figs. 5–12 (run 0 of the Monte Carlo set).

* ``fig05-06_reconstruction.png``: true offsets f_a, reconstructed f̂_a,filt, and the actual pump and motor
  displacements without and with compensation (Figs. 5–6);
* ``fig07_generator_speed.png``: ω_g fault-free, without and with compensation (Fig. 7);
* ``fig08_power.png``: generator power P_g fault-free, faulty, compensated (Fig. 8);
* ``fig09-12_generator_speed.png``: ω_g fault-free vs compensated (Fig. 9 nominal, 10 leakage, 11 aero,
  12 noise, depending on the scenario's uncertainty options);
* ``rotor_speed.png``: ω_r of the three twins, with the overspeed margin;
* ``reconstruction_error.png``: |f̂_filt − f| over all runs (median and maximum).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from wwcore.hydro_params import NOMINAL
from wwcore.scenario import Scenario

COLORS = {"fault_free": "tab:blue", "uncompensated": "tab:red", "compensated": "black"}


def _case(scenario: Scenario) -> str:
    p = scenario.plant
    if p.leak_factor != 1.0:
        return f"Fig. 10 (leakage ×{p.leak_factor:g})"
    if p.delta_cq != 0.0:
        return f"Fig. 11 (δ_CQ = {p.delta_cq:g})"
    if p.noise_pct >= 1.0:
        return f"Fig. 12 (noise ±{p.noise_pct:g} %)"
    return "Fig. 9 (nominal)"


def _save(fig: Any, path: Path, written: list[Path]) -> None:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    written.append(path)


def write_plots(folder: Path, scenario: Scenario, m: dict[str, Any], dt: float, run: int = 0) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    t = np.arange(m["fault_free"]["omega_g"].shape[0]) * dt
    written: list[Path] = []
    title = f"{scenario.name}, run {run}"

    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    for j, (name, ax) in enumerate(zip(("f_a,1 on u_p", "f_a,2 on u_M"), axes[:2], strict=True)):
        ax.plot(t, m["compensated"]["f_true"][:, run, j], color="tab:blue", lw=1.5, label="f_a (true)")
        ax.plot(t, m["compensated"]["f_filt"][:, run, j], "--", color="black", lw=1, label="f̂_a,filt (compensated)")
        ax.plot(t, m["uncompensated"]["f_filt"][:, run, j], ":", color="tab:red", lw=1, label="f̂_a,filt (uncomp.)")
        ax.set_ylabel(name)
        ax.legend(loc="lower right", fontsize=8)
    for name, style in (("x_p", "-"), ("x_M", "--")):
        for variant in ("uncompensated", "compensated"):
            axes[2].plot(t, m[variant][name][:, run], style, color=COLORS[variant], lw=1, label=f"{name} {variant}")
    axes[2].set_ylabel("displacement x̃ (–)")
    axes[2].set_xlabel("t (s)")
    axes[2].legend(fontsize=8, ncol=2)
    axes[0].set_title(f"Figs. 5–6: actuator offsets and reconstruction — {title}")
    _save(fig, folder / "fig05-06_reconstruction.png", written)

    fig, ax = plt.subplots(figsize=(9, 4))
    for variant in ("fault_free", "uncompensated", "compensated"):
        ax.plot(t, m[variant]["omega_g"][:, run], color=COLORS[variant], lw=1, label=variant.replace("_", "-"))
    ax.set(xlabel="t (s)", ylabel="ω_g (rad/s)", title=f"Fig. 7: generator speed — {title}")
    ax.legend()
    _save(fig, folder / "fig07_generator_speed.png", written)

    fig, ax = plt.subplots(figsize=(9, 4))
    for variant, style in (("fault_free", "-"), ("uncompensated", "-"), ("compensated", "--")):
        ax.plot(t, m[variant]["P_g"][:, run] / 1e6, style, color=COLORS[variant], lw=1, label=variant)
    ax.set(xlabel="t (s)", ylabel="P_g (MW)", title=f"Fig. 8: generator power — {title}")
    ax.legend()
    _save(fig, folder / "fig08_power.png", written)

    fig, ax = plt.subplots(figsize=(9, 4))
    for variant in ("fault_free", "compensated"):
        ax.plot(t, m[variant]["omega_g"][:, run], color=COLORS[variant], lw=1, label=variant.replace("_", "-"))
    ax.set(xlabel="t (s)", ylabel="ω_g (rad/s)", title=f"{_case(scenario)}: generator speed — {title}")
    ax.legend()
    _save(fig, folder / "fig09-12_generator_speed.png", written)

    fig, ax = plt.subplots(figsize=(9, 4))
    for variant in ("fault_free", "uncompensated", "compensated"):
        ax.plot(t, m[variant]["omega_r"][:, run], color=COLORS[variant], lw=1, label=variant)
    ax.axhline(NOMINAL.omega_r_rated, color="gray", ls=":", label="rated rotor speed")
    ax.set(xlabel="t (s)", ylabel="ω_r (rad/s)", title=f"rotor speed — {title}")
    ax.legend()
    _save(fig, folder / "rotor_speed.png", written)

    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for j, ax in enumerate(axes):
        err = np.abs(m["compensated"]["f_filt"][:, :, j] - m["compensated"]["f_true"][:, :, j])
        ax.semilogy(t, np.median(err, axis=1) + 1e-6, color="black", lw=1, label="median over runs")
        ax.semilogy(t, err.max(axis=1) + 1e-6, color="tab:red", lw=0.8, label="max over runs")
        ax.set_ylabel(f"|f̂_filt − f| on {('u_p', 'u_M')[j]}")
        ax.legend(fontsize=8)
    axes[-1].set_xlabel("t (s)")
    axes[0].set_title(f"reconstruction error, compensated, all runs — {scenario.name}")
    _save(fig, folder / "reconstruction_error.png", written)
    return written
