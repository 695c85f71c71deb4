"""Commands for detectability and random scenarios (registered by ``windwarden.cli``):

* ``windwarden detectability KIND|SCENARIO [--fault TYPE ...] [--sizes S,S,...] --runs N --layouts D --seed S
  --out DIR``: detection %, isolation % and delay against fault size per fault type (``docs/detectability.md``);
* ``windwarden scenarios random KIND --seed S [--out FILE]``: one random scenario file;
* ``windwarden eval random:KIND --runs N --seed S [--scenarios K] --out DIR``: a set of random scenarios scored
  together (``eval`` hands ``random:`` names to ``eval_random``).

Bad input is refused before anything runs, with exit code 2 and a message naming the argument.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from windwarden.commands.common import EXIT_BAD_INPUT, console, err_console, positive_int, with_wake_model
from windwarden.evaluation.kinds import EvalOptions

KINDS = ("turbine", "farm", "hydro")


def _refuse(message: str) -> int:
    err_console.print(f"[red]error:[/red] {message}", highlight=False)
    return EXIT_BAD_INPUT


# ---- detectability ------------------------------------------------------------------------------------------------
def add_detectability_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("detectability", help="detection %%, isolation %% and delay against fault size, per fault type")
    p.add_argument("plant", help="turbine, farm or hydro, or a scenario (name or file) whose plant settings to keep")
    p.add_argument("--fault", action="append", default=[], help="fault type (repeat it); default: all of the kind")
    p.add_argument("--sizes", default=None, help="comma-separated sizes in the type's unit (with one --fault)")
    p.add_argument("--runs", type=positive_int, default=40, help="window-runs per size (default 40)")
    p.add_argument("--layouts", type=positive_int, default=8, help="random layouts (fault times, winds); default 8")
    p.add_argument("--seed", type=int, default=0, help="master seed (default 0)")
    p.add_argument("--out", type=Path, default=None, help="folder for detectability.json, .md and img/*.png")
    p.add_argument("--workers", type=positive_int, default=None, help="processes per evaluation (default: all cores)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--list", action="store_true", help="list the kind's fault types, units and grids, and exit")
    p.set_defaults(func=cmd_detectability)


def _parse_sizes(text: str) -> list[float]:
    try:
        sizes = sorted({float(part) for part in text.split(",") if part.strip()})
    except ValueError:
        raise ValueError(f"--sizes: {text!r} is not a comma-separated list of numbers") from None
    if len(sizes) < 2:
        raise ValueError("--sizes: give at least two different sizes")
    if any(not math.isfinite(s) or s <= 0.0 for s in sizes):
        raise ValueError("--sizes: every size must be a finite number > 0")
    return sizes


def cmd_detectability(args: argparse.Namespace) -> int:
    from windwarden.evaluation.detectability import base_scenario, check_sizes, sweep
    from windwarden.evaluation.detectability_report import console_table, markdown, plot
    from windwarden.evaluation.fault_types import fault_type, types_of

    base = base_scenario(args.plant)  # an unknown scenario raises ScenarioError: exit 2
    kind = base.plant.kind
    if args.list:
        for t in types_of(kind):
            console.print(f"[bold]{t.name}[/bold] ({t.unit}): {t.label}; grid {', '.join(f'{s:g}' for s in t.sizes)}")
            console.print(f"  {t.grid_reason}", highlight=False)
        return 0
    try:
        types = [fault_type(name, kind) for name in args.fault] if args.fault else types_of(kind)
    except KeyError as error:
        return _refuse(str(error.args[0]))
    if not 0 <= args.seed < 2**63:
        return _refuse(f"--seed: {args.seed} is outside 0 … 2^63 − 1")
    if args.sizes is not None and len(types) != 1:
        return _refuse("--sizes needs exactly one --fault")
    if args.layouts > args.runs:
        return _refuse(f"--layouts ({args.layouts}) cannot exceed --runs ({args.runs}): each layout needs a run")
    grids = {}
    for t in types:
        try:
            sizes = _parse_sizes(args.sizes) if args.sizes is not None else list(t.sizes)
        except ValueError as error:
            return _refuse(str(error))
        problems = check_sizes(t, sizes, base)
        if problems:
            return _refuse(f"--sizes for {t.name}: " + "; ".join(problems))
        grids[t.name] = sizes
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
    results = []
    for t in types:
        sweep_args = {"runs": args.runs, "layouts": args.layouts, "seed": args.seed, "base": base}
        results.append(sweep(t, grids[t.name], **sweep_args, workers=args.workers, progress=not args.quiet))
        if args.out is not None:  # after each type, so a long sweep keeps what it has measured
            if not args.no_plots:
                plot(results[-1], args.out / "img" / f"{t.name}.png")
            images = {r["fault_type"]: f"img/{r['fault_type']}.png" for r in results if not args.no_plots}
            (args.out / "detectability.json").write_text(json.dumps(results, indent=1) + "\n")
            (args.out / "detectability.md").write_text(markdown(results, images))
    console.print(console_table(results))
    if args.out is not None:
        plots = "" if args.no_plots else f" and {len(results)} plots in {args.out / 'img'}"
        console.print(f"wrote {args.out / 'detectability.json'}, detectability.md{plots}")
    return 0


# ---- random scenarios -----------------------------------------------------------------------------------------
def add_random_parser(scenarios_parser: argparse.ArgumentParser) -> None:
    """``scenarios random`` under the ``scenarios`` command (which lists the shipped ones without it)."""
    sub = scenarios_parser.add_subparsers(dest="scenarios_command")
    p = sub.add_parser("random", help="write a random scenario (fault times, targets, kinds, sizes, winds)")
    p.add_argument("kind", help="turbine, farm or hydro")
    p.add_argument("--seed", type=int, required=True, help="generator seed")
    p.add_argument("--out", type=Path, default=None, help="scenario file to write (default: print it)")
    p.add_argument("--duration", type=float, default=None, help="s of simulated time (default per kind)")
    p.set_defaults(func=cmd_random_scenario)


def cmd_random_scenario(args: argparse.Namespace) -> int:
    from windwarden.evaluation.random_scenarios import SCHEDULES, generate
    from wwcore.scenario import dump_scenario

    if args.kind not in KINDS:
        return _refuse(f"unknown plant kind {args.kind!r}; known: {', '.join(KINDS)}")
    if args.duration is not None:
        least = SCHEDULES[args.kind].first_s + SCHEDULES[args.kind].window_s[1] + SCHEDULES[args.kind].min_gap_s
        if not math.isfinite(args.duration) or not least <= args.duration <= 100_000.0:
            return _refuse(f"--duration: {args.duration} s is outside {least:g} … 100000 s for a {args.kind} scenario")
    if not 0 <= args.seed < 2**63:
        return _refuse(f"--seed: {args.seed} is outside 0 … 2^63 − 1")
    text = dump_scenario(generate(args.kind, args.seed, duration_s=args.duration))
    if args.out is None:
        sys.stdout.write(text)
    else:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
        console.print(f"wrote {args.out}")
    return 0


def eval_random(args: argparse.Namespace, options: EvalOptions) -> int:
    """``windwarden eval random:KIND``: ``--scenarios K`` random scenarios (default one per run), scored together
    with the scenario's algorithms or those ``--detector``/``--estimator``/``--controller`` name."""
    from service.plugins import AlgorithmOptionError, UnknownAlgorithmError
    from windwarden.evaluation.detectability import BASES
    from windwarden.evaluation.random_scenarios import evaluate_set
    from windwarden.evaluation.random_summary import console_table, markdown
    from wwcore.scenario import dump_scenario, load_scenario

    kind = args.scenario.split(":", 1)[1]
    if kind not in KINDS:
        return _refuse(
            f"unknown plant kind {kind!r} in {args.scenario!r}; use random:turbine, random:farm or random:hydro"
        )
    if not 0 <= args.seed < 2**63:
        return _refuse(f"--seed: {args.seed} is outside 0 … 2^63 − 1")
    if options.compare:
        return _refuse("--compare: a random set has no paper tables; score a shipped scenario for them")
    scenarios = args.scenarios or args.runs
    if scenarios > args.runs:
        return _refuse(f"--scenarios ({scenarios}) cannot exceed --runs ({args.runs}): each scenario needs a run")
    # --wake-model: the farms are drawn on the base scenario with those wakes (refused for other kinds)
    base = None if args.wake_model is None else with_wake_model(load_scenario(BASES[kind]), args.wake_model)
    try:
        result = evaluate_set(kind, args.runs, args.seed, scenarios, options, base=base)
    except (UnknownAlgorithmError, AlgorithmOptionError) as error:
        return _refuse(str(error))
    console.print(console_table(result.card))
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "scorecard.json").write_text(json.dumps(result.card, indent=1) + "\n")
        (args.out / "summary.md").write_text(markdown(result.card))
        folder = args.out / "scenarios"
        folder.mkdir(exist_ok=True)
        for scenario in result.scenarios:
            (folder / f"{scenario.name}.toml").write_text(dump_scenario(scenario))
        console.print(f"wrote {args.out / 'scorecard.json'}, summary.md and {len(result.scenarios)} scenario files")
    return 0
