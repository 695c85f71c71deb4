"""Random scenarios: deterministic for a seed, always valid, distributed as documented; the set's pooled figures;
bad arguments refused with exit code 2 and nothing written."""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import tomllib
from collections import Counter

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import stats

from windwarden.cli import main
from windwarden.evaluation.fault_types import FAULT_TYPE_BY_NAME, WIND_RANGES
from windwarden.evaluation.random_scenarios import CASES, SCHEDULES, SIZE_RANGES, generate, scenario_seed
from windwarden.evaluation.random_summary import case_of, fault_free_lines, summarise
from windwarden.evaluation.scoring import windows_from_faults
from wwcore.scenario import dump_scenario, parse_scenario

KINDS = ("turbine", "farm", "hydro")


def _type_of(fault) -> str:
    """The fault type a generated fault names: the last word before its size."""
    words = fault.name.split(" ")
    return words[2] if words[1] == "speed-double" else words[1]


def _check_valid(kind: str, seed: int) -> None:
    s = generate(kind, seed)
    schedule = SCHEDULES[kind]
    again = parse_scenario(tomllib.loads(dump_scenario(s)))  # the file it writes is a valid scenario
    assert again == s
    assert s.plant.kind == kind and s.duration_s == schedule.duration_s
    windows = windows_from_faults(s.faults, s.duration_s)
    assert windows, "every random scenario has faults"
    assert windows[0].start_s >= schedule.first_s - 1e-9
    for a, b in itertools.pairwise(windows):
        assert b.start_s >= a.end_s + schedule.min_gap_s - 1e-6  # no overlap, quiet time between
    assert windows[-1].end_s + schedule.min_gap_s <= s.duration_s + 1e-9
    lo, hi = schedule.window_s
    for w in windows:
        assert lo - 0.011 <= w.end_s - w.start_s <= hi + 0.011
        assert round(w.start_s * 100) == pytest.approx(w.start_s * 100, abs=1e-6)  # on the 100 Hz tick
    for fault in s.faults:
        t = FAULT_TYPE_BY_NAME[_type_of(fault)]
        assert t.kind == kind and fault.target in t.targets
        low, high = SIZE_RANGES[t.name]
        assert low * (1 - 1e-3) <= t.size_of(fault.value) <= high * (1 + 1e-3)
        assert 1 <= fault.turbine <= s.plant.n_turbines
    wind = WIND_RANGES[kind]
    assert all(wind.lo <= v <= wind.hi for _, v in s.wind.mean)
    assert s.wind.mean[-1][0] >= s.duration_s
    if kind == "turbine":
        for w in windows:
            if len(w.targets) == 2:  # a double fault: one rotor- and one generator-speed sensor
                assert sorted(t[:7] for t in w.targets) == ["omega_g", "omega_r"]


@pytest.mark.parametrize("kind", KINDS)
def test_the_same_seed_gives_the_same_scenario_and_another_seed_another(kind):
    assert generate(kind, 12345) == generate(kind, 12345)
    assert dump_scenario(generate(kind, 12345)) == dump_scenario(generate(kind, 12345))
    assert generate(kind, 12345).faults != generate(kind, 12346).faults


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(min_value=0, max_value=2**63 - 1), kind=st.sampled_from(KINDS))
def test_every_seed_gives_a_valid_scenario_with_quiet_time_between_windows(seed, kind):
    _check_valid(kind, seed)


def _many(kind: str, n: int):
    return [generate(kind, scenario_seed(777, k)) for k in range(n)]


def test_cases_sizes_winds_and_lengths_follow_their_documented_distributions():
    scenarios = _many("turbine", 150)
    windows = [w for s in scenarios for w in windows_from_faults(s.faults, s.duration_s)]
    cases = Counter(case_of(w.name) for w in windows)
    names = [c[0] for c in CASES["turbine"]]
    expected = np.array([c[1] for c in CASES["turbine"]]) * len(windows)
    assert stats.chisquare([cases[n] for n in names], expected).pvalue > 1e-3
    # sizes log-uniform in [95 %-detected size, upper bound]
    for name in ("speed-rotor-offset", "speed-generator-gain", "converter-offset"):
        t = FAULT_TYPE_BY_NAME[name]
        lo, hi = SIZE_RANGES[name]
        u = [
            (math.log(t.size_of(f.value)) - math.log(lo)) / (math.log(hi) - math.log(lo))
            for s in scenarios
            for f in s.faults
            if _type_of(f) == name
        ]
        assert len(u) > 40
        assert stats.kstest(u, "uniform").pvalue > 1e-3
    # winds uniform over the operating range; window lengths uniform
    wind = WIND_RANGES["turbine"]
    levels = [(v - wind.lo) / (wind.hi - wind.lo) for s in scenarios for _, v in s.wind.mean]
    assert stats.kstest(levels, "uniform").pvalue > 1e-3
    lo, hi = SCHEDULES["turbine"].window_s
    lengths = [(w.end_s - w.start_s - lo) / (hi - lo) for w in windows]
    assert stats.kstest(np.clip(lengths, 0, 1), "uniform").pvalue > 1e-3
    # signs and targets even
    signs = Counter(np.sign(f.value) for s in scenarios for f in s.faults if _type_of(f) == "speed-rotor-offset")
    assert stats.binomtest(signs[1.0], signs[1.0] + signs[-1.0]).pvalue > 1e-3


def test_the_farm_draws_turbines_wind_cases_and_types_evenly():
    scenarios = _many("farm", 120)
    faults = [f for s in scenarios for f in s.faults]
    assert stats.chisquare(list(Counter(f.turbine for f in faults).values())).pvalue > 1e-3
    assert len(Counter(f.turbine for f in faults)) == 9
    assert stats.chisquare(list(Counter(_type_of(f) for f in faults).values())).pvalue > 1e-3
    cases = Counter(s.plant.wind_case for s in scenarios)
    assert set(cases) == {1, 2} and stats.binomtest(cases[1], len(scenarios)).pvalue > 1e-3


def test_the_cli_writes_the_generators_scenario(tmp_path):
    out = tmp_path / "r.toml"
    assert main(["scenarios", "random", "farm", "--seed", "42", "--out", str(out)]) == 0
    assert parse_scenario(tomllib.loads(out.read_text())) == generate("farm", 42)


@pytest.mark.parametrize(
    "argv",
    [
        ["scenarios", "random", "windmill", "--seed", "1"],
        ["scenarios", "random", "turbine", "--seed", "-1"],
        ["scenarios", "random", "turbine", "--seed", "1", "--duration", "50"],
        ["scenarios", "random", "hydro", "--seed", "1", "--duration", "nan"],
    ],
)
def test_bad_generator_arguments_are_refused_with_exit_2_and_nothing_written(tmp_path, argv):
    out = tmp_path / "r.toml"
    assert main([*argv, "--out", str(out)]) == 2
    assert not out.exists()


@pytest.mark.parametrize(
    "argv",
    [
        ["eval", "random:windmill", "--runs", "2"],
        ["eval", "random:hydro", "--runs", "2", "--scenarios", "3"],
        ["eval", "random:farm", "--runs", "2", "--compare"],
        ["eval", "hydro-fig9", "--runs", "2", "--scenarios", "2"],
        ["eval", "random:turbine", "--runs", "2", "--detector", "no-such-detector"],
    ],
)
def test_bad_random_set_arguments_are_refused_with_exit_2_and_nothing_written(tmp_path, argv):
    out = tmp_path / "set"
    assert main([*argv, "--out", str(out), "--quiet"]) == 2
    assert not out.exists()


def test_the_set_summary_pools_windows_by_their_runs():
    def entry(name, detected, isolated, delay, runs_flaps=0.0):
        return {
            "name": name,
            "detected_pct": detected,
            "isolated_pct": isolated,
            "isolated_time_pct": isolated,
            "delay_s_mean": delay,
            "delay_s_max": delay,
            "wrong_isolation_pct": 100.0 - isolated,
            "lost_pct": 0.0,
            "flaps_mean": runs_flaps,
            "end_recognised_pct": detected,
        }

    def card(runs, faults, count, observed):
        fa = {"count": count, "observed_s": observed, "flagged_s": 0.0}
        return {"runs": runs, "duration_s": 100.0, "faults": faults, "false_alarms": fa, "metrics": {}}

    cards = [
        card(
            4,
            [entry("r0 speed-rotor-offset 7 σ", 100.0, 75.0, 0.02), entry("r1 converter-offset 1 σ", 50.0, 50.0, 1.0)],
            1,
            800.0,
        ),
        card(2, [entry("r0 speed-rotor-offset 9 σ", 50.0, 50.0, 0.08, 1.0)], 0, 200.0),
    ]
    s = summarise("turbine", cards)
    rotor = s["cases"]["speed-rotor-offset"]
    assert rotor["window_runs"] == 6 and rotor["windows"] == 2
    assert rotor["detected_pct"] == pytest.approx(100.0 * 5 / 6)  # 4 of 4 and 1 of 2
    assert rotor["isolated_pct"] == pytest.approx(100.0 * 4 / 6)  # 3 of 4 and 1 of 2
    assert rotor["delay_s_mean"] == pytest.approx((0.02 * 4 + 0.08 * 1) / 5)
    assert rotor["delay_s_max"] == 0.08
    assert rotor["flaps_mean"] == pytest.approx(2.0 / 6)
    assert s["cases"]["converter-offset"]["detected_pct"] == 50.0
    assert s["speed_sensors"]["window_runs"] == 6  # the converter is not a speed sensor
    assert s["false_alarms"]["per_1000s"] == pytest.approx(1.0)  # 1 in 1000 s


def _window_entry(name: str) -> dict:
    """A scorecard ``faults`` row of a window detected and isolated in every run after 0.02 s."""
    figures = {"detected_pct": 100.0, "isolated_pct": 100.0, "isolated_time_pct": 100.0, "delay_s_mean": 0.02}
    return {"name": name, **figures, "delay_s_max": 0.02, "wrong_isolation_pct": 0.0, "lost_pct": 0.0}


def test_the_set_summary_judges_the_wind_estimate_against_the_twins_and_the_clean_runs():
    """A window whose twin shares a broken estimate reads 1.0 against its twin and shows against the clean run; the
    fault-free time's estimate is listed per scenario beside the clean run's and the anemometer's."""
    fa = {"count": 0, "observed_s": 1000.0, "flagged_s": 0.0}
    clean_fa = {"count": 1, "observed_s": 1700.0, "per_1000s": 1 / 1.7}
    wind = {
        "fault_free": {"fte": 3.4, "nfte": 3.4, "anemometer": 2.0, "fte_clean": 3.3},
        "r0 speed-generator-gain 1.4%": {"fte": 6.0, "fte_fault_free": 6.0, "fte_clean": 5.0, "anemometer": 2.0},
        "r1 speed-generator-gain 2%": {"fte": 0.33, "fte_fault_free": 0.3, "fte_clean": 0.3, "anemometer": 2.0},
    }
    card = {
        "scenario": "random-turbine-1",
        "runs": 4,
        "duration_s": 1800.0,
        "faults": [_window_entry(name) for name in wind if name != "fault_free"],
        "false_alarms": fa,
        "false_alarms_clean": clean_fa,
        "metrics": {"wind_rmse": wind},
    }
    s = summarise("turbine", [card])
    gain = s["cases"]["speed-generator-gain"]
    assert gain["fte_ratio_mean"] == pytest.approx((1.0 + 1.1) / 2) and gain["fte_ratio_max"] == pytest.approx(1.1)
    assert gain["fte_clean_ratio_max"] == pytest.approx(1.2)
    assert s["speed_sensors"]["fte_ratio_max"] == pytest.approx(1.1)
    assert s["speed_sensors"]["fte_clean_ratio_max"] == pytest.approx(1.2)
    assert s["fault_free_wind"] == [{"scenario": "random-turbine-1", **wind["fault_free"], "ratio": 3.4 / 3.3}]
    assert s["false_alarms_clean"]["count"] == 1 and s["false_alarms_clean"]["observed_s"] == 1700.0
    (line,) = fault_free_lines(s)
    assert "clean run 3.30 m/s" in line and "worse than the anemometer" in line


def test_a_small_random_set_is_scored_end_to_end_and_written(tmp_path, monkeypatch):
    """Two short hydrostatic scenarios of one run each: every scenario's scorecard, the pooled summary, and the
    scenario files, which replay as ordinary scenarios."""
    monkeypatch.setitem(SCHEDULES, "hydro", dataclasses.replace(SCHEDULES["hydro"], duration_s=70.0))
    out = tmp_path / "set"
    assert main(["eval", "random:hydro", "--runs", "2", "--seed", "9", "--out", str(out), "--quiet"]) == 0
    card = json.loads((out / "scorecard.json").read_text())
    assert card["scenario"] == "random:hydro" and card["runs"] == 2 and len(card["scenarios"]) == 2
    seeds = [s["scenario_seed"] for s in card["scenarios"]]
    assert seeds == [scenario_seed(9, 0), scenario_seed(9, 1)]
    windows = sum(len(s["scorecard"]["faults"]) for s in card["scenarios"])
    summary = card["summary"]
    assert sum(row["windows"] for row in summary["cases"].values()) == windows
    assert set(summary["cases"]) <= {"hydro-pump-offset", "hydro-motor-offset"}
    for row in summary["cases"].values():
        assert 0.0 <= row["detected_pct"] <= 100.0 and "reconstruction_error_pct_mean" in row
    files = sorted((out / "scenarios").glob("*.toml"))
    assert [f.stem for f in files] == sorted(f"random-hydro-{s}" for s in seeds)
    assert parse_scenario(tomllib.loads(files[0].read_text())) == generate("hydro", int(files[0].stem.split("-")[-1]))
    assert "random:hydro" in (out / "summary.md").read_text()
