r"""Paired comparison of two scorecards of the same runs (``windwarden compare A B``).

Two variants evaluated on the same scenario runs and seed see the same wind and noise run by run, so their
difference is best judged run by run. For every metric both scorecards keep per run (``per_run``: name → values in
run order) this computes, over the n runs where both values are finite,

.. math::

    d_i = b_i − a_i,\qquad \bar d = \frac1n \sum_i d_i,\qquad
    \mathrm{SE}(\bar d) = \sqrt{\frac{1}{n(n − 1)} \sum_i (d_i − \bar d)^2}

with the two means ā, b̄ and how many runs B had lower (b_i < a_i), equal and higher than A. d̄/SE is the paired
t statistic (n − 1 degrees of freedom).

Same runs means the same master seed, the same number of runs and the same ``runs_digest``: a hash of the scenario
without its name, description and supervisor section (plant, wind, faults, duration: everything that draws the
runs). Anything else is refused (``NotPairedError``), as is a file that is not a scorecard.
"""

from __future__ import annotations

import hashlib
import json
import math
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from wwcore.scenario import Scenario
from wwcore.scenario.mismatch import Mismatch

WIDTH = 100  # columns the table fits
IDENTITY = ("seed", "runs", "runs_digest")  # scorecard fields that must be equal for the runs to be the same


class NotPairedError(ValueError):
    """The two scorecards are not of the same runs, or not scorecards with per-run values."""


def runs_digest(scenario: Scenario) -> str:
    """SHA-256 (hex, first 16) of what draws a scenario's runs: everything but its name, description, supervisor.

    Values equal to their defaults are left out, so a scenario keeps its digest when the schema gains an option
    whose default is today's behaviour (and whether a default is written out or not changes nothing). An empty
    ``[mismatch]`` section is the design plant, the same runs as none."""
    body = scenario.model_dump(mode="json", exclude={"name", "description", "supervisor"}, exclude_defaults=True)
    body.setdefault("plant", {})["kind"] = scenario.plant.kind
    if scenario.plant.kind == "farm":
        # The wake model is named even at its default: a scorecard whose digest leaves it out (one written while
        # the row model was the default) must never pair with a Gauss one.
        body["plant"]["wake_model"] = scenario.plant.wake_model
    if scenario.mismatch is None or scenario.mismatch == Mismatch():
        body["mismatch"] = None
    return hashlib.sha256(json.dumps(body, sort_keys=True).encode()).hexdigest()[:16]


def load_scorecard(path: Path) -> dict[str, Any]:
    """A scorecard from ``path`` (the file, or the folder ``eval --out`` wrote it to)."""
    if path.is_dir():
        path = path / "scorecard.json"
    try:
        card = json.loads(path.read_text())
    except OSError as error:
        raise NotPairedError(f"{path}: cannot read ({error.strerror or error})") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise NotPairedError(f"{path}: not JSON ({error})") from None
    if not isinstance(card, dict) or not isinstance(card.get("per_run"), dict):
        raise NotPairedError(f"{path}: not a scorecard with per-run values (no 'per_run')")
    return card


@dataclass(frozen=True)
class PairedRow:
    """One metric: the means of A and B over the paired runs, the mean paired difference B − A and its SE."""

    metric: str
    n: int
    mean_a: float
    mean_b: float
    diff: float
    se: float  # NaN for n < 2
    lower: int  # runs with b < a
    equal: int
    higher: int

    def as_dict(self) -> dict[str, Any]:
        return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in self.__dict__.items()}


def paired_row(metric: str, a: list[float], b: list[float]) -> PairedRow:
    """The paired statistics of one metric from its values per run in A and B (same length, run order)."""
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    d = y - x
    n = len(d)
    nan = float("nan")
    return PairedRow(
        metric=metric,
        n=n,
        mean_a=float(x.mean()) if n else nan,
        mean_b=float(y.mean()) if n else nan,
        diff=float(d.mean()) if n else nan,
        se=float(d.std(ddof=1) / math.sqrt(n)) if n >= 2 else nan,
        lower=int((d < 0).sum()),
        equal=int((d == 0).sum()),
        higher=int((d > 0).sum()),
    )


def check_same_runs(a: dict[str, Any], b: dict[str, Any]) -> None:
    """Refuse (``NotPairedError``) unless the two scorecards are of the same runs."""
    differ = [f"{key}: {a.get(key)!r} against {b.get(key)!r}" for key in IDENTITY if a.get(key) != b.get(key)]
    missing = [key for key in IDENTITY if a.get(key) is None or b.get(key) is None]
    if missing:
        raise NotPairedError(f"cannot tell whether the runs are the same: no {', '.join(missing)} in the scorecard")
    if differ:
        raise NotPairedError("not the same runs (" + "; ".join(differ) + ")")
    for name, card in (("A", a), ("B", b)):
        wrong = [k for k, v in card["per_run"].items() if not isinstance(v, list) or len(v) != card["runs"]]
        if wrong:
            runs = card["runs"]
            raise NotPairedError(f"{name}: per_run {wrong[0]!r} does not hold one value for each of the {runs} runs")


def compare(a: dict[str, Any], b: dict[str, Any]) -> tuple[list[PairedRow], list[str]]:
    """Paired rows for every per-run metric the two scorecards share (in A's order), and the metrics only one has."""
    check_same_runs(a, b)
    shared = [k for k in a["per_run"] if k in b["per_run"]]
    if not shared:
        raise NotPairedError("the two scorecards share no per-run metric")
    only = sorted(set(a["per_run"]) ^ set(b["per_run"]))
    return [paired_row(k, a["per_run"][k], b["per_run"][k]) for k in shared], only


def describe(card: dict[str, Any]) -> str:
    """One line naming a scorecard's variant: scenario, algorithms, accommodation, options."""
    parts = [str(card.get("scenario"))]
    parts += [f"{k} {card[k]}" for k in ("detector", "controller") if card.get(k) is not None]
    if "accommodation" in card:
        parts.append("accommodation " + ("on" if card["accommodation"] else "off"))
    if card.get("options"):
        parts.append(", ".join(f"{k} = {v}" for k, v in card["options"].items()))
    return "; ".join(parts)


def _num(x: float) -> str:
    return "–" if math.isnan(x) else f"{x:.4g}"


def table(rows: list[PairedRow], numbers: dict[str, str] | None = None, width: int = WIDTH) -> str:
    """The paired rows as plain text within ``width`` columns: the means, B − A ± SE, t = (B − A)/SE, and how
    many runs B had lower / equal / higher than A. A fault window's name in a metric is written as its number
    (``numbers``, from ``report.window_numbers``; listed under the table); a metric name longer than its column
    continues on the next lines, in its column."""
    numbers = numbers or {}
    header = ("metric", "n", "A", "B", "B − A ± SE", "t", "runs B < / = / > A")
    used = sorted((name for name in numbers if any(name in r.metric for r in rows)), key=len, reverse=True)
    lines = []
    for r in rows:
        t = r.diff / r.se if r.se > 0 else float("nan")
        metric = r.metric
        for name in used:  # longest first: a name inside another is not replaced first
            metric = metric.replace(name, numbers[name])
        lines.append(
            (
                metric,
                str(r.n),
                _num(r.mean_a),
                _num(r.mean_b),
                f"{_num(r.diff)} ± {_num(r.se)}",
                "–" if math.isnan(t) else f"{t:+.1f}",
                f"{r.lower} / {r.equal} / {r.higher}",
            )
        )
    widths = [max(len(x[i]) for x in [header, *lines]) for i in range(len(header))]
    widths[0] = max(12, min(widths[0], width - sum(widths[1:]) - 2 * (len(widths) - 1)))

    def line(cells: tuple[str, ...]) -> list[str]:
        first, *more = textwrap.wrap(cells[0], widths[0], break_on_hyphens=False) or [""]
        rest = [c.rjust(w) for c, w in zip(cells[1:], widths[1:], strict=True)]
        return ["  ".join([first.ljust(widths[0]), *rest]).rstrip(), *more]

    out = [*line(header), "  ".join("-" * w for w in widths)]
    for cells in lines:
        out += line(cells)
    out += [f"{numbers[name]} {name}" for name in sorted(used, key=lambda n: int(numbers[n][1:]))]
    return "\n".join(out)
