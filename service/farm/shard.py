"""The per-turbine part of farm supervision, for a shard that owns some of the farm's turbines.

``FarmSupervisor`` is a detector and a farm controller. The ``analytic`` detector (and ``none``) works on each
turbine's own residuals: row i of its diagnosis depends on row i of the samples only, so it can run on any subset of
the turbines and give, for those rows, the numbers the whole farm's detector gives (the same numpy code on the same
values, element by element). Its false-alarm budget is the farm's (shared by the farm's N turbines,
``service.farm.analytic``), so a shard's detector is built for the farm's N but with rows for its own turbines only
(``ShardContext``). The controller (the dispatch, eqs. (18)–(26), and the accommodation) and the events are
farm-wide: a coordinator runs them (``FarmSupervisor.decide``) on the diagnoses of every shard.

The ``paper`` detector compares each turbine with the others of its row (rows formed across the whole farm from the
estimated wind direction): it is farm-wide and is refused here (``ShardingError``); run it under one supervisor.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise

import numpy as np

from service.farm.interfaces import FarmContext, FarmDiagnosis, FarmSample
from service.farm.pitch_trim import TrimInReadings
from service.farm.supervisor import FarmSupervisor
from service.plugins import FARM_DETECTORS, choose
from wwcore.farm_frames import FarmFrame
from wwcore.site import SiteInfo
from wwcore.turbine_params import BENCHMARK, TurbineParams

SHARDABLE_DETECTORS = ("analytic", "none")
"""Detectors whose diagnosis of a turbine depends on that turbine's samples only."""


class ShardingError(ValueError):
    """A sharded supervisor cannot run this (a farm-wide detector, or turbines the farm does not have)."""


def shardable(detector: str) -> str:
    """``detector`` if a shard can run it, else ``ShardingError`` saying why and what to do."""
    if detector not in SHARDABLE_DETECTORS:
        raise ShardingError(
            f"the {detector!r} farm detector compares turbines across the farm; a sharded supervisor runs only "
            f"per-turbine detectors ({', '.join(SHARDABLE_DETECTORS)}): run one supervisor for {detector!r}"
        )
    return detector


def parse_turbines(text: str) -> tuple[int, ...]:
    """``"1-40"``, ``"3,5,7-9"`` → the turbine numbers, ascending; ``ShardingError`` for anything else (an empty
    range, a repeat, a number below 1)."""
    numbers: list[int] = []
    for part in text.split(","):
        first, dash, last = part.strip().partition("-")
        try:
            lo = int(first)
            hi = int(last) if dash else lo
        except ValueError:
            raise ShardingError(f"turbines {text!r}: {part.strip()!r} is not a number or a range a-b") from None
        if lo < 1 or hi < lo:
            raise ShardingError(f"turbines {text!r}: {part.strip()!r} is not a range of turbine numbers from 1")
        numbers.extend(range(lo, hi + 1))
    if len(set(numbers)) != len(numbers):
        raise ShardingError(f"turbines {text!r}: a turbine is named twice")
    return tuple(sorted(numbers))


def shard_ranges(turbines: int, shards: int) -> list[str]:
    """Turbines 1 … ``turbines`` in ``shards`` contiguous ranges as even as can be (``--turbines`` values)."""
    if not 1 <= shards <= turbines:
        raise ShardingError(f"{shards} shards for {turbines} turbines: give 1 to {turbines}")
    edges = [round(i * turbines / shards) for i in range(shards + 1)]
    return [f"{lo + 1}-{hi}" for lo, hi in pairwise(edges)]


class ShardContext(FarmContext):
    """A ``FarmContext`` of one farm (N = ``turbines``, the site's) whose rows are ``shard_turbines`` only.

    What a per-turbine detector reads of it is the farm's (parameters, sensor noise, layout, N for the false-alarm
    budget) but ``n``, the number of rows it steps, is the shard's. Row i is turbine ``shard_turbines[i]``."""

    def __init__(self, site: SiteInfo, shard_turbines: Sequence[int], params: TurbineParams = BENCHMARK):
        super().__init__(site, len(site.turbines), params)
        owned = tuple(int(t) for t in shard_turbines)
        outside = [t for t in owned if not 1 <= t <= self.turbines]
        if not owned or outside:
            raise ShardingError(
                f"the farm has turbines 1-{self.turbines}; a shard cannot own {outside or 'no turbine'}"
            )
        if len(set(owned)) != len(owned):
            raise ShardingError(f"a shard owns each of its turbines once, not {list(owned)}")
        self.shard_turbines = owned
        self.n = len(owned)


class FarmShard:
    """The detector of a farm supervisor on some of the farm's turbines (module docstring).

    ``step(frame)`` takes the shard's rows of a farm sample (rows in ``turbines`` order) and returns their
    diagnosis. ``pitch_trim`` (rows, 3) deg is the trim the coordinator last commanded to these turbines: it is taken
    off the pitch readings, as the readings carry it (``pitch_trim.TrimInReadings``), before the detector sees them,
    as ``FarmSupervisor.untrimmed`` does for the whole farm.
    Options are checked as the whole supervisor checks them (detector and controller), so a shard refuses what one
    supervisor would refuse."""

    def __init__(
        self,
        site: SiteInfo,
        turbines: Sequence[int],
        *,
        detector: str | None = None,
        controller: str | None = None,
        options: dict | None = None,
        params: TurbineParams = BENCHMARK,
    ):
        choice = choose("farm", options, detector=detector, controller=controller)  # refuses bad options
        name = shardable(choice.names["detector"])
        self.context = ShardContext(site, turbines, params)
        self.detector = FARM_DETECTORS.create(name, context=self.context, options=choice.options["detector"])
        self.turbines = self.context.shard_turbines
        self.dt = params.dt
        self.pitch_trim: np.ndarray | None = None
        self.trim_read = TrimInReadings(self.context.n, params)
        self.diagnosis: FarmDiagnosis | None = None
        self.sample: FarmSample | None = None

    def step(self, frame: FarmFrame) -> FarmDiagnosis:
        sample = FarmSample.from_frame(frame, self.dt)
        read = self.trim_read.step(self.pitch_trim)
        if read.any():
            sample = sample.untrimmed(read)
        self.sample = sample
        self.diagnosis = self.detector.step(sample)
        return self.diagnosis


def coordinator_supervisor(
    site: SiteInfo,
    n: int,
    *,
    detector: str | None = None,
    controller: str | None = None,
    options: dict | None = None,
    params: TurbineParams = BENCHMARK,
) -> FarmSupervisor:
    """The farm-wide part for a sharded farm: a ``FarmSupervisor`` of the farm's ``n`` rows whose detector is
    ``none`` (its shards detect) and whose controller, events and references are those one supervisor would run.
    Its ``decide`` is called with the shards' diagnoses. The options are checked whole, as one supervisor checks
    them, and a farm-wide detector is refused (``ShardingError``)."""
    params_given = dict(options or {})
    choice = choose("farm", params_given, detector=detector, controller=controller)
    shardable(choice.names["detector"])
    mine = {key: params_given[key] for key in choice.options["controller"]}
    return FarmSupervisor(site, n, detector="none", controller=choice.names["controller"], options=mine, params=params)
