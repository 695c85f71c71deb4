"""The FastAPI app: settings, the Zenoh bridge opened and closed by the lifespan, one router per resource."""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import FastAPI
from fastapi.exceptions import RequestValidationError
from starlette.exceptions import HTTPException

from api.bridge import Bridge
from api.deps import auth_first
from api.errors import SafeJSONResponse, http_error, validation_error
from api.routes import events, faults, health, metrics, run, supervisor
from api.settings import ApiSettings


def create_app(settings: ApiSettings | None = None) -> FastAPI:
    settings = settings or ApiSettings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        app.state.bridge = Bridge(settings)
        try:
            yield
        finally:
            app.state.bridge.close()

    app = FastAPI(
        title="windwarden",
        version="1",
        lifespan=lifespan,
        default_response_class=SafeJSONResponse,
        description="Inject faults into a live windwarden run and watch its supervisor.",
    )
    app.state.settings = settings
    app.middleware("http")(auth_first)
    app.add_exception_handler(RequestValidationError, validation_error)
    app.add_exception_handler(HTTPException, http_error)
    for module in (health, run, faults, supervisor, events, metrics):
        app.include_router(module.router)
    return app
