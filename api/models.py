"""Request and response models, kept apart. The injection request is the scenario's fault schema."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from windwarden.live.faults import FAULT_NAME_MAX, FAULT_NAME_PATTERN, FAULT_NAME_RULE
from wwcore.scenario import FaultSpec
from wwcore.scenario.faults import FaultKind


class FaultRequest(FaultSpec):
    """A fault to inject, in the scenario file's schema. ``start_s`` is simulation time; a start in the past (or
    0) means now. Types are strict: numbers are JSON numbers (not strings, not booleans), ``turbine`` an integer,
    and every number finite."""

    model_config = ConfigDict(
        extra="forbid",
        strict=True,
        allow_inf_nan=False,
        json_schema_extra={
            "examples": [
                {
                    "target": "omega_r_m1",
                    "kind": "fixed",
                    "value": 1.4,
                    "start_s": 0.0,
                    "end_s": 1e4,
                    "name": "rotor sensor stuck at 1.4",
                }
            ]
        },
    )

    target: str = Field(
        min_length=1, max_length=64, description="sensor channel (e.g. omega_r_m1) or component (pitch_actuator_2)"
    )
    kind: FaultKind = Field(strict=False, description="one of the kinds' names (JSON has no enum type)")
    name: str | None = Field(
        default=None,
        min_length=1,
        max_length=FAULT_NAME_MAX,
        pattern=FAULT_NAME_PATTERN,
        description=f"label in listings and scorecards, {FAULT_NAME_RULE}; default target:kind@start",
    )

    def to_spec(self) -> FaultSpec:
        return FaultSpec.model_validate(self.model_dump())


class ErrorItem(BaseModel):
    loc: list[str | int]
    msg: str
    type: str


class ErrorOut(BaseModel):
    """A refused request: a message, or one item per bad field (as FastAPI's own 422s)."""

    detail: str | list[ErrorItem]


class Health(BaseModel):
    status: str = Field(description="ok while the API runs")
    zenoh: str = Field(description="open: the API's Zenoh session is up")
    plant: bool = Field(description="the plant's liveliness token is present")
    supervisor: bool = Field(description="the supervisor's liveliness token is present")
    uptime_s: float


class Latency(BaseModel):
    count: int
    p50_ms: float | None
    p99_ms: float | None
    max_ms: float | None


class RunStatus(BaseModel):
    """What the plant reports about its run."""

    model_config = ConfigDict(extra="allow")

    run_id: str
    scenario: str
    kind: str
    turbines: list[int]
    mode: str = Field(description="realtime or lockstep")
    speed: float = Field(description="realtime speed-up ×k")
    state: str = Field(description="waiting (for a supervisor), running or ended")
    t: float = Field(description="s, simulation time")
    tick: int
    duration_s: float
    real_time_factor: float | None = Field(description="simulated s per wall s since tick 0")
    ticks: int
    overruns: int = Field(description="ticks whose work ended after their deadline")
    overrun_pct: float
    latency: Latency = Field(description="sensor→refs round trip over the run")
    latency_recent: Latency = Field(description="the same over the last 1000 ticks")
    supervisor_alive: bool
    refs_fresh: bool | None


class FaultOut(BaseModel):
    label: str
    state: str = Field(description="pending, active, ended or cancelled")
    source: str = Field(description="scenario or api")
    start_s: float
    end_s: float | None
    cleared_at_s: float | None
    fault: dict[str, Any] = Field(description="the fault as scheduled (scenario schema)")


class FaultList(BaseModel):
    t: float = Field(description="s, simulation time of the listing")
    active: list[FaultOut]
    past: list[FaultOut] = Field(description="ended or cancelled")
    pending: list[FaultOut]


class Injected(BaseModel):
    t: float = Field(description="s, simulation time the plant applied the command at")
    fault: FaultOut


class TurbineStatus(BaseModel):
    """One turbine as its supervisor sees it. ``flagged``: the targets its FDI isolates as faulty now."""

    model_config = ConfigDict(extra="allow")

    turbine: int
    flagged: list[str]
    detected: bool = Field(description="any fault is flagged")
    observer: str | int | None = None
    estimates: dict[str, Any] = Field(default_factory=dict)
    margins: dict[str, float | None] = Field(
        default_factory=dict, description="residual statistic / its threshold; above 1 trips"
    )
    tick: int | None = None


class SupervisorStatus(BaseModel):
    model_config = ConfigDict(extra="allow")

    run_id: str | None
    kind: str | None
    tick: int | None
    t: float
    ready: bool
    stream_fresh: bool
    plant_alive: bool
    turbines: list[TurbineStatus]


class EventOut(BaseModel):
    seq: int = Field(description="position in the API's event stream; pass seq + 1 as since")
    t: float = Field(description="s, simulation time")
    type: str
    turbine: int = 1
    target: str | None = None
    run: int = 0
    detail: dict[str, Any] = Field(default_factory=dict)
    wall_time: float | None = None


class EventsPage(BaseModel):
    events: list[EventOut]
    next: int = Field(description="the cursor for the next page (since=next)")
