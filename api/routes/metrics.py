"""GET /metrics: Prometheus text format, from the plant's and supervisor's status and the API's own counters."""

from __future__ import annotations

import asyncio
import math
from typing import Any

from fastapi import APIRouter
from fastapi.responses import PlainTextResponse

from api.bridge import Bridge, QueryFailedError
from api.deps import ANY_ROUTE, BridgeDep, CountersDep, documented
from wwcore.keys import Process

router = APIRouter(tags=["metrics"])
STATUS_TIMEOUT_S = 0.5


def _num(data: Any, *path: str, scale: float = 1.0) -> float | None:
    """The number at ``path`` in a status reply, or None (a missing or non-numeric field is left out, not a 500)."""
    for key in path:
        data = data.get(key) if isinstance(data, dict) else None
    if isinstance(data, int | float) and math.isfinite(data):
        return float(data) * scale
    return None


def _dict(data: Any) -> dict[str, Any]:
    return data if isinstance(data, dict) else {}


def _escape(value: Any) -> str:
    return str(value).replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")


class Exposition:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def metric(self, name: str, kind: str, help_: str, samples: list[tuple[dict[str, Any], float | None]]) -> None:
        self.lines += [f"# HELP windwarden_{name} {help_}", f"# TYPE windwarden_{name} {kind}"]
        for labels, value in samples:
            if not isinstance(value, int | float) or not math.isfinite(value):
                continue
            label_text = ",".join(f'{k}="{_escape(v)}"' for k, v in labels.items())
            self.lines.append(
                f"windwarden_{name}{{{label_text}}} {float(value):.9g}"
                if label_text
                else f"windwarden_{name} {float(value):.9g}"
            )

    def text(self) -> str:
        return "\n".join(self.lines) + "\n"


def _gather(bridge: Bridge) -> tuple[dict[str, Any] | None, dict[str, Any] | None]:
    plant = sup = None
    if bridge.alive(Process.PLANT):
        try:
            plant = bridge.plant_status(STATUS_TIMEOUT_S)
        except QueryFailedError:
            plant = None
    if bridge.alive(Process.SUPERVISOR):
        try:
            sup = bridge.supervisor_status(STATUS_TIMEOUT_S)
        except QueryFailedError:
            sup = None
    return (plant if isinstance(plant, dict) else None), (sup if isinstance(sup, dict) else None)


@router.get("/metrics", response_class=PlainTextResponse, responses=documented(*ANY_ROUTE))
async def metrics(bridge: BridgeDep, counters: CountersDep) -> PlainTextResponse:
    plant, sup = await asyncio.to_thread(_gather, bridge)
    out = Exposition()
    out.metric(
        "up",
        "gauge",
        "1 if the process holds its liveliness token",
        [({"process": p.value}, float(bridge.alive(p))) for p in Process],
    )
    if plant is not None:
        out.metric("sim_time_seconds", "gauge", "simulation time of the run", [({}, _num(plant, "t"))])
        out.metric(
            "real_time_factor", "gauge", "simulated seconds per wall second", [({}, _num(plant, "real_time_factor"))]
        )
        out.metric("ticks_total", "counter", "plant ticks run", [({}, _num(plant, "ticks"))])
        out.metric(
            "overruns_total", "counter", "ticks whose work ended after their deadline", [({}, _num(plant, "overruns"))]
        )
        out.metric(
            "loop_latency_seconds",
            "summary",
            "sensor to refs round trip over the run",
            [
                ({"quantile": "0.5"}, _num(plant, "latency", "p50_ms", scale=1e-3)),
                ({"quantile": "0.99"}, _num(plant, "latency", "p99_ms", scale=1e-3)),
            ],
        )
        out.metric("refs_received_total", "counter", "refs the plant received", [({}, _num(plant, "refs_received"))])
    if sup is not None:
        out.metric(
            "supervisor_frames_total", "counter", "sensor ticks the supervisor stepped", [({}, _num(sup, "frames"))]
        )
        out.metric(
            "supervisor_flagged",
            "gauge",
            "targets flagged as faulty",
            [
                ({"turbine": t.get("turbine")}, len(t.get("flagged") or []))
                for t in (sup.get("turbines") if isinstance(sup.get("turbines"), list) else [])
                if isinstance(t, dict)
            ],
        )
    dropped = [
        ({"process": name, "stream": k}, v)
        for name, status in (("plant", plant), ("supervisor", sup))
        if status is not None
        for k, v in _dict(status.get("dropped")).items()
    ]
    dropped += [({"process": "api", "stream": k}, v) for k, v in bridge.drops.as_dict().items()]
    out.metric("wire_dropped_total", "counter", "messages dropped on receipt (unknown version, bad length, …)", dropped)
    out.metric("events_total", "counter", "events the API has seen", [({}, bridge.events.count())])
    out.metric(
        "injections_total",
        "counter",
        "fault injections by outcome",
        [({"outcome": k}, v) for k, v in sorted(counters.injections.items())],
    )
    out.metric(
        "api_requests_total",
        "counter",
        "HTTP requests by method, route and status (this one not yet counted)",
        [({"method": m, "route": r, "status": s}, n) for (m, r, s), n in sorted(counters.requests.items())],
    )
    out.metric(
        "api_refused_total",
        "counter",
        "HTTP requests refused, by reason (unauthorized, rate_limited, body_too_large, invalid, fault_cap, ...)",
        [({"reason": reason}, n) for reason, n in sorted(counters.refusals.items())],
    )
    return PlainTextResponse(out.text(), media_type="text/plain; version=0.0.4")
