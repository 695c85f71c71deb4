"""The farm's evaluator (``windwarden.kinds.farm``): the runs of ``farm`` and their scorecard; with ``--compare``
also the companion runs Tables 5–7 need (the paper's detector; the fault-free farm with the dispatch and with the
PI; no accommodation) and ``farm_tables.md`` (``farm_tables``); the plots of ``farm_plots``."""

from __future__ import annotations

from service.farm.supervisor import DEFAULT_CONTROLLER, DEFAULT_DETECTOR, FarmSupervisor
from service.plugins import FARM_CONTROLLERS, FARM_DETECTORS
from windwarden.evaluation.farm import Variant, run_variant, scorecard_of
from windwarden.evaluation.farm_plots import write_plots
from windwarden.evaluation.farm_tables import comparison_runs, tables_markdown
from windwarden.evaluation.kinds import EvalOptions, Evaluation
from wwcore.scenario import Scenario


def evaluate(scenario: Scenario, runs: int, seed: int, options: EvalOptions) -> Evaluation:
    detector = options.detector or scenario.supervisor.detector or DEFAULT_DETECTOR
    controller = options.controller or scenario.supervisor.controller or DEFAULT_CONTROLLER
    FARM_DETECTORS.factory(detector)  # unknown names are refused before anything runs
    FARM_CONTROLLERS.factory(controller)
    params = dict(scenario.supervisor.params)  # and so are options they refuse (AlgorithmOptionError)
    site = scenario.plant.site()
    FarmSupervisor(site, len(site.turbines), detector=detector, controller=controller, options=params)
    twins = bool(scenario.faults) and options.twins  # --no-twins: detection only, no damage numbers
    main = run_variant(
        scenario,
        runs,
        seed,
        options,
        detector=detector,
        controller=controller,
        accommodation=options.accommodation,
        twins=twins,
    )
    card = scorecard_of(main)
    extra: dict[str, str] = {}
    companions: dict[str, Variant] = {}
    if options.compare:
        companions = comparison_runs(scenario, runs, seed, options, main)
        extra["farm_tables.md"] = tables_markdown(scenario, main, companions)
        card["comparison"] = {name: scorecard_of(v)["metrics"] for name, v in companions.items()}

    def plot(out_dir):
        return write_plots(out_dir, scenario, main, companions)

    return Evaluation(card, plot=plot, extra_files=extra)
