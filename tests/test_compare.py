"""``windwarden compare``: paired per-run statistics of two scorecards (closed form), and its refusals."""

from __future__ import annotations

import json
import math

import pytest

from windwarden.cli import EXIT_BAD_INPUT, main
from windwarden.evaluation.paired import NotPairedError, compare, paired_row, runs_digest
from wwcore.scenario import load_scenario, parse_scenario


def card(per_run: dict, *, seed: int = 7, runs: int = 4, digest: str = "abc", **extra) -> dict:
    return {"scenario": "s", "seed": seed, "runs": runs, "runs_digest": digest, "per_run": per_run, **extra}


A = card({"missing_power_mwh": [1.0, 2.0, 3.0, 4.0], "damage.run.farm_miner_ratio": [1.1, 1.2, 1.3, 1.4]})
B = card({"missing_power_mwh": [2.0, 2.0, 5.0, 3.0], "damage.run.farm_miner_ratio": [1.0, 1.1, 1.2, 1.3]})


def test_paired_statistics_in_closed_form():
    row = paired_row("m", [1.0, 2.0, 3.0, 4.0], [2.0, 2.0, 5.0, 3.0])  # d = 1, 0, 2, −1
    assert (row.n, row.mean_a, row.mean_b, row.diff) == (4, 2.5, 3.0, 0.5)
    assert row.se == pytest.approx(math.sqrt(5.0 / 3.0) / 2.0)  # Σ(d − d̄)² = 5, s² = 5/3, SE = s/√4
    assert (row.lower, row.equal, row.higher) == (1, 1, 2)


def test_a_constant_shift_has_zero_standard_error_and_every_run_lower():
    row = paired_row("m", [1.0, 5.0, 2.0], [0.9, 4.9, 1.9])
    assert row.diff == pytest.approx(-0.1) and row.se == pytest.approx(0.0, abs=1e-12)
    assert (row.lower, row.equal, row.higher) == (3, 0, 0)


def test_runs_without_a_finite_value_in_either_are_left_out():
    row = paired_row("m", [1.0, float("inf"), 3.0], [2.0, 1.0, float("nan")])
    assert (row.n, row.diff) == (1, 1.0) and math.isnan(row.se)


def test_compare_pairs_every_shared_metric_and_names_the_others():
    b = card({**B["per_run"], "damage.run.wt1.damage_number": [1.0] * 4})
    rows, only = compare(A, b)
    assert [r.metric for r in rows] == ["missing_power_mwh", "damage.run.farm_miner_ratio"]
    assert rows[1].diff == pytest.approx(-0.1) and rows[1].lower == 4
    assert only == ["damage.run.wt1.damage_number"]


@pytest.mark.parametrize(
    ("other", "named"),
    [
        (card(B["per_run"], seed=8), "seed"),
        (card({k: [*v, 1.0] for k, v in B["per_run"].items()}, runs=5), "runs"),
        (card(B["per_run"], digest="abd"), "runs_digest"),
    ],
)
def test_scorecards_of_other_runs_are_refused(other, named):
    with pytest.raises(NotPairedError, match=named):
        compare(A, other)


def test_per_run_values_that_do_not_match_the_runs_are_refused():
    with pytest.raises(NotPairedError, match="missing_power_mwh"):
        compare(A, card({"missing_power_mwh": [1.0, 2.0, 3.0]}))


def test_the_digest_ignores_the_supervisor_and_the_name_but_not_the_runs():
    scenario = load_scenario("farm-case1")
    renamed = scenario.model_copy(update={"name": "other", "description": "x"})
    options = scenario.supervisor.model_copy(update={"params": {"ripple_compensation": False}})
    assert runs_digest(renamed) == runs_digest(scenario)
    assert runs_digest(scenario.model_copy(update={"supervisor": options})) == runs_digest(scenario)
    assert runs_digest(scenario.model_copy(update={"faults": scenario.faults[1:]})) != runs_digest(scenario)
    assert runs_digest(scenario.model_copy(update={"duration_s": 100.0})) != runs_digest(scenario)


def test_the_runs_digest_ignores_defaults_written_out():
    explicit = load_scenario("farm-case1")  # writes out wake_model = "gauss", the default
    data = explicit.model_dump(mode="json", exclude_none=True)
    del data["plant"]["wake_model"]
    bare = parse_scenario(data)
    assert bare == explicit and runs_digest(explicit) == runs_digest(bare)
    for change in ({"wind_case": 2}, {"wake_model": "rows"}):
        other = explicit.model_copy(update={"plant": explicit.plant.model_copy(update=change)})
        assert runs_digest(other) != runs_digest(explicit), change
    # farm-case1's digest while the row model was the default: a Gauss scorecard must not pair with one of those
    assert runs_digest(explicit) != "d7387c54f17d2784"


def _write(tmp_path, name: str, content) -> str:
    path = tmp_path / name
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    return str(path)


def test_the_command_prints_the_paired_rows_as_json(tmp_path, capsys):
    a, b = _write(tmp_path, "a.json", A), _write(tmp_path, "b.json", B)
    assert main(["compare", a, b, "--json", "--metric", "missing_*"]) == 0
    out = json.loads(capsys.readouterr().out)
    (row,) = out["rows"]
    assert row["metric"] == "missing_power_mwh" and row["diff"] == 0.5 and row["lower"] == 1
    assert row["se"] == pytest.approx(math.sqrt(5.0 / 3.0) / 2.0)


def test_the_command_prints_a_table(tmp_path, capsys):
    a, b = _write(tmp_path, "a.json", A), _write(tmp_path, "b.json", B)
    assert main(["compare", a, b]) == 0
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if line.startswith("missing_power_mwh"))
    assert row.split() == ["missing_power_mwh", "4", "2.5", "3", "0.5", "±", "0.6455", "+0.8", "1", "/", "1", "/", "2"]


@pytest.mark.parametrize(
    ("b", "message"),
    [
        (card(B["per_run"], seed=8), "seed"),
        ({"scenario": "s"}, "not a scorecard"),
        ("{not json", "not JSON"),
        (None, "cannot read"),
    ],
)
def test_the_command_refuses_with_exit_code_2_and_says_why(tmp_path, capsys, b, message):
    a = _write(tmp_path, "a.json", A)
    other = str(tmp_path / "missing.json") if b is None else _write(tmp_path, "b.json", b)
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(["compare", a, other]) == EXIT_BAD_INPUT
    assert message in " ".join(capsys.readouterr().err.split())
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written


def test_a_metric_filter_that_matches_nothing_is_refused(tmp_path, capsys):
    a, b = _write(tmp_path, "a.json", A), _write(tmp_path, "b.json", B)
    assert main(["compare", a, b, "--metric", "nothing*"]) == EXIT_BAD_INPUT
    assert "--metric" in capsys.readouterr().err
