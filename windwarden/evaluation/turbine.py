"""``windwarden eval`` for single benchmark turbines: Monte Carlo runs of plant + supervisor in batch mode.

Scorecard: detection figures per fault window from the event log (``scoring``), and ``metrics.wind_rmse``:
for the fault-free time and each fault window, the RMSE of the fault-tolerant estimate (FTE), the
non-fault-tolerant estimate (NFTE, observer 1 throughout) and the raw anemometer reading against the true
rotor-effective wind, pooled over runs. The first ``WARMUP_S`` seconds of each run are left out.

When the scenario has faults, each fault window of every run also has a fault-free twin: at the window's first
tick the chunk forks (``parallel.Branch``), and the copy ends every fault and runs to the window's end with the
same wind and noise streams, from the runs' own state (plant, controller, observers, flags). ``fte_fault_free``
is the twins' FTE RMSE over the window: "the FTE's fault-free RMSE" that the window is compared with, on the
same wind, from the same state, the fault being the only difference. Their detections are counted as
``false_alarms_twin``. A twin costs its window's length, next to the runs; nothing outside a window is scored on
one.

A twin forked at its window shares whatever the run carries into the window: an estimate already off the truth
there, or an earlier fault's lasting harm, is in the twin too, and FTE/twin reads 1. So with twins every run also
has a *clean run*: the same run (wind, noise, plant) with no fault from the first tick, stepped in the same batch
(``TurbineBatch(fault_free_twins=True)``, its second half of rows). ``fte_clean`` is its FTE RMSE over every metric
window, the fault-free time included: FTE/clean in a window is the faults' whole cost up to and through it, and
in the fault-free time what earlier faults left behind; the clean run's own RMSE against the anemometer's says
whether the estimate is any good at all. Its detections are false alarms over the whole run
(``false_alarms_clean``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial

import numpy as np

from plant_sim.turbine import TurbineBatch
from service.plugins import TURBINE_DETECTORS, TURBINE_ESTIMATORS
from service.turbine.supervisor import DEFAULT_DETECTOR, DEFAULT_ESTIMATOR, TurbineSupervisor
from windwarden.evaluation.kinds import EvalOptions, Evaluation
from windwarden.evaluation.parallel import Branch, run_chunks
from windwarden.evaluation.scoring import FaultWindow, twin_false_alarms, windows_from_faults
from windwarden.evaluation.scoring_policy import TURBINE as SCORING
from windwarden.evaluation.turbine_scoring import WARMUP_S, WIND_KEYS, detection, scorecard, wind_rmse, window_of_tick
from wwcore.channels import SENSOR_INDEX
from wwcore.events import Event
from wwcore.scenario import Scenario
from wwcore.stepping import run_ticks

TWIN_TURBINE = 0  # turbine number of the fault-free twin rows in events (no real turbine has it)
CLEAN_TURBINE = -1  # turbine number of the clean runs' rows in events (no real turbine has it)
TRACE_EVERY = 10  # ticks between stored trace samples of run 0 (10 Hz)
PROGRESS_EVERY = 1000  # ticks between progress reports
_ANEMOMETER = SENSOR_INDEX["v_hub_m"]


@dataclass
class ChunkResult:
    runs: list[int]
    events: list[Event]
    sq_err: dict[str, np.ndarray]  # estimate → (n_windows,) summed squared error over rows and ticks
    counts: np.ndarray  # (n_windows,) samples summed
    trace: dict[str, np.ndarray] = field(default_factory=dict)  # run 0 only
    twin_seconds: float = 0.0  # simulated time of the fault-free twins after the warm-up, per run
    clean_seconds: float = 0.0  # simulated time of the clean runs after the warm-up, per run


TURBINE_CHUNK = 50
"""Runs per chunk at most (``parallel.chunk_runs``: 20 runs are two chunks of 10, 100 runs two of 50). The step is
mostly per-tick interpreter work, so a batch of 50 runs costs about 1.7 times one run's tick (``windwarden bench
turbine``); larger chunks would save little and hold more memory."""


def _twin_spans(scenario: Scenario, n_steps: int, dt: float) -> list[tuple[int, int, int]]:
    """(window index, first tick, end tick) of the fault-free twin of each fault window."""
    windows = windows_from_faults(scenario.faults, scenario.duration_s)
    return [(i, round(w.start_s / dt), min(round(w.end_s / dt), n_steps)) for i, w in enumerate(windows, start=1)]


def batch_and_supervisor(
    scenario: Scenario,
    seed: int,
    run_ids: list[int],
    detector: str | None = None,
    estimator: str | None = None,
    options: dict | None = None,
    twins: bool = False,
) -> tuple[TurbineBatch, TurbineSupervisor]:
    """The batch of a turbine scenario's runs ``run_ids`` (with ``twins``: and their clean runs, module docstring)
    and the supervisor that watches it, its events naming the clean runs' rows ``CLEAN_TURBINE``; ``None``: the
    default detector, estimator and options."""
    plant = TurbineBatch(
        scenario.plant,
        scenario.wind,
        scenario.faults,
        seed=seed,
        runs=run_ids,
        mismatch=scenario.mismatch,
        fault_free_twins=twins,
    )
    supervisor = TurbineSupervisor(
        plant.n,
        detector=detector,
        estimator=estimator,
        options=options,
        noise_convention=scenario.plant.noise_convention,
        run_of_row=plant.run_of_row,
        turbine_of_row=np.where(plant.twin_of_row, CLEAN_TURBINE, plant.turbine_of_row),
    )
    return plant, supervisor


def simulate_chunk(
    run_ids: list[int],
    progress,
    scenario: Scenario,
    seed: int,
    detector: str,
    estimator: str,
    options: dict,
    twins: bool = True,
) -> ChunkResult:
    """The runs ``run_ids``, and with ``twins`` (when the scenario has faults) the fault-free twin of each fault
    window and the clean runs (module docstring)."""
    twins = twins and bool(scenario.faults)
    plant, supervisor = batch_and_supervisor(scenario, seed, run_ids, detector, estimator, options, twins)
    runs = len(run_ids)  # the runs' rows; with twins the clean runs' rows follow them
    n_steps = round(scenario.duration_s / plant.dt)
    which, labels = window_of_tick(scenario, n_steps, plant.dt)
    errors = _ErrorSums(len(labels), PROGRESS_EVERY, runs)
    clean_errors = _ErrorSums(len(labels), PROGRESS_EVERY, runs) if twins else None
    trace_row = run_ids.index(0) if 0 in run_ids else None
    trace: dict[str, list] = {k: [] for k in ("t", "wind", "fte", "fte_clean", "nfte", "anemometer", "selected")}
    branch_at: dict[int, list[tuple[int, int]]] = {}
    for i, first, end in _twin_spans(scenario, n_steps, plant.dt) if twins else []:
        if first < end:
            branch_at.setdefault(first, []).append((i, end))
    branches: list[Branch] = []
    events: list[Event] = []

    def fork_twins(k: int, refs) -> None:
        for i, end in branch_at.get(k, ()):
            branches.append(
                Branch(partial(_fault_free_twin, plant, supervisor, refs, which, i, end, len(labels), runs))
            )

    def record(k: int, frame, refs) -> None:
        truth_wind = plant.true_rotor_wind()
        est = supervisor.estimates
        if which[k] >= 0:
            _record(errors, which[k], frame, truth_wind, est, slice(0, runs))
            if clean_errors is not None:
                _record(clean_errors, which[k], frame, truth_wind, est, slice(runs, None))
        if trace_row is not None and k % TRACE_EVERY == 0:
            r = trace_row
            trace["t"].append(frame.t)
            trace["wind"].append(truth_wind[r])
            trace["fte"].append(est.wind[r])
            trace["fte_clean"].append(est.wind[r + runs] if twins else np.nan)
            trace["nfte"].append(np.nan if est.wind_reference is None else est.wind_reference[r])
            trace["anemometer"].append(frame.sensors[r, _ANEMOMETER])
            trace["selected"].append(est.selected[r])

    def report(k: int) -> None:
        nonlocal events
        if (k + 1) % PROGRESS_EVERY == 0:
            events += plant.drain_events() + supervisor.drain_events()
            progress(PROGRESS_EVERY * plant.dt)

    try:
        run_ticks(plant, supervisor, range(n_steps), before=fork_twins, stepped=record, advanced=report)
    except BaseException:
        for branch in branches:
            branch.abandon()
        raise
    events += plant.drain_events() + supervisor.drain_events()
    progress((n_steps % PROGRESS_EVERY) * plant.dt)
    sq, counts = errors.totals()
    sq["fte_clean"] = clean_errors.totals()[0]["fte"] if clean_errors is not None else np.zeros(len(labels))
    sq["fte_fault_free"] = np.zeros(len(labels))
    twin_s = 0.0
    for twin_sq, twin_events, seconds in (branch.result() for branch in branches):
        sq["fte_fault_free"] += twin_sq
        events += twin_events
        twin_s += seconds
    return ChunkResult(
        run_ids,
        events,
        sq,
        counts,
        {k: np.asarray(v) for k, v in trace.items()} if trace_row is not None else {},
        twin_s,
        max(n_steps * plant.dt - WARMUP_S, 0.0) if twins else 0.0,
    )


def _fault_free_twin(
    plant: TurbineBatch,
    supervisor: TurbineSupervisor,
    refs,
    which: np.ndarray,
    window: int,
    end: int,
    n_windows: int,
    runs: int,
) -> tuple[np.ndarray, list[Event], float]:
    """The chunk's runs from the start of fault window ``window`` to its end tick ``end`` without any fault: a
    forked copy of the chunk (``Branch``), so the twin starts from the runs' own state, with their wind and noise
    streams. Returns its FTE's summed squared wind error in the window's ticks (one entry per window), its
    supervisor's events (labelled ``TWIN_TURBINE``) and its simulated seconds. Only the first ``runs`` rows are
    the twin's: the clean runs' rows after them step along unchanged and are counted by the parent."""
    plant.end_all_faults()
    supervisor.turbine_of_row = np.where(np.arange(plant.n) < runs, TWIN_TURBINE, CLEAN_TURBINE)
    supervisor.drain_events()  # the runs' own, already counted by the parent
    plant.drain_events()
    errors = _ErrorSums(n_windows, PROGRESS_EVERY, runs)
    first = plant.k

    def record(k: int, frame, refs) -> None:
        if which[k] == window:
            _record(errors, window, frame, plant.true_rotor_wind(), supervisor.estimates, slice(0, runs))

    run_ticks(plant, supervisor, range(first, end), refs, stepped=record)
    sq, _ = errors.totals()
    observed = max(end - max(first, round(WARMUP_S / plant.dt)), 0) * plant.dt  # detections count after warm-up
    twin_events = [e for e in supervisor.drain_events() if e.turbine == TWIN_TURBINE]
    return sq["fte"], twin_events, observed


def _record(errors: _ErrorSums, window: int, frame, truth_wind: np.ndarray, est, rows: slice) -> None:
    """One tick's wind errors of the batch's ``rows`` (the runs', or the clean runs')."""
    nfte = None if est.wind_reference is None else est.wind_reference[rows]
    errors.record(window, truth_wind[rows], est.wind[rows], nfte, frame.sensors[rows, _ANEMOMETER])


class _ErrorSums:
    """Summed squared wind errors per metric window, from per-tick samples buffered in blocks.

    Per tick it only stores the rows (four row copies instead of a dozen small reductions); a full block is then
    reduced at once. The figures are bit for bit those of adding each tick's row sum to its window as the tick
    happens: a row of the block is summed as a 1-D array would be, and the row sums are added to the window's
    total in tick order (``np.add.accumulate`` adds left to right; ``np.sum`` would add them pairwise).
    """

    def __init__(self, n_windows: int, block: int, rows: int):
        self.window = np.empty(block, dtype=int)
        self.truth = np.empty((block, rows))
        self.fte = np.empty((block, rows))
        self.nfte = np.empty((block, rows))
        self.has_nfte = np.zeros(block, dtype=bool)
        self.anemometer = np.empty((block, rows))
        self.used = 0
        self.sq = {key: [0.0] * n_windows for key in ("fte", "nfte", "anemometer")}
        self.counts = np.zeros(n_windows)
        self.rows = rows

    def record(self, window: int, truth: np.ndarray, fte: np.ndarray, nfte: np.ndarray | None, anemometer) -> None:
        """Store one tick's true wind, FTE, NFTE (or None) and anemometer reading, each (rows,)."""
        j = self.used
        self.window[j] = window
        self.truth[j] = truth
        self.fte[j] = fte
        self.has_nfte[j] = nfte is not None
        if nfte is not None:
            self.nfte[j] = nfte
        self.anemometer[j] = anemometer
        self.used = j + 1
        if self.used == len(self.window):
            self._flush()

    def _flush(self) -> None:
        used = self.used
        if used == 0:
            return
        truth = self.truth[:used]
        err = self.fte[:used] - truth
        err *= err
        rows = {
            "fte": err.sum(axis=1),
            "nfte": np.square(self.nfte[:used] - truth).sum(axis=1),
            "anemometer": np.square(self.anemometer[:used] - truth).sum(axis=1),
        }
        window = self.window[:used]
        for w in np.unique(window):
            ticks = window == w
            self.counts[w] += self.rows * int(ticks.sum())
            for key, per_tick in rows.items():
                values = per_tick[ticks & self.has_nfte[:used]] if key == "nfte" else per_tick[ticks]
                self.sq[key][w] = _add_in_order(self.sq[key][w], values)
        self.used = 0

    def totals(self) -> tuple[dict[str, np.ndarray], np.ndarray]:
        self._flush()
        return {key: np.array(v) for key, v in self.sq.items()}, self.counts


def _add_in_order(total: float, values: np.ndarray) -> float:
    """total + v_0 + v_1 + … added left to right."""
    if len(values) == 0:
        return total
    return float(np.add.accumulate(np.concatenate(([total], values)))[-1])


def evaluate(scenario: Scenario, runs: int, seed: int, options: EvalOptions) -> Evaluation:
    detector = options.detector or scenario.supervisor.detector or DEFAULT_DETECTOR
    estimator = options.estimator or scenario.supervisor.estimator or DEFAULT_ESTIMATOR
    TURBINE_DETECTORS.factory(detector)  # unknown names are refused before anything runs
    TURBINE_ESTIMATORS.factory(estimator)
    params = dict(scenario.supervisor.params)  # and so are options they refuse (AlgorithmOptionError)
    TurbineSupervisor(1, detector=detector, estimator=estimator, options=params)
    twins = options.twins and bool(scenario.faults)
    results = run_chunks(
        simulate_chunk,
        runs,
        scenario.duration_s,
        options,
        args=(scenario, seed, detector, estimator, dict(scenario.supervisor.params), twins),
        max_chunk=TURBINE_CHUNK,
        label=scenario.name,
    )
    all_events = sorted((e for r in results for e in r.events), key=lambda e: (e.run, e.t))
    events = [e for e in all_events if e.turbine not in (TWIN_TURBINE, CLEAN_TURBINE)]
    twin_events = [e for e in all_events if e.turbine == TWIN_TURBINE]
    clean_events = [e for e in all_events if e.turbine == CLEAN_TURBINE]
    windows = windows_from_faults(scenario.faults, scenario.duration_s)
    labels = ["fault_free"] + [w.name for w in windows]
    counts = sum(r.counts for r in results)
    # the twins cover the fault windows only; the clean runs every metric window
    window_keys = (*WIND_KEYS, "fte_fault_free", "fte_clean") if twins else WIND_KEYS
    fault_free_keys = (*WIND_KEYS, "fte_clean") if twins else WIND_KEYS
    sq = {
        key: [sum(r.sq_err[key][i] for r in results if key in r.sq_err) for i in range(len(labels))]
        for key in window_keys
    }
    card = scorecard(
        scenario,
        runs=runs,
        seed=seed,
        detector=detector,
        estimator=estimator,
        score=detection(events, scenario.faults, scenario.duration_s, runs),
        wind=wind_rmse(labels, sq, counts, window_keys, fault_free_keys),
        twin=_twin_false_alarms(twin_events, runs, results[0].twin_seconds, windows) if twins else None,
        clean=_clean_false_alarms(clean_events, runs, results[0].clean_seconds) if twins else None,
    )
    trace = next((r.trace for r in results if r.trace), {})

    def plot(out_dir):
        from windwarden.evaluation.turbine_plots import plot_turbine

        return plot_turbine(scenario, trace, windows, out_dir)

    return Evaluation(card, plot=plot)


def _twin_false_alarms(events: list[Event], runs: int, duration_s: float, windows: list[FaultWindow]) -> dict:
    """Flags raised in the fault-free twins, which run over the fault windows, ``duration_s`` per run in all: a
    false-alarm count on the fault windows' own wind."""
    spans = [(w.start_s, w.end_s) for w in windows]
    return twin_false_alarms(events, runs * duration_s, SCORING, spans)


def _clean_false_alarms(events: list[Event], runs: int, duration_s: float) -> dict:
    """Flags raised in the clean runs (no fault from the first tick), ``duration_s`` per run after the warm-up: a
    false-alarm count over the scenario's whole wind (a flag up at the warm-up's end counts then, as in the runs)."""
    return twin_false_alarms(events, runs * duration_s, SCORING, [(0.0, WARMUP_S + duration_s)])
