"""Dependencies as ``Annotated`` aliases, the mapping of bridge failures to HTTP, and the documented errors.

``documented`` is the one place a route's error responses are declared; the contract test checks that each
declared code can be produced on that route, and the schema run that nothing else comes back.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Collection
from typing import Annotated, Any, TypeVar

from fastapi import Depends, HTTPException, Request, Security
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from api.accesslog import ApiCounters
from api.bridge import Bridge, QueryFailedError
from api.models import ErrorOut
from api.settings import ApiSettings

T = TypeVar("T")

bearer = HTTPBearer(auto_error=False, description="WINDWARDEN_API_TOKEN (printed by `windwarden up`)")


def get_settings(request: Request) -> ApiSettings:
    return request.app.state.settings


def get_bridge(request: Request) -> Bridge:
    return request.app.state.bridge


def get_counters(request: Request) -> ApiCounters:
    return request.app.state.counters


SettingsDep = Annotated[ApiSettings, Depends(get_settings)]
BridgeDep = Annotated[Bridge, Depends(get_bridge)]
CountersDep = Annotated[ApiCounters, Depends(get_counters)]
TokenDep = Annotated[HTTPAuthorizationCredentials | None, Security(bearer)]
"""Declares the bearer scheme on a route (OpenAPI); ``api.guard`` enforces it before anything else runs."""

RETRY_AFTER = {"Retry-After": {"description": "seconds to wait before trying again", "schema": {"type": "integer"}}}
ERRORS = {
    401: "missing or wrong bearer token (checked before the body is read)",
    408: "the request body did not all arrive within WINDWARDEN_API_BODY_TIMEOUT_S (the connection is closed)",
    413: "request body over WINDWARDEN_API_MAX_BODY_BYTES, refused unread (the connection is closed)",
    422: "invalid request: one item per bad field",
    429: "too many mutating requests from this client (WINDWARDEN_API_RATE_*); see Retry-After",
    502: "the plant or supervisor answered with something unusable",
    503: "the API has WINDWARDEN_API_MAX_CONCURRENT requests in progress (see Retry-After)",
    504: "no answer from the plant or supervisor within WINDWARDEN_QUERY_TIMEOUT_S",
}
UPSTREAM_503 = (
    "the plant or supervisor is not running (no liveliness token) or could not apply the command in time; or the "
    "API has WINDWARDEN_API_MAX_CONCURRENT requests in progress (then with Retry-After)"
)
ANY_ROUTE = (408, 413, 503)  # the body's time and size limits and the concurrency limit (api.guard)
MUTATING_ROUTE = (401, 429)  # the rate limit and the token (api.guard)
UPSTREAM = (502, 503, 504)  # a route that asks the plant or the supervisor


def documented(*codes: int, **descriptions: str) -> dict[int | str, dict[str, Any]]:
    """OpenAPI ``responses`` for error ``codes`` (``descriptions``: ``c404="..."`` for a route's own wording)."""
    out: dict[int | str, dict[str, Any]] = {}
    for code in sorted(set(codes)):
        description = descriptions.get(f"c{code}") or ERRORS.get(code, "")
        entry: dict[str, Any] = {"model": ErrorOut, "description": description}
        if code in (429, 503):
            entry["headers"] = RETRY_AFTER
        out[code] = entry
    return out


async def ask(function: Callable[..., T], *args: Any, passthrough: Collection[int] = ()) -> T:
    """Run a blocking bridge call in a worker thread and map its failures to HTTP.

    The transport's own failures: no answer in time → 504, a reply it cannot decode → 502. The plant's error
    replies: a status in ``passthrough`` (its 4xx refusals) or 503 (command not applied in time) pass through with
    the plant's problems as 422-style items; anything else → 502.
    """
    try:
        return await asyncio.to_thread(function, *args)
    except QueryFailedError as error:
        if not error.body:
            status = 504 if error.status == 503 else 502
        elif error.status in passthrough or error.status == 503:
            status = error.status
        else:
            status = 502
        detail: Any = str(error)
        problems = error.body.get("problems")
        if problems and status < 500:
            detail = [{"loc": ["body", str(p[0])], "msg": str(p[1]), "type": "value_error"} for p in problems]
        raise HTTPException(status_code=status, detail=detail) from None


def from_upstream(build: Callable[[], T], what: str) -> T:
    """``build()`` turns a reply into a response model; a reply without the expected fields is a 502, not a 500."""
    try:
        return build()
    except (KeyError, TypeError, ValueError, IndexError) as error:
        raise HTTPException(status_code=502, detail=f"unusable reply from {what}: {error}") from None


def unavailable(what: str) -> HTTPException:
    return HTTPException(status_code=503, detail=f"{what} is not running (no liveliness token)")
