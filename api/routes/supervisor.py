"""Supervisor status per turbine: flagged (isolated) faults, selected observer, estimates, residual margins."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Path

from api.deps import ANY_ROUTE, UPSTREAM, UPSTREAM_503, BridgeDep, ask, documented, from_upstream, unavailable
from api.models import SupervisorStatus, TurbineStatus
from wwcore.keys import Process

router = APIRouter(prefix="/supervisor", tags=["supervisor"])


def _status(raw: dict[str, Any]) -> SupervisorStatus:
    turbines = [TurbineStatus.model_validate({**t, "detected": bool(t.get("flagged"))}) for t in raw["turbines"]]
    return SupervisorStatus.model_validate({**raw, "turbines": turbines})


@router.get("/status", response_model=SupervisorStatus, responses=documented(*ANY_ROUTE, *UPSTREAM, c503=UPSTREAM_503))
async def supervisor_status(bridge: BridgeDep) -> SupervisorStatus:
    if not bridge.alive(Process.SUPERVISOR):
        raise unavailable("the supervisor")
    reply = await ask(bridge.supervisor_status)
    return from_upstream(lambda: _status(reply), "the supervisor")


@router.get(
    "/status/{turbine}",
    response_model=TurbineStatus,
    responses=documented(*ANY_ROUTE, *UPSTREAM, 404, 422, c404="no such turbine in this run", c503=UPSTREAM_503),
)
async def turbine_status(turbine: Annotated[int, Path(ge=1, le=10_000)], bridge: BridgeDep) -> TurbineStatus:
    if not bridge.alive(Process.SUPERVISOR):
        raise unavailable("the supervisor")
    reply = await ask(bridge.supervisor_status)
    status = from_upstream(lambda: _status(reply), "the supervisor")
    for entry in status.turbines:
        if entry.turbine == turbine:
            return entry
    known = sorted({t.turbine for t in status.turbines})
    raise HTTPException(status_code=404, detail=f"turbine {turbine} does not exist (this run has turbines {known})")
