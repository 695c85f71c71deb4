"""Detectability sweeps: the layouts (random times and winds, each size once), the statistics (probit fit,
measured crossings, exact binomial intervals) against closed-form answers, a tiny sweep through the command,
and bad arguments refused with exit code 2 before anything runs."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from windwarden.cli import main
from windwarden.evaluation.detectability import (
    TIMINGS,
    base_scenario,
    check_sizes,
    make_layout,
    size_rows,
    timing_table,
)
from windwarden.evaluation.detectability_stats import (
    clopper_pearson,
    crossing,
    fit_probit,
    probit_size,
    threshold_sizes,
)
from windwarden.evaluation.fault_types import FAULT_TYPES, WIND_RANGES, catalogue_table, fault_type, held_wind
from windwarden.evaluation.random_scenarios import distribution_table
from windwarden.evaluation.scoring import windows_from_faults


@pytest.mark.parametrize("name", [t.name for t in FAULT_TYPES])
def test_a_layout_places_every_size_once_at_random_times_with_quiet_time_between(name):
    t = fault_type(name)
    base = base_scenario(t.kind)
    assert check_sizes(t, t.sizes, base) == []  # the default grid is valid for the plant
    layout, eval_seed = make_layout(t, t.sizes, base, seed=5, index=0)
    again, again_seed = make_layout(t, t.sizes, base, seed=5, index=0)
    other, _ = make_layout(t, t.sizes, base, seed=5, index=1)
    assert layout.scenario == again.scenario and eval_seed == again_seed
    assert [f.start_s for f in other.scenario.faults] != [f.start_s for f in layout.scenario.faults]
    assert sorted(w["size"] for w in layout.windows) == sorted(t.sizes)
    timing = TIMINGS[t.kind]
    windows = windows_from_faults(layout.scenario.faults, layout.scenario.duration_s)
    assert len(windows) == len(t.sizes)
    assert windows[0].start_s >= timing.first_s
    for a, b in itertools.pairwise(windows):
        assert b.start_s - a.end_s >= timing.min_gap_s - 1e-6
    wind = WIND_RANGES[t.kind]
    mean = layout.scenario.wind.mean
    for w in layout.windows:
        assert wind.lo <= w["wind_mps"] <= wind.hi
        assert w["target"] in t.targets
        fault = next(f for f in layout.scenario.faults if f.name == w["name"])
        assert t.size_of(fault.value) == pytest.approx(w["size"], rel=1e-6)
        # the mean wind holds the window's level over the window
        times, levels = zip(*mean, strict=True)
        for time in (w["start_s"], w["end_s"]):
            assert np.interp(time, times, levels) == pytest.approx(w["wind_mps"])


def test_the_held_wind_ramps_between_windows_and_refuses_windows_too_close():
    points = held_wind([(20.0, 30.0), (70.0, 80.0)], [5.0, 15.0], settle_s=10.0, after_s=2.0)
    assert points == [(0.0, 5.0), (10.0, 5.0), (32.0, 5.0), (60.0, 15.0), (82.0, 15.0)]
    with pytest.raises(ValueError, match="settle"):
        held_wind([(20.0, 30.0), (35.0, 40.0)], [5.0, 15.0], settle_s=10.0, after_s=2.0)


def test_the_probit_fit_recovers_a_known_curve_and_its_quantiles():
    sizes = np.array([0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0])
    mu, sigma = math.log(2.0), 0.4
    n = np.full(len(sizes), 100000)
    k = np.round(n * stats.norm.cdf((np.log(sizes) - mu) / sigma))
    fit = fit_probit(sizes, k, n)
    assert fit is not None
    assert fit[0] == pytest.approx(mu, abs=2e-3) and fit[1] == pytest.approx(sigma, rel=5e-3)
    assert probit_size(fit, 0.5) == pytest.approx(2.0, rel=3e-3)
    assert probit_size(fit, 0.95) == pytest.approx(2.0 * math.exp(0.4 * 1.6448536), rel=5e-3)
    assert fit_probit(sizes, n.copy(), n) is None  # all detected: no curve
    assert fit_probit(sizes, np.zeros(len(sizes)), n) is None


def test_the_measured_crossing_interpolates_in_log_size():
    sizes = [1.0, 2.0, 4.0]
    assert crossing(sizes, [0.0, 40.0, 100.0], 0.5)["size"] == pytest.approx(2.0 * 2.0 ** (10 / 60))
    assert crossing(sizes, [0.0, 40.0, 100.0], 0.5)["bracket"] == [2.0, 4.0]
    assert crossing(sizes, [96.0, 100.0, 100.0], 0.95)["status"] == "below"
    assert crossing(sizes, [0.0, 10.0, 90.0], 0.95)["status"] == "above"


def test_exact_binomial_intervals():
    lo, hi = clopper_pearson(40, 40)
    assert hi == 1.0 and lo == pytest.approx(0.025 ** (1 / 40))  # 40 of 40: at least 91.2 %
    lo, hi = clopper_pearson(0, 40)
    assert lo == 0.0 and hi == pytest.approx(1 - 0.025 ** (1 / 40))


def _records(pattern):
    """Synthetic sweep records: pattern[layout][size index] = detected of 5 runs."""
    sizes = [1.0, 2.0, 4.0, 8.0]
    out = []
    for layout, row in enumerate(pattern):
        for size, k in zip(sizes, row, strict=True):
            out.append(
                {
                    "layout": layout,
                    "runs": 5,
                    "size": size,
                    "detected": k,
                    "isolated": max(k - 1, 0),
                    "wrong": 0,
                    "lost": 0,
                    "delay_s_mean": 0.1 * k / size if k else None,
                    "delay_s_max": 0.2 if k else None,
                    "flaps_mean": 0.0,
                    "wind_mps": 6.0 + 10.0 * layout,
                }
            )
    return sizes, out


def test_rows_pool_layouts_and_split_by_rated_wind():
    sizes, records = _records([[0, 2, 5, 5], [1, 3, 5, 5]])
    rows = size_rows(records, sizes, rated=12.0)
    assert rows[1]["n"] == 10 and rows[1]["detected_pct"] == 50.0 and rows[1]["isolated_pct"] == 30.0
    assert rows[1]["detected_pct_below_rated"] == 40.0 and rows[1]["detected_pct_above_rated"] == 60.0
    assert rows[1]["delay_s_mean"] == pytest.approx((0.1 * 2 / 2 * 2 + 0.1 * 3 / 2 * 3) / 5)
    assert rows[0]["delay_s_max"] == 0.2 and rows[0]["detected_pct"] == 10.0
    assert rows[0]["detected_ci_pct"] == pytest.approx([100.0 * x for x in clopper_pearson(1, 10)])


def test_threshold_sizes_bracket_the_measured_curve_with_a_layout_bootstrap():
    sizes, records = _records([[0, 2, 5, 5], [1, 3, 4, 5], [0, 2, 5, 5]])
    out = threshold_sizes(records, sizes, "detected", seed=3, bootstrap=40)
    p50 = out["p50"]
    assert p50["measured"]["bracket"] == [2.0, 4.0] or p50["measured"]["bracket"] == [1.0, 2.0]
    assert 1.0 < p50["fitted"] < 4.0 and p50["within_grid"]
    assert p50["ci95"][0] <= p50["fitted"] <= p50["ci95"][1]
    assert out["p95"]["fitted"] > p50["fitted"]


def test_a_tiny_sweep_through_the_command_gives_well_formed_monotone_output(tmp_path):
    """Two converter offsets, 0.05 σ (4.5 N m, under the CUSUMs' limit of 0.125 σ) and 3 σ (270 N m), on one
    layout of two runs: the large one is always detected and isolated, the small one no more often."""
    out = tmp_path / "sweep"
    argv = ["detectability", "turbine", "--fault", "converter-offset", "--sizes", "3,0.05"]
    assert main([*argv, "--runs", "2", "--layouts", "1", "--seed", "11", "--out", str(out), "--quiet"]) == 0
    results = json.loads((out / "detectability.json").read_text())
    (r,) = results
    assert r["fault_type"] == "converter-offset" and r["sizes"] == [0.05, 3.0] and r["runs_per_size"] == 2
    small, large = r["rows"]
    assert large["detected_pct"] == 100.0 and large["isolated_pct"] == 100.0
    assert small["detected_pct"] <= large["detected_pct"]
    assert large["delay_s_mean"] is not None and 0.0 <= large["delay_s_mean"] <= large["delay_s_max"] <= 10.0
    assert len(r["windows"]) == 2 and {w["size"] for w in r["windows"]} == {0.05, 3.0}
    assert set(r["thresholds"]) == {"detected", "isolated"}
    text = (out / "detectability.md").read_text()
    assert "converter-offset" in text and "img/converter-offset.png" in text
    png = out / "img" / "converter-offset.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size < 100_000


@pytest.mark.parametrize(
    "argv",
    [
        ["detectability", "windmill"],
        ["detectability", "turbine", "--fault", "farm-debris"],
        ["detectability", "turbine", "--fault", "no-such-type"],
        ["detectability", "turbine", "--sizes", "1,2"],
        ["detectability", "turbine", "--fault", "converter-offset", "--sizes", "1"],
        ["detectability", "turbine", "--fault", "converter-offset", "--sizes", "0,1"],
        ["detectability", "turbine", "--fault", "converter-offset", "--sizes", "a,b"],
        ["detectability", "turbine", "--fault", "converter-offset", "--sizes", "1,inf"],
        ["detectability", "farm", "--fault", "farm-debris", "--sizes", "1,60"],
        ["detectability", "hydro", "--fault", "hydro-pump-offset", "--sizes", "0.1,2"],
        ["detectability", "turbine", "--runs", "4", "--layouts", "5"],
        ["detectability", "turbine", "--seed", "-3"],
    ],
)
def test_bad_sweep_arguments_are_refused_with_exit_2_and_nothing_written(tmp_path, argv):
    out = tmp_path / "sweep"
    assert main([*argv, "--out", str(out), "--quiet"]) == 2
    assert not out.exists()


def test_the_docs_show_the_fault_types_timing_and_random_distributions_as_the_code_has_them():
    """docs/detectability.md's generated blocks (``tools/detectability_docs.py`` rewrites them)."""
    text = (Path(__file__).resolve().parent.parent / "docs" / "detectability.md").read_text()
    for table in (catalogue_table(), timing_table(), distribution_table()):
        assert table in text
