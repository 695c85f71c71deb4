"""The fault-tolerant wind estimate through speed-sensor faults, over a wind × sensor × kind × size grid.

Each *cell* is one fault (or one simultaneous pair) on the speed sensors, sized in the sensor's own noise σ where
the kind has a size (``FaultSize``); each (cell, run) is one turbine row of a ``TurbineBatch`` with its own wind
and noise streams and its own fault window, which starts at a random time and lasts ``window_s``. The batch runs
with ``fault_free_twins``: every row has a twin on the same wind and noise that no fault reaches, so up to the
window's start the two are the same turbine, and from then on the fault is the only difference (what
``windwarden eval``'s forked twins give, here for many windows at once).

Per (cell, run), from the supervisor's own events (the first detection in [start, end + grace)):

* ``detected``: a detection of any target; ``delay``: its time after the start;
* ``first_flag_isolated``: the set of targets flagged just after the first detection is exactly the fault's;
* ``detections``: onsets in the window, times the turbine's flagged set went from empty to non-empty;
* ``flaps``: times a flag on one of the fault's targets dropped while the fault was on (each one a "lost"
  flag: a flag that drops while the fault is still on);
* ``wrong``: targets outside the fault flagged at some time in the window;
* ``end_delay``: for a detected window without flaps, when the last of the fault's flags dropped after the
  end (staying down until end + grace); None when not recognised;
* ``ratio``: RMSE of the fault-tolerant wind estimate over the window, divided by its twin's over the same ticks.

Twin rows' detections after the warm-up are counted as false alarms.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from plant_sim.turbine import TurbineBatch
from plant_sim.turbine.trim import trim
from service.turbine.supervisor import TurbineSupervisor
from wwcore.channels import SENSOR_INDEX, SENSORS, noise_std
from wwcore.events import Event, EventType
from wwcore.scenario.faults import FaultKind, FaultSpec
from wwcore.scenario.turbine import TurbinePlant
from wwcore.scenario.wind import WindSpec
from wwcore.stepping import run_ticks
from wwcore.turbine_params import BENCHMARK

SHORT = {"omega_r_m1": "r1", "omega_r_m2": "r2", "omega_g_m1": "g1", "omega_g_m2": "g2"}
TARGET_OF_SHORT = {v: k for k, v in SHORT.items()}
WARMUP_S = 10.0  # as ``windwarden eval``: observers converge and the supervisor's warm-up ends
GRACE_S = 2.0  # after the end, the window's flags may still drop
START_S = (20.0, 40.0)  # fault windows start uniformly in this range (s)
STREAM_STRIDE = 100_000  # turbine number = 1 + run·STREAM_STRIDE + cell: streams depend on (seed, run, cell) only


@dataclass(frozen=True)
class FaultSize:
    """One sensor fault of a cell. ``size``: offset in σ of the sensor's noise, drift in σ per s, gain as the
    factor, fixed as a fraction of the operating point's speed at the mean wind, stuck none."""

    sensor: str  # r1, r2, g1, g2
    kind: FaultKind
    size: float | None = None

    @property
    def label(self) -> str:
        match self.kind:
            case FaultKind.OFFSET:
                return f"{self.sensor} offset {self.size:+g}σ"
            case FaultKind.DRIFT:
                return f"{self.sensor} drift {self.size:+g}σ/s"
            case FaultKind.GAIN:
                return f"{self.sensor} gain {self.size:g}"
            case FaultKind.FIXED:
                return f"{self.sensor} fixed {self.size:g}×"
        return f"{self.sensor} {self.kind.value}"

    def spec(self, wind: float, start_s: float, end_s: float, turbine: int, convention: str) -> FaultSpec:
        target = TARGET_OF_SHORT[self.sensor]
        sigma = noise_std(SENSORS[SENSOR_INDEX[target]], convention)
        value: float | None
        match self.kind:
            case FaultKind.OFFSET | FaultKind.DRIFT:
                value = self.size * sigma
            case FaultKind.GAIN:
                value = self.size
            case FaultKind.FIXED:
                op = trim(BENCHMARK, wind)
                value = self.size * (op.omega_r if self.sensor.startswith("r") else op.omega_g)
            case _:
                value = None
        return FaultSpec(
            target=target,
            kind=self.kind,
            value=value,
            start_s=start_s,
            end_s=end_s,
            turbine=turbine,
            name=f"{self.label}#{turbine}",
        )


@dataclass(frozen=True)
class Cell:
    faults: tuple[FaultSize, ...]

    @property
    def label(self) -> str:
        return " + ".join(f.label for f in self.faults)

    @property
    def targets(self) -> frozenset[str]:
        return frozenset(TARGET_OF_SHORT[f.sensor] for f in self.faults)


def single(sensor: str, kind: str, size: float | None = None) -> Cell:
    return Cell((FaultSize(sensor, FaultKind(kind), size),))


def pair(a: Cell, b: Cell) -> Cell:
    return Cell(a.faults + b.faults)


DEFAULT_WINDS = (4.0, 6.0, 7.0, 8.0, 10.0, 12.0, 14.0, 18.0, 24.0)
DEFAULT_SIZES: dict[str, tuple[float | None, ...]] = {
    "offset": (2.0, -3.0, 5.0, -10.0),
    "gain": (1.01, 0.98, 1.05, 0.9),
    "fixed": (0.0, 0.95, 1.2),
    "stuck": (None,),
    "drift": (0.2, -2.0),
}
DEFAULT_PAIRS = (
    pair(single("r2", "gain", 1.1), single("g1", "gain", 0.9)),
    pair(single("r1", "gain", 0.92), single("g2", "gain", 1.08)),
    pair(single("g1", "gain", 0.9), single("g2", "fixed", 0.85)),
    pair(single("r1", "offset", 5.0), single("r2", "offset", -5.0)),
    pair(single("r2", "offset", 3.0), single("g2", "offset", -3.0)),
)


def grid(
    sensors: Sequence[str] = ("r1", "r2", "g1", "g2"),
    sizes: dict[str, tuple[float | None, ...]] | None = None,
    pairs: Sequence[Cell] = DEFAULT_PAIRS,
) -> list[Cell]:
    """Every sensor × kind × size as a single fault, then the pairs."""
    sizes = DEFAULT_SIZES if sizes is None else sizes
    cells = [single(s, kind, size) for s in sensors for kind, values in sizes.items() for size in values]
    return cells + list(pairs)


@dataclass
class WindowResult:
    """One (cell, run) fault window and its twin."""

    cell: int
    run: int
    start_s: float
    end_s: float
    detected: bool
    delay_s: float | None
    first_flag_isolated: bool
    detections: int
    flaps: int
    wrong: int
    end_delay_s: float | None
    ratio: float
    rmse: float
    rmse_twin: float


@dataclass
class WindResult:
    wind: float
    windows: list[WindowResult]
    twin_false_alarms: int
    twin_observed_s: float
    cells: list[Cell] = field(default_factory=list)


def simulate_wind(
    run_ids: list[int],
    progress,
    cells: Sequence[Cell],
    wind: float,
    seed: int,
    window_s: float,
    detector: str | None = None,
    estimator: str | None = None,
    options: dict | None = None,
    convention: str = "sigma",
    wind_spec: dict | None = None,
    start_range: tuple[float, float] = START_S,
) -> WindResult:
    """Every cell × run of ``run_ids`` at mean wind ``wind``, with fault-free twins (module docstring)."""
    dt = BENCHMARK.dt
    keys = [(run, c) for run in run_ids for c in range(len(cells))]
    turbines = [1 + run * STREAM_STRIDE + c for run, c in keys]
    starts = []
    for run, c in keys:
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(run, c, 1)))
        starts.append(round(rng.uniform(*start_range) / dt) * dt)
    faults = [
        spec
        for (run, c), turbine, start in zip(keys, turbines, starts, strict=True)
        for spec in (f.spec(wind, start, start + window_s, turbine, convention) for f in cells[c].faults)
    ]
    spec = WindSpec(mean=[(0.0, wind)], **(wind_spec or {}))
    plant = TurbineBatch(
        TurbinePlant(noise_convention=convention),
        spec,
        faults,
        seed=seed,
        runs=(0,),
        turbines=turbines,
        fault_free_twins=True,
    )
    n = plant.n
    half = n // 2
    supervisor = TurbineSupervisor(
        n,
        detector=detector,
        estimator=estimator,
        options=dict(options or {}),
        noise_convention=convention,
        run_of_row=np.arange(n),
        turbine_of_row=np.ones(n, dtype=int),
    )
    start_k = np.tile(np.round(np.array(starts) / dt).astype(int), 2)
    end_k = start_k + round(window_s / dt)
    n_steps = int(end_k.max()) + round((GRACE_S + 1.0) / dt)
    sq = np.zeros(n)
    count = np.zeros(n)
    events: list[Event] = []
    every = 1000

    def record(k: int, frame, refs) -> None:
        nonlocal sq, count
        inside = (k >= start_k) & (k < end_k)
        err = supervisor.estimates.wind - plant.true_rotor_wind()
        sq += np.where(inside, err * err, 0.0)
        count += inside

    def report(k: int) -> None:
        if (k + 1) % every == 0:
            events.extend(supervisor.drain_events())
            progress(every * dt)

    run_ticks(plant, supervisor, range(n_steps), stepped=record, advanced=report)
    events += supervisor.drain_events()
    progress((n_steps % every) * dt)
    by_row: dict[int, list[Event]] = {}
    for e in events:
        if e.type in (EventType.DETECTION, EventType.RECOVERY):
            by_row.setdefault(e.run, []).append(e)
    windows = []
    for row, (run, c) in enumerate(keys):
        rmse = float(np.sqrt(sq[row] / count[row]))
        rmse_twin = float(np.sqrt(sq[row + half] / count[row + half]))
        windows.append(
            score_window(
                by_row.get(row, []), cells[c].targets, start_k[row] * dt, end_k[row] * dt, c, run, rmse, rmse_twin
            )
        )
    twin_alarms = sum(
        1 for row in range(half, n) for e in by_row.get(row, []) if e.type is EventType.DETECTION and e.t >= WARMUP_S
    )
    return WindResult(wind, windows, twin_alarms, half * (n_steps * dt - WARMUP_S), list(cells))


def score_window(
    events: Sequence[Event],
    targets: frozenset[str],
    start: float,
    end: float,
    cell: int = 0,
    run: int = 0,
    rmse: float = float("nan"),
    rmse_twin: float = float("nan"),
    grace: float = GRACE_S,
) -> WindowResult:
    """Detection figures of one fault window from one turbine's DETECTION/RECOVERY events (module docstring)."""
    by_time: dict[float, list[Event]] = {}
    for e in events:
        by_time.setdefault(e.t, []).append(e)
    flagged: frozenset[str] = frozenset()
    first: float | None = None
    first_set: frozenset[str] | None = None
    detections = flaps = 0
    wrong: set[str] = set()
    at_end: frozenset[str] | None = None
    cleared_at: float | None = None  # when the fault's flags last all dropped after the end
    for t in sorted(by_time):
        if t >= end + grace:
            break
        if t >= end and at_end is None:
            at_end = flagged
        before = set(flagged)
        now = set(flagged)
        for e in by_time[t]:
            (now.add if e.type is EventType.DETECTION else now.discard)(e.target)
        flagged = frozenset(now)
        if t < start:
            continue
        if t < end and (before - flagged) & targets:
            flaps += 1
        if flagged and not before:
            detections += 1
        if first is None and flagged - before:
            first, first_set = t, flagged
        wrong |= flagged - targets
        if t >= end:
            if flagged & targets:
                cleared_at = None
            elif before & targets:
                cleared_at = t
    if at_end is None:
        at_end = flagged
    end_delay = None
    if first is not None and flaps == 0:
        if not (at_end & targets):
            end_delay = 0.0 if not (flagged & targets) else None
        elif cleared_at is not None and not (flagged & targets):
            end_delay = cleared_at - end
    detected = first is not None
    return WindowResult(
        cell=cell,
        run=run,
        start_s=start,
        end_s=end,
        detected=detected,
        delay_s=None if first is None else first - start,
        first_flag_isolated=first_set == targets,
        detections=detections,
        flaps=flaps,
        wrong=len(wrong),
        end_delay_s=end_delay,
        ratio=rmse / rmse_twin if rmse_twin > 0 else float("nan"),
        rmse=rmse,
        rmse_twin=rmse_twin,
    )


@dataclass
class CellSummary:
    wind: float
    label: str
    runs: int
    detected_pct: float
    isolated_pct: float  # first flag names exactly the fault's targets
    delay_s_mean: float | None
    detections_mean: float
    flaps_mean: float
    flaps_max: int
    wrong_pct: float
    end_recognised_pct: float | None  # of the detected windows
    end_delay_s_max: float | None
    ratio_mean: float
    ratio_max: float


def summarise(result: WindResult) -> list[CellSummary]:
    out = []
    for c, cell in enumerate(result.cells):
        ws = [w for w in result.windows if w.cell == c]
        detected = [w for w in ws if w.detected]
        delays = [w.delay_s for w in detected]
        ends = [w.end_delay_s for w in detected if w.end_delay_s is not None]
        ratios = np.array([w.ratio for w in ws])
        out.append(
            CellSummary(
                wind=result.wind,
                label=cell.label,
                runs=len(ws),
                detected_pct=100.0 * len(detected) / len(ws),
                isolated_pct=100.0 * sum(w.first_flag_isolated for w in ws) / len(ws),
                delay_s_mean=float(np.mean(delays)) if delays else None,
                detections_mean=float(np.mean([w.detections for w in ws])),
                flaps_mean=float(np.mean([w.flaps for w in ws])),
                flaps_max=int(max(w.flaps for w in ws)),
                wrong_pct=100.0 * sum(w.wrong > 0 for w in ws) / len(ws),
                end_recognised_pct=100.0 * len(ends) / len(detected) if detected else None,
                end_delay_s_max=max(ends) if ends else None,
                ratio_mean=float(ratios.mean()),
                ratio_max=float(ratios.max()),
            )
        )
    return out


def group_of(label: str) -> str:
    """'rotor', 'generator' or 'pair' for a cell label."""
    if " + " in label:
        return "pair"
    return "rotor" if label.startswith("r") else "generator"


def summarise_groups(windows: Sequence[dict], threshold: float = 1.1) -> list[dict]:
    """Per (wind, group) over window records (``WindowResult`` fields plus ``wind`` and ``label``): windows,
    detected %, first-flag isolated % of the detected, windows with a flap %, most flaps, windows with more than
    one detection %, mean and worst FTE/twin of the detected windows, and how many of them exceed ``threshold``."""
    groups: dict[tuple[float, str], list[dict]] = {}
    for w in windows:
        groups.setdefault((w["wind"], group_of(w["label"])), []).append(w)
    out = []
    for (wind, group), ws in sorted(groups.items()):
        detected = [w for w in ws if w["detected"]]
        ratios = np.array([w["ratio"] for w in detected]) if detected else np.array([np.nan])
        out.append(
            {
                "wind": wind,
                "group": group,
                "windows": len(ws),
                "detected_pct": 100.0 * len(detected) / len(ws),
                "isolated_pct": 100.0 * sum(w["first_flag_isolated"] for w in detected) / max(len(detected), 1),
                "flapping_pct": 100.0 * sum(w["flaps"] > 0 for w in ws) / len(ws),
                "flaps_max": max(w["flaps"] for w in ws),
                "multiple_detections_pct": 100.0 * sum(w["detections"] > 1 for w in ws) / len(ws),
                "ratio_mean": float(np.mean(ratios)),
                "ratio_max": float(np.max(ratios)),
                "over_threshold": int(np.sum(ratios > threshold)),
            }
        )
    return out
