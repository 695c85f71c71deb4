"""The FastAPI app: settings, the Zenoh bridge opened and closed by the lifespan, the guard and the access log
around every request, one router per resource, and the OpenAPI pages from local assets."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI
from fastapi.exceptions import RequestValidationError
from starlette.exceptions import HTTPException

from api.accesslog import AccessLog, AccessLogFile, ApiCounters
from api.bridge import Bridge
from api.errors import SafeJSONResponse, http_error, validation_error
from api.guard import RequestGuard
from api.routes import docs, events, faults, health, metrics, run, supervisor
from api.routing import RouteTemplates
from api.settings import ApiProcessSettings, ApiSettings


def create_app(
    settings: ApiProcessSettings | None = None, bridge_factory: Callable[[ApiSettings], Any] = Bridge
) -> FastAPI:
    """The app; ``bridge_factory`` builds its link to plant and supervisor when it starts (a stand-in in tests).
    Given only the process's settings (``windwarden.live.config``), the limits come from the environment."""
    if not isinstance(settings, ApiSettings):
        settings = ApiSettings(**(settings.model_dump(exclude_unset=True) if settings is not None else {}))
    log_path = settings.access_log_path()
    access_log = AccessLogFile(log_path, settings.api_access_log_max_bytes) if log_path else None

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        app.state.injection_lock = asyncio.Lock()
        app.state.bridge = bridge_factory(settings)
        try:
            yield
        finally:
            app.state.bridge.close()
            if access_log is not None:
                access_log.close()

    app = FastAPI(
        title="windwarden",
        version="1",
        lifespan=lifespan,
        default_response_class=SafeJSONResponse,
        description="Inject faults into a live windwarden run and watch its supervisor.",
        docs_url=None,
        redoc_url=None,
    )
    app.state.settings = settings
    app.state.counters = ApiCounters()
    app.add_exception_handler(RequestValidationError, validation_error)
    app.add_exception_handler(HTTPException, http_error)
    modules = (health, run, faults, supervisor, events, metrics, docs)
    for module in modules:
        app.include_router(module.router)
    docs.add_assets(app)
    routes = RouteTemplates(
        [str(app.openapi_url), f"{docs.ASSETS_URL}/{{path:path}}"]
        + [route.path for module in modules for route in module.router.routes]
    )
    app.add_middleware(RequestGuard, settings=settings, routes=routes)  # inner: runs second
    app.add_middleware(AccessLog, log=access_log, counters=app.state.counters, routes=routes)  # outer: sees all
    return app
