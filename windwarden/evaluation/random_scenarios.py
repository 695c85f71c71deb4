"""Random scenarios: fault times, targets, kinds and sizes drawn from documented distributions, so that no figure
can be tuned to a fault time (``windwarden scenarios random KIND --seed S``, ``windwarden eval random:KIND``).

A random scenario of a plant kind (``generate``) is its shipped fault-free scenario (plant, turbulence,
supervisor) with a drawn mean wind and a drawn fault schedule:

* **Windows**: lengths uniform in ``window_s``; the first starts ``first_s`` plus a uniform draw in
  [0, extra_gap_s] after the run starts; each next one ``min_gap_s`` plus such a draw after the previous one
  ends (quiet time for the scoring's grace and for false alarms); windows never overlap; as many as fit in
  ``duration_s`` with ``min_gap_s`` of quiet time at the end.
* **Faults**: each window draws a case with the kind's weights (``CASES``); a case names the fault types it
  combines (two for a double speed-sensor fault, on one rotor- and one generator-speed sensor). Each fault draws
  its target uniformly among its type's targets (sensor, blade, actuator; the farm's turbine uniformly 1–9), its
  sign uniformly, and its size **log-uniformly from the size its type is detected at by 95 % up to the type's
  upper bound** (``SIZE_RANGES``; the 95 % sizes measured by ``windwarden detectability``, docs/detectability.md).
* **Wind**: the mean is piecewise linear through levels drawn uniformly over the kind's operating range
  (``fault_types.WIND_RANGES``) every ``wind_every_s``; the farm also draws its wind case (1 or 2).

``evaluate_set`` scores K such scenarios (scenario k drawn with the seed ``scenario_seed(S, k)``, so
``windwarden scenarios random KIND --seed <that seed>`` writes it again) with the plant kind's own evaluator,
spreads the runs over them, and pools the figures per fault case (``random_summary``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from windwarden.evaluation.detectability import BASES
from windwarden.evaluation.fault_types import (
    FAULT_TYPE_BY_NAME,
    WIND_RANGES,
    on_tick,
    place_windows,
)
from windwarden.evaluation.kinds import EvalOptions
from windwarden.evaluation.random_summary import summarise
from windwarden.kinds import kind_for
from wwcore.scenario import Scenario, load_scenario, parse_scenario


@dataclass(frozen=True)
class Schedule:
    """How a kind's random scenarios lay out time (s)."""

    duration_s: float
    window_s: tuple[float, float]
    first_s: float
    min_gap_s: float
    extra_gap_s: float
    wind_every_s: float
    reason: str


SCHEDULES: dict[str, Schedule] = {
    "turbine": Schedule(
        1800.0,
        (20.0, 60.0),
        60.0,
        60.0,
        90.0,
        300.0,
        "windows of 20–60 s (the benchmark's are 100 s; shorter ones give more per run); 60 s of quiet at least "
        "between them, 30 times the 2 s grace, so false alarms are counted on a real share of the run",
    ),
    "farm": Schedule(
        2400.0,
        (60.0, 200.0),
        180.0,
        120.0,
        180.0,
        600.0,
        "windows of 60–200 s (the shipped 200–400 s); the first after the 60 s warm-up and the 500-sample wind-"
        "direction estimate with room for the demand's 60-s mean; 120 s of quiet at least, 12 times the 10 s grace",
    ),
    "hydro": Schedule(
        300.0,
        (10.0, 30.0),
        10.0,
        10.0,
        20.0,
        60.0,
        "windows of 10–30 s (the paper's 30–40 s in 100 s runs); 10 s of quiet at least, five times the 2 s grace",
    ),
}

CASES: dict[str, tuple[tuple[str, float, tuple[str, ...]], ...]] = {
    "turbine": (
        ("speed-rotor-offset", 0.125, ("speed-rotor-offset",)),
        ("speed-generator-offset", 0.125, ("speed-generator-offset",)),
        ("speed-rotor-gain", 0.125, ("speed-rotor-gain",)),
        ("speed-generator-gain", 0.125, ("speed-generator-gain",)),
        ("speed-double", 0.2, ("speed-rotor-*", "speed-generator-*")),
        ("pitch-sensor-offset", 0.15, ("pitch-sensor-offset",)),
        ("converter-offset", 0.15, ("converter-offset",)),
    ),
    "farm": (
        ("farm-debris", 1.0 / 3.0, ("farm-debris",)),
        ("farm-pitch-misalignment", 1.0 / 3.0, ("farm-pitch-misalignment",)),
        ("farm-drivetrain", 1.0 / 3.0, ("farm-drivetrain",)),
    ),
    "hydro": (
        ("hydro-pump-offset", 0.5, ("hydro-pump-offset",)),
        ("hydro-motor-offset", 0.5, ("hydro-motor-offset",)),
    ),
}
"""Per kind: (case name, probability, fault types). ``speed-rotor-*`` draws offset or gain with equal odds.
Speed-sensor faults are 70 % of the turbine's windows (single 50 %, double 20 %), the rest pitch sensors and the
converter; the farm's three faults and hydro's two actuators have equal odds."""

DETECTED_95: dict[str, float] = {
    "speed-rotor-offset": 6.0,
    "speed-generator-offset": 6.0,
    "speed-rotor-gain": 3.0,
    "speed-generator-gain": 0.2,
    "pitch-sensor-offset": 4.0,
    "converter-offset": 0.5,
    "farm-debris": 3.0,
    "farm-pitch-misalignment": 0.5,
    "farm-drivetrain": 3.0,
    "hydro-pump-offset": 0.03,
    "hydro-motor-offset": 0.03,
}
"""The size each type is detected at by 95 % (docs/detectability.md), in its size unit: the lower bound of the
sizes random scenarios draw."""
SIZE_RANGES: dict[str, tuple[float, float]] = {
    name: (lower, FAULT_TYPE_BY_NAME[name].upper) for name, lower in DETECTED_95.items()
}
"""Sizes are drawn log-uniformly in [lower, upper]: from the 95 %-detected size to ``FaultType.upper``."""


def scenario_seed(seed: int, k: int) -> int:
    """The generator seed of the k-th scenario of a random set drawn with ``seed``."""
    return int(np.random.SeedSequence([seed, k, 0x5CE0]).generate_state(1)[0])


def _choose(rng: np.random.Generator, names: tuple[str, ...], kind: str) -> list[str]:
    out = []
    for name in names:
        if name.endswith("-*"):
            stem = name[:-2]
            options = [t for t in SIZE_RANGES if t.startswith(stem + "-")]
            name = options[int(rng.integers(len(options)))]
        out.append(name)
    return out


def draw_size(rng: np.random.Generator, type_name: str) -> float:
    lo, hi = SIZE_RANGES[type_name]
    return float(f"{math.exp(rng.uniform(math.log(lo), math.log(hi))):.4g}")


def _fault_name(window: int, case: str, type_name: str, size: float) -> str:
    """``r<window> <case> [<type>] <size> <unit>``: the case is the second word (``random_summary.case_of``)."""
    unit = FAULT_TYPE_BY_NAME[type_name].unit
    what = case if case == type_name else f"{case} {type_name}"
    return f"r{window} {what} {size:g}{'' if unit == '%' else ' '}{unit}"


def generate(kind: str, seed: int, *, base: Scenario | None = None, duration_s: float | None = None) -> Scenario:
    """A random scenario of a plant kind (module docstring), the same for the same seed."""
    if kind not in SCHEDULES:
        raise KeyError(f"unknown plant kind {kind!r}; known: {', '.join(SCHEDULES)}")
    base = base or load_scenario(BASES[kind])
    schedule = SCHEDULES[kind]
    duration = float(duration_s or schedule.duration_s)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0xFA17]))
    lengths: list[float] = []
    # enough lengths for any run; place_windows lays them out and the ones that do not fit are dropped
    for _ in range(int(duration // schedule.min_gap_s) + 1):
        lengths.append(float(rng.uniform(*schedule.window_s)))
    spans, _ = place_windows(
        rng, lengths, first_s=schedule.first_s, min_gap_s=schedule.min_gap_s, extra_gap_s=schedule.extra_gap_s
    )
    spans = [(s, e) for s, e in spans if e + schedule.min_gap_s <= duration]
    data = base.model_dump(mode="json", exclude_none=True)
    data.update(
        name=f"random-{kind}-{seed}",
        description=f"random {kind} scenario, seed {seed} (windwarden scenarios random {kind} --seed {seed})",
        duration_s=duration,
    )
    wind = WIND_RANGES[kind]
    points = np.arange(0.0, duration + schedule.wind_every_s, schedule.wind_every_s)
    data["wind"]["mean"] = [(float(t), round(float(rng.uniform(wind.lo, wind.hi)), 1)) for t in points]
    if kind == "farm":
        data["plant"]["wind_case"] = int(rng.integers(1, 3))
    names, weights, types = zip(*CASES[kind], strict=True)
    convention = getattr(base.plant, "noise_convention", "sigma")
    faults = []
    for i, (start, end) in enumerate(spans):
        case = int(rng.choice(len(names), p=np.asarray(weights) / sum(weights)))
        turbine = int(rng.integers(1, base.plant.n_turbines + 1))
        for type_name in _choose(rng, types[case], kind):
            fault_type = FAULT_TYPE_BY_NAME[type_name]
            target, sign = fault_type.draw_target(rng)
            size = draw_size(rng, type_name)
            spec = fault_type.fault(
                size,
                target=target,
                sign=sign,
                start_s=on_tick(start),
                end_s=on_tick(end),
                turbine=turbine,
                name=_fault_name(i, names[case], type_name, size),
                noise_convention=convention,
            )
            faults.append(spec.model_dump(mode="json", exclude_none=True))
    data["faults"] = faults
    return parse_scenario(data, f"<random {kind} seed {seed}>")


@dataclass
class RandomSet:
    """A scored set of random scenarios: the set's scorecard (JSON-ready) and the scenarios themselves."""

    card: dict[str, Any]
    scenarios: list[Scenario]


def evaluate_set(
    kind: str, runs: int, seed: int, scenarios: int, options: EvalOptions, base: Scenario | None = None
) -> RandomSet:
    """Score ``scenarios`` random scenarios (the k-th drawn with ``scenario_seed(seed, k)``), the runs spread over
    them (the first ``runs % scenarios`` get one more): each scenario's scorecard and the pooled summary."""
    entries, drawn = [], []
    for k in range(min(scenarios, runs)):
        n = runs // scenarios + (1 if k < runs % scenarios else 0)
        gen_seed = scenario_seed(seed, k)
        scenario = generate(kind, gen_seed, base=base)
        eval_seed = int(np.random.SeedSequence([seed, k, 0xE7A1]).generate_state(1)[0])
        card = kind_for(scenario.plant.kind).evaluate(scenario, n, eval_seed, options).scorecard
        entries.append({"name": scenario.name, "scenario_seed": gen_seed, "eval_seed": eval_seed, "scorecard": card})
        drawn.append(scenario)
    card = {
        "scenario": f"random:{kind}",
        "kind": kind,
        "runs": runs,
        "seed": seed,
        "summary": summarise(kind, [e["scorecard"] for e in entries]),
        "scenarios": entries,
    }
    return RandomSet(card, drawn)


def distribution_table() -> str:
    """The generator's distributions as ``docs/detectability.md`` shows them (``tests/test_random_scenarios.py``
    compares)."""
    lines = [
        "| kind | run | windows | first window | quiet time between | mean wind |",
        "|---|---|---|---|---|---|",
    ]
    for kind, s in SCHEDULES.items():
        r = WIND_RANGES[kind]
        lines.append(
            f"| {kind} | {s.duration_s:g} s | U({s.window_s[0]:g}, {s.window_s[1]:g}) s | {s.first_s:g} s + "
            f"U(0, {s.extra_gap_s:g}) s | {s.min_gap_s:g} s + U(0, {s.extra_gap_s:g}) s | U({r.lo:g}, {r.hi:g}) "
            f"m/s every {s.wind_every_s:g} s, linear between |"
        )
    lines += ["", "| kind | case | probability | fault types | size (log-uniform) | upper bound because |"]
    lines.append("|---|---|---|---|---|---|")
    for kind, cases in CASES.items():
        for name, p, types in cases:
            concrete = [t for pattern in types for t in SIZE_RANGES if t == pattern or t.startswith(pattern[:-1])]
            sizes = "; ".join(
                f"{t}: {SIZE_RANGES[t][0]:g}–{SIZE_RANGES[t][1]:g} {FAULT_TYPE_BY_NAME[t].unit}" for t in concrete
            )
            why = "; ".join(FAULT_TYPE_BY_NAME[t].upper_reason for t in concrete)
            lines.append(f"| {kind} | {name} | {p:.3g} | {', '.join(types)} | {sizes} | {why} |")
    return "\n".join(lines)
