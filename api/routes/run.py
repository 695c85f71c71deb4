"""GET /run: scenario, mode, simulation time, real-time factor, overruns, loop latency."""

from __future__ import annotations

from fastapi import APIRouter

from api.deps import ANY_ROUTE, UPSTREAM, UPSTREAM_503, BridgeDep, ask, documented, from_upstream, unavailable
from api.models import RunStatus
from wwcore.keys import Process

router = APIRouter(tags=["run"])


@router.get("/run", response_model=RunStatus, responses=documented(*ANY_ROUTE, *UPSTREAM, c503=UPSTREAM_503))
async def run_status(bridge: BridgeDep) -> RunStatus:
    if not bridge.alive(Process.PLANT):
        raise unavailable("the plant")
    reply = await ask(bridge.plant_status)
    return from_upstream(lambda: RunStatus.model_validate(reply), "the plant")
