"""The live system's step loop in one process, with no transport: the reference a lockstep run must match.

It is the batch loop of ``wwcore.stepping`` (measure, control, step, advance) driven through the kind's object
(``windwarden.kinds``), fed to the same score accumulator the plant node uses, and scored by the same
``kind.scorecard``.

``drop`` loses sensor frames as a congested real-time link does: the supervisor never sees frame k where
``drop[k]``, handles the gap as the supervisor node does (``guard.bridge_gap``) and the plant controls tick k with the
newest refs while they are within ``max_ref_age`` ticks, else falls back, as the plant node does. ``gaps`` picks how a
gap is handled, for the comparison ``tools/bench_drops.py`` makes: ``"bridge"`` (what the supervisor node does),
``"consecutive"`` (the frames after a gap fed as if none was missing), ``"step"`` (the whole supervisor, detectors
included, stepped on the interpolated frames). Without ``drop`` this is the lockstep reference.

``corrupt(k, records)`` changes the sensor records of tick k on their way to the supervisor (a dead sensor's NaN,
say); they then pass the supervisor node's ``readings.ReadingHold``, and the supervisor steps what it passes (a frame
it refuses is handled as a dropped one). ``BatchResult.held`` counts the held readings by channel.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from windwarden.kinds import RunInfo, kind_for
from windwarden.live.guard import bridge_gap
from windwarden.live.readings import ReadingHold
from wwcore.events import Event
from wwcore.scenario import Scenario
from wwcore.stepping import run_ticks


@dataclass
class BatchResult:
    events: list[Event]
    scorecard: dict[str, Any]
    held: dict[str, int] = field(default_factory=dict)  # readings held by ``ReadingHold``, by channel
    refused: int = 0  # frames ``ReadingHold`` refused


def random_drops(n: int, fraction: float, longest: int, seed: int) -> np.ndarray:
    """A ``drop`` mask of ``n`` ticks: bursts of 1 … ``longest`` ticks starting at random, ``fraction`` of the ticks
    on average (a burst starts with probability fraction / mean burst length); the first two ticks are kept."""
    rng = np.random.default_rng(seed)
    drop = np.zeros(n, dtype=bool)
    for start in np.flatnonzero(rng.random(n) < fraction / ((longest + 1) / 2)):
        drop[start : start + rng.integers(1, longest + 1)] = True
    drop[:2] = False
    return drop


def run_batch(
    scenario: Scenario,
    seed: int,
    drop: np.ndarray | None = None,
    max_ref_age: int = 10,
    gaps: str = "bridge",
    corrupt: Callable[[int, np.ndarray], np.ndarray] | None = None,
) -> BatchResult:
    kind = kind_for(scenario.plant.kind)
    plant = kind.make_plant(scenario, seed)
    turbines = kind.turbines(plant)
    supervisor = kind.make_supervisor(RunInfo.of(scenario, turbines, plant.dt))
    n_steps = round(scenario.duration_s / plant.dt)
    score = kind.score(scenario, n_steps, plant.dt)
    events: list[Event] = []
    refs = None
    hold = ReadingHold(kind.sensors)
    refused = 0
    if drop is None and corrupt is None:

        def controlled(k: int, frame: Any) -> None:
            score.on_tick(k, frame, plant)

        def stepped(k: int, frame: Any, refs: Any) -> None:
            score.on_refs(k, kind.refs_records(refs, supervisor, turbines))

        def advanced(k: int) -> None:
            events.extend(plant.drain_events() + supervisor.drain_events())

        run_ticks(plant, supervisor, range(n_steps), controlled=controlled, stepped=stepped, advanced=advanced)
    else:
        drop = np.zeros(n_steps, dtype=bool) if drop is None else drop
        bridge = {"bridge": getattr(supervisor, "bridge", None), "consecutive": None, "step": supervisor.step}[gaps]
        before, refs_tick = None, -1
        for k in range(n_steps):
            frame = plant.measure()
            plant.control(refs if k - refs_tick <= max_ref_age else None)
            score.on_tick(k, frame, plant)
            records = None if drop[k] else kind.frame_records(frame, turbines)
            if records is not None and corrupt is not None:
                records = hold.take(corrupt(k, records))
                refused += records is None
                frame = None if records is None else kind.frame_from_records(records)
            if records is not None:
                if before is not None:
                    bridge_gap(bridge, kind, before, records)
                refs, refs_tick, before = supervisor.step(frame), k, records
                score.on_refs(k, kind.refs_records(refs, supervisor, turbines))
            plant.advance()
            events += plant.drain_events() + supervisor.drain_events()
    metrics = score.result(list(scenario.faults))
    card = kind.scorecard(scenario, seed, list(scenario.faults), events, metrics)
    return BatchResult(events, card, dict(sorted(hold.held.items())), refused)
