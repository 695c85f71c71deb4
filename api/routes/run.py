"""GET /run: scenario, mode, simulation time, real-time factor, overruns, loop latency."""

from __future__ import annotations

from fastapi import APIRouter

from api.deps import BridgeDep, ask, unavailable
from api.models import ErrorOut, RunStatus
from wwcore.wire import Process

router = APIRouter(tags=["run"])


@router.get(
    "/run",
    response_model=RunStatus,
    responses={503: {"model": ErrorOut}, 502: {"model": ErrorOut}, 504: {"model": ErrorOut}},
)
async def run_status(bridge: BridgeDep) -> RunStatus:
    if not bridge.alive(Process.PLANT):
        raise unavailable("the plant")
    return RunStatus.model_validate(await ask(bridge.plant_status))
