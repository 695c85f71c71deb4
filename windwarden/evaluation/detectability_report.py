"""Tables (markdown, terminal) and plots of detectability sweeps (``detectability.sweep`` results)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rich.table import Table
from scipy import stats


def fmt(value: float | None, digits: int = 3) -> str:
    if value is None:
        return "–"
    if value == 0:
        return "0"
    return f"{value:.{digits}g}"


def level_text(result: dict[str, Any], what: str, level: str, ci: bool = True) -> str:
    """The size at a level (p50 | p95) of ``what`` (detected | isolated), as the docs' tables show it: the fitted
    size with its interval when it lies in the grid, else where the measured curve puts it."""
    entry = result["thresholds"][what][level]
    sizes = result["sizes"]
    measured = entry["measured"]
    if measured["status"] == "below":
        return f"≤ {fmt(sizes[0])}"
    if measured["status"] == "above":
        return f"> {fmt(sizes[-1])}"
    if entry.get("fitted") is None or not entry.get("within_grid"):
        lo, hi = measured["bracket"]
        return f"{fmt(lo)}–{fmt(hi)} (measured)"
    text = fmt(entry["fitted"])
    if ci and "ci95" in entry:
        lo, hi = entry["ci95"]
        text += f" [{_edge(lo, sizes)}, {_edge(hi, sizes)}]"
    return text


def _edge(value: float, sizes: Sequence[float]) -> str:
    if value < sizes[0]:
        return f"<{fmt(sizes[0])}"
    if value > sizes[-1]:
        return f">{fmt(sizes[-1])}"
    return fmt(value)


def _pct(value: float | None) -> str:
    return "–" if value is None else f"{value:.0f}"


def summary_markdown(results: Sequence[dict[str, Any]]) -> str:
    lines = [
        "| fault type | size unit | runs per size (layouts × runs) | 50 % detected | 95 % detected | "
        "95 % isolated (first flag) | false alarms per 1000 s |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in results:
        lines.append(
            f"| {r['fault_type']} | {_unit(r)} | {r['runs_per_size']} ({r['layouts']} × {r['runs_per_layout']}) | "
            f"{level_text(r, 'detected', 'p50')} | {level_text(r, 'detected', 'p95')} | "
            f"{level_text(r, 'isolated', 'p95')} | {r['false_alarms']['per_1000s']:.3f} "
            f"({r['false_alarms']['count']} in {r['false_alarms']['observed_s']:.0f} s) |"
        )
    return "\n".join(lines)


def _unit(r: dict[str, Any]) -> str:
    if r.get("sigma") is not None:
        return f"σ = {fmt(r['sigma'])} {r['value_unit']}"
    return r["unit"]


def _value(r: dict[str, Any], size: float) -> str:
    """A size in the fault value's own unit, where it differs."""
    if r.get("sigma") is not None:
        return f"{fmt(size * r['sigma'])} {r['value_unit']}"
    if r["unit"] == "%" and r["value_unit"] == "gain":
        return f"gain 1 ± {fmt(size / 100.0)}"
    if r["value_unit"] == "power factor":
        return f"× {fmt(1.0 - size / 100.0, 4)}"
    return ""


def type_markdown(r: dict[str, Any], image: str | None = None) -> str:
    """One fault type's section: its table by size, the 50 %/95 % sizes, and the plot."""
    bands = "detected_pct_below_rated" in r["rows"][0]
    head = "| size | fault value | n | detected % [95 % CI] | isolated % (first flag) | delay s mean / max | "
    head += "wrong isolation % | lost % | flaps per window |"
    rule = "|---|---|---|---|---|---|---|---|---|"
    if bands:
        head += " detected % below / above rated |"
        rule += "---|"
    lines = [f"### {r['fault_type']}: {r['label']}", ""]
    lines.append(
        f"Size in {_unit(r)}; {r['runs_per_size']} window-runs per size ({r['layouts']} layouts × "
        f"{r['runs_per_layout']} runs), {r['window_s']:g} s windows, winds {r['wind_range_mps'][0]:g}–"
        f"{r['wind_range_mps'][1]:g} m/s, base `{r['base']}`, seed {r['seed']}."
    )
    lines += ["", head, rule]
    for row in r["rows"]:
        lo, hi = row["detected_ci_pct"]
        delay = "–" if row["delay_s_mean"] is None else f"{fmt(row['delay_s_mean'])} / {fmt(row['delay_s_max'])}"
        line = (
            f"| {fmt(row['size'])} | {_value(r, row['size'])} | {row['n']} | {_pct(row['detected_pct'])} "
            f"[{lo:.0f}–{hi:.0f}] | {_pct(row['isolated_pct'])} | {delay} | {_pct(row['wrong_isolation_pct'])} | "
            f"{_pct(row['lost_pct'])} | {fmt(row['flaps_mean'], 2)} |"
        )
        if bands:
            line += f" {_pct(row['detected_pct_below_rated'])} / {_pct(row['detected_pct_above_rated'])} |"
        lines.append(line)
    lines += [
        "",
        f"Detected by 50 %: {level_text(r, 'detected', 'p50')}; by 95 %: {level_text(r, 'detected', 'p95')}; "
        f"isolated (first flag) by 95 %: {level_text(r, 'isolated', 'p95')} ({r['unit']}; probit fit, layout-"
        f"bootstrap 95 % interval). False alarms {r['false_alarms']['per_1000s']:.3f} per 1000 s "
        f"({r['false_alarms']['count']} in {r['false_alarms']['observed_s']:.0f} s outside the windows).",
    ]
    if image:
        lines += ["", f"![{r['fault_type']}]({image})"]
    return "\n".join(lines)


def markdown(results: Sequence[dict[str, Any]], images: dict[str, str] | None = None) -> str:
    images = images or {}
    parts = ["# Detectability", "", summary_markdown(results)]
    for r in results:
        parts += ["", type_markdown(r, images.get(r["fault_type"]))]
    return "\n".join(parts) + "\n"


def console_table(results: Sequence[dict[str, Any]]) -> Table:
    table = Table(title="detectability (sizes at which 50 % / 95 % of windows are detected)")
    for column in ("fault type", "unit", "runs/size", "50 % det.", "95 % det.", "95 % isol.", "FA/1000 s"):
        table.add_column(column)
    for r in results:
        table.add_row(
            r["fault_type"],
            _unit(r),
            str(r["runs_per_size"]),
            level_text(r, "detected", "p50", ci=False),
            level_text(r, "detected", "p95"),
            level_text(r, "isolated", "p95", ci=False),
            f"{r['false_alarms']['per_1000s']:.3f}",
        )
    return table


def plot(r: dict[str, Any], path: Path) -> Path:
    """Detected and isolated % (95 % intervals, fitted probit) and mean delay against size, log size axis."""
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    rows = r["rows"]
    sizes = np.array([row["size"] for row in rows])
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(5.6, 4.6), sharex=True, height_ratios=(2, 1))
    for what, marker, colour, shift in (("detected", "o", "tab:blue", 0.97), ("isolated", "s", "tab:orange", 1.03)):
        pct = np.array([row[f"{what}_pct"] for row in rows], dtype=float)
        ci = np.array([row[f"{what}_ci_pct"] for row in rows], dtype=float)
        err = np.vstack([pct - ci[:, 0], ci[:, 1] - pct])
        label = f"{what} % (first flag)" if what == "isolated" else f"{what} %"
        top.errorbar(sizes * shift, pct, yerr=err, fmt=marker, color=colour, ms=4, capsize=2, label=label)
        fit = r["thresholds"][what]["fit"]
        if fit is not None:
            grid = np.exp(np.linspace(math.log(sizes[0]), math.log(sizes[-1]), 200))
            curve = 100.0 * stats.norm.cdf((np.log(grid) - fit["mu"]) / fit["sigma"])
            top.plot(grid, curve, color=colour, lw=1, alpha=0.8)
    for level in (50, 95):
        top.axhline(level, color="grey", lw=0.6, ls=":")
    top.set_ylim(-3, 103)
    top.set_ylabel("% of window-runs")
    top.set_title(f"{r['fault_type']} ({r['runs_per_size']} window-runs per size)", fontsize=9)
    top.legend(fontsize=7, loc="lower right")
    delays = [(row["size"], row["delay_s_mean"]) for row in rows if row["delay_s_mean"] is not None]
    if delays:
        x, y = zip(*delays, strict=True)
        bottom.plot(x, np.maximum(y, 1e-3), "o-", color="tab:green", ms=3, lw=1)
        bottom.set_yscale("log")
    bottom.set_ylabel("mean delay s")
    bottom.set_xscale("log")
    bottom.set_xticks(sizes, [f"{s:g}" for s in sizes])
    bottom.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
    bottom.set_xlabel(f"size ({_unit(r)})")
    for ax in (top, bottom):
        ax.grid(True, which="both", lw=0.3, alpha=0.5)
        ax.tick_params(labelsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path
