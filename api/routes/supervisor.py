"""Supervisor status per turbine: flagged (isolated) faults, selected observer, estimates, residual margins."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Path

from api.deps import BridgeDep, ask, unavailable
from api.models import ErrorOut, SupervisorStatus, TurbineStatus
from wwcore.wire import Process

router = APIRouter(prefix="/supervisor", tags=["supervisor"])
ERRORS: dict[int | str, dict[str, Any]] = {code: {"model": ErrorOut} for code in (404, 502, 503, 504)}


def _status(raw: dict[str, Any]) -> SupervisorStatus:
    turbines = [TurbineStatus.model_validate({**t, "detected": bool(t.get("flagged"))}) for t in raw["turbines"]]
    return SupervisorStatus.model_validate({**raw, "turbines": turbines})


@router.get("/status", response_model=SupervisorStatus, responses=ERRORS)
async def supervisor_status(bridge: BridgeDep) -> SupervisorStatus:
    if not bridge.alive(Process.SUPERVISOR):
        raise unavailable("the supervisor")
    return _status(await ask(bridge.supervisor_status))


@router.get("/status/{turbine}", response_model=TurbineStatus, responses=ERRORS)
async def turbine_status(turbine: Annotated[int, Path(ge=1, le=10_000)], bridge: BridgeDep) -> TurbineStatus:
    if not bridge.alive(Process.SUPERVISOR):
        raise unavailable("the supervisor")
    status = _status(await ask(bridge.supervisor_status))
    for entry in status.turbines:
        if entry.turbine == turbine:
            return entry
    known = sorted({t.turbine for t in status.turbines})
    raise HTTPException(status_code=404, detail=f"turbine {turbine} does not exist (this run has turbines {known})")
