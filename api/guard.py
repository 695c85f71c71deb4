"""What every request passes before any route runs, in this order (pure ASGI, no body parsed):

1. mutating requests (POST, PUT, PATCH, DELETE) only:
   a. the client's token bucket (``WINDWARDEN_API_RATE_PER_S``, ``WINDWARDEN_API_RATE_BURST``) → 429 with
      ``Retry-After``; every mutating request takes a token, with the right bearer token or not, so guessing
      the token is rate-limited as well;
   b. the bearer token → 401 whatever the body;
2. the body: a declared ``Content-Length`` over ``WINDWARDEN_API_MAX_BODY_BYTES`` → 413 before a byte is read;
   otherwise it is read as it streams (chunked too), counting bytes, and the request is refused with 413 as soon
   as the count passes the limit, or with 408 if it has not all come within ``WINDWARDEN_API_BODY_TIMEOUT_S``;
   both close the connection, so the rest of the body is never read;
3. requests in progress: with ``WINDWARDEN_API_MAX_CONCURRENT`` already in the app → 503 with ``Retry-After``.
   A request holds its place only while the app works on it, not while its body trickles in.

The body read here is handed to the app unchanged. A 405 also gets an ``Allow`` header naming every method of its
path (Starlette names only the first route's).
"""

from __future__ import annotations

import asyncio
import secrets
from typing import Any

from starlette.datastructures import Headers
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from api.errors import SafeJSONResponse
from api.limits import TokenBuckets, retry_after
from api.routing import RouteTemplates, allowed_methods
from api.settings import ApiSettings

MUTATING = frozenset({"POST", "PUT", "PATCH", "DELETE"})


def token_ok(settings: ApiSettings, authorization: str | None) -> bool:
    expected = settings.api_token.get_secret_value() if settings.api_token else ""
    if not expected or not authorization:
        return False
    scheme, _, given = authorization.partition(" ")
    return scheme.lower() == "bearer" and secrets.compare_digest(given.strip().encode(), expected.encode())


def declared_length(headers: Headers) -> int | None:
    """The declared body length; None if the body is chunked or has none. (The HTTP server refuses a malformed
    or conflicting Content-Length before the app sees the request.)"""
    value = headers.get("content-length")
    try:
        return int(value) if value is not None else None
    except ValueError:
        return None


class RequestGuard:
    """ASGI middleware: concurrency limit, rate limit, token, body cap (see the module docstring)."""

    def __init__(self, app: ASGIApp, settings: ApiSettings, routes: RouteTemplates):
        self.app = app
        self.settings = settings
        self.routes = routes
        self.buckets = TokenBuckets(settings.api_rate_per_s, settings.api_rate_burst, settings.api_rate_clients)
        self.in_progress = 0

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = Headers(scope=scope)
        scope.setdefault("state", {})
        if scope["method"] in MUTATING:
            client = scope.get("client")
            wait = self.buckets.take(client[0] if client else "unknown")
            if wait > 0.0:
                detail = (
                    f"too many mutating requests from this client: {self.settings.api_rate_burst} at once, then "
                    f"{self.settings.api_rate_per_s:g} per second "
                    "(WINDWARDEN_API_RATE_BURST, WINDWARDEN_API_RATE_PER_S)"
                )
                await refuse(scope, receive, send, 429, "rate_limited", detail, {"Retry-After": retry_after(wait)})
                return
            if not token_ok(self.settings, headers.get("authorization")):
                detail = "missing or wrong bearer token"
                await refuse(scope, receive, send, 401, "unauthorized", detail, {"WWW-Authenticate": "Bearer"})
                return
        limit = self.settings.api_max_body_bytes
        declared = declared_length(headers)
        if declared is not None and declared > limit:
            await too_large(scope, receive, send, f"the declared body of {declared} bytes is over {limit} bytes")
            return
        timeout = self.settings.api_body_timeout_s
        try:
            body = await asyncio.wait_for(read_body(receive, limit, scope["state"]), timeout)
        except TimeoutError:
            detail = f"the body did not arrive within {timeout:g} s (WINDWARDEN_API_BODY_TIMEOUT_S)"
            await refuse(scope, receive, send, 408, "body_timeout", detail, {"Connection": "close"})
            return
        if body is None:
            await too_large(scope, receive, send, f"the body is over {limit} bytes")
            return
        if self.in_progress >= self.settings.api_max_concurrent:
            detail = f"{self.in_progress} requests in progress, the most this API takes (WINDWARDEN_API_MAX_CONCURRENT)"
            await refuse(scope, receive, send, 503, "overloaded", detail, {"Retry-After": "1"})
            return
        self.in_progress += 1
        try:
            await self.app(scope, replay(body, receive), self._allow_all_methods(scope, send))
        finally:
            self.in_progress -= 1

    def _allow_all_methods(self, scope: Scope, send: Send) -> Send:
        async def send_with_allow(message: Message) -> None:
            if message["type"] == "http.response.start" and message["status"] == 405:
                raw = [(k, v) for k, v in message.get("headers", []) if k.lower() != b"allow"]
                methods = ", ".join(allowed_methods(scope["app"], self.routes.of(scope)))
                message = {**message, "headers": [*raw, (b"allow", methods.encode("latin-1"))]}
            await send(message)

        return send_with_allow


async def read_body(receive: Receive, limit: int, state: dict[str, Any]) -> bytes | None:
    """The request body as it streams in, or None as soon as it passes ``limit`` bytes (the rest left unread).
    ``state["bytes_in"]`` counts the bytes read so far."""
    chunks: list[bytes] = []
    size = state["bytes_in"] = 0
    while True:
        message = await receive()
        if message["type"] != "http.request":  # the client went away: the app will see the disconnect
            break
        chunk = message.get("body", b"")
        size = state["bytes_in"] = size + len(chunk)
        if size > limit:
            return None
        chunks.append(chunk)
        if not message.get("more_body", False):
            break
    return b"".join(chunks)


def replay(body: bytes, receive: Receive) -> Receive:
    """A ``receive`` that hands over ``body`` once, then waits on the connection (for a disconnect)."""
    given = False

    async def receive_again() -> Message:
        nonlocal given
        if not given:
            given = True
            return {"type": "http.request", "body": body, "more_body": False}
        return await receive()

    return receive_again


async def refuse(
    scope: Scope, receive: Receive, send: Send, status: int, reason: str, detail: str, headers: dict[str, str]
) -> None:
    scope.setdefault("state", {})["refused"] = reason
    response = SafeJSONResponse({"detail": detail}, status_code=status, headers=headers)
    await response(scope, receive, send)


async def too_large(scope: Scope, receive: Receive, send: Send, detail: str) -> None:
    """413, and the connection closed after it: the server does not go on reading (draining) the body."""
    text = f"{detail} (WINDWARDEN_API_MAX_BODY_BYTES)"
    await refuse(scope, receive, send, 413, "body_too_large", text, {"Connection": "close"})
