"""Faults: list (active, pending, past), inject (the scenario's fault schema), clear.

An injection is checked here first (strict schema, the plant kind's rules, the run's clock, the caps on active
faults) and refused with 4xx naming the field; only a valid fault is sent to the plant, which checks it again and
applies it at its next tick. Injections run one at a time, so two at once cannot both pass a cap.
"""

from __future__ import annotations

import asyncio
from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Path, Request, status

from api.deps import (
    ANY_ROUTE,
    MUTATING_ROUTE,
    UPSTREAM,
    UPSTREAM_503,
    BridgeDep,
    CountersDep,
    SettingsDep,
    TokenDep,
    ask,
    documented,
    from_upstream,
    unavailable,
)
from api.limits import cap_problems
from api.models import FaultList, FaultOut, FaultRequest, Injected
from windwarden.live.faults import InjectionRefusedError, check_injection
from wwcore.keys import Process

router = APIRouter(prefix="/faults", tags=["faults"])
LABEL_PATTERN = r"^[\x20-\x7e]+$"  # printable ASCII: every label a scenario or an injection can give
C409_INJECT = (
    "a fault with this name exists, the run has ended, or the injection would pass a cap on active faults "
    "(WINDWARDEN_API_MAX_FAULTS_PER_TURBINE, WINDWARDEN_API_MAX_FAULTS) or on injections per run "
    "(WINDWARDEN_API_MAX_INJECTIONS)"
)


def _refused(refused: InjectionRefusedError) -> HTTPException:
    detail = [{"loc": ["body", field], "msg": msg, "type": "value_error"} for field, msg in refused.problems]
    return HTTPException(status_code=refused.status, detail=detail)


def _injected(reply: dict[str, Any]) -> Injected:
    return Injected(t=reply["t"], fault=FaultOut.model_validate(reply["fault"]))


def _listing(reply: dict[str, Any]) -> FaultList:
    faults = [FaultOut.model_validate(f) for f in reply["faults"]]
    return FaultList(
        t=reply["t"],
        active=[f for f in faults if f.state == "active"],
        pending=[f for f in faults if f.state == "pending"],
        past=[f for f in faults if f.state in ("ended", "cancelled")],
    )


@router.get("", response_model=FaultList, responses=documented(*ANY_ROUTE, *UPSTREAM, c503=UPSTREAM_503))
async def list_faults(bridge: BridgeDep) -> FaultList:
    if not bridge.alive(Process.PLANT):
        raise unavailable("the plant")
    reply = await ask(bridge.faults, {"op": "list"})
    return from_upstream(lambda: _listing(reply), "the plant")


@router.post(
    "",
    response_model=Injected,
    status_code=status.HTTP_201_CREATED,
    responses=documented(*ANY_ROUTE, *MUTATING_ROUTE, *UPSTREAM, 409, 422, c409=C409_INJECT, c503=UPSTREAM_503),
)
async def inject(
    fault: FaultRequest,
    request: Request,
    bridge: BridgeDep,
    settings: SettingsDep,
    counters: CountersDep,
    _: TokenDep,
) -> Injected:
    if not bridge.alive(Process.PLANT):
        raise unavailable("the plant")
    lock: asyncio.Lock = request.app.state.injection_lock
    async with lock:
        info = await ask(bridge.run_info)
        listing = await ask(bridge.faults, {"op": "list"})
        spec = fault.to_spec()
        try:
            t_now, kind = float(listing["t"]), str(info["kind"])
            n_turbines, duration_s = len(set(info["turbines"])), float(info["duration_s"])
            faults = list(listing["faults"])
        except (KeyError, TypeError, ValueError) as error:
            raise HTTPException(status_code=502, detail=f"unusable reply from the plant: {error}") from None
        try:
            check_injection(spec, kind, n_turbines, t_now, duration_s)
            capped = cap_problems(spec, faults, settings)
            if capped:
                request.state.refused = "fault_cap"
                raise InjectionRefusedError(capped, 409)
        except InjectionRefusedError as refused:
            counters.injections["refused"] += 1
            raise _refused(refused) from None
        fault_json = spec.model_dump(mode="json", exclude_none=True)
        reply = await ask(bridge.faults, {"op": "inject", "fault": fault_json}, passthrough=(409, 422))
    counters.injections["accepted"] += 1
    return from_upstream(lambda: _injected(reply), "the plant")


@router.delete(
    "/{label:path}",
    response_model=Injected,
    responses=documented(
        *ANY_ROUTE,
        *MUTATING_ROUTE,
        *UPSTREAM,
        404,
        409,
        422,
        c404="no fault with this label",
        c409="the fault has ended or been cleared already, or the run has ended",
        c503=UPSTREAM_503,
    ),
)
async def clear(
    label: Annotated[
        str,
        Path(
            min_length=1,
            max_length=128,
            pattern=LABEL_PATTERN,
            description="the fault's label as listed (printable ASCII, percent-encoded in the URL)",
        ),
    ],
    bridge: BridgeDep,
    _: TokenDep,
) -> Injected:
    if not bridge.alive(Process.PLANT):
        raise unavailable("the plant")
    reply = await ask(bridge.faults, {"op": "clear", "label": label}, passthrough=(404, 409, 422))
    return from_upstream(lambda: _injected(reply), "the plant")
