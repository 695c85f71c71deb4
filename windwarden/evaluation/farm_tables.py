"""Seed 001's Tables 5, 6 and 7 next to ours, as markdown (``windwarden eval farm-caseN --compare``).

The companion runs (``comparison_runs``), all on the same seed and run indices as the main evaluation:

* ``paper``: the scenario with the paper's detector (Table 5);
* ``no_accommodation``: the scenario with the main detector and the dispatch without accommodation (Table 7);
* ``paper_accommodation``: the same with the accommodation of eqs. (23)–(26) as published (eq. (26)'s P_min floor
  for the pitch and the drive-train faults; Table 7), when the main run uses another rule;
* the fault-free farm (the scenario without its faults): ``fault_free`` with the main detector and the dispatch,
  ``fault_free_paper`` with the paper's detector (false positives of both detectors, Table 5) and
  ``fault_free_pi`` with the PI farm controller (Table 6).

False positives in Table 5 are counted on the fault-free runs and outside the fault windows of the faulty runs
together, per 1000 s of farm operation (the paper's basis) and per fault type.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from service.farm.dispatch import ACCOMMODATION_RULES
from windwarden.evaluation.farm import Variant, run_variant, scorecard_of
from windwarden.evaluation.farm_damage import NUMBER_WORDS
from windwarden.evaluation.farm_scoring import (
    WARMUP_S,
    detection_by_type,
    energy_metrics,
    farm_windows,
    shown_turbines,
)
from windwarden.evaluation.kinds import EvalOptions
from windwarden.evaluation.paired import paired_row
from wwcore.scenario import Scenario
from wwcore.scenario.farm import FARM_FAULT_TYPES

# seed 001, Table 5: (detection time s or None, missed %, false positives per 1000 s) per case and fault
PAPER_TABLE5 = {
    1: {"debris": (0.795, 0.0, 0.061), "pitch_misalignment": (4.114, 50.0, 3.464), "drivetrain": (6.752, 0.0, 0.546)},
    2: {"debris": (0.775, 0.0, 1.746), "pitch_misalignment": (None, 100.0, 3.836), "drivetrain": (6.946, 0.0, 1.477)},
}
# Table 6: over-production and missing power of the PI reference, the dispatch normalised to 1
PAPER_TABLE6 = {1: (18.2, 1.0003), 2: (24.93, 1.00006)}
# Table 7: damage 2 and damage 3 without / with accommodation
PAPER_TABLE7 = {
    1: ((float("inf"), 1.0201), (float("inf"), 1.0040)),
    2: ((float("inf"), 1.0190), (float("inf"), 1.0032)),
}
FAULT_LABEL = {"debris": "F1", "pitch_misalignment": "F2", "drivetrain": "F3"}


def fault_free(scenario: Scenario) -> Scenario:
    return scenario.model_copy(update={"faults": [], "name": f"{scenario.name}-fault-free"})


def accommodation_rule(scenario: Scenario) -> str:
    return str(scenario.supervisor.params.get("accommodation_rule", ACCOMMODATION_RULES[0]))


def published(scenario: Scenario) -> Scenario:
    """The scenario with the accommodation of eqs. (23)–(26) as published, for the pitch fault too."""
    params = {**scenario.supervisor.params, "accommodation_rule": "paper", "pitch_rule": "paper"}
    return scenario.model_copy(update={"supervisor": scenario.supervisor.model_copy(update={"params": params})})


def comparison_runs(scenario: Scenario, runs: int, seed: int, options: EvalOptions, main: Variant) -> dict:
    """The companion configurations of Tables 5–7, on the same runs and seed as ``main``."""

    det, ctrl = main.detector, main.controller
    ff = fault_free(scenario)
    # name: (scenario, detector, controller, accommodation, twins, label)
    plan = {}
    if scenario.faults:
        plan["paper"] = (scenario, "paper", ctrl, main.accommodation, False, "paper detector")
        plan["no_accommodation"] = (scenario, det, "dispatch", False, True, "no accommodation")
        if main.accommodation and accommodation_rule(scenario) != "paper":
            plan["paper_accommodation"] = (published(scenario), det, "dispatch", True, True, "eq. (26)")
        plan["fault_free"] = (ff, det, "dispatch", True, False, "dispatch")
    plan["fault_free_paper"] = (ff, "paper", "dispatch", True, False, "paper detector")
    plan["fault_free_pi"] = (ff, det, "pi", True, False, "PI")
    return {
        name: run_variant(
            scn,
            runs,
            seed,
            options,
            detector=detector,
            controller=controller,
            accommodation=accommodation,
            twins=twins,
            label=f"{scn.name} ({label})",
        )
        for name, (scn, detector, controller, accommodation, twins, label) in plan.items()
    }


def _paper(x: float | None, case: int | None, digits: int = 3) -> str:
    """A figure of the paper's; – where the farm is not its 3 × 3."""
    return "–" if case is None else _fmt(x, digits)


def _fmt(x: float | None, digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and np.isnan(x)):
        return "NaN"
    if isinstance(x, float) and np.isinf(x):
        return "inf"
    return f"{x:.{digits}g}"


def table5_rows(scenario: Scenario, faulty: Variant | None, fault_free_run: Variant) -> dict[str, dict[str, Any]]:
    """Per fault type: delay, missed %, false positives per 1000 farm-s (fault-free runs + outside windows)."""

    turbines = scenario.plant.n_turbines
    ff = detection_by_type(fault_free_run.events, [], fault_free_run.runs, fault_free_run.scenario.duration_s, turbines)
    rows: dict[str, dict[str, Any]] = {}
    faulty_by = (
        detection_by_type(faulty.events, farm_windows(scenario), faulty.runs, scenario.duration_s, turbines)
        if faulty
        else {}
    )
    ff_seconds = fault_free_run.runs * (fault_free_run.scenario.duration_s - WARMUP_S)
    for name in FARM_FAULT_TYPES:
        f = faulty_by.get(name, {})
        count = ff[name]["false_positives"] + f.get("false_positives", 0)
        seconds = ff_seconds + (faulty.runs * (scenario.duration_s - WARMUP_S) if faulty else 0.0)
        rows[name] = {
            "delay_s": f.get("delay_s_mean"),
            "delay_s_max": f.get("delay_s_max"),
            "missed_pct": f.get("missed_pct"),
            "false_positives": count,
            "fp_per_1000s": 1000.0 * count / seconds,
            "fp_per_1000s_fault_free_only": ff[name]["false_positives_per_1000s"],
        }
    return rows


def paper_case(scenario: Scenario) -> int | None:
    """The paper's wind case when the farm is its 3 × 3 in one of its two winds; None: the paper has no figures."""
    return scenario.plant.wind_case if scenario.plant.is_paper_farm() else None


def farm_words(scenario: Scenario) -> tuple[str, str]:
    """(all, the others but one) of the farm's turbines as the tables write them: "nine", "eight" on the 3 × 3."""
    n = scenario.plant.n_turbines
    return ("nine" if n == 9 else str(n)), NUMBER_WORDS.get(n - 1, str(n - 1))


def tables_markdown(scenario: Scenario, main: Variant, comp: dict) -> str:

    case = paper_case(scenario)
    if case is None:
        plant = scenario.plant
        title = (
            f"# Tables 5–7 of seed 001's method: {plant.n_turbines} turbines, wind from {plant.direction_deg:g}° "
            f"(`{scenario.name}`, {main.runs} runs, seed {main.seed}); the paper's columns are for its 3 × 3 (–)"
        )
    else:
        title = f"# Seed 001, Tables 5–7: wind case {case} (`{scenario.name}`, {main.runs} runs, seed {main.seed})"
    lines = [
        title,
        "",
        "Ours: this project's farm plant (docs/farm.md); the paper's numbers from seed 001. Detection delay is the",
        "mean over detected faults of the time from onset to the first detection of the right fault type; missed is",
        "the share of fault windows not detected with the right type; false positives are detections of that type",
        "outside its fault windows, counted on the fault-free and the faulty runs together, per 1000 s of farm time.",
        "",
        "## Table 5: fault detection",
        "",
        "| fault | paper: delay | paper: missed | paper: FP/1000 s | ours, paper's detector: delay | missed "
        f"| FP/1000 s | ours, `{main.detector}`: delay | missed | FP/1000 s |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    ours_paper = table5_rows(scenario, comp.get("paper"), comp["fault_free_paper"])
    ours_main = table5_rows(scenario, main if scenario.faults else None, comp.get("fault_free", main))
    for name in FARM_FAULT_TYPES:
        a, b = ours_paper[name], ours_main[name]
        if case is None:
            paper = "| – | – | –"
        else:
            pd, pm, pf = PAPER_TABLE5[case][name]
            paper = f"| {_fmt(pd)} s | {_fmt(pm)} % | {_fmt(pf)}"
        lines.append(
            f"| {FAULT_LABEL[name]} {name} {paper} "
            f"| {_fmt(a['delay_s'])} s | {_fmt(a['missed_pct'])} % | {_fmt(a['fp_per_1000s'])} "
            f"| {_fmt(b['delay_s'])} s | {_fmt(b['missed_pct'])} % | {_fmt(b['fp_per_1000s'])} |"
        )
    dispatch = _energy(comp.get("fault_free", main) if scenario.faults else main)
    pi = _energy(comp["fault_free_pi"])
    over_d, miss_d = dispatch["over_production"]["mwh_per_run"], dispatch["missing_power"]["mwh_per_run"]
    over_p, miss_p = pi["over_production"]["mwh_per_run"], pi["missing_power"]["mwh_per_run"]
    po, pmiss = ("–", "–") if case is None else (f"{PAPER_TABLE6[case][0]:g}", f"{PAPER_TABLE6[case][1]:g}")
    lines += [
        "",
        "## Table 6: power tracking on the fault-free farm (lower is better; dispatch = 1)",
        "",
        "| controller | paper: over | paper: missing | ours: over | ours: missing | ours: over MWh/run | "
        "ours: missing MWh/run |",
        "|---|---|---|---|---|---|---|",
        f"| PI reference | {po} | {pmiss} | {_fmt(over_p / over_d if over_d > 0 else np.inf)} "
        f"| {_fmt(miss_p / miss_d if miss_d > 0 else np.inf, 4)} | {_fmt(over_p)} | {_fmt(miss_p)} |",
        f"| dispatch | 1 | 1 | 1 | 1 | {_fmt(over_d)} | {_fmt(miss_d)} |",
    ]
    if scenario.faults and "no_accommodation" in comp:
        lines += table7_lines(scenario, main, comp)
    lines.append("")
    return "\n".join(lines)


ACCOMMODATION_LABEL = {
    "paper": "eqs. (23)–(26) as published",
    "hold-torque": "(23)–(24), pitch trim (D-28), drive train held by speed, its 3P cancelled (D-26b, D-30)",
    "cancel": "(23)–(24), pitch trim (D-28), drive train's 3P cancelled, its ripple by the farm (D-31, D-29)",
}
PAIRED = (  # per-run metrics Table 7 gives as paired differences, accommodated − not
    ("missing power, MWh", "missing_power_mwh"),
    ("farm drive-train damage over the run (Miner, {n} turbines)", "damage.run.farm_miner_ratio"),
)


def table7_lines(scenario: Scenario, main: Variant, comp: dict) -> list[str]:
    """Table 7: the faulty turbine's damage beside the farm's (all its turbines), per fault window and over the
    run, without accommodation, with eq. (26) as published and with the main rule; paired differences per run."""

    case = paper_case(scenario)
    every, others = farm_words(scenario)
    (p2n, p3n), (p2a, p3a) = PAPER_TABLE7[case] if case is not None else ((None, None), (None, None))
    variants = [("no accommodation", comp["no_accommodation"], p2n, p3n)]
    if "paper_accommodation" in comp:
        variants.append((ACCOMMODATION_LABEL["paper"], comp["paper_accommodation"], p2a, p3a))
    variants.append((ACCOMMODATION_LABEL[accommodation_rule(scenario)], main, p2a, p3a))
    cards = [scorecard_of(v) for _, v, *_ in variants]
    lines = [
        "",
        "## Table 7: damage with and without accommodation, the faulty turbine's and the farm's",
        "",
        "Damage 3: DEL of the faulty turbine's shaft torque (rainflow, m = 4) over the whole run / its fault-free",
        "twin's (run), and over the fault window only (window), mean of the drive-train windows. Damage 2: rotor",
        "imbalance (1P phasor of the blade torques) over the fault window / the twin's; the twin's is ≈ 0, so the",
        f"ratio is huge (paper: inf); in N m as well. Farm: the {every} turbines' rainflow damage sums Σ_t Σ n S⁴ over",
        "the twin farm's (Miner's damage of the farm's drive trains over the twin's), per run then the mean, and",
        "pooled (the runs' sums before the ratio).",
        "",
        "| | paper: damage 2 | paper: damage 3 | ours: damage 2 (ratio; N m) | ours: damage 3 run "
        "| ours: damage 3 window | ours: farm Miner, run (mean of runs; pooled) | ours: missing MWh/run |",
        "|---|---|---|---|---|---|---|---|",
    ]

    def dn(card: dict, name: str, key: str) -> float | None:
        return card["metrics"]["damage"].get("by_type", {}).get(name, {}).get(key)

    for (label, _, paper2, paper3), card in zip(variants, cards, strict=True):
        lines.append(
            f"| {label} | {_paper(paper2, case)} | {_paper(paper3, case, 5)} "
            f"| {_fmt(dn(card, 'pitch_misalignment', 'imbalance_ratio'))}; "
            f"{_fmt(dn(card, 'pitch_misalignment', 'imbalance_nm'))} "
            f"| {_fmt(dn(card, 'drivetrain', 'damage_number_run'), 5)} "
            f"| {_fmt(dn(card, 'drivetrain', 'damage_number_window'), 4)} "
            f"| {_fmt(card['metrics']['damage'].get('farm_miner_ratio'), 4)}; "
            f"{_fmt(card['metrics']['damage'].get('farm_miner_ratio_pooled'), 4)} "
            f"| {_fmt(card['metrics']['missing_power']['mwh_per_run'])} |"
        )
    lines.append("")
    without = cards[0]
    for (label, *_), card in zip(variants[1:], cards[1:], strict=True):
        for span in ("run", "window"):
            n3, a3 = dn(without, "drivetrain", f"damage_number_{span}"), dn(card, "drivetrain", f"damage_number_{span}")
            nm, am = dn(without, "drivetrain", f"miner_ratio_{span}"), dn(card, "drivetrain", f"miner_ratio_{span}")
            if None not in (n3, a3, nm, am) and n3 > 1.0 and nm > 1.0:
                lines.append(
                    f"Excess drive-train damage of the faulty turbine removed by {label}, over the {span}: "
                    f"{100.0 * (n3 - a3) / (n3 - 1.0):.0f} % of the damage number's (DEL ratio) excess, "
                    f"{100.0 * (nm - am) / (nm - 1.0):.0f} % of the fatigue damage's (Miner, Σ n S⁴) excess.  "
                )
    lines += [
        "",
        f"### Table 7, per fault window: the faulty turbine, the other {others} and the farm",
        "",
        "Miner ratios over the window (Σ n S⁴ / the twin's); the farm's excess (farm − 1) is the faulty turbine's",
        f"share plus the other {others}'s, both in units of the twin farm's damage over the window: damage moved onto",
        "the healthy turbines shows as a larger 'others' share.",
        "",
        f"| fault window | variant | faulty: damage number | faulty: Miner | other {others}: Miner | farm: Miner "
        "| farm excess: faulty + others |",
        "|---|---|---|---|---|---|---|",
    ]
    for i, entry in enumerate(cards[0]["metrics"]["damage"].get("per_fault", [])):
        for (label, *_), card in zip(variants, cards, strict=True):
            e = card["metrics"]["damage"]["per_fault"][i]
            lines.append(
                f"| {entry['fault']} | {label} | {_fmt(e['damage_number_window'], 4)} "
                f"| {_fmt(e['miner_ratio_window'], 4)} | {_fmt(e['others_miner_ratio_window'], 4)} "
                f"| {_fmt(e['farm_miner_ratio_window'], 4)} "
                f"| {e['faulty_excess_window']:+.3f} {e['others_excess_window']:+.3f} |"
            )
    shown = shown_turbines(scenario)
    lines += [
        "",
        "### Table 7, over the run: each turbine's damage number and the farm's Miner ratio"
        + ("" if len(shown) == scenario.plant.n_turbines else " (the faulty turbines, then the first)"),
        "",
        "| variant | " + " | ".join(f"wt{t + 1}" for t in shown) + " | farm: Miner | farm: damage number |",
        "|---" * (len(shown) + 3) + "|",
    ]
    for (label, *_), card in zip(variants, cards, strict=True):
        d = card["metrics"]["damage"]
        numbers = " | ".join(_fmt(d["turbines_run"][f"wt{t + 1}"]["damage_number"], 4) for t in shown)
        lines.append(f"| {label} | {numbers} | {_fmt(d['farm_miner_ratio'], 4)} | {_fmt(d['farm_damage_number'], 4)} |")
    lines += [
        "",
        f"### Table 7, paired per run: accommodated ({ACCOMMODATION_LABEL[accommodation_rule(scenario)]}) − none",
        "",
        "Mean of the runs' differences ± its standard error (the same runs and seed; `windwarden compare`).",
        "",
        "| metric | none | accommodated | difference ± SE | runs lower |",
        "|---|---|---|---|---|",
    ]
    for label, key in PAIRED:
        if key in cards[0]["per_run"] and key in cards[-1]["per_run"]:
            r = paired_row(key, cards[0]["per_run"][key], cards[-1]["per_run"][key])
            name = label.format(n=scenario.plant.n_turbines)
            lines.append(
                f"| {name} | {_fmt(r.mean_a, 4)} | {_fmt(r.mean_b, 4)} | {r.diff:+.3g} ± {_fmt(r.se, 2)} "
                f"| {r.lower} of {r.n} |"
            )
    return lines


def _energy(v: Variant) -> dict[str, Any]:
    return energy_metrics(v.over_j, v.missing_j, v.demand_j)
