"""Every table the CLI prints fits 100 columns: no line is longer, and no row folds onto a second line.

The scorecard of every shipped scenario (its real fault names and windows, as ``windows_from_faults`` merges
them; flags from a synthetic event log) through ``report.render`` (``eval`` and the live end-of-run scorecard), the
detectability and random-scenario summaries, ``compare`` and ``scenarios``. A row is on one line when a single
rendered line holds every one of its cells whole.
"""

from __future__ import annotations

import io

import pytest
from rich.console import Console, Group
from rich.table import Table

from windwarden.commands.scenario_list import scenarios_listing
from windwarden.evaluation import paired
from windwarden.evaluation.detectability_report import console_table as detectability_table
from windwarden.evaluation.fault_types import FAULT_TYPES
from windwarden.evaluation.random_summary import console_table as random_table
from windwarden.evaluation.report import render, window_numbers
from windwarden.evaluation.scoring import score_detection, windows_from_faults
from windwarden.evaluation.scoring_policy import policy_for
from wwcore.events import Event, EventType
from wwcore.scenario import load_scenario, shipped_scenarios

WIDTH = 100
SHIPPED = sorted(shipped_scenarios())


def rendered(renderable, width: int = WIDTH) -> list[str]:
    console = Console(width=width, record=True, file=io.StringIO())
    console.print(renderable)
    return console.export_text().splitlines()


def tables(renderable) -> list[Table]:
    if isinstance(renderable, Table):
        return [renderable]
    if isinstance(renderable, Group):
        return [t for part in renderable.renderables for t in tables(part)]
    return []


def assert_fits(renderable) -> None:
    lines = rendered(renderable)
    assert max(map(len, lines)) <= WIDTH
    assert not any("…" in line for line in lines), "a cell was cut"
    found = tables(renderable)
    assert found
    for table in found:
        for r in range(table.row_count):
            cells = [str(column._cells[r]) for column in table.columns]
            assert any(all(c in line for c in cells) for line in lines), f"row folded: {cells}\n" + "\n".join(lines)


def scorecard(name: str) -> dict:
    """The scorecard of two runs of a shipped scenario: each window flagged 0.5 s in, released 0.3 s after."""
    s = load_scenario(shipped_scenarios()[name])
    windows = windows_from_faults(s.faults, s.duration_s)
    events = [
        Event(w.start_s + dt, kind, w.turbine, target, run)
        for run in range(2)
        for w in windows
        for target in w.targets
        for dt, kind in ((0.5, EventType.DETECTION), (w.end_s - w.start_s + 0.3, EventType.RECOVERY))
    ]
    turbines = sorted({f.turbine for f in s.faults} | {1})
    score = score_detection(
        events, windows, runs=2, duration_s=s.duration_s, policy=policy_for(s.plant.kind), turbines=turbines
    )
    metrics = {  # what the kinds put under a window's name, and a rule described in words
        "wind_rmse": {w.name: {"fte": 0.2, "nfte": 5.0, "anemometer": 1.8, "fte_fault_free": 0.2} for w in windows},
        "detection": {"rule": "|f̂_filt| > θ for 5 samples; release below 1 θ for 50 samples " * 2},
    }
    return {"scenario": name, "runs": 2, "seed": 7, **score.card_fields(), "metrics": metrics}


@pytest.mark.parametrize("name", SHIPPED)
def test_the_scorecard_of_every_shipped_scenario_fits_100_columns(name):
    card = scorecard(name)
    assert_fits(render(card))
    text = " ".join(" ".join(rendered(render(card))).split())
    for f in card["faults"]:  # every window named once, in full, under the first table
        assert " ".join(f"{window_numbers(card)[f['name']]} {f['name']}".split()) in text


def test_a_window_inside_the_warm_up_is_a_row_of_dashes_with_its_reason_in_the_legend():
    card = scorecard("demo")
    first = card["faults"][0]
    card["faults"][0] = {k: first[k] for k in ("name", "target", "turbine", "start_s", "end_s")} | {
        "note": "inside the warm-up: not scored"
    }
    assert_fits(render(card))
    assert any("#1" in line and "inside the warm-up: not scored" in line for line in rendered(render(card)))


def _detectability_result(name: str, runs: int) -> dict:
    level = {"measured": {"status": "within", "bracket": [0.1, 0.3]}, "fitted": 0.2487, "within_grid": True}
    return {
        "fault_type": name,
        "unit": "%",
        "sigma": 0.2,
        "value_unit": "deg",
        "runs_per_size": runs,
        "sizes": [0.05, 0.1, 0.2, 0.4],
        "thresholds": {
            "detected": {"p50": level, "p95": level | {"ci95": [0.07823, 0.3571]}},
            "isolated": {"p50": level, "p95": level},
        },
        "false_alarms": {"per_1000s": 0.208},
    }


@pytest.mark.parametrize("runs", [(20,), (20, 40)], ids=["same runs", "runs differ"])
def test_the_detectability_summary_of_every_fault_type_fits_100_columns(runs):
    results = [_detectability_result(t.name, runs[i % len(runs)]) for i, t in enumerate(FAULT_TYPES)]
    assert_fits(detectability_table(results))


def _case(**extra) -> dict:
    row = {"windows": 120, "window_runs": 2400, "detected_pct": 100.0, "isolated_pct": 99.5}
    row |= {"isolated_time_pct": 99.7, "delay_s_mean": 0.01234, "delay_s_max": 21.52, "wrong_isolation_pct": 0.5}
    return row | {"lost_pct": 1.25, "flaps_mean": 0.25, "end_recognised_pct": 100.0} | extra


@pytest.mark.parametrize(
    "extra",
    [
        {
            "fte_ratio_mean": 1.0012,
            "fte_ratio_max": 1.0571,
            "fte_clean_ratio_mean": 1.0123,
            "fte_clean_ratio_max": 1.2801,
        },
        {"reconstruction_error_pct_mean": 1.68, "reconstruction_error_pct_max": 2.21},
    ],
    ids=["turbine", "hydro"],
)
def test_the_random_scenario_summary_fits_100_columns(extra):
    fa = {"count": 3, "observed_s": 33720.0, "flagged_s": 4.2, "per_1000s": 0.089, "flagged_s_per_1000s": 0.12}
    summary = {"cases": {t.name: _case(**extra) for t in FAULT_TYPES}, "false_alarms": fa}
    summary["speed_sensors"] = _case(**extra)
    if "fte_ratio_mean" in extra:
        free = {"fte": 3.43, "nfte": 3.42, "anemometer": 2.0, "fte_clean": 3.41, "ratio": 1.006}
        summary["fault_free_wind"] = [{"scenario": f"random-turbine-{3678731415 + i}", **free} for i in range(5)]
    card = {"scenario": "random:turbine", "scenarios": [{}] * 5, "runs": 20, "seed": 1, "summary": summary}
    assert_fits(random_table(card))


def test_compare_fits_100_columns_with_the_windows_numbered():
    card = scorecard("demo")
    rows = [
        paired.paired_row(f"wind_rmse.{f['name']}.fte_fault_free", [0.21, 0.2345, 0.2], [0.2, 0.25, 0.1987])
        for f in card["faults"]
    ] + [paired.paired_row("over_production_mwh", [1.5, 2.0], [1.25, 2.5])]
    lines = paired.table(rows, window_numbers(card)).splitlines()
    assert max(map(len, lines)) <= WIDTH
    assert len(lines) == 2 + len(rows) + len(card["faults"])  # header, rule, one line per row, the legend
    assert lines[2].startswith("wind_rmse.#1.fte_fault_free") and lines[-1].startswith("#5 one rotor-speed")


def test_compare_folds_a_metric_name_too_long_for_its_column_within_100_columns():
    rows = [paired.paired_row("x" * 150, [1.0, 2.0], [1.5, 2.5])]
    lines = paired.table(rows).splitlines()
    assert max(map(len, lines)) <= WIDTH and "".join(lines).count("x") == 150


def test_the_scenario_listing_fits_100_columns_with_one_line_per_scenario():
    scenarios = {name: load_scenario(path) for name, path in shipped_scenarios().items()}
    lines = rendered(scenarios_listing(scenarios))
    assert max(map(len, lines)) <= WIDTH
    for name, s in scenarios.items():
        [line] = [ln for ln in lines if ln.startswith(name + " ")]
        assert line.split()[1:] == [s.plant.kind, f"{s.duration_s:g}", str(len(s.faults))]
    described = " ".join(" ".join(lines).split())
    assert all(" ".join(s.description.split()) in described for s in scenarios.values())
