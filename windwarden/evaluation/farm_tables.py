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

from typing import TYPE_CHECKING, Any

import numpy as np

from wwcore.scenario import Scenario
from wwcore.scenario.farm import FARM_FAULT_TYPES

if TYPE_CHECKING:
    from windwarden.evaluation.farm import Variant
    from windwarden.evaluation.kinds import EvalOptions

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
    from service.farm.dispatch import ACCOMMODATION_RULES

    return str(scenario.supervisor.params.get("accommodation_rule", ACCOMMODATION_RULES[0]))


def published(scenario: Scenario) -> Scenario:
    """The scenario with the accommodation of eqs. (23)–(26) as published, for the pitch fault too."""
    params = {**scenario.supervisor.params, "accommodation_rule": "paper", "pitch_rule": "paper"}
    return scenario.model_copy(update={"supervisor": scenario.supervisor.model_copy(update={"params": params})})


def comparison_runs(scenario: Scenario, runs: int, seed: int, options: EvalOptions, main: Variant) -> dict:
    """The companion configurations of Tables 5–7, on the same runs and seed as ``main``."""
    from windwarden.evaluation.farm import run_variant

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


def _fmt(x: float | None, digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and np.isnan(x)):
        return "NaN"
    if isinstance(x, float) and np.isinf(x):
        return "inf"
    return f"{x:.{digits}g}"


def table5_rows(scenario: Scenario, faulty: Variant | None, fault_free_run: Variant) -> dict[str, dict[str, Any]]:
    """Per fault type: delay, missed %, false positives per 1000 farm-s (fault-free runs + outside windows)."""
    from windwarden.evaluation.farm import WARMUP_S, detection_by_type, farm_windows

    ff = detection_by_type(fault_free_run.events, [], fault_free_run.runs, fault_free_run.scenario.duration_s)
    rows: dict[str, dict[str, Any]] = {}
    faulty_by = (
        detection_by_type(faulty.events, farm_windows(scenario), faulty.runs, scenario.duration_s) if faulty else {}
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


def tables_markdown(scenario: Scenario, main: Variant, comp: dict) -> str:
    from windwarden.evaluation.farm import power_metrics, scorecard_of

    case = scenario.plant.wind_case
    lines = [
        f"# Seed 001, Tables 5–7: wind case {case} (`{scenario.name}`, {main.runs} runs, seed {main.seed})",
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
        pd, pm, pf = PAPER_TABLE5[case][name]
        a, b = ours_paper[name], ours_main[name]
        lines.append(
            f"| {FAULT_LABEL[name]} {name} | {_fmt(pd)} s | {_fmt(pm)} % | {_fmt(pf)} "
            f"| {_fmt(a['delay_s'])} s | {_fmt(a['missed_pct'])} % | {_fmt(a['fp_per_1000s'])} "
            f"| {_fmt(b['delay_s'])} s | {_fmt(b['missed_pct'])} % | {_fmt(b['fp_per_1000s'])} |"
        )
    dispatch = power_metrics(comp.get("fault_free", main) if scenario.faults else main)
    pi = power_metrics(comp["fault_free_pi"])
    over_d, miss_d = dispatch["over_production"]["mwh_per_run"], dispatch["missing_power"]["mwh_per_run"]
    over_p, miss_p = pi["over_production"]["mwh_per_run"], pi["missing_power"]["mwh_per_run"]
    po, pmiss = PAPER_TABLE6[case]
    lines += [
        "",
        "## Table 6: power tracking on the fault-free farm (lower is better; dispatch = 1)",
        "",
        "| controller | paper: over | paper: missing | ours: over | ours: missing | ours: over MWh/run | "
        "ours: missing MWh/run |",
        "|---|---|---|---|---|---|---|",
        f"| PI reference | {po:g} | {pmiss:g} | {_fmt(over_p / over_d if over_d > 0 else np.inf)} "
        f"| {_fmt(miss_p / miss_d if miss_d > 0 else np.inf, 4)} | {_fmt(over_p)} | {_fmt(miss_p)} |",
        f"| dispatch | 1 | 1 | 1 | 1 | {_fmt(over_d)} | {_fmt(miss_d)} |",
    ]
    if scenario.faults and "no_accommodation" in comp:
        with_acc = scorecard_of(main)["metrics"]["damage"].get("by_type", {})
        without = scorecard_of(comp["no_accommodation"])["metrics"]["damage"].get("by_type", {})
        (p2n, p3n), (p2a, p3a) = PAPER_TABLE7[case]
        acc_power = power_metrics(main)
        no_power = power_metrics(comp["no_accommodation"])

        def dn(d: dict, name: str, key: str) -> float | None:
            return d.get(name, {}).get(key)

        lines += [
            "",
            "## Table 7: damage numbers with and without accommodation",
            "",
            "Damage 3: DEL of the faulty turbine's shaft torque (rainflow, m = 4) over the whole run / its fault-free",
            "twin's (run), and over the fault window only (window). Damage 2: rotor imbalance (1P phasor of the blade",
            "torques) over the fault window / the twin's; the twin's is ≈ 0, so the ratio is huge (paper: inf); in N m",
            "as well.",
            "",
            "| | paper: damage 2 | paper: damage 3 | ours: damage 2 (ratio; N m) | ours: damage 3 run | "
            "ours: damage 3 window | ours: missing MWh/run |",
            "|---|---|---|---|---|---|---|",
        ]
        rule = accommodation_rule(scenario)
        rows = [("no accommodation", without, p2n, p3n, no_power)]
        if "paper_accommodation" in comp:
            published = scorecard_of(comp["paper_accommodation"])["metrics"]["damage"].get("by_type", {})
            rows.append(
                ("eqs. (23)–(26) as published", published, p2a, p3a, power_metrics(comp["paper_accommodation"]))
            )
        label = {
            "paper": "eqs. (23)–(26) as published",
            "hold-torque": "(23)–(24), pitch trim (D-28), drive train held by speed, its 3P cancelled (D-26b, D-30)",
            "cancel": "(23)–(24), pitch trim (D-28), drive train's 3P cancelled, its ripple by the farm (D-31, D-29)",
        }[rule]
        rows.append((label, with_acc, p2a, p3a, acc_power))
        for label, d, paper2, paper3, pw in rows:
            lines.append(
                f"| {label} | {_fmt(paper2)} | {_fmt(paper3, 5)} "
                f"| {_fmt(dn(d, 'pitch_misalignment', 'imbalance_ratio'))}; "
                f"{_fmt(dn(d, 'pitch_misalignment', 'imbalance_nm'))} "
                f"| {_fmt(dn(d, 'drivetrain', 'damage_number_run'), 5)} "
                f"| {_fmt(dn(d, 'drivetrain', 'damage_number_window'), 4)} "
                f"| {_fmt(pw['missing_power']['mwh_per_run'])} |"
            )
        lines.append("")
        for label, d, *_ in rows[1:]:
            for span in ("run", "window"):
                n3 = dn(without, "drivetrain", f"damage_number_{span}")
                a3 = dn(d, "drivetrain", f"damage_number_{span}")
                nm = dn(without, "drivetrain", f"miner_ratio_{span}")
                am = dn(d, "drivetrain", f"miner_ratio_{span}")
                if None not in (n3, a3, nm, am) and n3 > 1.0 and nm > 1.0:
                    lines.append(
                        f"Excess drive-train damage removed by {label}, over the {span}: "
                        f"{100.0 * (n3 - a3) / (n3 - 1.0):.0f} % of the damage number's (DEL ratio) excess, "
                        f"{100.0 * (nm - am) / (nm - 1.0):.0f} % of the fatigue damage's (Miner, Σ n S⁴) excess.  "
                    )
    lines.append("")
    return "\n".join(lines)
