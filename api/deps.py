"""Dependencies as ``Annotated`` aliases, the bearer-token check, and the mapping of bridge failures to HTTP."""

from __future__ import annotations

import asyncio
import re
import secrets
from collections.abc import Awaitable, Callable
from typing import Annotated, Any, TypeVar

from fastapi import Depends, HTTPException, Request, Response, Security
from fastapi.responses import JSONResponse
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from api.bridge import Bridge, QueryFailedError
from api.settings import ApiSettings

T = TypeVar("T")
MUTATING = frozenset({"POST", "PUT", "PATCH", "DELETE"})

bearer = HTTPBearer(auto_error=False, description="WINDWARDEN_API_TOKEN (printed by `windwarden up`)")


def get_settings(request: Request) -> ApiSettings:
    return request.app.state.settings


def get_bridge(request: Request) -> Bridge:
    return request.app.state.bridge


SettingsDep = Annotated[ApiSettings, Depends(get_settings)]
BridgeDep = Annotated[Bridge, Depends(get_bridge)]
TokenDep = Annotated[HTTPAuthorizationCredentials | None, Security(bearer)]
"""Declares the bearer scheme on a route (OpenAPI); ``auth_first`` enforces it before anything else runs."""


def token_ok(settings: ApiSettings, authorization: str | None) -> bool:
    expected = settings.api_token.get_secret_value() if settings.api_token else ""
    if not expected or not authorization:
        return False
    scheme, _, given = authorization.partition(" ")
    return scheme.lower() == "bearer" and secrets.compare_digest(given.strip().encode(), expected.encode())


async def auth_first(request: Request, call_next: Callable[[Request], Awaitable[Response]]) -> Response:
    """Mutating requests without the right bearer token get 401 before their body is even read.

    Also counts every request for ``/metrics``.
    """
    if request.method in MUTATING and not token_ok(request.app.state.settings, request.headers.get("authorization")):
        response: Response = JSONResponse(
            {"detail": "missing or wrong bearer token"}, status_code=401, headers={"WWW-Authenticate": "Bearer"}
        )
    else:
        response = await call_next(request)
        if response.status_code == 405:  # Allow: every method the path supports, not only its first route's
            response.headers["allow"] = ", ".join(allowed_methods(request))
    bridge = getattr(request.app.state, "bridge", None)
    if bridge is not None:
        bridge.count_request(request.method, route_template(request), response.status_code)
    return response


def allowed_methods(request: Request) -> list[str]:
    paths = request.app.openapi()["paths"]
    return sorted(m.upper() for m in paths.get(route_template(request), {}))


def route_template(request: Request) -> str:
    """The route's path template (``/faults/{label}``), never the raw path: metric labels stay bounded."""
    state = request.app.state
    if getattr(state, "route_patterns", None) is None:
        templates = [r.path for r in request.app.routes if hasattr(r, "path")] + list(request.app.openapi()["paths"])
        state.route_patterns = [
            (re.compile("^" + re.sub(r"\\{[^/]+?\\}", "[^/]+", re.escape(t)) + "$"), t)
            for t in dict.fromkeys(templates)
        ]
    path = request.url.path
    return next((template for pattern, template in state.route_patterns if pattern.match(path)), "unmatched")


async def ask(function: Callable[..., T], *args: Any) -> T:
    """Run a blocking bridge call in a worker thread; Zenoh failures become 502/503/504 or the plant's 4xx."""
    try:
        return await asyncio.to_thread(function, *args)
    except QueryFailedError as error:
        status = error.status if 400 <= error.status < 600 and error.status != 500 else 502
        detail: Any = str(error)
        problems = error.body.get("problems")
        if problems:
            detail = [{"loc": ["body", field], "msg": msg, "type": "value_error"} for field, msg in problems]
        raise HTTPException(status_code=status, detail=detail) from None


def unavailable(what: str) -> HTTPException:
    return HTTPException(status_code=503, detail=f"{what} is not running (no liveliness token)")
