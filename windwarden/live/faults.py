"""Faults of a live run: the scenario's schedule plus what the API injects and clears, and the rules for both.

The same checks run in the API (so a bad request is refused with 4xx and never reaches the plant) and in the
plant (so a command from anywhere else on the network is refused too). Pure Python: no transport.

An injected fault uses the scenario's fault schema (``FaultSpec``); its ``start_s`` is simulation time, and a
start in the past means *now* (the next tick). Its default label is then built from the actual start.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

from wwcore.scenario import FaultSpec
from wwcore.scenario.model import FAULT_CHECKS

FAULT_NAME_MAX = 64
FAULT_NAME_PATTERN = r"^[A-Za-z0-9](?:[A-Za-z0-9 _.:+()-]*[A-Za-z0-9_.:+()-])?$"
FAULT_NAME_RULE = (
    f"1 to {FAULT_NAME_MAX} characters: letters, digits, space and _ . : + - ( ), starting with a letter or digit, "
    "not ending with a space"
)
"""An injected fault's name: short, printable, and usable as it is in a URL path (no ``/``, ``%``, ``?``, ``#``)
and in a log line, so any fault that can be injected can be listed and cleared."""
_FAULT_NAME = re.compile(FAULT_NAME_PATTERN)


class InjectionRefusedError(ValueError):
    """A fault that cannot be injected or cleared; ``problems`` are (field, message) pairs, ``status`` HTTP-like."""

    def __init__(self, problems: list[tuple[str, str]], status: int = 422):
        self.problems = problems
        self.status = status
        super().__init__("; ".join(f"{f}: {m}" for f, m in problems))


def fault_problems(fault: FaultSpec, kind: str, n_turbines: int) -> list[tuple[str, str]]:
    """The plant kind's rules for one fault (targets, kinds, physical ranges) plus finiteness of every number."""
    problems = [
        (name, f"{value!r} is not a finite number")
        for name, value in fault.model_dump().items()
        if isinstance(value, float) and not math.isfinite(value)
    ]
    if fault.name is not None and (len(fault.name) > FAULT_NAME_MAX or not _FAULT_NAME.fullmatch(fault.name)):
        problems.append(("name", f"a fault name is {FAULT_NAME_RULE}"))
    return problems + FAULT_CHECKS[kind](fault, n_turbines)


def check_injection(fault: FaultSpec, kind: str, n_turbines: int, t_now: float, duration_s: float) -> FaultSpec:
    """The fault as it would be injected at ``t_now`` (a start in the past moved to now); ``InjectionRefusedError``
    naming every bad field otherwise."""
    start = max(fault.start_s, t_now)
    problems = fault_problems(fault, kind, n_turbines)
    if fault.end_s is not None and fault.end_s <= start:
        problems.append(("end_s", f"{fault.end_s} s is not after the fault's start ({start:g} s; now is {t_now:g} s)"))
    if start >= duration_s:
        problems.append(("start_s", f"{start:g} s is after the run ends ({duration_s:g} s)"))
    if problems:
        raise InjectionRefusedError(problems)
    try:
        return FaultSpec.model_validate({**fault.model_dump(), "start_s": start})
    except ValueError as error:
        raise InjectionRefusedError([("start_s", str(error))]) from None


@dataclass
class FaultRecord:
    spec: FaultSpec
    source: str  # "scenario" or "api"
    cleared_at: float | None = None  # s, when it was cleared before its scheduled end
    cancelled: bool = False  # cleared before it started: it never acted

    @property
    def end_s(self) -> float | None:
        ends = [e for e in (self.spec.end_s, self.cleared_at) if e is not None]
        return min(ends) if ends else None

    def state(self, t: float) -> str:
        if self.cancelled:
            return "cancelled"
        if t < self.spec.start_s:
            return "pending"
        end = self.end_s
        return "ended" if end is not None and t >= end else "active"

    def to_json(self, t: float) -> dict[str, Any]:
        return {
            "label": self.spec.label,
            "state": self.state(t),
            "source": self.source,
            "start_s": self.spec.start_s,
            "end_s": self.end_s,
            "cleared_at_s": self.cleared_at,
            "fault": self.spec.model_dump(mode="json", exclude_none=True),
        }


class FaultBook:
    """Every fault of one run and its state. The plant node applies what the book accepts."""

    def __init__(self, kind: str, n_turbines: int, duration_s: float, scheduled: list[FaultSpec]):
        self.kind = kind
        self.n_turbines = n_turbines
        self.duration_s = duration_s
        self.records = [FaultRecord(f, "scenario") for f in scheduled]

    def labels(self) -> set[str]:
        return {r.spec.label for r in self.records}

    def prepare(self, fault: FaultSpec, t_now: float) -> FaultSpec:
        """The fault as it will be injected at ``t_now`` (start moved to now if in the past), or refused."""
        moved = check_injection(fault, self.kind, self.n_turbines, t_now, self.duration_s)
        if moved.label in self.labels():
            raise InjectionRefusedError([("name", f"a fault labelled {moved.label!r} exists already; name it")], 409)
        return moved

    def add(self, fault: FaultSpec, source: str = "api") -> FaultRecord:
        record = FaultRecord(fault, source)
        self.records.append(record)
        return record

    def find(self, label: str) -> FaultRecord:
        for record in self.records:
            if record.spec.label == label:
                return record
        raise InjectionRefusedError([("label", f"no fault labelled {label!r}")], 404)

    def check_clear(self, label: str, t_now: float) -> FaultRecord:
        record = self.find(label)
        state = record.state(t_now)
        if state in ("ended", "cancelled"):
            raise InjectionRefusedError([("label", f"fault {label!r} has {state} already")], 409)
        return record

    def mark_cleared(self, record: FaultRecord, t_now: float) -> None:
        if t_now <= record.spec.start_s:
            record.cancelled = True
        else:
            record.cleared_at = t_now

    def effective(self) -> list[FaultSpec]:
        """The faults as they acted (early clears applied, cancelled ones left out): what scoring uses."""
        out = []
        for r in self.records:
            if r.cancelled:
                continue
            out.append(r.spec if r.cleared_at is None else r.spec.model_copy(update={"end_s": r.end_s}))
        return out

    def listing(self, t: float) -> list[dict[str, Any]]:
        return [r.to_json(t) for r in self.records]
