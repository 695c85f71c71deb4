"""GET /events?since=N: the run's events in order (faults, detections, observer switches, liveliness, …)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query

from api.deps import ANY_ROUTE, BridgeDep, documented
from api.models import EventOut, EventsPage
from wwcore.events import EventType

router = APIRouter(tags=["events"])


@router.get("/events", response_model=EventsPage, responses=documented(*ANY_ROUTE, 422))
def events(
    bridge: BridgeDep,
    since: Annotated[int, Query(ge=0, le=2**62, description="first seq to return (the previous page's next)")] = 0,
    limit: Annotated[int, Query(ge=1, le=1000)] = 200,
    type: Annotated[list[EventType] | None, Query(description="only these event types")] = None,
) -> EventsPage:
    types = {t.value for t in type} if type else None
    found, nxt = bridge.events.since(since, limit, types)
    return EventsPage(events=[EventOut.model_validate(e) for e in found], next=nxt)
