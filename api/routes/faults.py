"""Faults: list (active, pending, past), inject (the scenario's fault schema), clear.

An injection is checked here first (schema, the plant kind's rules, the run's clock) and refused with 4xx naming
the field; only a valid fault is sent to the plant, which checks it again and applies it at its next tick.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Path, status

from api.deps import BridgeDep, TokenDep, ask, unavailable
from api.models import ErrorOut, FaultList, FaultOut, FaultRequest, Injected
from windwarden.live.faults import InjectionRefusedError, check_injection
from wwcore.wire import Process

router = APIRouter(prefix="/faults", tags=["faults"])
ERRORS: dict[int | str, dict[str, Any]] = {code: {"model": ErrorOut} for code in (401, 404, 409, 422, 502, 503, 504)}


def _refused(refused: InjectionRefusedError) -> HTTPException:
    detail = [{"loc": ["body", field], "msg": msg, "type": "value_error"} for field, msg in refused.problems]
    return HTTPException(status_code=refused.status, detail=detail)


@router.get("", response_model=FaultList, responses=ERRORS)
async def list_faults(bridge: BridgeDep) -> FaultList:
    if not bridge.alive(Process.PLANT):
        raise unavailable("the plant")
    reply = await ask(bridge.faults, {"op": "list"})
    faults = [FaultOut.model_validate(f) for f in reply["faults"]]
    return FaultList(
        t=reply["t"],
        active=[f for f in faults if f.state == "active"],
        pending=[f for f in faults if f.state == "pending"],
        past=[f for f in faults if f.state in ("ended", "cancelled")],
    )


@router.post("", response_model=Injected, status_code=status.HTTP_201_CREATED, responses=ERRORS)
async def inject(fault: FaultRequest, bridge: BridgeDep, _: TokenDep) -> Injected:
    if not bridge.alive(Process.PLANT):
        raise unavailable("the plant")
    info = await ask(bridge.run_info)
    now = await ask(bridge.plant_status)
    spec = fault.to_spec()
    try:
        check_injection(spec, info["kind"], len(set(info["turbines"])), float(now["t"]), float(info["duration_s"]))
    except InjectionRefusedError as refused:
        bridge.injections["refused"] += 1
        raise _refused(refused) from None
    reply = await ask(bridge.faults, {"op": "inject", "fault": spec.model_dump(mode="json", exclude_none=True)})
    bridge.injections["accepted"] += 1
    return Injected(t=reply["t"], fault=FaultOut.model_validate(reply["fault"]))


@router.delete("/{label}", response_model=Injected, responses=ERRORS)
async def clear(label: Annotated[str, Path(min_length=1, max_length=200)], bridge: BridgeDep, _: TokenDep) -> Injected:
    if not bridge.alive(Process.PLANT):
        raise unavailable("the plant")
    reply = await ask(bridge.faults, {"op": "clear", "label": label})
    return Injected(t=reply["t"], fault=FaultOut.model_validate(reply["fault"]))
