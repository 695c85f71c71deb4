"""The ``windwarden`` command: one entry point, one subcommand per job.

Exit codes: 0 success, 1 a failure while running, 2 bad input (scenario, options), refused before anything ran.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from rich.markup import escape

from windwarden.commands.common import (
    EXIT_BAD_INPUT,
    BadInputError,
    check_supervisor,
    console,
    err_console,
    positive_int,
    with_wake_model,
)
from windwarden.commands.live import LIVE_SUBCOMMANDS
from windwarden.commands.scenario_list import scenarios_listing
from windwarden.commands.sweep import add_detectability_parser, add_random_parser, eval_random
from wwcore.backend import BackendError, available, process_backend
from wwcore.scenario import ScenarioError, load_scenario, shipped_scenarios


def _add_eval(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("eval", help="score a scenario over Monte Carlo runs (batch mode, no transport)")
    p.add_argument("scenario", help="shipped scenario name, path to a scenario file, or random:KIND (a random set)")
    p.add_argument("--runs", type=positive_int, default=10, help="Monte Carlo runs (default 10)")
    p.add_argument("--seed", type=int, default=0, help="master seed (default 0)")
    p.add_argument("--out", type=Path, default=None, help="folder for scorecard.json and plots")
    p.add_argument("--detector", default=None, help="registered detector name (overrides the scenario)")
    p.add_argument("--estimator", default=None, help="registered estimator/observer name")
    p.add_argument("--controller", default=None, help="farm controller: dispatch or pi")
    p.add_argument("--no-accommodation", action="store_true", help="farm: dispatch without fault accommodation")
    p.add_argument(
        "--wake-model",
        choices=("gauss", "jensen", "rows"),
        default=None,
        help="farm: FLORIS's Gauss or Jensen wakes, or the paper's row model (default: the scenario's)",
    )
    p.add_argument("--no-compensation", action="store_true", help="hydro: do not apply the virtual actuator")
    p.add_argument("--compare", action="store_true", help="also write the paper-comparison tables and plots")
    p.add_argument(
        "--no-twins", action="store_true", help="no fault-free twins (turbine: as a live run; farm: no damage numbers)"
    )
    p.add_argument("--plugin", action="append", default=[], help="import this module first (registers algorithms)")
    p.add_argument("--workers", type=positive_int, default=None, help="local processes (default: one per core)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="run on this Dask scheduler (docs/cluster.md)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument(
        "--step-backend",
        choices=("numba", "numpy"),
        default="numba",
        help="the step code: compiled (numba, default) or the numpy reference; the same numbers (docs/cluster.md)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--scenarios", type=positive_int, default=None, help="random:KIND: scenarios drawn (default: runs)")
    p.set_defaults(func=cmd_eval)


def cmd_eval(args: argparse.Namespace) -> int:
    from service.plugins import AlgorithmOptionError, UnknownAlgorithmError, load_plugins
    from windwarden.evaluation.cluster import ClusterError
    from windwarden.evaluation.kinds import EvalOptions, unused_switches
    from windwarden.evaluation.report import render
    from windwarden.evaluation.usage import ResourceMonitor, execution_line, execution_record
    from windwarden.kinds import kind_for

    try:
        load_plugins(tuple(args.plugin))
    except ModuleNotFoundError as error:
        raise BadInputError(f"--plugin: cannot import {error.name!r}") from None
    try:
        available(args.step_backend)
    except BackendError as error:
        raise BadInputError(f"--step-backend: {error}") from None
    options = EvalOptions(
        detector=args.detector,
        estimator=args.estimator,
        controller=args.controller,
        accommodation=not args.no_accommodation,
        compensation=not args.no_compensation,
        compare=args.compare,
        twins=not args.no_twins,
        workers=args.workers,
        scheduler=args.scheduler,
        plugins=tuple(args.plugin),
        progress=not args.quiet,
    )
    if args.scenario.startswith("random:"):
        with process_backend(args.step_backend):
            return eval_random(args, options)
    if args.scenarios is not None:
        raise BadInputError("--scenarios: only a random set (random:KIND) is drawn from scenarios")
    scenario = load_scenario(args.scenario)
    if args.wake_model is not None:
        scenario = with_wake_model(scenario, args.wake_model)
    refused = [f"{flag}: {message}" for flag, message in unused_switches(scenario.plant.kind, options)]
    try:
        check_supervisor(scenario, detector=args.detector, estimator=args.estimator, controller=args.controller)
    except BadInputError as error:
        refused.append(str(error))
    if refused:
        raise BadInputError("\n".join(refused))
    try:
        with ResourceMonitor() as usage, process_backend(args.step_backend):
            evaluation = kind_for(scenario.plant.kind).evaluate(scenario, args.runs, args.seed, options)
    except (UnknownAlgorithmError, AlgorithmOptionError) as error:
        raise BadInputError(str(error)) from None
    except ClusterError as error:
        raise BadInputError(f"--scheduler: {error}") from None
    console.print(render(evaluation.scorecard))
    execution = execution_record(options, usage.report())
    execution["step_backend"] = args.step_backend
    console.print(execution_line(execution), highlight=False)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "scorecard.json").write_text(json.dumps(evaluation.scorecard, indent=2) + "\n")
        (args.out / "execution.json").write_text(json.dumps(execution, indent=2) + "\n")
        for name, text in evaluation.extra_files.items():
            (args.out / name).write_text(text)
        written = [] if args.no_plots else evaluation.plot(args.out)
        console.print(f"wrote {args.out / 'scorecard.json'}" + (f" and {len(written)} plots" if written else ""))
    return 0


def _add_scenarios(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("scenarios", help="list the shipped scenarios; 'scenarios random KIND' draws one")
    p.set_defaults(func=cmd_scenarios)
    add_random_parser(p)


def cmd_scenarios(args: argparse.Namespace) -> int:
    console.print(scenarios_listing({name: load_scenario(path) for name, path in shipped_scenarios().items()}))
    return 0


def _add_compare(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "compare",
        help="paired per-run comparison of two scorecards of the same runs (B − A, standard error, runs lower)",
    )
    p.add_argument("a", type=Path, help="scorecard A (scorecard.json or the folder eval --out wrote)")
    p.add_argument("b", type=Path, help="scorecard B, of the same runs (scenario, seed, runs)")
    p.add_argument("--metric", action="append", default=[], help="only metrics matching this glob (repeatable)")
    p.add_argument("--json", action="store_true", help="print the comparison as JSON")
    p.set_defaults(func=cmd_compare)


def cmd_compare(args: argparse.Namespace) -> int:
    from fnmatch import fnmatch

    from windwarden.evaluation import paired
    from windwarden.evaluation.report import window_numbers

    try:
        a, b = paired.load_scorecard(args.a), paired.load_scorecard(args.b)
        rows, only = paired.compare(a, b)
    except paired.NotPairedError as error:
        raise BadInputError(str(error)) from None
    if args.metric:
        rows = [r for r in rows if any(fnmatch(r.metric, pattern) for pattern in args.metric)]
        if not rows:
            raise BadInputError(f"--metric: no per-run metric matches {', '.join(args.metric)}")
    if args.json:
        result = {"a": str(args.a), "b": str(args.b), "rows": [r.as_dict() for r in rows], "only_one": only}
        sys.stdout.write(json.dumps(result) + "\n")
        return 0
    lines = [
        f"A: {args.a} ({paired.describe(a)})",
        f"B: {args.b} ({paired.describe(b)})",
        f"the same {a['runs']} runs: seed {a['seed']}, runs digest {a['runs_digest']}; paired per run:",
        "B − A = mean of the runs' differences ± its standard error",
        "",
        paired.table(rows, window_numbers(a)),
    ]
    if only:
        lines += ["", f"in one scorecard only (not compared): {', '.join(only)}"]
    sys.stdout.write("\n".join(lines) + "\n")
    return 0


def _add_bench(sub: argparse._SubParsersAction) -> None:
    from windwarden.bench import add_parser

    add_parser(sub)


SUBCOMMANDS: list[Callable[[argparse._SubParsersAction], None]] = [
    _add_eval,
    _add_scenarios,
    _add_compare,
    _add_bench,
    add_detectability_parser,
    *LIVE_SUBCOMMANDS,
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="windwarden", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for add in SUBCOMMANDS:
        add(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (ScenarioError, BadInputError) as error:  # escaped: a message may hold brackets (tuple[float, float])
        err_console.print(f"[red]error:[/red] {escape(str(error))}", highlight=False)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
