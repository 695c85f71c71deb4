"""The shape of a plant kind (``PlantKind``) and the run description the supervisor receives (``RunInfo``)."""

from __future__ import annotations

from typing import Any, ClassVar, Protocol

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from windwarden.evaluation.kinds import EvalOptions, Evaluation
from wwcore.events import Event
from wwcore.scenario import FaultSpec, Scenario, SupervisorSpec
from wwcore.site import SiteInfo
from wwcore.stepping import Plant, Supervisor
from wwcore.wire import MessageSchema


class RunInfo(BaseModel):
    """What the supervisor may know of a run: the site's published parameters (``SiteInfo``) and the supervisor's
    algorithms; never the fault schedule, the wind, a model mismatch or any truth: the supervisor learns about faults
    from the sensors only. Served by the plant on the ``plant/run`` queryable, checked on arrival (``from_json``):
    an unknown field anywhere is refused."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    run_id: str
    kind: str
    scenario: str
    turbines: tuple[int, ...] = Field(description="turbine number of each row of the plant batch")
    dt: float = Field(gt=0.0)
    duration_s: float = Field(gt=0.0)
    mode: str
    speed: float
    site: SiteInfo
    supervisor: SupervisorSpec
    recording_id: str = ""
    extra: dict[str, Any] = Field(default_factory=dict)
    run_key: int = 0  # the run identity every sensor frame of the run carries (drawn by the plant)

    @classmethod
    def of(
        cls,
        scenario: Scenario,
        turbines: list[int],
        dt: float,
        run_id: str = "batch",
        mode: str = "batch",
        speed: float = 1.0,
        run_key: int = 0,
    ) -> RunInfo:
        return cls(
            run_id=run_id,
            kind=scenario.plant.kind,
            scenario=scenario.name,
            turbines=tuple(int(t) for t in turbines),
            dt=float(dt),
            duration_s=scenario.duration_s,
            mode=mode,
            speed=speed,
            site=scenario.plant.site(float(dt)),
            supervisor=scenario.supervisor,
            recording_id=run_id,
            run_key=run_key,
        )

    def to_json(self) -> dict[str, Any]:
        return self.model_dump(mode="json")

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> RunInfo:
        """The run description in a ``plant.run`` body; ``pydantic.ValidationError`` (a ``ValueError``) naming the
        field for anything else, an unknown field included."""
        return cls.model_validate(data)


class ScoreAccumulator(Protocol):
    """Continuous metrics of one run, fed tick by tick by the plant node (or the batch loop)."""

    def on_tick(self, k: int, frame: Any, plant: Plant) -> None:
        """Tick k after ``control`` and before ``advance``: keep what the metrics need from truth and sensors."""

    def on_refs(self, k: int, refs: np.ndarray) -> None:
        """The supervisor's refs computed from tick k (wire records, one per turbine) arrived."""

    def result(self, faults: list[FaultSpec]) -> dict[str, Any]:
        """The metrics for the faults as they acted."""


class PlantKind(Protocol):
    """Everything the rest of the program needs of one plant kind: its scenario section (which builds its
    ``SiteInfo``), plant and supervisor factories, wire schemas and conversions, status, score accumulator and live
    scorecard, the batch evaluator, and the names of its dashboard panels (``dashboards.panels.PANELS``)."""

    kind: str
    section: ClassVar[type[BaseModel]]  # the scenario's [plant] section of this kind (``wwcore.scenario``)
    panels: tuple[str, ...]  # its dashboard panels, by name
    example_fault: dict[str, Any]  # a valid injection body, for the docs and the start-up banner
    sensors: MessageSchema
    refs: MessageSchema
    truth: MessageSchema

    def evaluate(self, scenario: Scenario, runs: int, seed: int, options: EvalOptions) -> Evaluation:
        """``windwarden eval``: Monte Carlo runs in batch mode, their scorecard and plots."""

    def make_plant(self, scenario: Scenario, seed: int) -> Plant:
        """Run 0 of ``windwarden eval SCENARIO --seed seed``: the same constructor and random streams."""

    def make_supervisor(self, info: RunInfo) -> Supervisor:
        """The supervisor ``windwarden eval`` builds for this run, from the run description alone."""

    def turbines(self, plant: Plant) -> list[int]:
        """Turbine number of each row of the plant batch."""

    def frame_records(self, frame: Any, turbines: list[int]) -> np.ndarray:
        """``plant.measure()``'s frame as sensor records, one per turbine."""

    def frame_from_records(self, records: np.ndarray) -> Any:
        """Sensor records (one per turbine, in row order) back into the frame ``supervisor.step`` takes."""

    def refs_records(self, refs: Any, supervisor: Supervisor, turbines: list[int]) -> np.ndarray:
        """``supervisor.step``'s refs as refs records, one per turbine (with display extras)."""

    def refs_from_records(self, records: np.ndarray) -> Any:
        """Refs records back into what ``plant.control`` takes."""

    def hold_unserved(self, records: np.ndarray, served: np.ndarray, last: np.ndarray | None) -> np.ndarray:
        """A tick's refs completed without the rows not ``served`` (no sender of the plan owns them: a sharded
        supervisor's lost shard), those rows filled so that their turbines keep their last reference (``last``:
        the refs the plant took last). Only a farm is ever sharded."""

    def truth_records(self, plant: Plant, frame: Any, turbines: list[int]) -> np.ndarray:
        """Ground truth at the current tick as truth records (display only)."""

    def inject(self, plant: Plant, fault: FaultSpec) -> None: ...

    def clear(self, plant: Plant, label: str) -> None: ...

    def status(self, supervisor: Supervisor, refs: np.ndarray | None, turbines: list[int]) -> list[dict[str, Any]]:
        """Per turbine: flagged targets, selected observer, estimates, residual margins to their thresholds."""

    def score(self, scenario: Scenario, n_steps: int, dt: float) -> ScoreAccumulator: ...

    def scorecard(
        self, scenario: Scenario, seed: int, faults: list[FaultSpec], events: list[Event], metrics: dict[str, Any]
    ) -> dict[str, Any]:
        """The kind's scorecard from events and accumulated metrics (the batch evaluator's schema)."""


def records_from_batch(schema: MessageSchema, values: dict[str, Any], turbines: list[int]) -> np.ndarray:
    """n records of ``schema`` with each field taken from ``values`` (scalars broadcast, arrays row by row)."""
    rec = schema.empty(len(turbines))
    rec["turbine"] = turbines
    for name, value in values.items():
        rec[name] = value
    return rec


def finite_or_none(x: float) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None
