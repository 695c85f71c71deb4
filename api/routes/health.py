"""GET /health: the container health check. 200 while the API runs; says which services are alive."""

from __future__ import annotations

import time

from fastapi import APIRouter

from api.deps import ANY_ROUTE, BridgeDep, documented
from api.models import Health
from wwcore.keys import Process

router = APIRouter(tags=["health"])


@router.get("/health", response_model=Health, responses=documented(*ANY_ROUTE))
def health(bridge: BridgeDep) -> Health:
    return Health(
        status="ok",
        zenoh="closed" if bridge.session.is_closed() else "open",
        plant=bridge.alive(Process.PLANT),
        supervisor=bridge.alive(Process.SUPERVISOR),
        uptime_s=time.time() - bridge.started,
    )
